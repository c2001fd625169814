//! ROS 2 messages this crate reads and writes, their CDR form and their `ros2msg` schema text.
//!
//! sensor_msgs/Image, CompressedImage and PointCloud2 (with PointField) are written by hand here;
//! the contact stage's depth ([`DepthMap`]) becomes an Image (32FC1) and a PointCloud2 (x y z)
//! by [`Image::depth32fc1`] and [`PointCloud2::xyz`], the one conversion of every transport. The project's
//! messages are the Rust mirrors in `unitac_core::msg`, generated from the `.msg` files in
//! msg/unitac_msgs; their codecs below are generated from the same definition
//! (`unitac_core::for_each_message!`), one [`CdrField`] call per field, with the `.msg` text as
//! their schema. A field added to a `.msg` file needs no edit here.

use crate::cdr::{CdrError, CdrReader, CdrWriter, MAX_IMAGE_BYTES, MAX_SEQUENCE};
use unitac_core::Stamp;
use unitac_core::msg::{
    ArmCommand, ContactEpisode, ContactState, DepthMap, GripperCommand, GripperStatus, Header,
    Message, PolicyStatus, PropertyComparison, SlipState, TactileLatent, TactileProperties,
    VisualObservation,
};

pub use unitac_core::msg::MAX_LATENT_DIMS;

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

impl Image {
    /// The `depth` Image of a depth map: 32FC1, metres, little-endian, NaN where unknown
    /// (REP 117), the map's stamp and frame_id.
    pub fn depth32fc1(d: &DepthMap) -> Self {
        Self {
            header: d.header.clone(),
            height: d.height,
            width: d.width,
            encoding: "32FC1".into(),
            is_bigendian: 0,
            step: d.width.saturating_mul(4),
            data: d.depth_m.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }
}

/// sensor_msgs/msg/PointField.
#[derive(Debug, Clone, PartialEq)]
pub struct PointField {
    pub name: String,
    pub offset: u32,
    pub datatype: u8,
    pub count: u32,
}

impl PointField {
    /// PointField's FLOAT32 constant.
    pub const FLOAT32: u8 = 7;
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            name: r.string("fields.name")?,
            offset: r.u32("fields.offset")?,
            datatype: r.u8("fields.datatype")?,
            count: r.u32("fields.count")?,
        })
    }
}

/// Most fields a PointCloud2 read here may have.
pub const MAX_POINT_FIELDS: usize = 64;

/// sensor_msgs/msg/PointCloud2.
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloud2 {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    pub data: Vec<u8>,
    pub is_dense: bool,
}

impl PointCloud2 {
    /// The `points` of a depth map: one point per known pixel, row by row
    /// ([`DepthMap::points`]: REP 103 optical frame, metres), fields x y z float32, unorganized
    /// (height 1), dense (no NaN points).
    pub fn xyz(d: &DepthMap) -> Self {
        let pts = d.points();
        let field = |name: &str, offset: u32| PointField {
            name: name.into(),
            offset,
            datatype: PointField::FLOAT32,
            count: 1,
        };
        let n = u32::try_from(pts.len()).unwrap_or(u32::MAX);
        Self {
            header: d.header.clone(),
            height: 1,
            width: n,
            fields: vec![field("x", 0), field("y", 4), field("z", 8)],
            is_bigendian: false,
            point_step: 12,
            row_step: n.saturating_mul(12),
            data: pts.iter().flatten().flat_map(|v| v.to_le_bytes()).collect(),
            is_dense: true,
        }
    }
}

impl RosMessage for PointCloud2 {
    const TYPE: &'static str = "sensor_msgs/msg/PointCloud2";
    fn write_cdr(&self, w: &mut CdrWriter) {
        self.header.write_cdr(w);
        w.u32(self.height);
        w.u32(self.width);
        w.u32(u32::try_from(self.fields.len()).unwrap_or(u32::MAX));
        for f in &self.fields {
            w.string(&f.name);
            w.u32(f.offset);
            w.u8(f.datatype);
            w.u32(f.count);
        }
        w.bool(self.is_bigendian);
        w.u32(self.point_step);
        w.u32(self.row_step);
        w.bytes(&self.data);
        w.bool(self.is_dense);
    }
    fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let header = Header::read_cdr(r)?;
        let height = r.u32("height")?;
        let width = r.u32("width")?;
        let n = r.u32("fields")? as usize;
        if n > MAX_POINT_FIELDS {
            return Err(CdrError::TooLong {
                what: "fields",
                len: n,
                max: MAX_POINT_FIELDS,
            });
        }
        let fields = (0..n)
            .map(|_| PointField::read(r))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            header,
            height,
            width,
            fields,
            is_bigendian: r.bool("is_bigendian")?,
            point_step: r.u32("point_step")?,
            row_step: r.u32("row_step")?,
            data: r.bytes("data", MAX_IMAGE_BYTES)?.to_vec(),
            is_dense: r.bool("is_dense")?,
        })
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

