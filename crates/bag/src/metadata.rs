//! rosbag2 `metadata.yaml`: parsing (versions 4 to 9, lenient about optional fields) and writing
//! (version 9, the layout `ros2 bag record` on Jazzy writes and rosbags reads).
//!
//! A metadata file is input from outside: its size, topic count and file list are bounded, and a
//! listed file must be a plain relative path inside the bag directory (no `..`, not absolute).

use serde::Deserialize;
use std::fmt::Write as _;
use std::path::{Component, Path};
use thiserror::Error;

/// Largest metadata.yaml read.
pub const MAX_METADATA_BYTES: usize = 4 << 20;
/// Most topics / files a bag may list.
pub const MAX_TOPICS: usize = 10_000;
pub const MAX_FILES: usize = 100_000;

#[derive(Debug, Clone, PartialEq, Deserialize)]
struct File {
    rosbag2_bagfile_information: BagInfo,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct BagInfo {
    pub version: u32,
    #[serde(default)]
    pub storage_identifier: String,
    #[serde(default)]
    pub relative_file_paths: Vec<String>,
    #[serde(default)]
    pub topics_with_message_count: Vec<TopicWithCount>,
    #[serde(default)]
    pub message_count: u64,
    #[serde(default)]
    pub compression_format: String,
    #[serde(default)]
    pub compression_mode: String,
    #[serde(default)]
    pub starting_time: Option<StartingTime>,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct StartingTime {
    pub nanoseconds_since_epoch: i64,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct TopicWithCount {
    pub topic_metadata: TopicMetadata,
    #[serde(default)]
    pub message_count: u64,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct TopicMetadata {
    pub name: String,
    #[serde(rename = "type")]
    pub type_name: String,
    #[serde(default)]
    pub serialization_format: String,
    /// A YAML string (versions <= 8) or a list (version 9).
    #[serde(default)]
    pub offered_qos_profiles: serde_yaml::Value,
}

/// Why a metadata.yaml was refused (one line each).
#[derive(Debug, Error)]
pub enum MetadataError {
    #[error("{0}")]
    Bounds(#[from] unitac_core::yaml::YamlBoundError),
    #[error("{}", one_line(&.0.to_string()))]
    Yaml(#[from] serde_yaml::Error),
    #[error("{0} topics, over the limit {MAX_TOPICS}")]
    TooManyTopics(usize),
    #[error("{0} files, over the limit {MAX_FILES}")]
    TooManyFiles(usize),
    #[error("file '{0}' is not a relative path inside the bag directory")]
    NotRelative(String),
    #[error("file '{0}' is listed more than once")]
    Duplicate(String),
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Parse metadata.yaml text.
pub fn parse(text: &str) -> Result<BagInfo, MetadataError> {
    unitac_core::yaml::check(text, MAX_METADATA_BYTES)?;
    let f: File = serde_yaml::from_str(text)?;
    let info = f.rosbag2_bagfile_information;
    if info.topics_with_message_count.len() > MAX_TOPICS {
        return Err(MetadataError::TooManyTopics(
            info.topics_with_message_count.len(),
        ));
    }
    if info.relative_file_paths.len() > MAX_FILES {
        return Err(MetadataError::TooManyFiles(info.relative_file_paths.len()));
    }
    let mut seen = std::collections::BTreeSet::new();
    for p in &info.relative_file_paths {
        if !is_plain_relative(p) {
            return Err(MetadataError::NotRelative(p.clone()));
        }
        let normal: std::path::PathBuf = Path::new(p)
            .components()
            .filter(|c| matches!(c, Component::Normal(_)))
            .collect();
        if !seen.insert(normal) {
            return Err(MetadataError::Duplicate(p.clone()));
        }
    }
    Ok(info)
}

fn is_plain_relative(p: &str) -> bool {
    !p.is_empty()
        && Path::new(p)
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
}

/// The QoS rosbag2 records for a reliable, volatile publisher with default depth, as a v9 list
/// entry (infinite durations are rosbag2's `9223372036 s 854775807 ns`).
const QOS_V9: &str = "- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false";

/// `offered_qos_profiles` of a channel, as the YAML string rosbag2 puts in MCAP channel metadata.
pub fn default_qos_yaml() -> &'static str {
    QOS_V9
}

/// One topic's line in the metadata written by [`render`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicCount {
    pub name: String,
    pub type_name: String,
    pub count: u64,
}

/// What [`render`] needs to know about a written bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WrittenBag {
    pub file_name: String,
    pub start_ns: i64,
    pub end_ns: i64,
    pub topics: Vec<TopicCount>,
    pub compression: String,
}

fn yaml_str(s: &str) -> String {
    // Single-quoted YAML scalar: only the quote itself needs escaping.
    format!("'{}'", s.replace('\'', "''"))
}

/// metadata.yaml version 9 for an MCAP bag of one file. Deterministic: topics in the order given.
pub fn render(bag: &WrittenBag) -> String {
    let count: u64 = bag.topics.iter().map(|t| t.count).sum();
    let duration = if count == 0 {
        0
    } else {
        bag.end_ns.saturating_sub(bag.start_ns).max(0)
    };
    let start = if count == 0 { 0 } else { bag.start_ns };
    let mut s = String::new();
    let _ = writeln!(s, "rosbag2_bagfile_information:");
    let _ = writeln!(s, "  version: 9");
    let _ = writeln!(s, "  storage_identifier: mcap");
    let _ = writeln!(s, "  duration:\n    nanoseconds: {duration}");
    let _ = writeln!(s, "  starting_time:\n    nanoseconds_since_epoch: {start}");
    let _ = writeln!(s, "  message_count: {count}");
    if bag.topics.is_empty() {
        let _ = writeln!(s, "  topics_with_message_count: []");
    } else {
        let _ = writeln!(s, "  topics_with_message_count:");
    }
    for t in &bag.topics {
        let _ = writeln!(s, "    - topic_metadata:");
        let _ = writeln!(s, "        name: {}", yaml_str(&t.name));
        let _ = writeln!(s, "        type: {}", yaml_str(&t.type_name));
        let _ = writeln!(s, "        serialization_format: cdr");
        let _ = writeln!(s, "        offered_qos_profiles:");
        for line in QOS_V9.lines() {
            let _ = writeln!(s, "          {line}");
        }
        let _ = writeln!(s, "        type_description_hash: ''");
        let _ = writeln!(s, "      message_count: {}", t.count);
    }
    let _ = writeln!(s, "  compression_format: ''");
    let _ = writeln!(s, "  compression_mode: ''");
    let _ = writeln!(
        s,
        "  relative_file_paths:\n    - {}",
        yaml_str(&bag.file_name)
    );
    let _ = writeln!(s, "  files:");
    let _ = writeln!(s, "    - path: {}", yaml_str(&bag.file_name));
    let _ = writeln!(
        s,
        "      starting_time:\n        nanoseconds_since_epoch: {start}"
    );
    let _ = writeln!(s, "      duration:\n        nanoseconds: {duration}");
    let _ = writeln!(s, "      message_count: {count}");
    let _ = writeln!(s, "  custom_data: ~");
    let _ = writeln!(s, "  ros_distro: unitac");
    if !bag.compression.is_empty() {
        // Chunk compression is inside the MCAP file; rosbag2's compression_* fields describe
        // file/message compression and stay empty.
        let _ = writeln!(s, "# mcap chunk compression: {}", bag.compression);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::yaml::YamlBoundError;

    #[test]
    fn written_metadata_parses_back() {
        let bag = WrittenBag {
            file_name: "out_0.mcap".into(),
            start_ns: 10,
            end_ns: 25,
            topics: vec![TopicCount {
                name: "/gs/image_raw".into(),
                type_name: "sensor_msgs/msg/Image".into(),
                count: 3,
            }],
            compression: "zstd".into(),
        };
        let info = parse(&render(&bag)).unwrap();
        assert_eq!(info.version, 9);
        assert_eq!(info.storage_identifier, "mcap");
        assert_eq!(info.message_count, 3);
        assert_eq!(info.relative_file_paths, ["out_0.mcap"]);
        let t = &info.topics_with_message_count[0];
        assert_eq!(t.topic_metadata.type_name, "sensor_msgs/msg/Image");
        assert!(t.topic_metadata.offered_qos_profiles.is_sequence());
    }

    #[test]
    fn hostile_metadata_is_rejected() {
        let escape = "rosbag2_bagfile_information:\n  version: 5\n  relative_file_paths: ['../../etc/passwd']\n";
        assert!(
            parse(escape)
                .unwrap_err()
                .to_string()
                .contains("not a relative path")
        );
        let abs =
            "rosbag2_bagfile_information:\n  version: 5\n  relative_file_paths: ['/etc/passwd']\n";
        assert!(parse(abs).is_err());
        assert!(parse("{").is_err());
        assert!(parse("rosbag2_bagfile_information: 3").is_err());
        let twice = "rosbag2_bagfile_information:\n  version: 9\n  relative_file_paths: [a.mcap, ./a.mcap]\n";
        assert!(matches!(parse(twice), Err(MetadataError::Duplicate(_))));
        let big = "#".repeat(MAX_METADATA_BYTES + 1);
        assert!(matches!(
            parse(&big),
            Err(MetadataError::Bounds(YamlBoundError::TooLarge { .. }))
        ));
    }
}
