//! ROS 2 messages this crate reads and writes, their CDR form and their `ros2msg` schema text.
//!
//! sensor_msgs/Image and sensor_msgs/CompressedImage are defined here; the project's messages are
//! the Rust mirrors in `unitac_core::msg`, whose schema text comes straight from the `.msg` files
//! in msg/unitac_msgs (one source of truth: a field added there and not here fails the round-trip
//! tests against rosbags).

use crate::cdr::{CdrError, CdrReader, CdrWriter, MAX_IMAGE_BYTES, MAX_SEQUENCE};
use unitac_core::Stamp;
use unitac_core::msg::{
    ContactEpisode, ContactState, GripperCommand, GripperMode, Header, LatentSource, PolicyStatus,
    PropertyComparison, TactileLatent, TactileProperties, Winner,
};

/// Most dimensions in a TactileLatent's shape.
pub const MAX_LATENT_DIMS: usize = 16;

/// sensor_msgs/msg/Image.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub encoding: String,
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    pub data: Vec<u8>,
}

impl Image {
    /// An rgb8 Image of a frame: its capture stamp, frame_id `<sensor_id>_optical_frame`.
    pub fn rgb8(f: &unitac_core::Frame) -> Self {
        Self {
            header: Header::optical(f.stamp, &f.sensor_id),
            height: f.height,
            width: f.width,
            encoding: "rgb8".into(),
            is_bigendian: 0,
            step: f.width * 3,
            data: f.data().to_vec(),
        }
    }
}

/// sensor_msgs/msg/CompressedImage.
#[derive(Debug, Clone, PartialEq)]
pub struct CompressedImage {
    pub header: Header,
    /// e.g. "jpeg", "png", "rgb8; jpeg compressed bgr8".
    pub format: String,
    pub data: Vec<u8>,
}

/// sensor_msgs/msg/Image with its pixels borrowed from the CDR payload (no copy).
#[derive(Debug, Clone, PartialEq)]
pub struct ImageView<'a> {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub encoding: String,
    pub is_bigendian: u8,
    pub step: u32,
    pub data: &'a [u8],
}

impl<'a> ImageView<'a> {
    pub fn from_cdr(payload: &'a [u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(payload)?;
        let v = Self::read(&mut r)?;
        r.finish()?;
        Ok(v)
    }
    fn read(r: &mut CdrReader<'a>) -> Result<Self, CdrError> {
        Ok(ImageView {
            header: Header::read_cdr(r)?,
            height: r.u32("height")?,
            width: r.u32("width")?,
            encoding: r.string("encoding")?,
            is_bigendian: r.u8("is_bigendian")?,
            step: r.u32("step")?,
            data: r.bytes("data", MAX_IMAGE_BYTES)?,
        })
    }
}

impl Image {
    pub fn view(&self) -> ImageView<'_> {
        ImageView {
            header: self.header.clone(),
            height: self.height,
            width: self.width,
            encoding: self.encoding.clone(),
            is_bigendian: self.is_bigendian,
            step: self.step,
            data: &self.data,
        }
    }
}

/// sensor_msgs/msg/CompressedImage with its bytes borrowed from the CDR payload.
#[derive(Debug, Clone, PartialEq)]
pub struct CompressedImageView<'a> {
    pub header: Header,
    pub format: String,
    pub data: &'a [u8],
}

impl<'a> CompressedImageView<'a> {
    pub fn from_cdr(payload: &'a [u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(payload)?;
        let v = Self::read(&mut r)?;
        r.finish()?;
        Ok(v)
    }
    fn read(r: &mut CdrReader<'a>) -> Result<Self, CdrError> {
        Ok(CompressedImageView {
            header: Header::read_cdr(r)?,
            format: r.string("format")?,
            data: r.bytes("data", MAX_IMAGE_BYTES)?,
        })
    }
}

impl CompressedImage {
    pub fn view(&self) -> CompressedImageView<'_> {
        CompressedImageView {
            header: self.header.clone(),
            format: self.format.clone(),
            data: &self.data,
        }
    }
}

/// A message with a ROS type name, a CDR form and a schema.
pub trait RosMessage: Sized {
    /// e.g. `sensor_msgs/msg/Image`.
    const TYPE: &'static str;
    fn write_cdr(&self, w: &mut CdrWriter);
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError>;

