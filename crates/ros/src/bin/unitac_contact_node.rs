//! Contact node: sensor_msgs/Image in (or CompressedImage: `image_transport`; best-effort, REP 2003); ContactState per frame,
//! ContactEpisode on release, ContactClip (the episode's frames, for the inference node) and the
//! learned background (latched, for the sampler's sensor prior) out, reliable; SlipState per frame
//! in contact when the scene has a `slip` stage; with a depth calibration in the scene's contact
//! stage, `depth` (Image 32FC1, metres, NaN where unknown) and `points` (PointCloud2, x y z in
//! the optical frame) per frame; with `contact.overlay:=true`, `contact_overlay` (Image rgb8, the
//! picture `unitac contact --overlay` writes); /diagnostics once a second. A thin driver of the
//! same `ContactStage` (and `SlipStage`) the embedded runtime runs; its clock is the images'
//! capture stamps, so replays give the same answers as live runs.
//!
//! Topics (relative, so namespaces and remaps apply): `image` (or `image/compressed`) in; `contact_state`,
//! `contact_episode`, `contact_clip`, `background`, `slip_state`, `depth`, `points`,
//! `contact_overlay` out. Parameters
//! (`--ros-args --params-file x.yaml`): see `Params`.

use futures::{FutureExt, StreamExt};
use r2r::{QosProfile, RosParams};
use std::time::{Duration, Instant};
use unitac_core::{Chain, Msg, sensor_id_of};
use unitac_ros::drops::DropCounter;
use unitac_ros::node::NodeBase;
use unitac_ros::{convert, diagnostics, image};

/// The node's own parameters. The contact stage's parameters come from the scene file's contact
/// stage, as `unitac run` reads them; override one with `contact.<key>` (e.g.
/// `-p contact.noise_k:=4.0`, or in a params file); an unknown key is an error.
#[derive(RosParams, Debug, Clone)]
struct Params {
    /// Scene: a scene name (looked up like `unitac run --scene`) or a path to a scene YAML
    scene: String,
    /// Sensor id used in messages (default: the image's frame_id without "_optical_frame")
    sensor_id: String,
    /// gelsight-mini | digit | generic (sensors/), or a profile of $UNITAC_SENSORS (empty: the scene's sensor)
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
            sensor_id: String::new(),
            sensor_kind: String::new(),
            image_transport: "raw".into(),
            image_qos: "sensor_data".into(),
        }
    }
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

/// The image subscription, by `image_transport`.
enum Input {
    Raw(Sub<r2r::sensor_msgs::msg::Image>),
    Compressed(Sub<r2r::sensor_msgs::msg::CompressedImage>),
}

/// A subscription's message stream.
type Sub<T> = futures::stream::BoxStream<'static, T>;

