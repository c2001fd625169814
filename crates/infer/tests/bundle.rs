//! Bad bundles give one clear error each; several problems come back in one error.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use unitac_infer::{Bundle, RuntimeConfig};

fn edit(dir: &std::path::Path, f: impl FnOnce(&mut serde_json::Value)) {
    let p = dir.join("manifest.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    f(&mut m);
    std::fs::write(&p, serde_json::to_string_pretty(&m).unwrap()).unwrap();
}

fn load_err(dir: &std::path::Path, models: &[&str]) -> String {
    let b = Bundle::open(dir).unwrap();
    b.load(models, &RuntimeConfig::default())
        .unwrap_err()
        .to_string()
}

#[test]
fn the_reference_bundle_loads_and_names_its_models() {
    let b = Bundle::open(&common::reference()).unwrap();
    let models = b
        .load(
            &[
                "encoder",
                "properties",
                "velocity_timing_fixture",
                "velocity_gaussian",
            ],
            &RuntimeConfig::default(),
        )
        .unwrap();
    assert_eq!(models.len(), 4);
    assert!(models[0].id.starts_with("unitac-reference@"));
}

#[test]
fn missing_file() {
    let d = common::copy_reference("missing");
    std::fs::remove_file(d.join("encoder.onnx")).unwrap();
    let e = load_err(&d, &["encoder"]);
    assert!(
        e.contains("encoder: file not found") && e.contains("encoder.onnx"),
        "{e}"
    );
}

#[test]
fn wrong_sha256() {
    let d = common::copy_reference("sha");
    edit(&d, |m| {
        m["models"]["properties"]["sha256"] = "00".repeat(32).into()
    });
    let e = load_err(&d, &["properties"]);
    assert!(
        e.contains("properties: sha256 of properties.onnx is")
            && e.contains("the manifest says 0000"),
        "{e}"
    );
}

#[test]
fn wrong_shape_and_dtype_are_listed_together() {
    let d = common::copy_reference("shape");
    edit(&d, |m| {
        m["models"]["velocity_timing_fixture"]["inputs"][0]["shape"][1] = 65.into();
        m["models"]["velocity_timing_fixture"]["outputs"][0]["dtype"] = "float64".into();
        m["models"]["encoder"]["inputs"][1]["name"] = "bg".into();
    });
    let e = load_err(&d, &["encoder", "velocity_timing_fixture"]);
    assert!(
        e.contains("velocity_timing_fixture: input 'x' dim 1 is 64 in the file, declared 65"),
        "{e}"
    );
    assert!(
        e.contains("velocity_timing_fixture: output 'v' is float32 in the file, declared float64"),
        "{e}"
    );
    assert!(
        e.contains("encoder: input 'bg' is declared but the file has"),
        "{e}"
    );
    assert!(
        e.contains("encoder: the file has input 'background' that the manifest does not declare"),
        "{e}"
    );
    assert!(!e.contains('\n'), "one line: {e}");
}

#[test]
fn unknown_model_and_bad_manifest() {
    let e = load_err(&common::reference(), &["policy"]);
    assert!(e.contains("policy: not in the manifest"), "{e}");
    let d = common::copy_reference("manifest");
    std::fs::write(d.join("manifest.json"), b"{ not json").unwrap();
    assert!(
        Bundle::open(&d)
            .unwrap_err()
            .to_string()
            .contains("manifest.json")
    );
    edit_text(&d);
    let e = Bundle::open(&d).unwrap_err().to_string();
    assert!(e.contains("crop"), "{e}");
}

fn edit_text(d: &std::path::Path) {
    let good = std::fs::read_to_string(common::reference().join("manifest.json")).unwrap();
    std::fs::write(
        d.join("manifest.json"),
        good.replace("center_square", "letterbox"),
    )
    .unwrap();
}

/// Preprocessing that does not make the clip the encoder declares is one line
/// when the bundle opens (it used to load, then fail in ONNX Runtime on every episode).
#[test]
fn preprocess_must_match_the_encoder_input_shape() {
    for (key, value, want) in [
        ("size", 32, "size 32"),
        ("clip_frames", 2, "clip_frames 2"),
        ("size", 1024, "size 1024"),
    ] {
        let d = common::copy_reference(&format!("pre-{key}-{value}"));
        edit(&d, |m| m["preprocess"][key] = value.into());
        let e = Bundle::open(&d).unwrap_err().to_string();
        assert!(
            e.contains("encoder input 'clip' is [batch, 4, 3, 64, 64]") && e.contains(want),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
}
