//! Reading rosbag2 bags: a directory (metadata.yaml + .mcap or .db3 files), a bare .mcap or a
//! bare .db3, as one stream of raw messages in file order.
//!
//! MCAP is read record by record from the file (opcode, length, body; the length checked against
//! [`MAX_RECORD_BYTES`] before anything is read into a buffer reused across records); each chunk
//! record is decompressed here (zstd, lz4 or none) after checking its claimed size against the
//! same limit (an uncompressed one is walked in place), its CRC is checked, and the records inside
//! are walked with bounds checks, so memory stays bounded whatever the file says. The summary
//! section is never needed: a file a recorder could not finish (killed, disk full) is read up to
//! its last complete record and flagged [`BagReader::truncated`]. sqlite3 (Humble's default) is
//! read with rusqlite from the `topics` and `messages` tables, in pages ordered by (timestamp, id).
//!
//! Messages of every topic come out with their raw CDR bytes, whatever their type; decoding is the
//! caller's choice (see [`crate::ros::is_known_type`]).

mod discover;
mod mcap;
mod sqlite;

pub use self::mcap::{McapError, read_mcap_bytes};
pub use sqlite::SqliteError;

use self::mcap::McapFile;
use crate::BagError;
use crate::cdr::MAX_IMAGE_BYTES;
use crate::metadata;
use discover::{Kind, read_bounded, storage_files_in, storage_kind};
use sqlite::SqliteFile;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Longest MCAP record (and decompressed chunk) accepted: the largest image plus headroom.
pub const MAX_RECORD_BYTES: usize = MAX_IMAGE_BYTES + (1 << 20);

/// A callback that sees one message with its payload borrowed: (topic, log time \[ns], CDR).
pub type Visit<'f, R> = dyn FnMut(&Arc<TopicInfo>, i64, &[u8]) -> R + 'f;

/// A topic as the bag declares it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    pub name: String,
    /// e.g. `sensor_msgs/msg/Image` (empty if the file gives none).
    pub type_name: String,
    /// Serialization format / message encoding, `cdr` for ROS 2.
    pub encoding: String,
    /// The `ros2msg` schema text the file carries for the type (MCAP), empty when it has none
    /// (sqlite3, metadata.yaml).
    pub schema: String,
}

/// One message, undecoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawMessage {
    pub topic: Arc<TopicInfo>,
    /// Receive time in the bag [ns since the epoch].
    pub log_time: i64,
    /// Serialized payload (CDR with its 4-byte encapsulation header).
    pub data: Vec<u8>,
}

/// Which messages to return.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Only these topics (all when empty).
    pub topics: Vec<String>,
    /// Only messages with `log_time >= start_ns`.
    pub start_ns: Option<i64>,
    /// Only messages with `log_time < end_ns`.
    pub end_ns: Option<i64>,
}

impl ReadOptions {
    pub(crate) fn wants(&self, topic: &str, t: i64) -> bool {
        (self.topics.is_empty() || self.topics.iter().any(|x| x == topic))
            && self.start_ns.is_none_or(|s| t >= s)
            && self.end_ns.is_none_or(|e| t < e)
    }
}

/// A bag opened for reading: an iterator over its messages.
#[derive(Debug)]
pub struct BagReader {
    path: PathBuf,
    files: VecDeque<PathBuf>,
    current: Option<Storage>,
    opts: ReadOptions,
    declared: Vec<TopicInfo>,
    truncated: Vec<PathBuf>,
    failed: bool,
}

#[derive(Debug)]
enum Storage {
    Mcap(Box<McapFile>),
    Sqlite(Box<SqliteFile>),
}