// ---------------------------------------------------------------------------------------------
// msg/unitac_msgs: one `CdrField` call per field, generated from the .msg files (see
// `unitac_core::msg`), so a field added there is encoded, decoded and bounded here with no edit.

/// A field type's CDR form; the generated codecs call this once per field, in `.msg` order.
pub trait CdrField: Sized {
    fn write_field(&self, w: &mut CdrWriter);
    /// `max`: the most elements of a sequence (other types ignore it).
    fn read_field(r: &mut CdrReader<'_>, what: &'static str, max: usize) -> Result<Self, CdrError>;
}

macro_rules! primitive_fields {
    ($($t:ty => $m:ident),* $(,)?) => {$(
        impl CdrField for $t {
            fn write_field(&self, w: &mut CdrWriter) {
                w.$m(*self);
            }
            fn read_field(
                r: &mut CdrReader<'_>,
                what: &'static str,
                _: usize,
            ) -> Result<Self, CdrError> {
                r.$m(what)
            }
        }
    )*};
}
primitive_fields!(
    bool => bool, u8 => u8, u32 => u32, i32 => i32, u64 => u64, f32 => f32, f64 => f64,
);

impl CdrField for String {
    fn write_field(&self, w: &mut CdrWriter) {
        w.string(self);
    }
    fn read_field(r: &mut CdrReader<'_>, what: &'static str, _: usize) -> Result<Self, CdrError> {
        r.string(what)
    }
}

impl CdrField for Stamp {
    fn write_field(&self, w: &mut CdrWriter) {
        write_time(w, *self);
    }
    fn read_field(r: &mut CdrReader<'_>, what: &'static str, _: usize) -> Result<Self, CdrError> {
        read_time(r, what)
    }
}

impl CdrField for Header {
    fn write_field(&self, w: &mut CdrWriter) {
        self.write_cdr(w);
    }
    fn read_field(r: &mut CdrReader<'_>, _: &'static str, _: usize) -> Result<Self, CdrError> {
        Header::read_cdr(r)
    }
}

/// Fixed arrays (`float32[2]`): the elements, no count.
impl<T: CdrField + Copy + Default, const N: usize> CdrField for [T; N] {
    fn write_field(&self, w: &mut CdrWriter) {
        for x in self {
            x.write_field(w);
        }
    }
    fn read_field(r: &mut CdrReader<'_>, what: &'static str, max: usize) -> Result<Self, CdrError> {
        let mut a = [T::default(); N];
        for x in &mut a {
            *x = T::read_field(r, what, max)?;
        }
        Ok(a)
    }
}

/// Sequences of one element type: the writer's and reader's `seq_*` pair for it.
macro_rules! cdr_sequence {
    ($($t:ty => $seq:ident),* $(,)?) => {$(
        impl CdrField for Vec<$t> {
            fn write_field(&self, w: &mut CdrWriter) {
                w.$seq(self);
            }
            fn read_field(
                r: &mut CdrReader<'_>,
                what: &'static str,
                max: usize,
            ) -> Result<Self, CdrError> {
                r.$seq(what, max)
            }
        }
    )*};
}
cdr_sequence!(u32 => seq_u32, f32 => seq_f32, f64 => seq_f64, String => seq_string);

impl CdrField for Vec<u8> {
    fn write_field(&self, w: &mut CdrWriter) {
        w.bytes(self);
    }
    fn read_field(r: &mut CdrReader<'_>, what: &'static str, max: usize) -> Result<Self, CdrError> {
        r.bytes(what, max).map(<[u8]>::to_vec)
    }
}

/// A field's sequence bound: its own, or [`MAX_SEQUENCE`].
fn limit(max: Option<usize>) -> usize {
    max.unwrap_or(MAX_SEQUENCE)
}

