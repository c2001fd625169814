//! Stage node: any subset of a scene's stages, with topics derived from the stage graph
//! (launch/stage_graph.yaml). It subscribes to every kind its stages consume that none of them
//! makes and publishes every kind they make; the topic is the kind's name (`image`, or
//! `image/compressed` with `image_transport:=compressed`, for frames), relative, so namespaces and
//! remaps apply (crates/ros/README.md lists them with their QoS). The launch plan runs one per
//! group of a scene's stages: `unitac_contact` (contact, slip: per frame, beside the camera) and
//! `unitac_inference` (encoder, compare, sampler: the models, per episode, on this host or
//! another).
//!
//! The stages, their parameters and model bundles come from the scene file through the same
//! registry and typed structs as `unitac run`; `<stage>.<key>` parameters override the scene's
//! stage params (an unknown key is an error). One chain in one thread with the clock rule of
//! every transport (each stage sees its input's stamp), so replays give the answers live runs
//! and the embedded runtime give. /diagnostics once a second: counts, latency (frames and
//! clips), per-stage timings, and `in_contact` when the node runs a contact stage.

use futures::{FutureExt, StreamExt};
use r2r::{QosProfile, RosParams};
use std::time::{Duration, Instant};
use unitac_core::graph::StageGraph;
use unitac_core::{Chain, Msg, Scene, sensor_id_of};
use unitac_ros::drops::DropCounter;
use unitac_ros::node::NodeBase;
use unitac_ros::topics::{self, Publish, Subscription};
use unitac_ros::{convert, diagnostics, image};

#[derive(RosParams, Debug, Clone)]
struct Params {
    /// Scene: a scene name (looked up like `unitac run --scene`) or a path to a scene YAML
    scene: String,
    /// The scene's stages to run, comma-separated, e.g. `contact,slip` (empty: every stage of the
    /// scene that the stage node runs). r2r's derived parameters have no arrays.
    stages: String,
    /// Sensor id used in messages (default: the image's frame_id without "_optical_frame")
    sensor_id: String,
    /// a profile of sensors/ (gelsight-mini, digit, generic, ...) or of $UNITAC_SENSORS (empty: the scene's sensor)
    sensor_kind: String,
    /// raw: sensor_msgs/Image on `image`; compressed: sensor_msgs/CompressedImage (jpeg, png) on
    /// `image/compressed`, as image_transport names it
    image_transport: String,
    /// sensor_data (best effort, newest frames: a robot) | reliable (every frame: replays that
    /// are compared frame by frame)
    image_qos: String,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            scene: "fabric_selection".into(),
            stages: String::new(),
            sensor_id: String::new(),
            sensor_kind: String::new(),
            image_transport: "raw".into(),
            image_qos: "sensor_data".into(),
        }
    }
}

/// Stage kinds the generic node runs: those of every group without an executable of its own.
fn runnable(graph: &StageGraph) -> Vec<&str> {
    graph
        .stages
        .iter()
        .filter(|(_, io)| {
            graph
                .groups
                .get(&io.group)
                .is_some_and(|g| g.executable.is_none())
        })
        .map(|(k, _)| k.as_str())
        .collect()
}

/// The stage kinds to run: those `stages` names (each one the node runs), else all it runs.
fn wanted<'g>(p: &Params, runnable: &[&'g str]) -> anyhow::Result<Vec<&'g str>> {
    let named = unitac_ros::list_param(&p.stages);
    if let Some(bad) = named.iter().find(|s| !runnable.contains(&s.as_str())) {
        anyhow::bail!(
            "stages: '{bad}' is not a stage this node runs ({})",
            runnable.join(", ")
        );
    }
    Ok(runnable
        .iter()
        .copied()
        .filter(|k| named.is_empty() || named.iter().any(|w| w == k))
        .collect())
}

/// An image received: its header stamp (checked) and the converted frame.
struct Received {
    stamp: anyhow::Result<unitac_core::Stamp>,
    frame: Result<unitac_core::Frame, unitac_bag::ImageError>,
}

/// A header stamp as a capture time, or why it cannot be one (ROS time is unsigned; nanosec
/// below 1e9). Never rewritten silently.
fn checked_stamp(t: &r2r::builtin_interfaces::msg::Time) -> anyhow::Result<unitac_core::Stamp> {
    if t.sec < 0 || t.nanosec > 999_999_999 {
        anyhow::bail!(
            "header stamp {}.{:09} is not a valid ROS time",
            t.sec,
            t.nanosec
        );
    }
    Ok(convert::stamp(t))
}

/// Everything queued on `sub`, converted (r2r's subscription buffer is small and drops silently).
fn drain<T>(
    sub: &mut (impl futures::Stream<Item = T> + Unpin),
    out: &mut Vec<Received>,
    mut convert: impl FnMut(&T) -> Received,
) {
    while let Some(Some(m)) = sub.next().now_or_never() {
        out.push(convert(&m));
    }
}

/// A subscription's message stream.
type Sub<T> = futures::stream::BoxStream<'static, T>;

