//! Rust mirror of msg/unitac_msgs, and [`Msg`], what flows between stages.
//!
//! Field meanings and units are documented once, in the `.msg` files; the names match them so the
//! ROS conversion in crates/ros is a plain field copy. These types serialize to JSON for the
//! command line and the golden files.

use crate::clock::Stamp;
use crate::frame::Frame;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Stamp,
    pub frame_id: String,
}

impl Header {
    pub fn new(stamp: Stamp, frame_id: impl Into<String>) -> Self {
        Self {
            stamp,
            frame_id: frame_id.into(),
        }
    }
    /// `<sensor>_optical_frame` (REP 103), the frame_id of everything a sensor produces.
    pub fn optical(stamp: Stamp, sensor_id: &str) -> Self {
        Self::new(stamp, crate::frame::optical_frame_id(sensor_id))
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactState {
    pub header: Header,
    pub sensor_id: String,
    pub frame_seq: u64,
    pub in_contact: bool,
    pub area_px: f32,
    pub area_mm2: f32,
    pub centroid_px: [f32; 2],
    pub bbox_px: [u32; 4],
    pub strength: f32,
    pub episode_id: u64,
    pub background_age_s: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactEpisode {
    pub header: Header,
    pub sensor_id: String,
    pub episode_id: u64,
    pub start: Stamp,
    pub end: Stamp,
    pub frame_count: u32,
    pub peak_area_px: f32,
    pub peak_area_mm2: f32,
    pub peak_frame_seq: u64,
    pub label: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TactileProperties {
    pub header: Header,
    pub sensor_id: String,
    pub episode_id: u64,
    pub label: String,
    pub hardness: f32,
    pub hardness_std: f32,
    pub roughness: f32,
    pub roughness_std: f32,
    pub texture: f32,
    pub texture_std: f32,
    pub model_id: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Winner {
    A = 0,
    B = 1,
    Tie = 2,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PropertyComparison {
    pub header: Header,
    pub property: String,
    pub episode_a: u64,
    pub label_a: String,
    pub episode_b: u64,
    pub label_b: String,
    pub winner: Winner,
    pub score_a: f32,
    pub score_b: f32,
    pub margin: f32,
    pub confidence: f32,
    pub sentence: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LatentSource {
    Real = 0,
    Predicted = 1,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TactileLatent {
    pub header: Header,
    pub source: LatentSource,
    pub sensor_id: String,
    pub shape: Vec<u32>,
    pub data: Vec<f32>,
    pub model_id: String,
    pub solver: String,
    pub steps: u32,
    pub guidance: f32,
    pub elapsed_s: f64,
    pub valid: bool,
    pub guard_report: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GripperMode {
    Position = 0,
    Force = 1,
    Stop = 2,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GripperCommand {
    pub header: Header,
    pub mode: GripperMode,
    pub position_m: f64,
    pub speed_m_s: f64,
    pub force_n: f64,
    pub reason: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolicyStatus {
    pub header: Header,
    pub scene: String,
    pub mode: String,
    pub phase: String,
    pub safety_ok: bool,
    pub message: String,
}

/// The frames of one contact episode, centred on its peak (for the touch encoder). Bounded by the
/// contact stage's `clip_frames`. Not a ROS message: nodes pass frames as sensor_msgs/Image.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeClip {
    pub sensor_id: String,
    pub episode_id: u64,
    pub label: String,
    /// Index into `frames` of the peak-area frame.
    pub peak_index: usize,
    pub frames: Vec<Frame>,
    /// The non-contact frame (the contact stage's background) at the time of the episode.
    pub background: Option<Frame>,
}

/// Everything that flows between stages. Frames may be dropped under load (drop-oldest edges);
/// every other variant is an event and is never dropped.
#[derive(Debug, Clone, PartialEq)]
pub enum Msg {
    Frame(Frame),
    Contact(ContactState),
    Episode(ContactEpisode),
    Clip(EpisodeClip),
    /// The contact stage's non-contact frame, announced when it is learned or loaded: the
    /// sensor prior (Z_sen) for the flow sampler.
    Background(Frame),
    Properties(TactileProperties),
    Comparison(PropertyComparison),
    Latent(TactileLatent),
    Command(GripperCommand),
    Status(PolicyStatus),
}

impl Msg {
    pub fn is_frame(&self) -> bool {
        matches!(self, Msg::Frame(_))
    }
    /// The time this message belongs to (capture time for frames, header stamp otherwise).
    pub fn stamp(&self) -> Stamp {
        match self {
            Msg::Frame(f) => f.stamp,
            Msg::Contact(m) => m.header.stamp,
            Msg::Episode(m) => m.header.stamp,
            Msg::Clip(m) => m.frames.last().map_or(Stamp::ZERO, |f| f.stamp),
            Msg::Background(f) => f.stamp,
            Msg::Properties(m) => m.header.stamp,
            Msg::Comparison(m) => m.header.stamp,
            Msg::Latent(m) => m.header.stamp,
            Msg::Command(m) => m.header.stamp,
            Msg::Status(m) => m.header.stamp,
        }
    }
    /// Short type name, as used in counters and JSON (`"frame"`, `"contact_state"`, ...).
    pub fn kind(&self) -> &'static str {
        match self {
            Msg::Frame(_) => "frame",
            Msg::Contact(_) => "contact_state",
            Msg::Episode(_) => "contact_episode",
            Msg::Clip(_) => "episode_clip",
            Msg::Background(_) => "background",
            Msg::Properties(_) => "tactile_properties",
            Msg::Comparison(_) => "property_comparison",
            Msg::Latent(_) => "tactile_latent",
            Msg::Command(_) => "gripper_command",
            Msg::Status(_) => "policy_status",
        }
    }
    /// JSON of an event (`{"type": kind, ...fields}`); frames give only their metadata.
    pub fn to_json(&self) -> serde_json::Value {
        let body = match self {
            Msg::Frame(f) | Msg::Background(f) => serde_json::json!({
                "sensor_id": f.sensor_id, "seq": f.seq, "stamp": f.stamp,
                "width": f.width, "height": f.height,
            }),
            Msg::Contact(m) => serde_json::to_value(m).unwrap_or_default(),
            Msg::Episode(m) => serde_json::to_value(m).unwrap_or_default(),
            Msg::Clip(m) => serde_json::json!({
                "sensor_id": m.sensor_id, "episode_id": m.episode_id, "label": m.label,
                "peak_index": m.peak_index,
                "frame_seqs": m.frames.iter().map(|f| f.seq).collect::<Vec<_>>(),
            }),
            Msg::Properties(m) => serde_json::to_value(m).unwrap_or_default(),
            Msg::Comparison(m) => serde_json::to_value(m).unwrap_or_default(),
            Msg::Latent(m) => serde_json::to_value(m).unwrap_or_default(),
            Msg::Command(m) => serde_json::to_value(m).unwrap_or_default(),
            Msg::Status(m) => serde_json::to_value(m).unwrap_or_default(),
        };
        let mut v = serde_json::json!({ "type": self.kind() });
        if let (Some(obj), serde_json::Value::Object(fields)) = (v.as_object_mut(), body) {
            obj.extend(fields);
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_carries_type_and_fields() {
        let m = Msg::Status(PolicyStatus {
            header: Header::new(Stamp(1), "base"),
            scene: "fabric_selection".into(),
            mode: "vtla_real".into(),
            phase: "press".into(),
            safety_ok: true,
            message: String::new(),
        });
        let j = m.to_json();
        assert_eq!(j["type"], "policy_status");
        assert_eq!(j["phase"], "press");
        assert_eq!(j["header"]["stamp"], 1);
        assert!(!m.is_frame());
    }
}