    /// The full CDR payload (encapsulation header included).
    fn to_cdr(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.write_cdr(&mut w);
        w.finish()
    }
    /// Decode a whole payload; trailing bytes beyond alignment padding are an error.
    fn from_cdr(payload: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(payload)?;
        let m = Self::read_cdr(&mut r)?;
        r.finish()?;
        Ok(m)
    }
}

fn write_time(w: &mut CdrWriter, t: Stamp) {
    let (sec, nanosec) = t.to_sec_nanosec();
    w.i32(sec);
    w.u32(nanosec);
}
fn read_time(r: &mut CdrReader<'_>, what: &'static str) -> Result<Stamp, CdrError> {
    let sec = r.i32(what)?;
    let nanosec = r.u32(what)?;
    Ok(Stamp::from_sec_nanosec(sec, nanosec))
}

impl RosMessage for Header {
    const TYPE: &'static str = "std_msgs/msg/Header";
    fn write_cdr(&self, w: &mut CdrWriter) {
        write_time(w, self.stamp);
        w.string(&self.frame_id);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Header {
            stamp: read_time(r, "header.stamp")?,
            frame_id: r.string("header.frame_id")?,
        })
    }
}

impl RosMessage for Image {
    const TYPE: &'static str = "sensor_msgs/msg/Image";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.u32(self.height);
        w.u32(self.width);
        w.string(&self.encoding);
        w.u8(self.is_bigendian);
        w.u32(self.step);
        w.bytes(&self.data);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let v = ImageView::read(r)?;
        Ok(Image {
            header: v.header,
            height: v.height,
            width: v.width,
            encoding: v.encoding,
            is_bigendian: v.is_bigendian,
            step: v.step,
            data: v.data.to_vec(),
        })
    }
}

impl RosMessage for CompressedImage {
    const TYPE: &'static str = "sensor_msgs/msg/CompressedImage";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.string(&self.format);
        w.bytes(&self.data);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let v = CompressedImageView::read(r)?;
        Ok(CompressedImage {
            header: v.header,
            format: v.format,
            data: v.data.to_vec(),
        })
    }
}

impl RosMessage for ContactState {
    const TYPE: &'static str = "unitac_msgs/msg/ContactState";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.string(&self.sensor_id);
        w.u64(self.frame_seq);
        w.bool(self.in_contact);
        w.f32(self.area_px);
        w.f32(self.area_mm2);
        for &c in &self.centroid_px {
            w.f32(c);
        }
        for &b in &self.bbox_px {
            w.u32(b);
        }
        w.f32(self.strength);
        w.u64(self.episode_id);
        w.f64(self.background_age_s);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(ContactState {
            header: Header::read_cdr(r)?,
            sensor_id: r.string("sensor_id")?,
            frame_seq: r.u64("frame_seq")?,
            in_contact: r.bool("in_contact")?,
            area_px: r.f32("area_px")?,
            area_mm2: r.f32("area_mm2")?,
            centroid_px: [r.f32("centroid_px")?, r.f32("centroid_px")?],
            bbox_px: [
                r.u32("bbox_px")?,
                r.u32("bbox_px")?,
                r.u32("bbox_px")?,
                r.u32("bbox_px")?,
            ],
            strength: r.f32("strength")?,
            episode_id: r.u64("episode_id")?,
            background_age_s: r.f64("background_age_s")?,
        })
    }
}

impl RosMessage for ContactEpisode {
    const TYPE: &'static str = "unitac_msgs/msg/ContactEpisode";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.string(&self.sensor_id);
        w.u64(self.episode_id);
        write_time(w, self.start);
        write_time(w, self.end);
        w.u32(self.frame_count);
        w.f32(self.peak_area_px);
        w.f32(self.peak_area_mm2);
        w.u64(self.peak_frame_seq);
        w.string(&self.label);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(ContactEpisode {
            header: Header::read_cdr(r)?,
            sensor_id: r.string("sensor_id")?,
            episode_id: r.u64("episode_id")?,
            start: read_time(r, "start")?,
            end: read_time(r, "end")?,
            frame_count: r.u32("frame_count")?,
            peak_area_px: r.f32("peak_area_px")?,
            peak_area_mm2: r.f32("peak_area_mm2")?,
            peak_frame_seq: r.u64("peak_frame_seq")?,
            label: r.string("label")?,
        })
    }
}