macro_rules! unitac_codecs {
    (
        messages {
            $( $msg:ident [$to:ident, $from:ident] { $( $f:ident : $t:ty => $max:expr ),* $(,)? } )*
        }
        enums { $( $e:ty ),* $(,)? }
    ) => {
        $(
            impl RosMessage for $msg {
                const TYPE: &'static str = <$msg as Message>::ROS_TYPE;
                fn write_cdr(&self, w: &mut CdrWriter) {
                    $( self.$f.write_field(w); )*
                }
                fn read_cdr(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
                    let m = $msg {
                        $( $f: <$t as CdrField>::read_field(r, stringify!($f), limit($max))?, )*
                    };
                    m.check()?;
                    Ok(m)
                }
            }
        )*

        $(
            /// A `uint8` with the message's constants; any other value is an error.
            impl CdrField for $e {
                fn write_field(&self, w: &mut CdrWriter) {
                    w.u8(u8::from(*self));
                }
                fn read_field(
                    r: &mut CdrReader<'_>,
                    what: &'static str,
                    _: usize,
                ) -> Result<Self, CdrError> {
                    <$e>::try_from(r.u8(what)?).map_err(|e| CdrError::BadEnum { what, value: e.0 })
                }
            }
        )*

        /// The .msg text of every type this crate knows (type name as `pkg/msg/Type`), in a fixed
        /// order.
        pub const KNOWN_TYPES: &[(&str, &str)] = &[
            ("builtin_interfaces/msg/Time", TIME_MSG),
            ("std_msgs/msg/Header", HEADER_MSG),
            ("sensor_msgs/msg/Image", IMAGE_MSG),
            ("sensor_msgs/msg/CompressedImage", COMPRESSED_IMAGE_MSG),
            ("sensor_msgs/msg/PointField", POINT_FIELD_MSG),
            ("sensor_msgs/msg/PointCloud2", POINT_CLOUD2_MSG),
            $( (<$msg as Message>::ROS_TYPE, <$msg as Message>::MSG_TEXT), )*
        ];
    };
}

unitac_core::for_each_message!(unitac_codecs);

// ---------------------------------------------------------------------------------------------
// Schemas (ros2msg: the .msg text, then each dependency after a line of 80 '=' and `MSG: pkg/Type`)

