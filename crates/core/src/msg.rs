//! Rust mirror of msg/unitac_msgs, and [`Msg`], what flows between stages.
//!
//! # One definition: the `.msg` files
//! Every message of msg/unitac_msgs (but ContactClip, whose Rust side [`ContactClip`] holds
//! frames, not images, and is written by hand) is
//! generated at build time from its `.msg` file by crates/core/build.rs (the generator is
//! crates/core/build/msggen.rs): the struct with the same field names in the same order (field
//! docs are the `.msg` comments), an enum for each `uint8` field that has `FIELD_*` constants
//! ([`Winner`], [`LatentSource`], [`GripperMode`]), and a [`Message`] impl. The same definition
//! reaches the two other places a message is spelled out through
//! [`for_each_message!`](crate::for_each_message): crates/bag expands it into the CDR codecs
//! (`RosMessage`), crates/ros into the r2r conversions. So adding a field to a message is one
//! edit, in its `.msg` file (plus the stage that fills it in and the tests that set it).
//!
//! Why the `.msg` files and not a Rust list checked against them: rclpy peers, `colcon` and the
//! bags need the `.msg` files anyway, so making them the source leaves nothing to keep in step.
//! What they cannot say sits in four small tables at the top of msggen.rs: enum names, sequence
//! bounds ([`MAX_LATENT_DIMS`]), hand-written checks ([`TactileLatent::check_shape`]), and
//! ContactClip's exclusion. `cargo doc -p unitac-core` shows the generated types.
//!
//! `for_each_message!(callback)` calls `callback!` with
//! ```text
//! messages {
//!     ContactState [contact_state, contact_state_from] {
//!         header: $crate::msg::Header => None,
//!         centroid_px: [f32; 2] => None,
//!         ...
//!     }
//!     TactileLatent [tactile_latent, tactile_latent_from] {
//!         shape: Vec<u32> => Some($crate::msg::MAX_LATENT_DIMS),
//!         ...
//!     }
//! }
//! enums { $crate::msg::Winner, $crate::msg::LatentSource, $crate::msg::GripperMode, }
//! ```
//! (message, the snake-case names for conversion functions, then each field with its Rust type and
//! its sequence bound, `None` for the codec's default).
//!
//! These types serialize to JSON for the command line and the golden files.

use crate::clock::Stamp;
use crate::frame::Frame;
use serde::{Deserialize, Serialize};
use thiserror::Error;

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

/// Most dimensions in a TactileLatent's shape.
pub const MAX_LATENT_DIMS: usize = 16;
/// Most condition sources a predicted TactileLatent names.
pub const MAX_CONDITION_SOURCES: usize = 16;
/// Most named values in a VisualObservation.
pub const MAX_VISUAL_VALUES: usize = 64;

/// A project message (msg/unitac_msgs): its ROS type name, its `.msg` text, and the checks a
/// decoder runs beyond the field types.
pub trait Message: Sized {
    /// e.g. `unitac_msgs/msg/ContactState`.
    const ROS_TYPE: &'static str;
    /// The `.msg` file, verbatim (the `ros2msg` schema text of bags).
    const MSG_TEXT: &'static str;
    /// Checks beyond the field types (see `CHECKS` in crates/core/build/msggen.rs). Every decoder
    /// (CDR in crates/bag, r2r in crates/ros) runs it on what it decoded.
    fn check(&self) -> Result<(), MsgError> {
        Ok(())
    }
}

/// A decoded message that breaks a rule its field types cannot express.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MsgError {
    #[error("shape has {0} dimensions (at most {MAX_LATENT_DIMS})")]
    TooManyDims(usize),
    #[error("shape {shape:?} needs {needs} values, data has {data}")]
    ShapeMismatch {
        shape: Vec<u32>,
        needs: u64,
        data: usize,
    },
    #[error("shape {0:?} needs more values than a u64 counts")]
    ShapeOverflow(Vec<u32>),
    #[error("{names} names but {values} values (they pair up one to one)")]
    NamesValues { names: usize, values: usize },
    #[error("{0} named values (at most {MAX_VISUAL_VALUES})")]
    TooManyValues(usize),
    #[error(
        "{sources} condition sources but {ages} ages (they pair up one to one, at most {MAX_CONDITION_SOURCES})"
    )]
    ConditionSources { sources: usize, ages: usize },
}

/// A wire value that is none of an enum's constants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[error("unknown value {0}")]
pub struct UnknownValue(pub u8);

