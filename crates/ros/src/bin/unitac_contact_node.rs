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
    // What the contact stage emits beyond the states: depth (a depth calibration), the overlay.
    let (with_depth, with_overlay) = unitac_pipeline::stage_configs(&scene)?
        .iter()
        .find_map(|c| match c {
            unitac_pipeline::StageConfig::Contact { params, .. } => {
                Some((params.depth_calibration.is_some(), params.overlay))
            }
            _ => None,
        })
        .unwrap_or((false, false));
    let mut chain = Chain::new(stages);
    let sensor_id = p.sensor_id;

    let image_qos = unitac_ros::image::image_qos(&p.image_qos)?;
    let node = &mut base.node;
    // One of the two subscriptions, by `image_transport`.
    let (mut raw, mut compressed) = match p.image_transport.as_str() {
        "raw" => (
            Some(node.subscribe::<r2r::sensor_msgs::msg::Image>("image", image_qos.clone())?),
            None,
        ),
        "compressed" => (
            None,
            Some(node.subscribe::<r2r::sensor_msgs::msg::CompressedImage>(
                "image/compressed",
                image_qos.clone(),
            )?),
        ),
        other => anyhow::bail!("image_transport must be raw or compressed, got '{other}'"),
    };
    let reliable = QosProfile::default;
    let pub_state =
        node.create_publisher::<r2r::unitac_msgs::msg::ContactState>("contact_state", reliable())?;
    let pub_ep = node
        .create_publisher::<r2r::unitac_msgs::msg::ContactEpisode>("contact_episode", reliable())?;
    let pub_clip =
        node.create_publisher::<r2r::unitac_msgs::msg::ContactClip>("contact_clip", reliable())?;
    let pub_slip =
        node.create_publisher::<r2r::unitac_msgs::msg::SlipState>("slip_state", reliable())?;
    // Latched: an inference node started later still gets the sensor prior.
    let pub_bg = node.create_publisher::<r2r::sensor_msgs::msg::Image>(
        "background",
        QosProfile::default().keep_last(1).transient_local(),
    )?;
    // Only the topics the scene makes: a subscriber of `depth` on a scene without depth sees no
    // publisher rather than a silent one.
    let pub_depth = with_depth
        .then(|| node.create_publisher::<r2r::sensor_msgs::msg::Image>("depth", reliable()))
        .transpose()?;
    let pub_points = with_depth
        .then(|| node.create_publisher::<r2r::sensor_msgs::msg::PointCloud2>("points", reliable()))
        .transpose()?;
    let pub_overlay = with_overlay
        .then(|| {
            node.create_publisher::<r2r::sensor_msgs::msg::Image>("contact_overlay", reliable())
        })
        .transpose()?;
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_contact: {}", node.fully_qualified_name()?),
        &sensor_id,
    );
    let mut counters = diagnostics::Counters::default();
    let mut drops = DropCounter::default();
    let (mut seq, mut in_contact) = (0u64, false);
    let publish = |out: Vec<Msg>, in_contact: &mut bool, counters: &mut diagnostics::Counters| {
        for m in out {
            let r = match m {
                Msg::ContactState(c) => {
                    *in_contact = c.in_contact;
                    pub_state.publish(&convert::contact_state(&c))
                }
                Msg::ContactEpisode(e) => pub_ep.publish(&convert::contact_episode(&e)),
                Msg::ContactClip(c) => pub_clip.publish(&convert::contact_clip(&c)),
                Msg::Background(f) => pub_bg.publish(&image::from_frame(&f)),
                Msg::SlipState(s) => pub_slip.publish(&convert::slip_state(&s)),
                Msg::Depth(d) => {
                    let (Some(pd), Some(pp)) = (&pub_depth, &pub_points) else {
                        continue;
                    };
                    counters.published(pd.publish(&image::depth(&d)));
                    pp.publish(&image::points(&d))
                }
                Msg::ContactOverlay(f) => match &pub_overlay {
                    Some(po) => po.publish(&image::from_frame(&f)),
                    None => continue,
                },
                _ => continue,
            };
            counters.published(r);
        }
    };
    while !base.stopped() {
        base.spin(Duration::from_millis(5));
        // Drain everything queued (r2r's subscription buffer is small and drops silently; the
        // stamp gaps below count what was lost anyway).
        let mut inputs = Vec::new();
        let id = |frame_id: &str| sensor_id_of(Some(&sensor_id), frame_id, "sensor");
        if let Some(sub) = raw.as_mut() {
            drain(sub, &mut inputs, |m| {
                // Images are numbered from 0 in arrival order, as a bag replay numbers them.
                let n = seq;
                seq += 1;
                Received {
                    stamp: checked_stamp(&m.header.stamp),
                    frame: image::to_frame(m, &id(&m.header.frame_id), n),
                }
            });
        }
        if let Some(sub) = compressed.as_mut() {
            drain(sub, &mut inputs, |m| {
                // Images are numbered from 0 in arrival order, as a bag replay numbers them.
                let n = seq;
                seq += 1;
                Received {
                    stamp: checked_stamp(&m.header.stamp),
                    frame: image::compressed_to_frame(m, &id(&m.header.frame_id), n),
                }
            });
        }
        for r in inputs {
            // Each frame is counted once: in, and then either processed, or an error (a bad
            // stamp, an undecodable image, a frame the stage rejects). Only stamp gaps between
            // frames that arrived count as drops.
            counters.frames_in += 1;
            let t0 = Instant::now();
            let frame = match (r.stamp, r.frame) {
                (Ok(stamp), Ok(f)) => {
                    counters.dropped += drops.observe(stamp.0);
                    f
                }
                (Err(e), _) => {
                    drops.arrived_without_stamp();
                    counters.error(e.to_string());
                    continue;
                }
                (Ok(stamp), Err(e)) => {
                    drops.observe(stamp.0);
                    counters.error(e.to_string());
                    continue;
                }
            };
            let captured = frame.stamp;
            let out = chain.run(Msg::Frame(frame));
            for e in out.errors {
                counters.error(e.to_string());
            }
            publish(out.produced, &mut in_contact, &mut counters);
            counters.latency(base.age_s(captured));
            counters.busy_s += t0.elapsed().as_secs_f64();
        }
        let extra = [("in_contact", in_contact.to_string())];
        if let Some(a) = diag.tick(&mut counters, base.now(), &extra) {
            base.publish_diagnostics(&a)?;
        }
    }
    // Flush an open episode and save the background (background_dir).
    let end = chain.finish();
    for e in &end.errors {
        eprintln!("unitac_contact_node: finishing: {e}");
    }
    publish(end.produced, &mut in_contact, &mut counters);
    base.spin(Duration::from_millis(50));
    Ok(())
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_contact_node", run)
}