impl RosMessage for TactileProperties {
    const TYPE: &'static str = "unitac_msgs/msg/TactileProperties";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.string(&self.sensor_id);
        w.u64(self.episode_id);
        w.string(&self.label);
        for v in [
            self.hardness,
            self.hardness_std,
            self.roughness,
            self.roughness_std,
            self.texture,
            self.texture_std,
        ] {
            w.f32(v);
        }
        w.string(&self.model_id);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(TactileProperties {
            header: Header::read_cdr(r)?,
            sensor_id: r.string("sensor_id")?,
            episode_id: r.u64("episode_id")?,
            label: r.string("label")?,
            hardness: r.f32("hardness")?,
            hardness_std: r.f32("hardness_std")?,
            roughness: r.f32("roughness")?,
            roughness_std: r.f32("roughness_std")?,
            texture: r.f32("texture")?,
            texture_std: r.f32("texture_std")?,
            model_id: r.string("model_id")?,
        })
    }
}

fn winner(v: u8) -> Result<Winner, CdrError> {
    match v {
        0 => Ok(Winner::A),
        1 => Ok(Winner::B),
        2 => Ok(Winner::Tie),
        value => Err(CdrError::BadEnum {
            what: "winner",
            value,
        }),
    }
}

impl RosMessage for PropertyComparison {
    const TYPE: &'static str = "unitac_msgs/msg/PropertyComparison";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.string(&self.property);
        w.u64(self.episode_a);
        w.string(&self.label_a);
        w.u64(self.episode_b);
        w.string(&self.label_b);
        w.u8(self.winner as u8);
        w.f32(self.score_a);
        w.f32(self.score_b);
        w.f32(self.margin);
        w.f32(self.confidence);
        w.string(&self.sentence);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(PropertyComparison {
            header: Header::read_cdr(r)?,
            property: r.string("property")?,
            episode_a: r.u64("episode_a")?,
            label_a: r.string("label_a")?,
            episode_b: r.u64("episode_b")?,
            label_b: r.string("label_b")?,
            winner: winner(r.u8("winner")?)?,
            score_a: r.f32("score_a")?,
            score_b: r.f32("score_b")?,
            margin: r.f32("margin")?,
            confidence: r.f32("confidence")?,
            sentence: r.string("sentence")?,
        })
    }
}

impl RosMessage for TactileLatent {
    const TYPE: &'static str = "unitac_msgs/msg/TactileLatent";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.u8(self.source as u8);
        w.string(&self.sensor_id);
        w.seq_u32(&self.shape);
        w.seq_f32(&self.data);
        w.string(&self.model_id);
        w.string(&self.solver);
        w.u32(self.steps);
        w.f32(self.guidance);
        w.f64(self.elapsed_s);
        w.bool(self.valid);
        w.string(&self.guard_report);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let header = Header::read_cdr(r)?;
        let source = match r.u8("source")? {
            0 => LatentSource::Real,
            1 => LatentSource::Predicted,
            value => {
                return Err(CdrError::BadEnum {
                    what: "source",
                    value,
                });
            }
        };
        Ok(TactileLatent {
            header,
            source,
            sensor_id: r.string("sensor_id")?,
            shape: r.seq_u32("shape", MAX_LATENT_DIMS)?,
            data: r.seq_f32("data", MAX_SEQUENCE)?,
            model_id: r.string("model_id")?,
            solver: r.string("solver")?,
            steps: r.u32("steps")?,
            guidance: r.f32("guidance")?,
            elapsed_s: r.f64("elapsed_s")?,
            valid: r.bool("valid")?,
            guard_report: r.string("guard_report")?,
        })
    }
}

impl RosMessage for GripperCommand {
    const TYPE: &'static str = "unitac_msgs/msg/GripperCommand";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.u8(self.mode as u8);
        w.f64(self.position_m);
        w.f64(self.speed_m_s);
        w.f64(self.force_n);
        w.string(&self.reason);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let header = Header::read_cdr(r)?;
        let mode = match r.u8("mode")? {
            0 => GripperMode::Position,
            1 => GripperMode::Force,
            2 => GripperMode::Stop,
            value => {
                return Err(CdrError::BadEnum {
                    what: "mode",
                    value,
                });
            }
        };
        Ok(GripperCommand {
            header,
            mode,
            position_m: r.f64("position_m")?,
            speed_m_s: r.f64("speed_m_s")?,
            force_n: r.f64("force_n")?,
            reason: r.string("reason")?,
        })
    }
}