include!(concat!(env!("OUT_DIR"), "/msg_generated.rs"));

pub mod samples;

impl TactileLatent {
    /// At most [`MAX_LATENT_DIMS`] dimensions, and as many values as the shape says.
    pub fn check_shape(&self) -> Result<(), MsgError> {
        if self.shape.len() > MAX_LATENT_DIMS {
            return Err(MsgError::TooManyDims(self.shape.len()));
        }
        let needs = self
            .shape
            .iter()
            .try_fold(1u64, |n, &d| n.checked_mul(u64::from(d)))
            .ok_or_else(|| MsgError::ShapeOverflow(self.shape.clone()))?;
        if needs != self.data.len() as u64 {
            return Err(MsgError::ShapeMismatch {
                shape: self.shape.clone(),
                needs,
                data: self.data.len(),
            });
        }
        if self.condition_sources.len() != self.condition_age_s.len()
            || self.condition_sources.len() > MAX_CONDITION_SOURCES
        {
            return Err(MsgError::ConditionSources {
                sources: self.condition_sources.len(),
                ages: self.condition_age_s.len(),
            });
        }
        Ok(())
    }
}

impl VisualObservation {
    /// As many names as values, at most [`MAX_VISUAL_VALUES`] of each.
    pub fn check_lengths(&self) -> Result<(), MsgError> {
        if self.names.len() != self.values.len() {
            return Err(MsgError::NamesValues {
                names: self.names.len(),
                values: self.values.len(),
            });
        }
        if self.names.len() > MAX_VISUAL_VALUES {
            return Err(MsgError::TooManyValues(self.names.len()));
        }
        Ok(())
    }
    /// The value named `name`, if the camera model gave one.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.names
            .iter()
            .position(|n| n == name)
            .and_then(|i| self.values.get(i).copied())
    }
}

/// The frames of one contact episode, centred on its peak (for the touch encoder). Bounded by the
/// contact stage's `clip_frames`. Not a ROS message: nodes pass frames as sensor_msgs/Image.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactClip {
    pub sensor_id: String,
    pub episode_id: u64,
    pub label: String,
    /// Index into `frames` of the peak-area frame.
    pub peak_index: usize,
    pub frames: Vec<Frame>,
    /// The non-contact frame (the contact stage's background) at the time of the episode.
    pub background: Option<Frame>,
}

/// The gel's depth per pixel from the contact stage's depth estimate (a scene whose contact stage
/// has a depth calibration), one per frame once the background is known. On ROS it is two
/// messages: `depth` (sensor_msgs/Image 32FC1, metres) and `points` (sensor_msgs/PointCloud2,
/// x y z float32 in `<sensor>_optical_frame`), both made from this by the bag crate's codecs.
/// Not a ROS message of its own.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthMap {
    /// Capture stamp of the frame, frame_id `<sensor>_optical_frame`.
    pub header: Header,
    pub width: u32,
    pub height: u32,
    /// The side of one pixel on the gel at this frame size \[m] (the calibration's mm per pixel).
    pub pixel_m: f64,
    /// Indentation of the gel surface \[m], positive where the surface is pushed in (away from
    /// the touched object, toward the sensor's camera), row-major; NaN where unknown (REP 117:
    /// no measurement, e.g. under the gel's marker dots).
    pub depth_m: Vec<f32>,
}

