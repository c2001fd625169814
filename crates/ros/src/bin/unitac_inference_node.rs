//! Inference node: the inference stages of a scene (touch encoder + property head, Property
//! Comparison, flow sampler with SPSS) on what the contact node publishes. ContactClip and the
//! latched background Image in (reliable), and the camera's VisualObservation (the sampler's
//! object-level condition); TactileProperties, TactileLatent (real and predicted) and
//! PropertyComparison out (reliable); /diagnostics once a second with model timings.
//!
//! The stages, their parameters and model bundles come from the scene file (the same file
//! `unitac run` reads, through the same registry), so the robot and the embedded runtime run the
//! same configuration; `encoder.<key>`, `compare.<key>`, `sampler.<key>` parameters override
//! the scene's stage params (an unknown key is an error). Each stage's clock is its input's
//! stamp, as in every transport.
//!
//! Topics (relative): `contact_clip`, `background`, `visual_observation` in;
//! `tactile_properties`, `tactile_latent`, `property_comparison` out.

use futures::{FutureExt, StreamExt};
use r2r::{QosProfile, RosParams};
use std::time::Duration;
use unitac_core::{Chain, Msg, Scene, sensor_id_of};
use unitac_ros::node::NodeBase;
use unitac_ros::{convert, diagnostics, image};

/// Stage kinds this node runs (launch/stage_nodes.yaml; the contact stage runs in the contact
/// node).
fn inference_stages() -> anyhow::Result<&'static [&'static str]> {
    unitac_ros::node_stages("unitac_inference_node")
}

#[derive(RosParams, Debug, Clone)]
struct Params {
    /// Scene: a scene name (looked up like `unitac run --scene`) or a path to a scene YAML
    scene: String,
    /// Run only these of the scene's inference stages, comma-separated (empty: all of encoder,
    /// compare, sampler). r2r's derived parameters have no arrays.
    stages: String,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            scene: "fabric_selection".into(),
            stages: String::new(),
        }
    }
}

/// The scene's inference stages (those `stages` names, else all), built and checked before the
/// node subscribes to anything.
fn build(
    p: &Params,
    overrides: &[(String, serde_yaml::Value)],
) -> anyhow::Result<(Scene, Vec<Box<dyn unitac_core::Stage>>)> {
    let wanted = unitac_ros::list_param(&p.stages);
    let all = inference_stages()?;
    if let Some(bad) = wanted.iter().find(|s| !all.contains(&s.as_str())) {
        anyhow::bail!(
            "stages: '{bad}' is not an inference stage ({})",
            all.join(", ")
        );
    }
    let kinds: Vec<&str> = all
        .iter()
        .copied()
        .filter(|k| wanted.is_empty() || wanted.iter().any(|w| w == k))
        .collect();
    unitac_ros::scene_stages("unitac_inference_node", &p.scene, "", &kinds, overrides)
}

/// Calls and seconds per stage, for the diagnostics' model timings.
struct Timing(Vec<(String, u64, f64)>);

impl Timing {
    /// From the chain's per-stage counters.
    fn of(chain: &Chain) -> Self {
        Self(
            chain
                .runners()
                .iter()
                .map(|r| {
                    let s = r.stats();
                    (r.name().to_string(), s.input, s.busy_ns as f64 * 1e-9)
                })
                .collect(),
        )
    }
    fn values(&self) -> Vec<(&str, String)> {
        self.0
            .iter()
            .map(|(name, n, s)| {
                let mean_ms = if *n > 0 { s / *n as f64 * 1e3 } else { 0.0 };
                (name.as_str(), format!("{n} calls, mean {mean_ms:.3} ms"))
            })
            .collect()
    }
}