/// The image subscription, by `image_transport`.
enum Images {
    Raw(Sub<r2r::sensor_msgs::msg::Image>),
    Compressed(Sub<r2r::sensor_msgs::msg::CompressedImage>),
}

impl Images {
    fn new(node: &mut r2r::Node, transport: &str, qos: QosProfile) -> anyhow::Result<Self> {
        let t = topics::topic("frame");
        Ok(match transport {
            "raw" => Self::Raw(Box::pin(node.subscribe(t, qos)?)),
            "compressed" => {
                Self::Compressed(Box::pin(node.subscribe(&format!("{t}/compressed"), qos)?))
            }
            other => anyhow::bail!("image_transport must be raw or compressed, got '{other}'"),
        })
    }

    /// Everything queued, converted; images are numbered from `seq` on in arrival order, as a
    /// bag replay numbers them.
    fn drain(&mut self, seq: &mut u64, sensor_id: &str) -> Vec<Received> {
        let id = |frame_id: &str| sensor_id_of(Some(sensor_id), frame_id, "sensor");
        let mut next = || {
            let n = *seq;
            *seq += 1;
            n
        };
        let mut inputs = Vec::new();
        match self {
            Self::Raw(sub) => drain(sub, &mut inputs, |m| Received {
                stamp: checked_stamp(&m.header.stamp),
                frame: image::to_frame(m, &id(&m.header.frame_id), next()),
            }),
            Self::Compressed(sub) => drain(sub, &mut inputs, |m| Received {
                stamp: checked_stamp(&m.header.stamp),
                frame: image::compressed_to_frame(m, &id(&m.header.frame_id), next()),
            }),
        }
        inputs
    }
}

/// One input of the node: the images, or a subscription to another kind.
enum Input {
    Frames {
        images: Images,
        seq: u64,
        drops: DropCounter,
    },
    Events(Subscription),
}

/// Calls and seconds per stage, for the diagnostics' model timings.
fn timings(chain: &Chain) -> Vec<(String, String)> {
    chain
        .runners()
        .iter()
        .map(|r| {
            let s = r.stats();
            let secs = s.busy_ns as f64 * 1e-9;
            let mean_ms = if s.input > 0 {
                secs / s.input as f64 * 1e3
            } else {
                0.0
            };
            (
                r.name().to_string(),
                format!("{} calls, mean {mean_ms:.3} ms", s.input),
            )
        })
        .collect()
}

/// (kind, publisher) for every kind the node's stages make.
type Outputs = Vec<(String, Publish)>;

/// The node's state between inputs.
struct Node {
    chain: Chain,
    outputs: Outputs,
    counters: diagnostics::Counters,
    in_contact: bool,
    /// Episode ids count up per sensor: a gap is a clip lost on the way.
    last_episode: std::collections::HashMap<String, u64>,
}

impl Node {
    /// Publish what the chain produced, each on its kind's topic.
    fn publish(&mut self, out: Vec<Msg>) {
        for m in out {
            if let Msg::ContactState(c) = &m {
                self.in_contact = c.in_contact;
            }
            if let Some((_, p)) = self.outputs.iter().find(|(k, _)| *k == m.kind()) {
                self.counters.published(p(&m));
            }
        }
    }

    /// One input through the chain; `base` gives the age of what it carries.
    fn process(&mut self, m: Msg, base: &NodeBase<Params>) {
        self.counters.frames_in += 1;
        let captured = match &m {
            Msg::Frame(f) => Some(f.stamp),
            Msg::ContactClip(c) => {
                let last = self.last_episode.insert(c.sensor_id.clone(), c.episode_id);
                if let Some(prev) = last.filter(|&p| c.episode_id > p) {
                    self.counters.dropped += c.episode_id - prev - 1;
                }
                c.frames.last().map(|f| f.stamp)
            }
            _ => None,
        };
        let t0 = Instant::now();
        let out = self.chain.run(m);
        self.counters.busy_s += t0.elapsed().as_secs_f64();
        for e in out.errors {
            self.counters.error(e.to_string());
        }
        self.publish(out.produced);
        if let Some(t) = captured {
            self.counters.latency(base.age_s(t));
        }
    }

    /// One received image: counted once, as in, and then processed or an error (a bad stamp,
    /// an undecodable image). Only stamp gaps between images that arrived count as drops.
    fn image(&mut self, r: Received, drops: &mut DropCounter, base: &NodeBase<Params>) {
        match (r.stamp, r.frame) {
            (Ok(stamp), Ok(f)) => {
                self.counters.dropped += drops.observe(stamp.0);
                self.process(Msg::Frame(f), base);
            }
            (Err(e), _) => {
                self.counters.frames_in += 1;
                drops.arrived_without_stamp();
                self.counters.error(e.to_string());
            }
            (Ok(stamp), Err(e)) => {
                self.counters.frames_in += 1;
                drops.observe(stamp.0);
                self.counters.error(e.to_string());
            }
        }
    }