impl DepthMap {
    /// The point of pixel (x, y) in the optical frame (REP 103: x right, y down, z out of the
    /// gel toward the object; origin at the image centre on the gel surface at rest) \[m]; None
    /// where the depth is unknown. An indentation is a negative z.
    pub fn point(&self, x: u32, y: u32) -> Option<[f32; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let d = *self
            .depth_m
            .get(y as usize * self.width as usize + x as usize)?;
        if !d.is_finite() {
            return None;
        }
        let s = self.pixel_m;
        let cx = (f64::from(self.width) - 1.0) / 2.0;
        let cy = (f64::from(self.height) - 1.0) / 2.0;
        Some([
            ((f64::from(x) - cx) * s) as f32,
            ((f64::from(y) - cy) * s) as f32,
            -d,
        ])
    }
    /// Every known pixel's point, row by row ([`DepthMap::point`]).
    pub fn points(&self) -> Vec<[f32; 3]> {
        let mut out = Vec::new();
        for y in 0..self.height {
            for x in 0..self.width {
                if let Some(p) = self.point(x, y) {
                    out.push(p);
                }
            }
        }
        out
    }
    /// FNV-1a (64 bit) of the depth values' little-endian bytes: what the JSON of a depth event
    /// carries instead of the values, so event streams compare the bytes.
    pub fn digest(&self) -> String {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in self.depth_m.iter().flat_map(|v| v.to_le_bytes()) {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
        format!("{h:016x}")
    }
}

/// [`Msg`] and its per-variant methods, from the message list of the `.msg` files
/// ([`for_each_message!`](crate::for_each_message)): one variant per message, named after it,
/// plus the three that are not ROS messages of their own (a frame, the background frame, an
/// episode's clip).
macro_rules! declare_msg {
    (
        messages { $( $name:ident [$snake:ident, $from:ident] { $( $field:ident : $ty:ty => $max:expr, )* } )* }
        enums { $( $e:path, )* }
    ) => {
        /// Everything that flows between stages. Frames may be dropped under load (drop-oldest
        /// edges); every other variant is an event and is never dropped.
        #[derive(Debug, Clone, PartialEq)]
        pub enum Msg {
            Frame(Frame),
            /// The contact stage's non-contact frame, announced when it is learned or loaded: the
            /// sensor prior (Z_sen) for the flow sampler.
            Background(Frame),
            /// unitac_msgs/ContactClip (an episode's frames, for the encoder).
            ContactClip(ContactClip),
            /// The gel's depth of a frame (contact stage with a depth calibration).
            Depth(DepthMap),
            /// The contact stage's picture of a frame for a person (`overlay` param): the frame
            /// with the contact outline and centroid, beside it the depth colour map.
            ContactOverlay(Frame),
            $(
                #[doc = concat!("unitac_msgs/", stringify!($name), ".")]
                $name($name),
            )*
        }

        impl Msg {
            pub fn is_frame(&self) -> bool {
                matches!(self, Msg::Frame(_))
            }
            /// The time this message belongs to (capture time for frames, header stamp otherwise).
            pub fn stamp(&self) -> Stamp {
                match self {
                    Msg::Frame(f) | Msg::Background(f) | Msg::ContactOverlay(f) => f.stamp,
                    Msg::Depth(d) => d.header.stamp,
                    Msg::ContactClip(m) => m.frames.last().map_or(Stamp::ZERO, |f| f.stamp),
                    $( Msg::$name(m) => m.header.stamp, )*
                }
            }
            /// Short type name, as used in counters and JSON (`"frame"`, `"contact_state"`, ...:
            /// a message's name in snake case).
            pub fn kind(&self) -> &'static str {
                match self {
                    Msg::Frame(_) => "frame",
                    Msg::Background(_) => "background",
                    Msg::ContactClip(_) => "contact_clip",
                    Msg::Depth(_) => "depth",
                    Msg::ContactOverlay(_) => "contact_overlay",
                    $( Msg::$name(_) => stringify!($snake), )*
                }
            }
            /// JSON of an event (`{"type": kind, ...fields}`); frames give only their metadata.
            pub fn to_json(&self) -> serde_json::Value {
                let body = match self {
                    Msg::Frame(f) | Msg::Background(f) | Msg::ContactOverlay(f) => serde_json::json!({
                        "sensor_id": f.sensor_id, "seq": f.seq, "stamp": f.stamp,
                        "width": f.width, "height": f.height,
                    }),
                    Msg::ContactClip(m) => serde_json::json!({
                        "sensor_id": m.sensor_id, "episode_id": m.episode_id, "label": m.label,
                        "peak_index": m.peak_index,
                        "frame_seqs": m.frames.iter().map(|f| f.seq).collect::<Vec<_>>(),
                    }),
                    Msg::Depth(d) => serde_json::json!({
                        "header": d.header, "width": d.width, "height": d.height,
                        "pixel_m": d.pixel_m,
                        "known": d.depth_m.iter().filter(|v| v.is_finite()).count(),
                        "max_m": f64::from(d.depth_m.iter().copied().filter(|v| v.is_finite()).fold(0.0f32, f32::max)),
                        "digest": d.digest(),
                    }),
                    $( Msg::$name(m) => serde_json::to_value(m).unwrap_or_default(), )*
                };
                let mut v = serde_json::json!({ "type": self.kind() });
                if let (Some(obj), serde_json::Value::Object(fields)) = (v.as_object_mut(), body) {
                    obj.extend(fields);
                }
                v
            }
        }
    };
}