const TIME_MSG: &str = "int32 sec\nuint32 nanosec\n";
const HEADER_MSG: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";
const IMAGE_MSG: &str = "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n\
uint8 is_bigendian\nuint32 step\nuint8[] data\n";
const COMPRESSED_IMAGE_MSG: &str = "std_msgs/Header header\nstring format\nuint8[] data\n";
const POINT_FIELD_MSG: &str = "uint8 INT8    = 1\nuint8 UINT8   = 2\nuint8 INT16   = 3\n\
uint8 UINT16  = 4\nuint8 INT32   = 5\nuint8 UINT32  = 6\nuint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\n\n\
string name\nuint32 offset\nuint8  datatype\nuint32 count\n";
const POINT_CLOUD2_MSG: &str = "std_msgs/Header header\nuint32 height\nuint32 width\n\
PointField[] fields\nbool    is_bigendian\nuint32  point_step\nuint32  row_step\nuint8[] data\n\
bool is_dense\n";

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
    use unitac_core::msg::samples;

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

    /// Round trip, and every cut of the payload is an error (never a panic).
    fn round_trip<M: RosMessage + PartialEq + std::fmt::Debug>(m: &M) {
        let b = m.to_cdr();
        assert_eq!(&M::from_cdr(&b).unwrap(), m, "{}", M::TYPE);
        for n in 0..b.len().saturating_sub(3) {
            assert!(M::from_cdr(&b[..n]).is_err(), "{} cut at {n}", M::TYPE);
        }
    }

    /// Every message of msg/unitac_msgs, through the same definition as the codecs.
    #[test]
    fn every_generated_codec_round_trips() {
        macro_rules! round_trip_each {
            (
                messages { $( $msg:ident [$to:ident, $from:ident] { $($fields:tt)* } )* }
                enums { $($e:tt)* }
            ) => {
                $( round_trip(&samples::$to()); )*
            };
        }
        unitac_core::for_each_message!(round_trip_each);
        assert_eq!(KNOWN_TYPES.len(), 6 + 11);
        // The decoder runs the message's checks: names and values pair up.
        let mut v = samples::visual_observation();
        v.values.pop();
        assert!(VisualObservation::from_cdr(&v.to_cdr()).is_err());
        for (t, text) in KNOWN_TYPES {
            assert!(schema_text(t).unwrap().starts_with(text.trim_end()), "{t}");
        }
        // A latent's source byte comes right after the header (stamp 8, length 4, 17 bytes).
        let mut bad = samples::tactile_latent().to_cdr();
        bad[4 + 12 + 17] = 9;
        assert_eq!(
            TactileLatent::from_cdr(&bad),
            Err(CdrError::BadEnum {
                what: "source",
                value: 9
            })
        );
    }

    /// The generated layout is the one the hand-written codec had (and rosbags reads: see
    /// tests/interop.rs): fields in .msg order, fixed arrays without a count, enums as one byte.
    #[test]
    fn generated_layout_is_field_by_field() {
        let (cmp, cmd) = (samples::property_comparison(), samples::gripper_command());
        let mut w = CdrWriter::new();
        w.i32(1_700_000_000);
        w.u32(123_456_789);
        w.string("gs_optical_frame");
        w.string("roughness");
        w.u64(1);
        w.string("a");
        w.u64(2);
        w.string("b");
        w.u8(2);
        for v in [0.5, 0.5, 0.0, 0.5] {
            w.f32(v);
        }
        w.string("A and B are as rough");
        assert_eq!(cmp.to_cdr(), w.finish());

        let mut w = CdrWriter::new();
        w.i32(1_700_000_000);
        w.u32(123_456_789);
        w.string("gs_optical_frame");
        w.u8(1);
        for v in [0.02, 0.05, 4.5] {
            w.f64(v);
        }
        w.string("press");
        assert_eq!(cmd.to_cdr(), w.finish());
    }

    #[test]
    fn enum_values_bounds_and_checks_are_errors() {
        let (cmp, cmd) = (samples::property_comparison(), samples::gripper_command());
        // The mode byte comes right after the header (4 + 8 + 4 + 17 bytes).
        let mut bad = cmd.to_cdr();
        bad[4 + 12 + 17] = 3;
        assert_eq!(
            GripperCommand::from_cdr(&bad),
            Err(CdrError::BadEnum {
                what: "mode",
                value: 3
            })
        );
        // The winner byte comes after everything up to label_b.
        let mut w = CdrWriter::new();
        cmp.header.write_cdr(&mut w);
        w.string(&cmp.property);
        w.u64(cmp.episode_a);
        w.string(&cmp.label_a);
        w.u64(cmp.episode_b);
        w.string(&cmp.label_b);
        let pos = w.finish().len();
        let b = cmp.to_cdr();
        assert_eq!(b[pos], 2);
        let mut bad = b.clone();
        bad[pos] = 7;
        assert_eq!(
            PropertyComparison::from_cdr(&bad),
            Err(CdrError::BadEnum {
                what: "winner",
                value: 7
            })
        );

        let latent = |shape: Vec<u32>, n: usize| TactileLatent {
            shape,
            data: vec![1.0; n],
            ..samples::tactile_latent()
        };
        // Shape and data disagree: the message's own check.
        assert!(matches!(
            TactileLatent::from_cdr(&latent(vec![2, 3], 5).to_cdr()),
            Err(CdrError::Check(_))
        ));
        // One dimension too many: refused by the reader's bound, before the data.
        assert_eq!(
            TactileLatent::from_cdr(&latent(vec![1; MAX_LATENT_DIMS + 1], 1).to_cdr()),
            Err(CdrError::TooLong {
                what: "shape",
                len: MAX_LATENT_DIMS + 1,
                max: MAX_LATENT_DIMS
            })
        );
        let ok = latent(vec![1; MAX_LATENT_DIMS], 1);
        assert_eq!(TactileLatent::from_cdr(&ok.to_cdr()).unwrap(), ok);
    }

    #[test]
    fn depth_becomes_a_32fc1_image_and_an_xyz_cloud() {
        let d = DepthMap {
            header: header(),
            width: 2,
            height: 2,
            pixel_m: 0.5e-4,
            depth_m: vec![0.0, f32::NAN, 0.002, 0.0],
        };
        let img = Image::depth32fc1(&d);
        assert_eq!(
            (img.encoding.as_str(), img.step, img.data.len()),
            ("32FC1", 8, 16)
        );
        assert!(f32::from_le_bytes(img.data[4..8].try_into().unwrap()).is_nan());
        assert_eq!(Image::from_cdr(&img.to_cdr()).unwrap(), img);
        let pc = PointCloud2::xyz(&d);
        assert_eq!(
            (pc.height, pc.width, pc.point_step, pc.row_step),
            (1, 3, 12, 36)
        );
        assert_eq!(pc.data.len(), 36);
        let names: Vec<&str> = pc.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["x", "y", "z"]);
        // The second point is pixel (0, 1): left of and below the centre, pressed in (negative
        // z); the NaN pixel (1, 0) has none.
        let f = |i: usize| f32::from_le_bytes(pc.data[i * 4..i * 4 + 4].try_into().unwrap());
        assert_eq!([f(3), f(4), f(5)], [-0.25e-4, 0.25e-4, -0.002]);
        round_trip(&pc);
        let s = schema_text(PointCloud2::TYPE).unwrap();
        assert!(s.contains("MSG: sensor_msgs/PointField\n") && s.contains("MSG: std_msgs/Header"));
        // A field count beyond the bound is refused before reading them.
        let mut w = CdrWriter::new();
        header().write_cdr(&mut w);
        w.u32(1);
        w.u32(1);
        w.u32(1_000_000);
        assert!(matches!(
            PointCloud2::from_cdr(&w.finish()),
            Err(CdrError::TooLong { what: "fields", .. })
        ));
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