    /// Everything queued on every input, in the graph's kind order.
    fn drain(&mut self, inputs: &mut [Input], sensor_id: &str, base: &NodeBase<Params>) {
        for input in inputs {
            match input {
                Input::Frames { images, seq, drops } => {
                    for r in images.drain(seq, sensor_id) {
                        self.image(r, drops, base);
                    }
                }
                Input::Events(sub) => {
                    while let Some(Some(m)) = sub.next().now_or_never() {
                        match m {
                            Ok(m) => self.process(m, base),
                            Err(e) => {
                                self.counters.frames_in += 1;
                                self.counters.error(e.to_string());
                            }
                        }
                    }
                }
            }
        }
    }
}

/// What the scene's stages make beyond their `makes`: the `may_make` kinds their params turn on
/// (the contact stage's depth with a depth calibration, its overlay).
fn optional_outputs(scene: &Scene) -> anyhow::Result<Vec<&'static str>> {
    let mut on = Vec::new();
    for c in unitac_pipeline::stage_configs(scene)? {
        if let unitac_pipeline::StageConfig::Contact { params, .. } = c {
            if params.depth_calibration.is_some() {
                on.push("depth");
            }
            if params.overlay {
                on.push("contact_overlay");
            }
        }
    }
    Ok(on)
}

/// The node's topics from the graph: the inputs of `kinds` and the publishers of what they
/// make (a `may_make` kind only when the scene turns it on: a subscriber of `depth` on a scene
/// without depth sees no publisher rather than a silent one).
fn topics_of(
    base: &mut NodeBase<Params>,
    graph: &StageGraph,
    kinds: &[&str],
    scene: &Scene,
    p: &Params,
) -> anyhow::Result<(Vec<Input>, Outputs)> {
    let mut inputs = Vec::new();
    for k in graph.inputs_of(kinds) {
        inputs.push(if k == "frame" {
            let qos = image::image_qos(&p.image_qos)?;
            Input::Frames {
                images: Images::new(&mut base.node, &p.image_transport, qos)?,
                seq: 0,
                drops: DropCounter::default(),
            }
        } else {
            Input::Events(topics::subscription(&mut base.node, k)?)
        });
    }
    let optional = optional_outputs(scene)?;
    let mut outputs = Vec::new();
    for k in graph.outputs_of(kinds) {
        let always = kinds
            .iter()
            .filter_map(|s| graph.stage(s))
            .any(|io| io.makes.iter().any(|m| m == k));
        if always || optional.contains(&k) {
            outputs.push((k.to_string(), topics::publisher(&mut base.node, k)?));
        }
    }
    Ok((inputs, outputs))
}

fn run() -> anyhow::Result<()> {
    let graph = unitac_pipeline::registry::graph();
    let runnable = runnable(graph);
    let mut base = NodeBase::<Params>::new("unitac_stages", &runnable)?;
    let p = base.params()?;
    let wanted = wanted(&p, &runnable)?;
    let (scene, stages) = unitac_ros::scene_stages(
        "unitac_stage_node",
        &p.scene,
        &p.sensor_kind,
        &wanted,
        base.stage_overrides(),
    )?;
    // The stages the scene has, in its order.
    let kinds: Vec<&str> = scene.stages.iter().map(|s| s.kind.as_str()).collect();
    let name = base.node.name()?;
    if kinds.is_empty() {
        eprintln!(
            "unitac_stage_node: scene '{}' has none of the stages {} to run; idle",
            scene.name,
            wanted.join(", ")
        );
    }
    let (mut inputs, outputs) = topics_of(&mut base, graph, &kinds, &scene, &p)?;
    let mut node = Node {
        chain: Chain::new(stages),
        outputs,
        counters: diagnostics::Counters::default(),
        in_contact: false,
        last_episode: Default::default(),
    };
    let hardware_id = if p.sensor_id.is_empty() {
        scene.name.clone()
    } else {
        p.sensor_id.clone()
    };
    let mut diag = diagnostics::Updater::new(
        &format!("{name}: {}", base.node.fully_qualified_name()?),
        &hardware_id,
    );
    let has_contact = kinds.contains(&"contact");
    while !base.stopped() {
        base.spin(Duration::from_millis(5));
        node.drain(&mut inputs, &p.sensor_id, &base);
        let mut extra: Vec<(String, String)> = timings(&node.chain);
        if has_contact {
            extra.push(("in_contact".into(), node.in_contact.to_string()));
        }
        let extra: Vec<(&str, String)> =
            extra.iter().map(|(k, v)| (k.as_str(), v.clone())).collect();
        if let Some(a) = diag.tick(&mut node.counters, base.now(), &extra) {
            base.publish_diagnostics(&a)?;
        }
    }
    // Flush an open episode and save the background (background_dir).
    let end = node.chain.finish();
    for e in &end.errors {
        eprintln!("unitac_stage_node: finishing: {e}");
    }
    node.publish(end.produced);
    base.spin(Duration::from_millis(50));
    Ok(())
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_stage_node", run)
}
