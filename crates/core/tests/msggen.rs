//! The message generator (crates/core/build/msggen.rs) on the real .msg files and on edited
//! copies: what adding a field produces, and which `.msg` lines it refuses.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[path = "../build/msggen.rs"]
#[allow(dead_code)]
mod msggen;

use msggen::{MsgFile, generate, parse};

fn msg_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../msg/unitac_msgs/msg")
}

fn real(name: &str) -> MsgFile {
    MsgFile {
        name: name.into(),
        text: std::fs::read_to_string(msg_dir().join(format!("{name}.msg"))).unwrap(),
    }
}

fn all_real() -> Vec<MsgFile> {
    let mut names: Vec<String> = std::fs::read_dir(msg_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "msg"))
        .map(|p| p.file_stem().unwrap().to_str().unwrap().to_string())
        .collect();
    names.sort();
    names.iter().map(|n| real(n)).collect()
}

fn with_text(name: &str, text: &str) -> MsgFile {
    MsgFile {
        name: name.into(),
        text: text.into(),
    }
}

#[test]
fn real_messages_map_field_by_field() {
    let c = parse(&real("ContactState")).unwrap();
    let got: Vec<(&str, &str, &str)> = c
        .fields
        .iter()
        .map(|f| (f.name.as_str(), f.ros_type.as_str(), f.rust_type.as_str()))
        .collect();
    assert_eq!(
        got,
        [
            ("header", "std_msgs/Header", "Header"),
            ("sensor_id", "string", "String"),
            ("frame_seq", "uint64", "u64"),
            ("in_contact", "bool", "bool"),
            ("area_px", "float32", "f32"),
            ("area_m2", "float32", "f32"),
            ("centroid_px", "float32[2]", "[f32; 2]"),
            ("bbox_px", "uint32[4]", "[u32; 4]"),
            ("strength", "float32", "f32"),
            ("episode_id", "uint64", "u64"),
            ("background_age_s", "float64", "f64"),
        ]
    );
    assert!(c.doc.starts_with("Contact state of one tactile sensor"));
    assert_eq!(
        c.fields[4].doc,
        "contact area [px, in the published image's pixels]"
    );

    let e = parse(&real("ContactEpisode")).unwrap();
    assert_eq!(e.fields[3].rust_type, "Stamp");

    let l = parse(&real("TactileLatent")).unwrap();
    let shape = l.fields.iter().find(|f| f.name == "shape").unwrap();
    assert_eq!(shape.rust_type, "Vec<u32>");
    assert_eq!(shape.max.as_deref(), Some("MAX_LATENT_DIMS"));
    let data = l.fields.iter().find(|f| f.name == "data").unwrap();
    assert_eq!(data.max, None);
    assert_eq!(l.enums.len(), 1);
    assert_eq!(l.enums[0].name, "LatentSource");
    assert_eq!(
        l.enums[0].variants,
        [("Real".to_string(), 0), ("Predicted".to_string(), 1)]
    );

    let p = parse(&real("PropertyComparison")).unwrap();
    assert_eq!(p.enums[0].name, "Winner");
    let names: Vec<&str> = p.enums[0]
        .variants
        .iter()
        .map(|(v, _)| v.as_str())
        .collect();
    assert_eq!(names, ["A", "B", "Tie"]);
    let g = parse(&real("GripperCommand")).unwrap();
    assert_eq!(g.enums[0].name, "GripperMode");
    assert_eq!(g.fields[1].rust_type, "GripperMode");
}

#[test]
fn every_real_file_generates_and_contact_clip_is_left_to_hand_code() {
    let files = all_real();
    assert_eq!(files.len(), 12);
    let code = generate(&files).unwrap();
    for f in &files {
        let generated = code.contains(&format!("pub struct {} {{", f.name));
        assert_eq!(generated, f.name != "ContactClip", "{}", f.name);
    }
    // Same input, same bytes.
    assert_eq!(generate(&files).unwrap(), code);
    // Markdown in the comments is escaped: `[px]` is not a link, `<sensor>` not an HTML tag.
    assert!(code.contains(r"\\[px\\]"));
    assert!(code.contains(r"\\<sensor\\>"));
}

/// Adding a field is one edit, in the .msg file: the struct and the `for_each_message!` entry
/// (what crates/bag's codec and crates/ros' conversion are expanded from) both get it.
#[test]
fn a_field_added_to_a_msg_file_reaches_struct_and_macro() {
    let mut files = all_real();
    let state = files.iter_mut().find(|f| f.name == "ContactState").unwrap();
    state
        .text
        .push_str("float32[3] slip_dir   # slip direction\nuint32[] taxels\n");
    let code = generate(&files).unwrap();
    assert!(code.contains("    pub slip_dir: [f32; 3],\n"));
    assert!(code.contains("    pub taxels: Vec<u32>,\n"));
    let entry = code
        .split("ContactState [contact_state, contact_state_from] {")
        .nth(1)
        .unwrap();
    let entry = entry.split('}').next().unwrap();
    assert!(entry.contains("slip_dir: [f32; 3] => None,"), "{entry}");
    assert!(
        entry.contains("taxels: ::std::vec::Vec<u32> => None,"),
        "{entry}"
    );
    // ...after the existing fields, in .msg order.
    assert!(entry.find("background_age_s").unwrap() < entry.find("slip_dir").unwrap());
}

#[test]
fn lines_it_cannot_map_are_errors_with_file_and_line() {
    let err = |text: &str| parse(&with_text("X", text)).unwrap_err().to_string();
    assert_eq!(
        err("std_msgs/Header header\ngeometry_msgs/Pose pose\n"),
        "X.msg:2: field pose: type geometry_msgs/Pose is not supported"
    );
    assert!(err("uint8[<=4] small").contains("bounded sequences are not supported"));
    assert!(err("int32 LIMIT=3\nint32 limit").contains("only uint8 constants"));
    assert!(err("uint8 COLOUR_RED=0\nuint8 mode").contains("constant COLOUR_RED names no field"));
    assert!(err("uint8 MODE_A=300\nuint8 mode").contains("is not a uint8"));
    assert!(err("float32 MODE_A=1\nuint8 mode").contains("only uint8"));
    assert!(err("uint8 MODE_A=1\nfloat32 mode").contains("field mode is not uint8"));
    assert!(err("string").contains("expected `type name`"));
}

#[test]
fn constants_make_an_enum_named_after_the_field() {
    let d = parse(&with_text(
        "Light",
        "# A light.\nuint8 COLOUR_RED=0\nuint8 COLOUR_DARK_GREEN=5\n\
         uint8 colour  # which\nbool on\n",
    ))
    .unwrap();
    assert_eq!(d.doc, "A light.");
    assert_eq!(d.fields[0].rust_type, "Colour");
    assert_eq!(
        d.enums[0].variants,
        [("Red".to_string(), 0), ("DarkGreen".to_string(), 5)]
    );
    let code = generate(&[with_text("Light", &d.text)]).unwrap();
    assert!(code.contains("pub enum Colour {\n    Red = 0,\n    DarkGreen = 5,\n}"));
    assert!(code.contains("            5 => Ok(Self::DarkGreen),\n"));
    assert!(
        code.contains("light [light, light_from]") || code.contains("Light [light, light_from]")
    );
    assert!(code.contains("$crate::msg::Colour,"));
}