for_each_message!(declare_msg);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_carries_type_and_fields() {
        let m = Msg::PolicyStatus(PolicyStatus {
            header: Header::new(Stamp(1), "base"),
            scene: "fabric_selection".into(),
            mode: "vtla_real".into(),
            phase: "press".into(),
            safety_ok: true,
            message: String::new(),
            clamped: Vec::new(),
        });
        let j = m.to_json();
        assert_eq!(j["type"], "policy_status");
        assert_eq!(j["phase"], "press");
        assert_eq!(j["header"]["stamp"], 1);
        assert!(!m.is_frame());
    }

    fn latent(shape: Vec<u32>, n: usize) -> TactileLatent {
        TactileLatent {
            shape,
            data: vec![0.5; n],
            ..samples::tactile_latent()
        }
    }

    #[test]
    fn depth_points_are_in_the_optical_frame_and_skip_unknown_pixels() {
        let d = DepthMap {
            header: Header::optical(Stamp(5), "gs"),
            width: 3,
            height: 2,
            pixel_m: 1e-4,
            depth_m: vec![0.0, f32::NAN, 0.001, 0.0, 0.0, 0.0],
        };
        let p = d.points();
        assert_eq!(p.len(), 5, "the NaN pixel has no point");
        // Pixel (0, 0): left of and above the centre (1, 0.5); a press is a negative z.
        assert_eq!(p[0], [-1e-4, -0.5e-4, 0.0]);
        assert_eq!(d.point(2, 0), Some([1e-4, -0.5e-4, -0.001]));
        assert_eq!(d.point(1, 0), None);
        assert_eq!(d.point(3, 0), None);
        let j = Msg::Depth(d.clone()).to_json();
        assert_eq!(
            (j["type"].as_str(), j["known"].as_u64()),
            (Some("depth"), Some(5))
        );
        let mut e = d.clone();
        e.depth_m[0] = 1e-6;
        assert_ne!(e.digest(), d.digest());
    }

    #[test]
    fn latent_shape_must_match_data() {
        assert_eq!(latent(vec![2, 3], 6).check(), Ok(()));
        assert_eq!(latent(vec![], 1).check(), Ok(()));
        assert_eq!(
            latent(vec![2, 3], 5).check(),
            Err(MsgError::ShapeMismatch {
                shape: vec![2, 3],
                needs: 6,
                data: 5
            })
        );
        assert_eq!(
            latent(vec![1; MAX_LATENT_DIMS + 1], 1).check(),
            Err(MsgError::TooManyDims(MAX_LATENT_DIMS + 1))
        );
        // Overflow is an error, not a wrap (or a panic in debug builds).
        let big = latent(vec![u32::MAX; 3], 0);
        assert_eq!(big.check(), Err(MsgError::ShapeOverflow(vec![u32::MAX; 3])));
        assert_eq!(
            latent(vec![2, 3], 5).check().unwrap_err().to_string(),
            "shape [2, 3] needs 6 values, data has 5"
        );
    }

    #[test]
    fn visual_names_and_values_pair_up() {
        let ok = samples::visual_observation();
        assert_eq!(ok.check(), Ok(()));
        assert_eq!(ok.get("cup_width_m"), Some(0.081));
        assert_eq!(ok.get("nothing"), None);
        let short = VisualObservation {
            values: vec![1.0],
            ..ok.clone()
        };
        assert_eq!(
            short.check().unwrap_err().to_string(),
            "2 names but 1 values (they pair up one to one)"
        );
        let n = MAX_VISUAL_VALUES + 1;
        let long = VisualObservation {
            names: vec!["x".into(); n],
            values: vec![0.0; n],
            ..ok
        };
        assert_eq!(long.check(), Err(MsgError::TooManyValues(n)));
    }

    #[test]
    fn enums_from_constants_keep_wire_values_and_json_names() {
        assert_eq!(u8::from(Winner::Tie), 2);
        assert_eq!(Winner::try_from(1), Ok(Winner::B));
        assert_eq!(Winner::try_from(3), Err(UnknownValue(3)));
        assert_eq!(GripperMode::try_from(2), Ok(GripperMode::Stop));
        assert_eq!(LatentSource::try_from(1), Ok(LatentSource::Predicted));
        assert_eq!(serde_json::to_value(Winner::Tie).unwrap(), "tie");
        assert_eq!(
            serde_json::to_value(LatentSource::Predicted).unwrap(),
            "predicted"
        );
        // Messages without extra rules check fine.
        assert_eq!(ContactState::ROS_TYPE, "unitac_msgs/msg/ContactState");
        assert!(PolicyStatus::MSG_TEXT.contains("bool safety_ok"));
    }
}
