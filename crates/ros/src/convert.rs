//! Conversions between `unitac-core` messages and the generated `unitac_msgs` types.
//!
//! The per-message functions (`contact_state` / `contact_state_from`, `tactile_latent` /
//! `tactile_latent_from`, ... one pair per message of msg/unitac_msgs) are generated from the
//! `.msg` files through `unitac_core::for_each_message!`: one [`RosField`] call per field, then the
//! message's own checks ([`unitac_core::msg::Message::check`]). Decoding applies the same bounds as
//! the CDR codec in crates/bag (sequence lengths, string lengths, fixed array sizes, enum values),
//! so a message is accepted here exactly when a bag would accept it. ContactClip carries images
//! and is converted by hand ([`contact_clip`], [`contact_clip_from`]).

use r2r::builtin_interfaces::msg::Time;
use r2r::std_msgs::msg::Header as RosHeader;
use r2r::unitac_msgs::msg as ros;
use thiserror::Error;
use unitac_bag::cdr::{MAX_SEQUENCE, MAX_STRING};
use unitac_core::Stamp;
use unitac_core::msg::{ContactClip, Header, Message, MsgError};

/// Most frames a ContactClip may carry (the contact stage's clip_frames is far below this).
pub const MAX_CLIP_FRAMES: usize = 256;