fn run() -> anyhow::Result<()> {
    let mut base = NodeBase::<Params>::new("unitac_inference", inference_stages()?)?;
    let p = base.params()?;
    let (scene, stages) = build(&p, base.stage_overrides())?;
    let mut chain = Chain::new(stages);
    if chain.is_empty() {
        eprintln!(
            "unitac_inference_node: scene '{}' has no inference stages to run; idle",
            scene.name
        );
    }
    let node = &mut base.node;
    let reliable = QosProfile::default;
    let mut clips = node.subscribe::<r2r::unitac_msgs::msg::ContactClip>(
        "contact_clip",
        reliable().keep_last(50),
    )?;
    let mut backgrounds = node.subscribe::<r2r::sensor_msgs::msg::Image>(
        "background",
        QosProfile::default().keep_last(1).transient_local(),
    )?;
    let mut visuals = node.subscribe::<r2r::unitac_msgs::msg::VisualObservation>(
        "visual_observation",
        reliable().keep_last(10),
    )?;
    let pub_props = node.create_publisher::<r2r::unitac_msgs::msg::TactileProperties>(
        "tactile_properties",
        reliable(),
    )?;
    // Transient-local (the last 10): a policy node started later, or one whose subscription was
    // not matched yet when a predicted latent went out at startup, still gets it.
    let pub_latent = node.create_publisher::<r2r::unitac_msgs::msg::TactileLatent>(
        "tactile_latent",
        reliable().keep_last(10).transient_local(),
    )?;
    let pub_cmp = node.create_publisher::<r2r::unitac_msgs::msg::PropertyComparison>(
        "property_comparison",
        reliable(),
    )?;
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_inference: {}", node.fully_qualified_name()?),
        &scene.name,
    );
    let mut counters = diagnostics::Counters::default();
    let mut last_episode = std::collections::HashMap::<String, u64>::new();
    let handle = |input: Msg, counters: &mut diagnostics::Counters, chain: &mut Chain| {
        counters.frames_in += 1;
        let t0 = std::time::Instant::now();
        // The clock rule of every transport: each stage sees its input's stamp.
        let out = chain.run(input);
        counters.busy_s += t0.elapsed().as_secs_f64();
        for e in out.errors {
            counters.error(e.to_string());
        }
        for m in out.produced {
            let r = match &m {
                Msg::TactileProperties(x) => pub_props.publish(&convert::tactile_properties(x)),
                Msg::TactileLatent(x) => pub_latent.publish(&convert::tactile_latent(x)),
                Msg::PropertyComparison(x) => pub_cmp.publish(&convert::property_comparison(x)),
                _ => continue,
            };
            counters.published(r);
        }
    };
    while !base.stopped() {
        base.spin(Duration::from_millis(5));
        while let Some(Some(bg)) = backgrounds.next().now_or_never() {
            let id = sensor_id_of(None, &bg.header.frame_id, "sensor");
            match image::to_frame(&bg, &id, 0) {
                Ok(f) => handle(Msg::Background(f), &mut counters, &mut chain),
                Err(e) => counters.error(format!("background: {e}")),
            }
        }
        while let Some(Some(v)) = visuals.next().now_or_never() {
            match convert::visual_observation_from(&v) {
                Ok(v) => handle(Msg::VisualObservation(v), &mut counters, &mut chain),
                Err(e) => counters.error(format!("visual_observation: {e}")),
            }
        }
        while let Some(Some(c)) = clips.next().now_or_never() {
            // Episode ids count up per sensor: a gap is a clip lost on the way.
            let last = last_episode.insert(c.sensor_id.clone(), c.episode_id);
            if let Some(prev) = last.filter(|&p| c.episode_id > p) {
                counters.dropped += c.episode_id - prev - 1;
            }
            match convert::contact_clip_from(&c) {
                Ok(clip) => {
                    let captured = clip.frames.last().map(|f| f.stamp);
                    handle(Msg::ContactClip(clip), &mut counters, &mut chain);
                    if let Some(t) = captured {
                        counters.latency(base.age_s(t));
                    }
                }
                Err(e) => counters.error(format!("contact_clip: {e}")),
            }
        }
        let timing = Timing::of(&chain);
        let extra = timing.values();
        if let Some(a) = diag.tick(&mut counters, base.now(), &extra) {
            base.publish_diagnostics(&a)?;
        }
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_inference_node", run)
}