impl Input {
    fn new(node: &mut r2r::Node, transport: &str, qos: QosProfile) -> anyhow::Result<Self> {
        Ok(match transport {
            "raw" => Self::Raw(Box::pin(node.subscribe("image", qos)?)),
            "compressed" => Self::Compressed(Box::pin(node.subscribe("image/compressed", qos)?)),
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

/// The node's publishers: the states, episodes, clips, slip and the latched background, and
/// only the topics the scene makes of depth and the overlay (a subscriber of `depth` on a scene
/// without depth sees no publisher rather than a silent one).
struct Outputs {
    state: r2r::Publisher<r2r::unitac_msgs::msg::ContactState>,
    episode: r2r::Publisher<r2r::unitac_msgs::msg::ContactEpisode>,
    clip: r2r::Publisher<r2r::unitac_msgs::msg::ContactClip>,
    slip: r2r::Publisher<r2r::unitac_msgs::msg::SlipState>,
    background: r2r::Publisher<r2r::sensor_msgs::msg::Image>,
    depth: Option<(
        r2r::Publisher<r2r::sensor_msgs::msg::Image>,
        r2r::Publisher<r2r::sensor_msgs::msg::PointCloud2>,
    )>,
    overlay: Option<r2r::Publisher<r2r::sensor_msgs::msg::Image>>,
}

impl Outputs {
    fn new(node: &mut r2r::Node, with_depth: bool, with_overlay: bool) -> anyhow::Result<Self> {
        let reliable = QosProfile::default;
        Ok(Self {
            state: node.create_publisher("contact_state", reliable())?,
            episode: node.create_publisher("contact_episode", reliable())?,
            clip: node.create_publisher("contact_clip", reliable())?,
            slip: node.create_publisher("slip_state", reliable())?,
            // Latched: an inference node started later still gets the sensor prior.
            background: node.create_publisher(
                "background",
                QosProfile::default().keep_last(1).transient_local(),
            )?,
            depth: if with_depth {
                Some((
                    node.create_publisher("depth", reliable())?,
                    node.create_publisher("points", reliable())?,
                ))
            } else {
                None
            },
            overlay: with_overlay
                .then(|| node.create_publisher("contact_overlay", reliable()))
                .transpose()?,
        })
    }

    /// Publish what the chain produced; `in_contact` follows the contact states.
    fn publish(&self, out: Vec<Msg>, in_contact: &mut bool, counters: &mut diagnostics::Counters) {
        for m in out {
            let r = match m {
                Msg::ContactState(c) => {
                    *in_contact = c.in_contact;
                    self.state.publish(&convert::contact_state(&c))
                }
                Msg::ContactEpisode(e) => self.episode.publish(&convert::contact_episode(&e)),
                Msg::ContactClip(c) => self.clip.publish(&convert::contact_clip(&c)),
                Msg::Background(f) => self.background.publish(&image::from_frame(&f)),
                Msg::SlipState(s) => self.slip.publish(&convert::slip_state(&s)),
                Msg::Depth(d) => {
                    let Some((pd, pp)) = &self.depth else {
                        continue;
                    };
                    counters.published(pd.publish(&image::depth(&d)));
                    pp.publish(&image::points(&d))
                }
                Msg::ContactOverlay(f) => match &self.overlay {
                    Some(po) => po.publish(&image::from_frame(&f)),
                    None => continue,
                },
                _ => continue,
            };
            counters.published(r);
        }
    }
}

/// What the scene's contact stage emits beyond the states: depth (a depth calibration), the
/// overlay.
fn contact_extras(scene: &unitac_core::Scene) -> anyhow::Result<(bool, bool)> {
    Ok(unitac_pipeline::stage_configs(scene)?
        .iter()
        .find_map(|c| match c {
            unitac_pipeline::StageConfig::Contact { params, .. } => {
                Some((params.depth_calibration.is_some(), params.overlay))
            }
            _ => None,
        })
        .unwrap_or((false, false)))
}

/// The node's state between frames.
struct Node {
    chain: Chain,
    outputs: Outputs,
    counters: diagnostics::Counters,
    drops: DropCounter,
    in_contact: bool,
}

impl Node {
    /// One received image through the chain. Each frame is counted once: in, and then either
    /// processed, or an error (a bad stamp, an undecodable image, a frame the stage rejects).
    /// Only stamp gaps between frames that arrived count as drops.
    fn process(&mut self, r: Received, base: &NodeBase<Params>) {
        self.counters.frames_in += 1;
        let t0 = Instant::now();
        let frame = match (r.stamp, r.frame) {
            (Ok(stamp), Ok(f)) => {
                self.counters.dropped += self.drops.observe(stamp.0);
                f
            }
            (Err(e), _) => {
                self.drops.arrived_without_stamp();
                self.counters.error(e.to_string());
                return;
            }
            (Ok(stamp), Err(e)) => {
                self.drops.observe(stamp.0);
                self.counters.error(e.to_string());
                return;
            }
        };
        let captured = frame.stamp;
        let out = self.chain.run(Msg::Frame(frame));
        for e in out.errors {
            self.counters.error(e.to_string());
        }
        self.outputs
            .publish(out.produced, &mut self.in_contact, &mut self.counters);
        self.counters.latency(base.age_s(captured));
        self.counters.busy_s += t0.elapsed().as_secs_f64();
    }
}

fn run() -> anyhow::Result<()> {
    // Stage kinds this node runs (launch/stage_nodes.yaml).
    let stages = unitac_ros::node_stages("unitac_contact_node")?;
    let mut base = NodeBase::<Params>::new("unitac_contact", stages)?;
    let p = base.params()?;
    let (scene, stages) = unitac_ros::scene_stages(
        "unitac_contact_node",
        &p.scene,
        &p.sensor_kind,
        stages,
        base.stage_overrides(),
    )?;
    let (with_depth, with_overlay) = contact_extras(&scene)?;
    let sensor_id = p.sensor_id;
    let image_qos = unitac_ros::image::image_qos(&p.image_qos)?;
    let mut input = Input::new(&mut base.node, &p.image_transport, image_qos)?;
    let mut node = Node {
        chain: Chain::new(stages),
        outputs: Outputs::new(&mut base.node, with_depth, with_overlay)?,
        counters: diagnostics::Counters::default(),
        drops: DropCounter::default(),
        in_contact: false,
    };
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_contact: {}", base.node.fully_qualified_name()?),
        &sensor_id,
    );
    let mut seq = 0u64;
    while !base.stopped() {
        base.spin(Duration::from_millis(5));
        // Drain everything queued (r2r's subscription buffer is small and drops silently; the
        // stamp gaps count what was lost anyway).
        for r in input.drain(&mut seq, &sensor_id) {
            node.process(r, &base);
        }
        let extra = [("in_contact", node.in_contact.to_string())];
        if let Some(a) = diag.tick(&mut node.counters, base.now(), &extra) {
            base.publish_diagnostics(&a)?;
        }
    }
    // Flush an open episode and save the background (background_dir).
    let end = node.chain.finish();
    for e in &end.errors {
        eprintln!("unitac_contact_node: finishing: {e}");
    }
    node.outputs
        .publish(end.produced, &mut node.in_contact, &mut node.counters);
    base.spin(Duration::from_millis(50));
    Ok(())
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_contact_node", run)
}