/// A `unitac_msgs` message that does not make a valid core message.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ConvertError {
    #[error("{field}: expected {expected} elements, got {got}")]
    FixedLength {
        field: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("{field}: length {len} is over the limit {max}")]
    TooLong {
        field: &'static str,
        len: usize,
        max: usize,
    },
    #[error("{field}: unknown value {value}")]
    BadEnum { field: &'static str, value: u8 },
    #[error(transparent)]
    Check(#[from] MsgError),
    #[error("clip has {0} frames (1..={MAX_CLIP_FRAMES})")]
    ClipFrames(usize),
    #[error("peak_index {index} is outside the clip's {frames} frames")]
    PeakIndex { index: usize, frames: usize },
    #[error("{what}: {reason}")]
    Image { what: String, reason: String },
    #[error("joint_states: {0}")]
    JointState(String),
}

pub fn time(t: Stamp) -> Time {
    let (sec, nanosec) = t.to_sec_nanosec();
    Time { sec, nanosec }
}
pub fn stamp(t: &Time) -> Stamp {
    Stamp::from_sec_nanosec(t.sec, t.nanosec)
}
pub fn header(h: &Header) -> RosHeader {
    RosHeader {
        stamp: time(h.stamp),
        frame_id: h.frame_id.clone(),
    }
}
pub fn header_from(h: &RosHeader) -> Header {
    Header {
        stamp: stamp(&h.stamp),
        frame_id: h.frame_id.clone(),
    }
}

/// A field type's r2r form; the generated conversions call this once per field.
pub trait RosField: Sized {
    type Ros;
    fn to_ros(&self) -> Self::Ros;
    /// `max`: the most elements of a sequence (other types ignore it).
    fn from_ros(v: &Self::Ros, field: &'static str, max: usize) -> Result<Self, ConvertError>;
}

macro_rules! primitive_fields {
    ($($t:ty),* $(,)?) => {$(
        impl RosField for $t {
            type Ros = $t;
            fn to_ros(&self) -> $t {
                *self
            }
            fn from_ros(v: &$t, _: &'static str, _: usize) -> Result<Self, ConvertError> {
                Ok(*v)
            }
        }
    )*};
}
primitive_fields!(bool, u8, u32, i32, u64, f32, f64);

/// Strings: as long as the CDR reader allows (its limit counts the NUL).
impl RosField for String {
    type Ros = String;
    fn to_ros(&self) -> String {
        self.clone()
    }
    fn from_ros(v: &String, field: &'static str, _: usize) -> Result<Self, ConvertError> {
        if v.len() >= MAX_STRING {
            return Err(ConvertError::TooLong {
                field,
                len: v.len() + 1,
                max: MAX_STRING,
            });
        }
        Ok(v.clone())
    }
}

impl RosField for Stamp {
    type Ros = Time;
    fn to_ros(&self) -> Time {
        time(*self)
    }
    fn from_ros(v: &Time, _: &'static str, _: usize) -> Result<Self, ConvertError> {
        Ok(stamp(v))
    }
}

impl RosField for Header {
    type Ros = RosHeader;
    fn to_ros(&self) -> RosHeader {
        header(self)
    }
    fn from_ros(v: &RosHeader, field: &'static str, max: usize) -> Result<Self, ConvertError> {
        Ok(Header {
            stamp: stamp(&v.stamp),
            frame_id: String::from_ros(&v.frame_id, field, max)?,
        })
    }
}

/// Fixed-size ROS arrays arrive as Vec: exactly N elements or an error.
impl<T: RosField + Copy + Default, const N: usize> RosField for [T; N] {
    type Ros = Vec<T::Ros>;
    fn to_ros(&self) -> Vec<T::Ros> {
        self.iter().map(T::to_ros).collect()
    }
    fn from_ros(v: &Vec<T::Ros>, field: &'static str, max: usize) -> Result<Self, ConvertError> {
        if v.len() != N {
            return Err(ConvertError::FixedLength {
                field,
                expected: N,
                got: v.len(),
            });
        }
        let mut a = [T::default(); N];
        for (x, r) in a.iter_mut().zip(v) {
            *x = T::from_ros(r, field, max)?;
        }
        Ok(a)
    }
}

impl<T: RosField> RosField for Vec<T> {
    type Ros = Vec<T::Ros>;
    fn to_ros(&self) -> Vec<T::Ros> {
        self.iter().map(T::to_ros).collect()
    }
    fn from_ros(v: &Vec<T::Ros>, field: &'static str, max: usize) -> Result<Self, ConvertError> {
        if v.len() > max {
            return Err(ConvertError::TooLong {
                field,
                len: v.len(),
                max,
            });
        }
        v.iter().map(|r| T::from_ros(r, field, max)).collect()
    }
}

/// A field's sequence bound: its own, or the CDR reader's default.
fn limit(max: Option<usize>) -> usize {
    max.unwrap_or(MAX_SEQUENCE)
}

macro_rules! unitac_conversions {
    (
        messages {
            $( $msg:ident [$to:ident, $from:ident] { $( $f:ident : $t:ty => $max:expr ),* $(,)? } )*
        }
        enums { $( $e:ty ),* $(,)? }
    ) => {
        $(
            #[doc = concat!("`unitac_core::msg::", stringify!($msg), "` to r2r.")]
            pub fn $to(m: &unitac_core::msg::$msg) -> ros::$msg {
                ros::$msg {
                    $( $f: m.$f.to_ros(), )*
                }
            }

            #[doc = concat!(
                "r2r to `unitac_core::msg::", stringify!($msg),
                "`: bounds, enum values and the message's checks."
            )]
            pub fn $from(m: &ros::$msg) -> Result<unitac_core::msg::$msg, ConvertError> {
                let v = unitac_core::msg::$msg {
                    $( $f: <$t as RosField>::from_ros(&m.$f, stringify!($f), limit($max))?, )*
                };
                v.check()?;
                Ok(v)
            }
        )*

        $(
            /// A `uint8` with the message's constants; any other value is an error.
            impl RosField for $e {
                type Ros = u8;
                fn to_ros(&self) -> u8 {
                    u8::from(*self)
                }
                fn from_ros(v: &u8, field: &'static str, _: usize) -> Result<Self, ConvertError> {
                    <$e>::try_from(*v).map_err(|e| ConvertError::BadEnum { field, value: e.0 })
                }
            }
        )*
    };
}

unitac_core::for_each_message!(unitac_conversions);