impl RosMessage for PolicyStatus {
    const TYPE: &'static str = "unitac_msgs/msg/PolicyStatus";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.string(&self.scene);
        w.string(&self.mode);
        w.string(&self.phase);
        w.bool(self.safety_ok);
        w.string(&self.message);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(PolicyStatus {
            header: Header::read_cdr(r)?,
            scene: r.string("scene")?,
            mode: r.string("mode")?,
            phase: r.string("phase")?,
            safety_ok: r.bool("safety_ok")?,
            message: r.string("message")?,
        })
    }
}

// ---------------------------------------------------------------------------------------------
// Schemas (ros2msg: the .msg text, then each dependency after a line of 80 '=' and `MSG: pkg/Type`)

const TIME_MSG: &str = "int32 sec\nuint32 nanosec\n";
const HEADER_MSG: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";
const IMAGE_MSG: &str = "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n\
uint8 is_bigendian\nuint32 step\nuint8[] data\n";
const COMPRESSED_IMAGE_MSG: &str = "std_msgs/Header header\nstring format\nuint8[] data\n";

/// The .msg text of every type this crate knows (type name as `pkg/msg/Type`), in a fixed order.
pub const KNOWN_TYPES: &[(&str, &str)] = &[
    ("builtin_interfaces/msg/Time", TIME_MSG),
    ("std_msgs/msg/Header", HEADER_MSG),
    ("sensor_msgs/msg/Image", IMAGE_MSG),
    ("sensor_msgs/msg/CompressedImage", COMPRESSED_IMAGE_MSG),
    (
        "unitac_msgs/msg/ContactState",
        include_str!("../../../msg/unitac_msgs/msg/ContactState.msg"),
    ),
    (
        "unitac_msgs/msg/ContactEpisode",
        include_str!("../../../msg/unitac_msgs/msg/ContactEpisode.msg"),
    ),
    (
        "unitac_msgs/msg/TactileProperties",
        include_str!("../../../msg/unitac_msgs/msg/TactileProperties.msg"),
    ),
    (
        "unitac_msgs/msg/PropertyComparison",
        include_str!("../../../msg/unitac_msgs/msg/PropertyComparison.msg"),
    ),
    (
        "unitac_msgs/msg/TactileLatent",
        include_str!("../../../msg/unitac_msgs/msg/TactileLatent.msg"),
    ),
    (
        "unitac_msgs/msg/GripperCommand",
        include_str!("../../../msg/unitac_msgs/msg/GripperCommand.msg"),
    ),
    (
        "unitac_msgs/msg/PolicyStatus",
        include_str!("../../../msg/unitac_msgs/msg/PolicyStatus.msg"),
    ),
];

/// True if this crate can decode messages of this type.
pub fn is_known_type(type_name: &str) -> bool {
    KNOWN_TYPES.iter().any(|(t, _)| *t == type_name)
}

fn msg_text(type_name: &str) -> Option<&'static str> {
    KNOWN_TYPES
        .iter()
        .find(|(t, _)| *t == type_name)
        .map(|(_, m)| *m)
}

/// `pkg/msg/Type` for a field type as written in a .msg file (`std_msgs/Header`, `Header`).
fn field_type_name(own_pkg: &str, ty: &str) -> Option<String> {
    let base = ty.split('[').next()?.trim();
    const PRIMITIVES: &[&str] = &[
        "bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
        "uint64", "float32", "float64", "string", "wstring",
    ];
    if PRIMITIVES.contains(&base) || base.starts_with("string<") {
        return None;
    }
    Some(match base.split_once('/') {
        Some((pkg, name)) => format!("{pkg}/msg/{}", name.trim_start_matches("msg/")),
        None if base == "Header" => "std_msgs/msg/Header".to_string(),
        None => format!("{own_pkg}/msg/{base}"),
    })
}

/// Types a .msg text uses directly, in order of first use.
fn direct_deps(type_name: &str, text: &str) -> Vec<String> {
    let pkg = type_name.split('/').next().unwrap_or_default();
    let mut out: Vec<String> = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or_default().trim();
        let mut parts = line.split_whitespace();
        let (Some(ty), Some(name)) = (parts.next(), parts.next()) else {
            continue;
        };
        if name.contains('=') {
            continue;
        }
        if let Some(t) = field_type_name(pkg, ty) {
            if !out.contains(&t) {
                out.push(t);
            }
        }
    }
    out
}

