//! The message generator: reads the `.msg` files of msg/unitac_msgs and writes the Rust side of
//! every message (struct, enums, `Message` impl, and the `for_each_message!` macro that
//! crates/bag and crates/ros expand into their CDR codecs and r2r conversions).
//!
//! `build.rs` runs it at build time; core's unit tests run it on texts of their own. It has no
//! dependencies so that the build script stays small. What a `.msg` file cannot say lives in the
//! four tables below, next to the parser, so that every rule is in one file.

use std::fmt;

/// Messages that get no generated mirror: ContactClip carries images; its Rust side is
/// `ContactClip` (frames as `Frame`), converted by hand in crates/ros.
pub const NOT_GENERATED: &[&str] = &["ContactClip"];

/// Rust names of constant-backed enums, where the field name alone would be too vague
/// (default: the field name in CamelCase, e.g. `winner` -> `Winner`).
pub const ENUM_NAMES: &[(&str, &str, &str)] = &[
    ("TactileLatent", "source", "LatentSource"),
    ("GripperCommand", "mode", "GripperMode"),
];

/// Sequence bounds tighter than the CDR reader's default (a `const` of `unitac_core::msg`).
pub const BOUNDS: &[(&str, &str, &str)] = &[
    ("TactileLatent", "shape", "MAX_LATENT_DIMS"),
    (
        "TactileLatent",
        "condition_sources",
        "MAX_CONDITION_SOURCES",
    ),
    ("TactileLatent", "condition_age_s", "MAX_CONDITION_SOURCES"),
    ("VisualObservation", "names", "MAX_VISUAL_VALUES"),
    ("VisualObservation", "values", "MAX_VISUAL_VALUES"),
];

/// Checks beyond the field types (a method of the message in msg.rs); every decoder runs them.
pub const CHECKS: &[(&str, &str)] = &[
    ("TactileLatent", "check_shape"),
    ("VisualObservation", "check_lengths"),
];

/// One `.msg` file: its type name (file stem) and text.
#[derive(Debug, Clone)]
pub struct MsgFile {
    pub name: String,
    pub text: String,
}

/// A `.msg` line the generator cannot turn into Rust.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GenError {
    pub file: String,
    pub line: usize,
    pub reason: String,
}

impl fmt::Display for GenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.msg:{}: {}", self.file, self.line, self.reason)
    }
}

impl std::error::Error for GenError {}

/// A field as the `.msg` file declares it, with its Rust type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub name: String,
    /// As written in the `.msg` file, e.g. `float32[2]`, `std_msgs/Header`.
    pub ros_type: String,
    /// As it appears in the generated struct, e.g. `[f32; 2]`, `Header`, `Winner`.
    pub rust_type: String,
    /// The element's Rust type (`f32` for `float32[2]`) and whether it is one of ours.
    pub elem: String,
    pub elem_is_enum: bool,
    pub array: Array,
    /// The line's trailing comment.
    pub doc: String,
    /// The name of a `unitac_core::msg` constant bounding this sequence, if any.
    pub max: Option<String>,
}

/// Scalar, fixed array or sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Array {
    No,
    Fixed(usize),
    Sequence,
}

/// `elem` as a scalar, fixed array or sequence, with the paths to use in the struct (`qualify`
/// false) or in `for_each_message!` (true: absolute, through `$crate`).
fn render(elem: &str, is_enum: bool, array: Array, qualify: bool) -> String {
    let e = match (qualify, elem) {
        (false, _) => elem.to_string(),
        (true, "Stamp") => "$crate::clock::Stamp".into(),
        (true, "Header") => "$crate::msg::Header".into(),
        (true, "String") => "::std::string::String".into(),
        (true, _) if is_enum => format!("$crate::msg::{elem}"),
        (true, _) => elem.to_string(),
    };
    match (array, qualify) {
        (Array::No, _) => e,
        (Array::Fixed(n), _) => format!("[{e}; {n}]"),
        (Array::Sequence, false) => format!("Vec<{e}>"),
        (Array::Sequence, true) => format!("::std::vec::Vec<{e}>"),
    }
}

/// A `uint8` field whose values are the message's `FIELD_*` constants.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EnumDef {
    pub name: String,
    pub field: String,
    pub doc: String,
    /// (variant, wire value)
    pub variants: Vec<(String, u8)>,
}

/// One parsed message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MessageDef {
    pub name: String,
    pub doc: String,
    pub fields: Vec<Field>,
    pub enums: Vec<EnumDef>,
    pub text: String,
}

fn camel(upper_or_snake: &str) -> String {
    upper_or_snake
        .split('_')
        .filter(|w| !w.is_empty())
        .map(|w| {
            let lower = w.to_ascii_lowercase();
            let mut c = lower.chars();
            c.next()
                .map(|f| f.to_ascii_uppercase().to_string() + c.as_str())
                .unwrap_or_default()
        })
        .collect()
}