pub fn contact_clip(m: &ContactClip) -> ros::ContactClip {
    let last = m.frames.last();
    let mut header = RosHeader::default();
    if let Some(f) = last {
        header.stamp = time(f.stamp);
        header.frame_id = unitac_core::optical_frame_id(&f.sensor_id);
    }
    ros::ContactClip {
        header,
        sensor_id: m.sensor_id.clone(),
        episode_id: m.episode_id,
        label: m.label.clone(),
        peak_index: u32::try_from(m.peak_index).unwrap_or(u32::MAX),
        frames: m.frames.iter().map(crate::image::from_frame).collect(),
        background: m
            .background
            .as_ref()
            .map(crate::image::from_frame)
            .unwrap_or_default(),
    }
}

/// A clip from the wire: frame count bounded, every image checked, peak index in range.
pub fn contact_clip_from(m: &ros::ContactClip) -> Result<ContactClip, ConvertError> {
    // Every field named: a field added to ContactClip.msg fails to compile here until handled.
    let ros::ContactClip {
        header: _,
        sensor_id,
        episode_id,
        label,
        peak_index,
        frames,
        background,
    } = m;
    if frames.is_empty() || frames.len() > MAX_CLIP_FRAMES {
        return Err(ConvertError::ClipFrames(frames.len()));
    }
    let peak_index = *peak_index as usize;
    if peak_index >= frames.len() {
        return Err(ConvertError::PeakIndex {
            index: peak_index,
            frames: frames.len(),
        });
    }
    let sensor_id = String::from_ros(sensor_id, "sensor_id", 0)?;
    let label = String::from_ros(label, "label", 0)?;
    let image = |what: String, img: &r2r::sensor_msgs::msg::Image, seq| {
        crate::image::to_frame(img, &sensor_id, seq).map_err(|reason| ConvertError::Image {
            what,
            reason: reason.to_string(),
        })
    };
    let frames = frames
        .iter()
        .enumerate()
        .map(|(i, f)| image(format!("frame {i}"), f, i as u64))
        .collect::<Result<Vec<_>, _>>()?;
    let background = if background.width == 0 {
        None
    } else {
        Some(image("background".into(), background, 0)?)
    };
    Ok(ContactClip {
        sensor_id,
        episode_id: *episode_id,
        label,
        peak_index,
        frames,
        background,
    })
}

/// A `sensor_msgs/JointState` from a gripper driver (e.g. the gripper node's `joint_states`) as a
/// GripperStatus: joint `joint` (or the only joint when `joint` is empty), position = the finger
/// opening \[m], effort = the grip force \[N]; the rest is unknown (NaN target and current, no
/// object detection, activation and motion empty, no fault). A missing joint, a missing or
/// non-finite position, or more than [`MAX_SEQUENCE`] joints is an error.
pub fn gripper_status_from_joint_state(
    m: &r2r::sensor_msgs::msg::JointState,
    joint: &str,
) -> Result<unitac_core::msg::GripperStatus, ConvertError> {
    let bad = ConvertError::JointState;
    if m.name.len() > MAX_SEQUENCE {
        return Err(ConvertError::TooLong {
            field: "name",
            len: m.name.len(),
            max: MAX_SEQUENCE,
        });
    }
    let i = if joint.is_empty() && m.name.len() <= 1 {
        0
    } else {
        m.name
            .iter()
            .position(|n| n == joint)
            .ok_or_else(|| bad(format!("no joint '{joint}' in {:?}", m.name)))?
    };
    let opening_m = *m
        .position
        .get(i)
        .ok_or_else(|| bad(format!("joint {i} has no position")))?;
    if !opening_m.is_finite() {
        return Err(bad(format!("position {opening_m} is not finite")));
    }
    Ok(unitac_core::msg::GripperStatus {
        header: header_from(&m.header),
        opening_m,
        target_m: f64::NAN,
        force_n: m.effort.get(i).copied().unwrap_or(f64::NAN),
        current_a: f64::NAN,
        object_detected: false,
        activation: String::new(),
        motion: String::new(),
        fault: String::new(),
    })
}

