//! Rewriting a cut recording into a valid bag (`unitac bag repair IN OUT`).
//!
//! A recorder killed with SIGKILL (or stopped by a full disk) leaves an MCAP file without its
//! summary and footer. Our reader recovers every complete record, but `ros2 bag`, rosbags and
//! Foxglove look for the footer first ("File end magic is invalid") and read nothing. [`repair`]
//! streams every message the reader recovers, with its topic's schema from the input (or the
//! one this crate knows for the type), into a new bag written by [`BagWriter`]: footer, summary,
//! indexes and metadata.yaml, readable by all of them. The input is never modified.

use crate::BagError;
use crate::read::{BagReader, ReadOptions};
use crate::ros::schema_text;
use crate::write::{BagWriter, TopicId, WriteOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What [`repair`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RepairReport {
    /// The bag written (a directory, or the file for a path ending in `.mcap`).
    pub output: PathBuf,
    /// Messages copied, per topic in order of first appearance.
    pub topics: Vec<(String, u64)>,
    /// Storage files of the input that ended before their end record.
    pub truncated: Vec<PathBuf>,
    /// Topics left out because neither the input nor this crate has their schema.
    pub skipped_topics: Vec<String>,
    /// Messages left out because they were over the size limit.
    pub skipped_messages: u64,
    /// A corrupt record that stopped reading: everything before it was copied.
    pub stopped_by: Option<String>,
}

impl RepairReport {
    pub fn messages(&self) -> u64 {
        self.topics.iter().map(|(_, n)| n).sum()
    }
}

/// Copy every readable message of the bag at `input` into a new bag at `output`.
/// Errors: the input cannot be opened, or the output cannot be written.
pub fn repair(input: &Path, output: &Path) -> Result<RepairReport, BagError> {
    let mut reader = BagReader::open(input, ReadOptions::default())?;
    let mut writer = BagWriter::create(output, WriteOptions::default())?;
    let mut ids: BTreeMap<String, Option<TopicId>> = BTreeMap::new();
    let mut report = RepairReport::default();
    let mut failed = None;
    loop {
        let next = reader.next_with(&mut |topic, log_time, data| -> Result<(), BagError> {
            let id = match ids.get(&topic.name) {
                Some(id) => *id,
                None => {
                    let schema = if topic.schema.is_empty() {
                        schema_text(&topic.type_name)
                    } else {
                        Some(topic.schema.clone())
                    };
                    let id = match schema {
                        Some(s) => {
                            Some(writer.add_topic_with_schema(&topic.name, &topic.type_name, &s)?)
                        }
                        None => {
                            report.skipped_topics.push(topic.name.clone());
                            None
                        }
                    };
                    ids.insert(topic.name.clone(), id);
                    id
                }
            };
            if let Some(id) = id {
                writer.write_raw(id, log_time, data)?;
                match report.topics.iter_mut().find(|(n, _)| *n == topic.name) {
                    Some((_, n)) => *n += 1,
                    None => report.topics.push((topic.name.clone(), 1)),
                }
            }
            Ok(())
        });
        match next {
            Ok(Some(written)) => written?,
            Ok(None) => break,
            Err(BagError::TooLarge { .. }) => report.skipped_messages += 1,
            Err(e) => {
                failed = Some(e.to_string());
                break;
            }
        }
    }
    report.truncated = reader.truncated().to_vec();
    report.stopped_by = failed;
    report.output = writer.finish()?;
    Ok(report)
}
