//! rosbag2 I/O for the UniTac robot stack, with no ROS installation.
//!
//! - [`cdr`] and [`ros`]: a small CDR codec and the messages we exchange (sensor_msgs/Image,
//!   CompressedImage, std_msgs/Header and msg/unitac_msgs), every length bounded;
//! - [`image`]: Image / CompressedImage to a core RGB8 [`unitac_core::Frame`];
//! - [`read`]: a rosbag2 directory (metadata.yaml + .mcap or .db3) or a bare .mcap, streamed with
//!   bounded memory; truncated files are read up to their last complete record;
//! - [`write`](mod@write): rosbag2-compatible MCAP (profile ros2, ros2msg schemas, cdr) plus metadata.yaml;
//! - [`repair`](mod@repair): a cut recording (recorder killed, disk full) rewritten into a valid bag;
//! - [`replay`]: a bag as a runtime [`unitac_core::Source`], and the replay loop behind
//!   `unitac replay` (stages driven by the bag's stamps, optional output bag).

pub mod cdr;
pub mod fuzzing;
pub mod image;
pub mod metadata;
pub mod read;
pub mod repair;
pub mod replay;
pub mod ros;
pub mod write;

pub use cdr::CdrError;
pub use image::ImageError;
pub use metadata::MetadataError;
pub use read::{BagReader, McapError, RawMessage, ReadOptions, SqliteError, TopicInfo};
pub use repair::{RepairReport, repair};
pub use replay::{BagSource, ReplayError, ReplayOptions};
pub use ros::{CompressedImage, Image, PointCloud2, PointField, RosMessage};
pub use write::{BagWriter, Compression, UnknownCompression, WriteOptions};

use std::path::PathBuf;
use thiserror::Error;

/// Errors of this crate. Each displays as one line with its cause, and none exposes a
/// `source()`: printing an anyhow chain (`{:#}`) would repeat the cause otherwise.
#[derive(Debug, Error)]
pub enum BagError {
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error(
        "{0}: no bag here (expected a directory with metadata.yaml, .mcap or .db3 files, or a .mcap file)"
    )]
    NotABag(PathBuf),
    #[error("{path}: {error}")]
    Metadata {
        path: PathBuf,
        error: metadata::MetadataError,
    },
    #[error("{path}: unsupported: {msg}")]
    Unsupported { path: PathBuf, msg: String },
    #[error("{path}: MCAP: {error}")]
    Mcap {
        path: PathBuf,
        error: read::McapError,
    },
    #[error("{path}: sqlite3: {error}")]
    Sqlite {
        path: PathBuf,
        error: read::SqliteError,
    },
    #[error("{0}: listed in metadata.yaml, but there is no such file")]
    MissingFile(PathBuf),
    #[error("{path}: message of {len} bytes on {} at {log_time} ns is over the limit {max}: skipped", topic.name)]
    TooLarge {
        path: PathBuf,
        topic: std::sync::Arc<TopicInfo>,
        log_time: i64,
        len: u64,
        max: usize,
    },
    #[error("writing {path}: {msg}")]
    Write { path: PathBuf, msg: String },
    #[error("{topic} ({type_name}): {error}")]
    Cdr {
        topic: String,
        type_name: String,
        error: CdrError,
    },
}
