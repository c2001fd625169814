//! Per-stage parameter overrides on top of a scene file (ROS parameters, params files).
//!
//! An override is `<stage kind>.<key> = value`, e.g. `contact.noise_k = 5.0`: the value replaces
//! (or adds) `key` in the `params:` of every stage of that kind in the scene, and the result is
//! checked by parsing the stage's typed parameter struct, the same struct `unitac run` parses.
//! An unknown stage kind, a stage the scene does not run, an unknown key or a mistyped value is a
//! one-line error; nothing is dropped silently.

use crate::registry::stage_configs;
use serde_yaml::Value;
use unitac_core::{Scene, SceneError};

/// Applies `overrides` (`(dotted key, value)`) to the stages of `scene` whose kind is in
/// `kinds` (the stages a node runs), then checks the typed parameters of every stage.
pub fn apply(
    scene: &mut Scene,
    kinds: &[&str],
    overrides: &[(String, Value)],
) -> Result<(), SceneError> {
    let bad = |field: &str, msg: String| SceneError::BadValue {
        path: scene.path.clone(),
        field: field.to_string(),
        msg,
    };
    for (name, value) in overrides {
        let Some((kind, key)) = name
            .split_once('.')
            .filter(|(k, key)| !k.is_empty() && !key.is_empty())
        else {
            return Err(bad(
                name,
                format!(
                    "a stage parameter is named <stage>.<key> with <stage> one of {}",
                    kinds.join(", ")
                ),
            ));
        };
        if !kinds.contains(&kind) {
            return Err(bad(
                name,
                format!(
                    "'{kind}' is not a stage this node runs ({})",
                    kinds.join(", ")
                ),
            ));
        }
        let mut found = false;
        for st in scene.stages.iter_mut().filter(|s| s.kind == kind) {
            found = true;
            if st.params.is_null() {
                st.params = Value::Mapping(Default::default());
            }
            let Value::Mapping(m) = &mut st.params else {
                return Err(bad(
                    name,
                    format!("the scene's {kind} params are not a mapping"),
                ));
            };
            m.insert(Value::String(key.to_string()), value.clone());
        }
        if !found {
            return Err(bad(name, format!("the scene runs no {kind} stage")));
        }
        // The typed structs reject unknown keys and mistyped values; checked per override so
        // the error names the parameter that caused it.
        if let Err(e) = stage_configs(scene) {
            let msg = match e {
                SceneError::BadValue { msg, .. } => msg,
                other => other.to_string(),
            };
            return Err(bad(name, msg));
        }
    }
    stage_configs(scene).map(|_| ())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;

    /// A fresh scene from its own file: the tests run in parallel threads, and one writing the
    /// file another is reading made that one see it empty.
    fn scene() -> Scene {
        static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let dir = std::env::temp_dir().join(format!("unitac-overrides-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = dir.join(format!("s{n}.yaml"));
        std::fs::write(
            &path,
            "scene: s\nsource: {kind: mock, sensor: gelsight-mini, scenario: fabric_selection}\n\
             stages:\n  - kind: contact\n    params: {clip_frames: 8}\n",
        )
        .unwrap();
        Scene::load(&path, &crate::scene_context()).unwrap()
    }

    fn contact_params(s: &Scene) -> unitac_contact::ContactParams {
        match stage_configs(s).unwrap().remove(0) {
            crate::StageConfig::Contact { params, .. } => params,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn an_override_reaches_the_typed_params() {
        let mut s = scene();
        let o = vec![
            ("contact.noise_k".to_string(), Value::from(5.5)),
            (
                "contact.episode_labels".to_string(),
                serde_yaml::from_str("[a, b]").unwrap(),
            ),
            // An integer for a float field is fine, as in a scene file.
            ("contact.enter_area_px".to_string(), Value::from(300)),
        ];
        apply(&mut s, &["contact"], &o).unwrap();
        let p = contact_params(&s);
        assert_eq!(p.noise_k, 5.5);
        assert_eq!(p.enter_area_px, 300.0);
        assert_eq!(p.episode_labels, ["a", "b"]);
        assert_eq!(p.clip_frames, 8, "scene values not overridden stay");
    }

    #[test]
    fn unknown_and_mistyped_keys_are_one_line_errors() {
        for (k, v, want) in [
            ("contact.no_such_key", Value::from(1), "no_such_key"),
            ("contact.noise_k", Value::from("loud"), "noise_k"),
            (
                "encoder.providers",
                Value::from("cpu"),
                "not a stage this node runs",
            ),
            ("noise_k", Value::from(1.0), "<stage>.<key>"),
            (
                "sampler.steps",
                Value::from(4),
                "not a stage this node runs",
            ),
        ] {
            let mut s = scene();
            let e = apply(&mut s, &["contact"], &[(k.to_string(), v)])
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{k}: {e}");
            assert!(!e.contains('\n'), "{k}: {e}");
        }
        let mut s = scene();
        let e = apply(
            &mut s,
            &["contact", "sampler"],
            &[("sampler.steps".into(), Value::from(4))],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("runs no sampler"), "{e}");
    }
}
