//! rosbag2 I/O for the UniTac robot stack, with no ROS installation.
//!
//! - [`cdr`] and [`ros`]: a small CDR codec and the messages we exchange (sensor_msgs/Image,
//!   CompressedImage, std_msgs/Header and msg/unitac_msgs), every length bounded;
//! - [`image`]: Image / CompressedImage to a core RGB8 [`unitac_core::Frame`];
//! - [`read`]: a rosbag2 directory (metadata.yaml + .mcap or .db3) or a bare .mcap, streamed with
//!   bounded memory; truncated files are read up to their last complete record;
//! - [`write`](mod@write): rosbag2-compatible MCAP (profile ros2, ros2msg schemas, cdr) plus metadata.yaml;
//! - [`replay`]: a bag as a runtime [`unitac_core::Source`], and the replay loop behind
//!   `unitac replay` (stages driven by the bag's stamps, optional output bag).

pub mod cdr;
pub mod fuzzing;
pub mod image;
pub mod metadata;
pub mod read;
pub mod replay;
pub mod ros;
pub mod write;

pub use cdr::CdrError;
pub use image::ImageError;
pub use read::{BagReader, RawMessage, ReadOptions, TopicInfo};
pub use replay::{BagSource, ReplayOptions};
pub use ros::{CompressedImage, Image, RosMessage};
pub use write::{BagWriter, Compression, WriteOptions};

use std::path::PathBuf;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum BagError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "{0}: no bag here (expected a directory with metadata.yaml, .mcap or .db3 files, or a .mcap file)"
    )]
    NotABag(PathBuf),
    #[error("{path}: metadata.yaml: {msg}")]
    Metadata { path: PathBuf, msg: String },
    #[error("{path}: unsupported: {msg}")]
    Unsupported { path: PathBuf, msg: String },
    #[error("{path}: MCAP: {msg}")]
    Mcap { path: PathBuf, msg: String },
    #[error("{path}: sqlite3: {msg}")]
    Sqlite { path: PathBuf, msg: String },
    #[error("{path}: message of {len} bytes on {topic} is over the limit {max}")]
    TooLarge {
        path: PathBuf,
        topic: String,
        len: usize,
        max: usize,
    },
    #[error("writing {path}: {msg}")]
    Write { path: PathBuf, msg: String },
    #[error("{topic} ({type_name}): {source}")]
    Cdr {
        topic: String,
        type_name: String,
        source: CdrError,
    },
}
