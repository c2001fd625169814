//! Writing rosbag2-compatible MCAP: profile `ros2`, one `ros2msg` schema per type (dependencies
//! included), `cdr` channels with rosbag2's `offered_qos_profiles` metadata, and a metadata.yaml
//! (version 9) beside the file when writing a bag directory.
//!
//! Crash behaviour: chunks are built in memory (the writer never seeks back into the file) and each
//! finished chunk is written and flushed at once, so a recorder killed with SIGKILL leaves a file
//! of complete chunks (plus at most a partial last one) that [`crate::BagReader`] reads back. The
//! metadata.yaml is written when the bag is created (listing the file, no counts) and rewritten
//! with the counts by [`BagWriter::finish`].
//!
//! Output depends only on what is written: no wall clock, no host names, topics in the order they
//! were added. Two runs over the same input give the same bytes.

use crate::BagError;
use crate::metadata::{self, TopicCount, WrittenBag};
use crate::ros::{RosMessage, schema_text};
use std::collections::BTreeMap;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Chunk compression.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compression {
    #[default]
    None,
    Zstd,
    Lz4,
}

impl Compression {
    fn name(self) -> &'static str {
        match self {
            Compression::None => "",
            Compression::Zstd => "zstd",
            Compression::Lz4 => "lz4",
        }
    }
}

/// A compression name that is none of none, zstd, lz4.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("'{0}' is not one of: none, zstd, lz4")]
pub struct UnknownCompression(pub String);

impl std::str::FromStr for Compression {
    type Err = UnknownCompression;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "none" | "" => Ok(Compression::None),
            "zstd" => Ok(Compression::Zstd),
            "lz4" => Ok(Compression::Lz4),
            _ => Err(UnknownCompression(s.to_string())),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WriteOptions {
    pub compression: Compression,
    /// Uncompressed bytes per chunk; a chunk is closed and flushed once it is this large.
    pub chunk_size: u64,
}

impl Default for WriteOptions {
    fn default() -> Self {
        Self {
            compression: Compression::Zstd,
            chunk_size: 1 << 20,
        }
    }
}

/// Handle of a topic added to a [`BagWriter`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TopicId(usize);

#[derive(Debug)]
struct Topic {
    channel: u16,
    name: String,
    type_name: String,
    count: u64,
    sequence: u32,
}

/// An MCAP bag being written (a rosbag2 directory, or a bare file when the path ends in `.mcap`).
pub struct BagWriter {
    dir: Option<PathBuf>,
    file_path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<std::fs::File>>>,
    opts: WriteOptions,
    schemas: BTreeMap<String, u16>,
    topics: Vec<Topic>,
    bounds: Option<(i64, i64)>,
    pending: u64,
}

impl std::fmt::Debug for BagWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagWriter")
            .field("file", &self.file_path)
            .field("topics", &self.topics)
            .finish_non_exhaustive()
    }
}

/// The cause of an MCAP writer error: its `Io` variant displays only "I/O error from writing,
/// or reading a compression stream", which hides a full disk.
fn mcap_cause(e: mcap::McapError) -> String {
    match e {
        mcap::McapError::Io(io) => io.to_string(),
        other => other.to_string(),
    }
}

impl BagWriter {
    /// Create a new bag. `path` ending in `.mcap` is a bare file; anything else is a rosbag2
    /// directory `<path>/` with `<name>_0.mcap` and metadata.yaml. Existing bags are not
    /// overwritten.
    pub fn create(path: &Path, opts: WriteOptions) -> Result<Self, BagError> {
        let werr = |msg: String| BagError::Write {
            path: path.to_path_buf(),
            msg,
        };
        if path.exists() {
            return Err(werr("already exists; not overwriting a bag".into()));
        }
        let (dir, file_path) = if path.extension().is_some_and(|e| e == "mcap") {
            (None, path.to_path_buf())
        } else {
            let name = path
                .file_name()
                .and_then(|n| n.to_str())
                .filter(|n| !n.is_empty())
                .ok_or_else(|| werr("a bag directory needs a UTF-8 name".into()))?;
            std::fs::create_dir_all(path).map_err(|e| werr(e.to_string()))?;
            (
                Some(path.to_path_buf()),
                path.join(format!("{name}_0.mcap")),
            )
        };
        let file = std::fs::File::create_new(&file_path).map_err(|e| BagError::Write {
            path: file_path.clone(),
            msg: e.to_string(),
        })?;
        let mcap_opts = mcap::WriteOptions::new()
            .profile("ros2")
            .library("unitac-bag")
            .compression(match opts.compression {
                Compression::None => None,
                Compression::Zstd => Some(mcap::Compression::Zstd),
                Compression::Lz4 => Some(mcap::Compression::Lz4),
            })
            // We close chunks ourselves (and flush them) in `write_raw`.
            .chunk_size(None)
            .disable_seeking(true);
        let writer = mcap_opts
            .create(BufWriter::new(file))
            .map_err(|e| BagError::Write {
                path: file_path.clone(),
                msg: mcap_cause(e),
            })?;
        let w = Self {
            dir,
            file_path,
            writer: Some(writer),
            opts,
            schemas: BTreeMap::new(),
            topics: Vec::new(),
            bounds: None,
            pending: 0,
        };
        w.write_metadata()?;
        Ok(w)
    }

    fn werr(&self, msg: impl std::fmt::Display) -> BagError {
        BagError::Write {
            path: self.file_path.clone(),
            msg: msg.to_string(),
        }
    }

    fn mcap(&mut self) -> Result<&mut mcap::Writer<BufWriter<std::fs::File>>, BagError> {
        let path = self.file_path.clone();
        self.writer.as_mut().ok_or(BagError::Write {
            path,
            msg: "bag already finished".into(),
        })
    }