fn snake(camel_name: &str) -> String {
    let mut out = String::new();
    for (i, ch) in camel_name.chars().enumerate() {
        if ch.is_ascii_uppercase() && i > 0 {
            out.push('_');
        }
        out.push(ch.to_ascii_lowercase());
    }
    out
}

/// Rust type of a primitive or known ROS type, without array suffix.
fn base_rust_type(base: &str) -> Option<&'static str> {
    Some(match base {
        "bool" => "bool",
        "byte" | "uint8" => "u8",
        "int8" => "i8",
        "uint16" => "u16",
        "int16" => "i16",
        "uint32" => "u32",
        "int32" => "i32",
        "uint64" => "u64",
        "int64" => "i64",
        "float32" => "f32",
        "float64" => "f64",
        "string" => "String",
        "builtin_interfaces/Time" => "Stamp",
        "std_msgs/Header" | "Header" => "Header",
        _ => return None,
    })
}

/// Parse one `.msg` file.
pub fn parse(file: &MsgFile) -> Result<MessageDef, GenError> {
    let err = |line: usize, reason: String| GenError {
        file: file.name.clone(),
        line,
        reason,
    };
    let mut doc = Vec::new();
    let mut fields = Vec::new();
    // (name, value, line) of each constant.
    let mut constants: Vec<(String, u8, usize)> = Vec::new();
    for (i, raw) in file.text.lines().enumerate() {
        let line = i + 1;
        let (code, comment) = match raw.split_once('#') {
            Some((c, m)) => (c.trim(), m.trim()),
            None => (raw.trim(), ""),
        };
        if code.is_empty() {
            if fields.is_empty() && constants.is_empty() && !comment.is_empty() {
                doc.push(comment.to_string());
            }
            continue;
        }
        // A constant is `type NAME=value`; the type itself may hold `<=` (bounded types).
        let (ty, rest) = code.split_once(char::is_whitespace).unwrap_or((code, ""));
        if let Some((name, value)) = rest.split_once('=') {
            let name = name.trim();
            if name.is_empty() || name.contains(char::is_whitespace) {
                return Err(err(line, format!("cannot read constant `{code}`")));
            }
            if ty != "uint8" {
                return Err(err(line, format!("constant {name}: only uint8 constants")));
            }
            let value: u8 = value
                .trim()
                .parse()
                .map_err(|_| err(line, format!("constant {name}: `{value}` is not a uint8")))?;
            constants.push((name.to_string(), value, line));
            continue;
        }
        let mut parts = code.split_whitespace();
        let (Some(ty), Some(name), None) = (parts.next(), parts.next(), parts.next()) else {
            return Err(err(
                line,
                format!("cannot read `{code}` (expected `type name`)"),
            ));
        };
        let (base, array) = match ty.split_once('[') {
            Some((b, rest)) => (b, Some(rest.trim_end_matches(']'))),
            None => (ty, None),
        };
        let elem = base_rust_type(base)
            .ok_or_else(|| err(line, format!("field {name}: type {base} is not supported")))?;
        let array = match array {
            None => Array::No,
            Some("") => Array::Sequence,
            Some(n) => Array::Fixed(n.parse().map_err(|_| {
                err(
                    line,
                    format!("field {name}: array size `{n}` (bounded sequences are not supported)"),
                )
            })?),
        };
        let max = BOUNDS
            .iter()
            .find(|(m, f, _)| *m == file.name && *f == name)
            .map(|(_, _, c)| c.to_string());
        if max.is_some() && array != Array::Sequence {
            return Err(err(line, format!("field {name}: a bound needs a sequence")));
        }
        fields.push(Field {
            name: name.to_string(),
            ros_type: ty.to_string(),
            rust_type: render(elem, false, array, false),
            elem: elem.to_string(),
            elem_is_enum: false,
            array,
            doc: comment.to_string(),
            max,
        });
    }
    let mut enums = Vec::new();
    for f in &mut fields {
        let prefix = format!("{}_", f.name.to_ascii_uppercase());
        let variants: Vec<(String, u8)> = constants
            .iter()
            .filter_map(|(c, v, _)| c.strip_prefix(&prefix).map(|rest| (camel(rest), *v)))
            .collect();
        if variants.is_empty() {
            continue;
        }
        if f.ros_type != "uint8" || f.array != Array::No {
            let line = constants
                .iter()
                .find(|(c, _, _)| c.starts_with(&prefix))
                .map_or(0, |(_, _, l)| *l);
            return Err(err(
                line,
                format!("constants {prefix}*: field {} is not uint8", f.name),
            ));
        }
        let name = ENUM_NAMES
            .iter()
            .find(|(m, field, _)| *m == file.name && *field == f.name)
            .map_or_else(|| camel(&f.name), |(_, _, n)| n.to_string());
        f.rust_type = name.clone();
        f.elem = name.clone();
        f.elem_is_enum = true;
        enums.push(EnumDef {
            name,
            field: f.name.clone(),
            doc: f.doc.clone(),
            variants,
        });
    }
    if let Some((c, _, line)) = constants.iter().find(|(c, _, _)| {
        !fields
            .iter()
            .any(|f| c.starts_with(&format!("{}_", f.name.to_ascii_uppercase())))
    }) {
        return Err(err(
            *line,
            format!("constant {c} names no field (expected FIELD_VALUE)"),
        ));
    }
    Ok(MessageDef {
        name: file.name.clone(),
        doc: doc.join("\n"),
        fields,
        enums,
        text: file.text.clone(),
    })
}