/// The JointState a gripper driver publishes for `s` (the inverse of
/// [`gripper_status_from_joint_state`] for the opening and force).
pub fn joint_state(
    s: &unitac_core::msg::GripperStatus,
    joint: &str,
) -> r2r::sensor_msgs::msg::JointState {
    r2r::sensor_msgs::msg::JointState {
        header: header(&s.header),
        name: vec![joint.to_string()],
        position: vec![s.opening_m],
        velocity: Vec::new(),
        effort: vec![s.force_n],
    }
}

/// The arm target of an ArmCommand as a `geometry_msgs/PoseStamped` for a Cartesian controller or
/// MoveIt Servo: the fingertip centre at (x_m, y_m, z_m + lift_m) in `frame` (the frame of the
/// policy's table coordinates), the tool turned by `tool_rpy` (roll, pitch, yaw about the frame's
/// fixed axes, as in URDF). None for `home`: the arm stack's own named pose, not a place.
pub fn arm_pose(
    a: &unitac_core::msg::ArmCommand,
    frame: &str,
    tool_rpy: [f64; 3],
) -> Option<r2r::geometry_msgs::msg::PoseStamped> {
    if a.target == "home" {
        return None;
    }
    let [r, p, y] = tool_rpy.map(|v| v / 2.0);
    let (sr, cr, sp, cp, sy, cy) = (r.sin(), r.cos(), p.sin(), p.cos(), y.sin(), y.cos());
    let orientation = r2r::geometry_msgs::msg::Quaternion {
        x: sr * cp * cy - cr * sp * sy,
        y: cr * sp * cy + sr * cp * sy,
        z: cr * cp * sy - sr * sp * cy,
        w: cr * cp * cy + sr * sp * sy,
    };
    let mut header = header(&a.header);
    header.frame_id = frame.to_string();
    Some(r2r::geometry_msgs::msg::PoseStamped {
        header,
        pose: r2r::geometry_msgs::msg::Pose {
            position: r2r::geometry_msgs::msg::Point {
                x: a.x_m,
                y: a.y_m,
                z: a.z_m + a.lift_m,
            },
            orientation,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_arm_command_is_a_pose_in_the_arm_frame_and_home_is_none() {
        let mut a = unitac_core::msg::samples::arm_command();
        a.target = "cup".into();
        (a.x_m, a.y_m, a.z_m, a.lift_m) = (0.4, -0.1, 0.05, 0.1);
        let p = arm_pose(&a, "table", [std::f64::consts::PI, 0.0, 0.0]).unwrap();
        assert_eq!(p.header.frame_id, "table");
        assert_eq!(stamp(&p.header.stamp), a.header.stamp);
        let q = &p.pose.orientation;
        let pos = &p.pose.position;
        assert_eq!((pos.x, pos.y), (0.4, -0.1));
        assert!((pos.z - 0.15).abs() < 1e-12);
        // Roll by pi: the tool's z axis points down.
        assert!((q.x.abs() - 1.0).abs() < 1e-12 && q.y.abs() < 1e-12 && q.w.abs() < 1e-12);
        let q = arm_pose(&a, "table", [0.0, 0.0, std::f64::consts::FRAC_PI_2])
            .unwrap()
            .pose
            .orientation;
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((q.z - h).abs() < 1e-12 && (q.w - h).abs() < 1e-12);
        a.target = "home".into();
        assert!(arm_pose(&a, "table", [0.0; 3]).is_none());
    }

    #[test]
    fn joint_states_become_gripper_status_with_unknowns_nan() {
        let mut g = samples::gripper_status();
        g.opening_m = 0.05;
        g.force_n = 7.5;
        let js = joint_state(&g, "finger");
        let back = gripper_status_from_joint_state(&js, "finger").unwrap();
        assert_eq!(back.header, g.header);
        assert_eq!((back.opening_m, back.force_n), (0.05, 7.5));
        assert!(back.target_m.is_nan() && back.current_a.is_nan());
        assert!(!back.object_detected && back.fault.is_empty());
        // The only joint when none is named; a named joint that is not there, or no position.
        assert!(gripper_status_from_joint_state(&js, "").is_ok());
        assert!(gripper_status_from_joint_state(&js, "wrist").is_err());
        let mut no_pos = js.clone();
        no_pos.position.clear();
        assert!(gripper_status_from_joint_state(&no_pos, "finger").is_err());
        let mut nan = js;
        nan.position[0] = f64::NAN;
        assert!(gripper_status_from_joint_state(&nan, "finger").is_err());
    }
    use unitac_core::msg::samples::{self, contact_state as state, tactile_latent as latent};

    /// Every message of msg/unitac_msgs, through the same definition as the conversions.
    #[test]
    fn generated_conversions_round_trip() {
        macro_rules! round_trip_each {
            (
                messages { $( $msg:ident [$to:ident, $from:ident] { $($fields:tt)* } )* }
                enums { $($e:tt)* }
            ) => {
                $( assert_eq!($from(&$to(&samples::$to())), Ok(samples::$to())); )*
            };
        }
        unitac_core::for_each_message!(round_trip_each);
        let r = contact_state(&state());
        assert_eq!(r.centroid_px, vec![3.0, 4.0]);
        assert_eq!(r.header.stamp.sec, 1_700_000_000);
        assert_eq!(tactile_latent(&latent()).source, 1);
        assert_eq!(
            property_comparison(&samples::property_comparison()).winner,
            2
        );
    }

    #[test]
    fn bad_fields_are_typed_errors() {
        let mut r = contact_state(&state());
        r.centroid_px.push(1.0);
        assert_eq!(
            contact_state_from(&r),
            Err(ConvertError::FixedLength {
                field: "centroid_px",
                expected: 2,
                got: 3
            })
        );

        let mut r = tactile_latent(&latent());
        r.source = 5;
        assert_eq!(
            tactile_latent_from(&r),
            Err(ConvertError::BadEnum {
                field: "source",
                value: 5
            })
        );
        let mut r = tactile_latent(&latent());
        r.data.pop();
        let e = tactile_latent_from(&r).unwrap_err();
        assert!(matches!(
            e,
            ConvertError::Check(MsgError::ShapeMismatch { .. })
        ));
        assert_eq!(e.to_string(), "shape [2, 3] needs 6 values, data has 5");
        let mut r = tactile_latent(&latent());
        r.shape = vec![1; 17];
        assert_eq!(
            tactile_latent_from(&r),
            Err(ConvertError::TooLong {
                field: "shape",
                len: 17,
                max: 16
            })
        );
        let mut r = tactile_latent(&latent());
        r.model_id = "x".repeat(MAX_STRING);
        assert!(matches!(
            tactile_latent_from(&r),
            Err(ConvertError::TooLong {
                field: "model_id",
                ..
            })
        ));

        let mut g = gripper_command(&samples::gripper_command());
        g.mode = 9;
        assert_eq!(
            gripper_command_from(&g).unwrap_err().to_string(),
            "mode: unknown value 9"
        );
    }

    #[test]
    fn clips_are_bounded() {
        let empty = ros::ContactClip::default();
        assert_eq!(contact_clip_from(&empty), Err(ConvertError::ClipFrames(0)));
        let frame = unitac_core::Frame::new("gs", 0, Stamp(5), 2, 2, vec![9; 12]).unwrap();
        let clip = ContactClip {
            sensor_id: "gs".into(),
            episode_id: 4,
            label: "cup".into(),
            peak_index: 1,
            frames: vec![frame.clone(), frame],
            background: None,
        };
        let mut r = contact_clip(&clip);
        assert_eq!(r.header.frame_id, "gs_optical_frame");
        let back = contact_clip_from(&r).unwrap();
        assert_eq!((back.peak_index, back.frames.len()), (1, 2));
        assert_eq!(back.frames[1].data(), clip.frames[1].data());
        r.peak_index = 2;
        assert_eq!(
            contact_clip_from(&r),
            Err(ConvertError::PeakIndex {
                index: 2,
                frames: 2
            })
        );
        r.peak_index = 0;
        r.frames[1].encoding = "rgb16".into();
        assert!(matches!(
            contact_clip_from(&r),
            Err(ConvertError::Image { ref what, .. }) if what == "frame 1"
        ));
    }
}