    /// Add a topic of a type this crate knows (see [`crate::ros::KNOWN_TYPES`]).
    pub fn add_topic(&mut self, name: &str, type_name: &str) -> Result<TopicId, BagError> {
        let schema = schema_text(type_name)
            .ok_or_else(|| self.werr(format!("no schema for type '{type_name}'")))?;
        self.add_topic_with_schema(name, type_name, &schema)
    }

    /// Add a topic with its own ros2msg schema text (e.g. copied from an input bag).
    pub fn add_topic_with_schema(
        &mut self,
        name: &str,
        type_name: &str,
        schema: &str,
    ) -> Result<TopicId, BagError> {
        if let Some(i) = self.topics.iter().position(|t| t.name == name) {
            if self.topics[i].type_name != type_name {
                return Err(self.werr(format!(
                    "topic {name} already has type {}, not {type_name}",
                    self.topics[i].type_name
                )));
            }
            return Ok(TopicId(i));
        }
        let schema_id = match self.schemas.get(type_name) {
            Some(&id) => id,
            None => {
                let id = self
                    .mcap()?
                    .add_schema(type_name, "ros2msg", schema.as_bytes())
                    .map_err(|e| self.werr(mcap_cause(e)))?;
                self.schemas.insert(type_name.to_string(), id);
                id
            }
        };
        let mut meta = BTreeMap::new();
        meta.insert(
            "offered_qos_profiles".to_string(),
            metadata::default_qos_yaml().to_string(),
        );
        meta.insert("topic_type_hash".to_string(), String::new());
        let channel = self
            .mcap()?
            .add_channel(schema_id, name, "cdr", &meta)
            .map_err(|e| self.werr(mcap_cause(e)))?;
        self.topics.push(Topic {
            channel,
            name: name.to_string(),
            type_name: type_name.to_string(),
            count: 0,
            sequence: 0,
        });
        Ok(TopicId(self.topics.len() - 1))
    }

    /// Write one serialized message (CDR payload) at `log_time` \[ns].
    pub fn write_raw(
        &mut self,
        topic: TopicId,
        log_time: i64,
        data: &[u8],
    ) -> Result<(), BagError> {
        let t = self.topics.get_mut(topic.0).ok_or(BagError::Write {
            path: self.file_path.clone(),
            msg: format!("unknown topic id {}", topic.0),
        })?;
        t.count += 1;
        t.sequence = t.sequence.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id: t.channel,
            sequence: t.sequence,
            log_time: u64::try_from(log_time.max(0)).unwrap_or(0),
            publish_time: u64::try_from(log_time.max(0)).unwrap_or(0),
        };
        self.bounds = Some(match self.bounds {
            None => (log_time, log_time),
            Some((a, b)) => (a.min(log_time), b.max(log_time)),
        });
        let chunk_size = self.opts.chunk_size;
        let path = self.file_path.clone();
        self.mcap()?
            .write_to_known_channel(&header, data)
            .map_err(|e| BagError::Write {
                path,
                msg: mcap_cause(e),
            })?;
        self.pending += data.len() as u64 + 32;
        if self.pending >= chunk_size {
            self.flush()?;
        }
        Ok(())
    }

    /// Serialize and write a message.
    pub fn write<M: RosMessage>(
        &mut self,
        topic: TopicId,
        log_time: i64,
        msg: &M,
    ) -> Result<(), BagError> {
        self.write_raw(topic, log_time, &msg.to_cdr())
    }

    /// Close the last chunk and flush it to the file (the bag stays open), then rewrite
    /// metadata.yaml with the messages on disk: a recorder killed after this leaves metadata
    /// that counts what `unitac bag repair` will recover.
    pub fn flush(&mut self) -> Result<(), BagError> {
        self.pending = 0;
        self.mcap()?.flush().map_err(|e| self.werr(mcap_cause(e)))?;
        self.write_metadata()
    }

    fn write_metadata(&self) -> Result<(), BagError> {
        let Some(dir) = &self.dir else {
            return Ok(());
        };
        let (start, end) = self.bounds.unwrap_or((0, 0));
        let text = metadata::render(&WrittenBag {
            file_name: self
                .file_path
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or_default()
                .to_string(),
            start_ns: start,
            end_ns: end,
            topics: self
                .topics
                .iter()
                .map(|t| TopicCount {
                    name: t.name.clone(),
                    type_name: t.type_name.clone(),
                    count: t.count,
                })
                .collect(),
            compression: self.opts.compression.name().to_string(),
        });
        let tmp = dir.join("metadata.yaml.tmp");
        let path = dir.join("metadata.yaml");
        let io = |e: std::io::Error| BagError::Write {
            path: path.clone(),
            msg: e.to_string(),
        };
        std::fs::write(&tmp, text).map_err(io)?;
        std::fs::rename(&tmp, &path).map_err(io)
    }

    /// Messages written per topic so far, in the order topics were added.
    pub fn counts(&self) -> Vec<(String, u64)> {
        self.topics
            .iter()
            .map(|t| (t.name.clone(), t.count))
            .collect()
    }

    /// Write the summary and footer, and the final metadata.yaml. Returns the bag path.
    pub fn finish(mut self) -> Result<PathBuf, BagError> {
        if let Some(mut w) = self.writer.take() {
            w.finish().map_err(|e| self.werr(mcap_cause(e)))?;
            let mut inner = w.into_inner();
            inner.flush().map_err(|e| self.werr(e))?;
        }
        self.write_metadata()?;
        Ok(self.dir.clone().unwrap_or_else(|| self.file_path.clone()))
    }
}