/// The `ros2msg` schema of a known type: its .msg text, then every type it depends on
/// (depth first, each once) after a line of 80 '=' and `MSG: pkg/Type`.
pub fn schema_text(type_name: &str) -> Option<String> {
    let main = msg_text(type_name)?;
    let mut order: Vec<String> = Vec::new();
    let mut stack = direct_deps(type_name, main);
    stack.reverse();
    while let Some(t) = stack.pop() {
        if order.contains(&t) {
            continue;
        }
        let text = msg_text(&t)?;
        let mut more = direct_deps(&t, text);
        order.push(t);
        more.reverse();
        stack.extend(more);
    }
    let mut s = main.trim_end().to_string();
    s.push('\n');
    for t in order {
        s.push_str(&"=".repeat(80));
        s.push('\n');
        s.push_str("MSG: ");
        s.push_str(&t.replacen("/msg/", "/", 1));
        s.push('\n');
        s.push_str(msg_text(&t)?.trim_end());
        s.push('\n');
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Header {
        Header::new(Stamp(1_700_000_000_123_456_789), "gelsight_optical_frame")
    }

    #[test]
    fn image_round_trip_and_layout() {
        let img = Image {
            header: header(),
            height: 2,
            width: 1,
            encoding: "rgb8".into(),
            is_bigendian: 0,
            step: 3,
            data: vec![1, 2, 3, 4, 5, 6],
        };
        let b = img.to_cdr();
        assert_eq!(&b[..4], &[0, 1, 0, 0]);
        // sec, nanosec, then frame_id length incl. NUL.
        assert_eq!(&b[4..8], &1_700_000_000i32.to_le_bytes());
        assert_eq!(&b[12..16], &23u32.to_le_bytes());
        assert_eq!(Image::from_cdr(&b).unwrap(), img);
        // Cutting the payload anywhere is an error, never a panic.
        for n in 0..b.len() - 3 {
            assert!(Image::from_cdr(&b[..n]).is_err(), "cut at {n}");
        }
    }

    #[test]
    fn project_messages_round_trip() {
        let c = ContactState {
            header: header(),
            sensor_id: "gs".into(),
            frame_seq: 5,
            in_contact: true,
            area_px: 1.5,
            area_mm2: 0.25,
            centroid_px: [3.0, 4.0],
            bbox_px: [1, 2, 3, 4],
            strength: 0.5,
            episode_id: 2,
            background_age_s: 1.25,
        };
        assert_eq!(ContactState::from_cdr(&c.to_cdr()).unwrap(), c);
        let l = TactileLatent {
            header: header(),
            source: LatentSource::Predicted,
            sensor_id: "gs".into(),
            shape: vec![2, 3],
            data: vec![0.5; 6],
            model_id: "m".into(),
            solver: "heun".into(),
            steps: 8,
            guidance: 1.5,
            elapsed_s: 0.01,
            valid: true,
            guard_report: String::new(),
        };
        assert_eq!(TactileLatent::from_cdr(&l.to_cdr()).unwrap(), l);
        let mut bad = l.to_cdr();
        bad[4 + 12 + 23] = 9; // the source byte, right after the header (stamp 8, len 4, 23 bytes)
        assert!(TactileLatent::from_cdr(&bad).is_err());
    }

    #[test]
    fn schema_has_dependencies_once() {
        let s = schema_text("unitac_msgs/msg/ContactEpisode").unwrap();
        let sep = "=".repeat(80);
        assert_eq!(s.matches(&sep).count(), 2);
        assert!(s.contains("MSG: std_msgs/Header\n"));
        assert!(s.contains("MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"));
        let img = schema_text("sensor_msgs/msg/Image").unwrap();
        assert!(img.starts_with("std_msgs/Header header\nuint32 height"));
        assert!(schema_text("geometry_msgs/msg/Twist").is_none());
        // Constants are not dependencies.
        let g = schema_text("unitac_msgs/msg/GripperCommand").unwrap();
        assert_eq!(g.matches("MSG: ").count(), 2);
    }
}
