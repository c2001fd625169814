//! ROS 2 side of the UniTac robot stack (r2r). The only crate that links ROS.
//!
//! Nodes here are thin: they convert between ROS messages and the `unitac-core` types and drive
//! the same stages as the embedded runtime. [`convert`] holds the field-by-field conversions.

pub mod convert;

use std::time::{Duration, Instant};

/// Spin `node` until `done()` holds or `timeout` passes; returns whether `done()` held.
/// The spin wait is short (10 ms) so delivery is not capped the way a 100 ms spin would cap it.
pub fn spin_until(node: &mut r2r::Node, timeout: Duration, mut done: impl FnMut() -> bool) -> bool {
    let t0 = Instant::now();
    while t0.elapsed() < timeout {
        if done() {
            return true;
        }
        node.spin_once(Duration::from_millis(10));
    }
    done()
}

/// A list parameter: comma-separated, items trimmed, empty items dropped (r2r's derived
/// parameters have no arrays).
pub fn list_param(s: &str) -> Vec<String> {
    s.split(',')
        .map(str::trim)
        .filter(|x| !x.is_empty())
        .map(str::to_string)
        .collect()
}

pub mod diagnostics;
pub mod drops;
pub mod image;
pub mod node;
pub mod topics;

/// The stages of `scene` (a name or a path) whose kind is in `kinds`, built by the same registry
/// `unitac run` uses, from the scene's params with the node's `<stage>.<key>` overrides applied.
/// `sensor_kind` (non-empty) replaces the scene's sensor. The effective params go to stderr, one
/// line per stage (`<node>: effective params: <kind>: ...`), so a test can compare them with
/// `unitac scene params`.
pub fn scene_stages(
    node: &str,
    scene: &str,
    sensor_kind: &str,
    kinds: &[&str],
    overrides: &[(String, serde_yaml::Value)],
) -> anyhow::Result<(unitac_core::Scene, Vec<Box<dyn unitac_core::Stage>>)> {
    let s = scene_kept(node, scene, sensor_kind, kinds, overrides)?;
    let stages = unitac_pipeline::build_stages(&s)?;
    Ok((s, stages))
}

/// The typed configuration of `scene`'s stages whose kind is in `kinds`, as [`scene_stages`]
/// would build them (same overrides, same effective-params lines), for a node that needs the
/// concrete stage (the policy node calls the policy stage's watchdog API).
pub fn scene_configs(
    node: &str,
    scene: &str,
    kinds: &[&str],
    overrides: &[(String, serde_yaml::Value)],
) -> anyhow::Result<(unitac_core::Scene, Vec<unitac_pipeline::StageConfig>)> {
    let s = scene_kept(node, scene, "", kinds, overrides)?;
    let configs = unitac_pipeline::stage_configs(&s)?;
    Ok((s, configs))
}

/// The scene with only the stages of `kinds`, overrides applied, effective params printed.
fn scene_kept(
    node: &str,
    scene: &str,
    sensor_kind: &str,
    kinds: &[&str],
    overrides: &[(String, serde_yaml::Value)],
) -> anyhow::Result<unitac_core::Scene> {
    let mut s = unitac_pipeline::load_scene(scene, None)?;
    if !sensor_kind.is_empty() {
        s.source.sensor = sensor_kind
            .parse()
            .map_err(|e| anyhow::anyhow!("sensor_kind: {e}"))?;
    }
    s.stages.retain(|st| kinds.contains(&st.kind.as_str()));
    unitac_pipeline::overrides::apply(&mut s, kinds, overrides)?;
    for line in unitac_pipeline::effective_params(&s)? {
        eprintln!("{node}: effective params: {line}");
    }
    Ok(s)
}