/// Text with Markdown's active characters escaped (the `.msg` comments use brackets for units
/// and angle brackets for placeholders).
fn escape_md(text: &str) -> String {
    let mut s = String::new();
    for ch in text.chars() {
        if matches!(ch, '[' | ']' | '<' | '>' | '*' | '_' | '`' | '\\') {
            s.push('\\');
        }
        s.push(ch);
    }
    s
}

/// A `#[doc]` line (the text is escaped, the code span is not).
fn doc_attr(indent: &str, code: &str, text: &str) -> String {
    let text = escape_md(text);
    let doc = match (code.is_empty(), text.is_empty()) {
        (true, _) => text,
        (false, true) => format!("`{code}`"),
        (false, false) => format!("`{code}`: {text}"),
    };
    format!("{indent}#[doc = {doc:?}]\n")
}

/// The generated Rust: one struct and its enums per message, then `for_each_message!`.
pub fn generate(files: &[MsgFile]) -> Result<String, GenError> {
    let mut defs = Vec::new();
    for f in files {
        if !NOT_GENERATED.contains(&f.name.as_str()) {
            defs.push(parse(f)?);
        }
    }
    let mut out = String::from(
        "// @generated by crates/core/build.rs (build/msggen.rs) \
         from msg/unitac_msgs/msg/*.msg.\n\n",
    );
    for d in &defs {
        let path = format!("msg/unitac_msgs/msg/{}.msg", d.name);
        for line in d.doc.lines() {
            out += &doc_attr("", "", line);
        }
        out += &format!("#[doc = \"\\n\\nGenerated from `{path}`.\"]\n");
        out += "#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]\n";
        out += &format!("pub struct {} {{\n", d.name);
        for f in &d.fields {
            out += &doc_attr("    ", &f.ros_type, &f.doc);
            out += &format!("    pub {}: {},\n", f.name, f.rust_type);
        }
        out += "}\n\n";
        let check = CHECKS
            .iter()
            .find(|(m, _)| *m == d.name)
            .map(|(_, c)| {
                format!(
                    "    fn check(&self) -> Result<(), MsgError> {{\n        self.{c}()\n    }}\n"
                )
            })
            .unwrap_or_default();
        let (name, text) = (&d.name, &d.text);
        out += &format!(
            "impl Message for {name} {{\n    \
                 const ROS_TYPE: &'static str = \"unitac_msgs/msg/{name}\";\n    \
                 const MSG_TEXT: &'static str = {text:?};\n\
             {check}}}\n\n"
        );
        for e in &d.enums {
            out += &doc_attr("", &format!("{}.{}", d.name, e.field), &e.doc);
            out += "#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]\n";
            out += "#[serde(rename_all = \"lowercase\")]\n";
            out += &format!("pub enum {} {{\n", e.name);
            for (v, n) in &e.variants {
                out += &format!("    {v} = {n},\n");
            }
            out += "}\n\n";
            let name = &e.name;
            out += &format!(
                "impl From<{name}> for u8 {{\n    \
                     fn from(v: {name}) -> u8 {{\n        \
                         v as u8\n    \
                     }}\n\
                 }}\n\n\
                 impl TryFrom<u8> for {name} {{\n    \
                     type Error = UnknownValue;\n    \
                     fn try_from(v: u8) -> Result<Self, UnknownValue> {{\n        \
                         match v {{\n"
            );
            for (v, n) in &e.variants {
                out += &format!("            {n} => Ok(Self::{v}),\n");
            }
            out += "            _ => Err(UnknownValue(v)),\n        }\n    }\n}\n\n";
        }
    }
    out +=
        "/// Calls `$callback!` once with every generated message and enum of msg/unitac_msgs:\n";
    out += "/// see the [module docs](crate::msg) for the shape of its input.\n";
    out += "#[macro_export]\n\
             macro_rules! for_each_message {\n    \
                 ($callback:ident) => {\n        \
                     $callback! {\n            \
                         messages {\n";
    for d in &defs {
        let s = snake(&d.name);
        out += &format!("                {} [{s}, {s}_from] {{\n", d.name);
        for f in &d.fields {
            let max = f
                .max
                .as_ref()
                .map_or_else(|| "None".to_string(), |c| format!("Some($crate::msg::{c})"));
            out += &format!(
                "                    {}: {} => {max},\n",
                f.name,
                render(&f.elem, f.elem_is_enum, f.array, true)
            );
        }
        out += "                }\n";
    }
    out += "            }\n            enums {\n";
    for d in &defs {
        for e in &d.enums {
            out += &format!("                $crate::msg::{},\n", e.name);
        }
    }
    out += "            }\n        }\n    };\n}\n";
    Ok(out)
}