impl BagReader {
    /// Open a bag directory, a bare `.mcap` or a bare `.db3`.
    pub fn open(path: &Path, opts: ReadOptions) -> Result<Self, BagError> {
        let io = |e| BagError::Io {
            path: path.to_path_buf(),
            error: e,
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        let mut declared = Vec::new();
        let files: Vec<PathBuf> = if meta.is_file() {
            if storage_kind(path).is_none() {
                return Err(BagError::NotABag(path.to_path_buf()));
            }
            vec![path.to_path_buf()]
        } else {
            let mpath = path.join("metadata.yaml");
            if mpath.is_file() {
                let text = read_bounded(&mpath, metadata::MAX_METADATA_BYTES)?;
                let info = metadata::parse(&text).map_err(|error| BagError::Metadata {
                    path: mpath.clone(),
                    error,
                })?;
                if !info.compression_mode.is_empty() || !info.compression_format.is_empty() {
                    return Err(BagError::Unsupported {
                        path: path.to_path_buf(),
                        msg: format!(
                            "rosbag2 {} compression '{}' (decompress with `ros2 bag convert`; \
                             MCAP chunk compression is supported)",
                            info.compression_mode, info.compression_format
                        ),
                    });
                }
                declared = info
                    .topics_with_message_count
                    .iter()
                    .map(|t| TopicInfo {
                        name: t.topic_metadata.name.clone(),
                        type_name: t.topic_metadata.type_name.clone(),
                        encoding: t.topic_metadata.serialization_format.clone(),
                        schema: String::new(),
                    })
                    .collect();
                let listed: Vec<PathBuf> = info
                    .relative_file_paths
                    .iter()
                    .map(|p| path.join(p))
                    .collect();
                // A recording that died before writing its final metadata lists no files.
                if listed.is_empty() {
                    storage_files_in(path)?
                } else {
                    listed
                }
            } else {
                storage_files_in(path)?
            }
        };
        if files.is_empty() {
            return Err(BagError::NotABag(path.to_path_buf()));
        }
        for f in &files {
            if !f.is_file() {
                return Err(BagError::MissingFile(f.clone()));
            }
            if storage_kind(f).is_none() {
                return Err(BagError::Unsupported {
                    path: f.clone(),
                    msg: "storage file is neither .mcap nor .db3".into(),
                });
            }
        }
        Ok(Self {
            path: path.to_path_buf(),
            files: files.into(),
            current: None,
            opts,
            declared,
            truncated: Vec::new(),
            failed: false,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
    /// Topics listed in metadata.yaml (empty for a bare file).
    pub fn declared_topics(&self) -> &[TopicInfo] {
        &self.declared
    }
    /// Storage files that ended before their end (no footer, cut record): read up to there.
    pub fn truncated(&self) -> &[PathBuf] {
        &self.truncated
    }

    /// The next message, its payload borrowed for the call of `f` (no copy for MCAP chunks).
    /// `Ok(None)` at the end.
    pub fn next_with<R>(&mut self, f: &mut Visit<'_, R>) -> Result<Option<R>, BagError> {
        if self.failed {
            return Ok(None);
        }
        let r = self.next_with_inner(f);
        if let Err(e) = &r {
            if !matches!(e, BagError::TooLarge { .. }) {
                self.failed = true;
            }
        }
        r
    }

    fn next_with_inner<R>(&mut self, f: &mut Visit<'_, R>) -> Result<Option<R>, BagError> {
        loop {
            if self.current.is_none() {
                let Some(p) = self.files.pop_front() else {
                    return Ok(None);
                };
                self.current = Some(match storage_kind(&p) {
                    Some(Kind::Sqlite) => Storage::Sqlite(Box::new(SqliteFile::open(&p)?)),
                    _ => Storage::Mcap(Box::new(McapFile::open(&p)?)),
                });
            }
            let next = match &mut self.current {
                Some(Storage::Mcap(m)) => {
                    let r = m.next_with(&self.opts, f);
                    if m.truncated && !self.truncated.contains(&m.path) {
                        tracing::warn!(
                            "{}: file ends before its end record; read up to the last complete record",
                            m.path.display()
                        );
                        self.truncated.push(m.path.clone());
                    }
                    r
                }
                Some(Storage::Sqlite(s)) => s
                    .next(&self.opts)
                    .map(|o| o.map(|m| f(&m.topic, m.log_time, &m.data))),
                None => Ok(None),
            }?;
            match next {
                Some(m) => return Ok(Some(m)),
                None => self.current = None,
            }
        }
    }
}

impl Iterator for BagReader {
    type Item = Result<RawMessage, BagError>;
    /// After an error that leaves the file unreadable (corrupt MCAP record, sqlite failure) the
    /// iterator ends; a message over the size limit is one error and reading goes on.
    fn next(&mut self) -> Option<Self::Item> {
        self.next_with(&mut |topic, log_time, data| RawMessage {
            topic: Arc::clone(topic),
            log_time,
            data: data.to_vec(),
        })
        .transpose()
    }
}
