//! Sensor node: one per sensor. Publishes sensor_msgs/Image on `image_raw` (reliable; consumers
//! subscribe best-effort per REP 2003), stamped with the capture time, frame_id
//! `<sensor_id>_optical_frame`, and /diagnostics once a second (rate, drops, errors, device state).
//!
//! Sources (`source` parameter):
//! - `mock`: the simulated sensor, paced to its frame rate.
//! - `v4l`: a live GelSight Mini or DIGIT found by `serial` (reconnects on replug; see the driver
//!   crate). Stamps are the driver's capture times.
//! - `bag`: a rosbag2 bag's image topic, republished as its raw CDR bytes (no decode, no copy of
//!   the pixels into a message type) at the bag's pace, with /clock carrying the bag time so
//!   nodes under `use_sim_time` see bag time. sensor_msgs/Image goes to `image_raw`,
//!   CompressedImage to `image_raw/compressed` (image_transport's names).

use r2r::{QosProfile, RosParams};
use std::time::{Duration, Instant};
use unitac_core::scene::SourceKind;
use unitac_core::{Pacer, Scene, SourceError};
use unitac_ros::node::NodeBase;
use unitac_ros::{convert, diagnostics, image};

/// Consecutive frame errors after which a live source is given up (about 40 s at 25 fps).
const MAX_ERRORS_IN_A_ROW: u32 = 1000;

/// The source comes from the scene file's `source:` (kind, sensor, scenario, seed, fps, serial,
/// path), built by the same registry `unitac run` uses; these parameters override it.
#[derive(RosParams, Debug, Clone)]
struct Params {
    /// Scene: a scene name (looked up like `unitac run --scene`) or a path to a scene YAML
    scene: String,
    /// mock | v4l | bag (empty: the scene's source)
    source: String,
    /// a profile of sensors/ (gelsight-mini, digit, generic, ...) or of $UNITAC_SENSORS (empty: the scene's sensor)
    sensor_kind: String,
    /// Sensor id: frame_id is `<sensor_id>_optical_frame` (empty: the scene's, else mock_KIND
    /// for the mock sensor, the serial for a live one)
    sensor_id: String,
    /// Serial of a live sensor (v4l; empty: the scene's, else the only one of its kind)
    serial: String,
    /// Start the scenario (mock) or the bag again at its end
    repeat: bool,
    /// Wait until this many subscribers matched before the first frame (mock, bag; 0: no wait)
    wait_subscribers: i32,
    /// Bag path: rosbag2 directory, .mcap or .db3 (bag source; empty: the scene's)
    bag: String,
    /// Image topic in the bag (empty: the first Image or CompressedImage topic)
    bag_topic: String,
    /// Playback rate: bag time per wall time (bag source)
    rate: f64,
    /// Publish /clock with the bag's time (bag source; for nodes under use_sim_time)
    publish_clock: bool,
    /// History depth of the image publisher (reliable; 1..=64): deeper lets a reliable
    /// subscriber that falls behind catch up instead of losing frames
    image_depth: i32,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            scene: "fabric_selection".into(),
            source: String::new(),
            sensor_kind: String::new(),
            sensor_id: String::new(),
            serial: String::new(),
            repeat: false,
            wait_subscribers: 0,
            bag: String::new(),
            bag_topic: String::new(),
            rate: 1.0,
            publish_clock: true,
            image_depth: 10,
        }
    }
}

type Base = NodeBase<Params>;

/// The image publisher's QoS: reliable (it matches best-effort and reliable subscribers), keep
/// last `image_depth`.
fn image_qos(p: &Params) -> anyhow::Result<QosProfile> {
    let max = unitac_ros::image::RELIABLE_IMAGE_DEPTH;
    match usize::try_from(p.image_depth) {
        Ok(d) if (1..=max).contains(&d) => Ok(QosProfile::default().keep_last(d)),
        _ => anyhow::bail!("image_depth must be 1..={max}, got {}", p.image_depth),
    }
}

fn wait_for_subscribers(
    base: &mut Base,
    wanted: i32,
    count: impl Fn() -> usize,
) -> anyhow::Result<()> {
    let wanted = usize::try_from(wanted).unwrap_or(0);
    if wanted > 0 && !base.spin_until(Duration::from_secs(30), || count() >= wanted) {
        anyhow::bail!("fewer than {wanted} subscribers matched within 30 s");
    }
    Ok(())
}

/// Mock and V4L2: frames from a `Source`, converted to rgb8 Images.
/// The scene with this node's overrides applied (source kind, sensor, id, serial, bag).
fn scene_of(p: &Params) -> anyhow::Result<Scene> {
    let mut scene = unitac_pipeline::load_scene(&p.scene, None)?;
    let src = &mut scene.source;
    if !p.source.is_empty() {
        src.kind = match p.source.as_str() {
            "mock" => SourceKind::Mock,
            "v4l" => SourceKind::V4l,
            "bag" => SourceKind::Bag,
            other => anyhow::bail!("source '{other}' is not one of mock, v4l, bag"),
        };
    }
    if !p.sensor_kind.is_empty() {
        src.sensor = p.sensor_kind.parse()?;
    }
    if !p.sensor_id.is_empty() {
        src.sensor_id = Some(p.sensor_id.clone());
    }
    if !p.serial.is_empty() {
        src.serial = Some(p.serial.clone());
    }
    if !p.bag.is_empty() {
        src.path = Some(p.bag.clone().into());
    }
    Ok(scene)
}

fn run_source(base: &mut Base, p: &Params, scene: &Scene) -> anyhow::Result<()> {
    let live = scene.source.kind == SourceKind::V4l;
    let open = || unitac_pipeline::build_source(scene, None).map_err(anyhow::Error::from);
    let mut source = open()?;
    let publisher = base
        .node
        .create_publisher::<r2r::sensor_msgs::msg::Image>("image_raw", image_qos(p)?)?;
    let hardware_id = source.name().to_string();
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_sensor: {}", base.node.fully_qualified_name()?),
        &hardware_id,
    );
    let mut counters = diagnostics::Counters::default();
    if !live {
        wait_for_subscribers(base, p.wait_subscribers, || {
            publisher
                .get_inter_process_subscription_count()
                .unwrap_or(0)
        })?;
    }
    let (mut errors_in_a_row, mut device) = (0u32, "streaming".to_string());
    let mut last_seq: Option<u64> = None;
    'outer: loop {
        // Mock stamps are wall-clock capture times: the mock's frame times shifted to now.
        let mut offset = None::<i64>;
        let mut pacer = Pacer::real_time();
        loop {
            if base.stopped() {
                break 'outer;
            }
            let next = source.next_frame();
            let mut f = match next {
                Ok(Some(f)) => f,
                Ok(None) => break,
                Err(e) => {
                    counters.errors += 1;
                    counters.last_error = e.to_string();
                    errors_in_a_row += 1;
                    device = match &e {
                        SourceError::Unavailable(_) => "unavailable (waiting for replug)".into(),
                        SourceError::Fatal(_) => anyhow::bail!("{}: {e}", source.name()),
                        SourceError::Frame(_) => device,
                    };
                    if errors_in_a_row >= MAX_ERRORS_IN_A_ROW {
                        anyhow::bail!(
                            "{}: {errors_in_a_row} errors in a row, last: {e}",
                            source.name()
                        );
                    }
                    base.spin(Duration::from_millis(1));
                    continue;
                }
            };
            errors_in_a_row = 0;
            device = "streaming".into();
            if let Some(prev) = last_seq.filter(|&s| f.seq > s) {
                counters.dropped += f.seq - prev - 1;
            }
            last_seq = Some(f.seq);
            if !live {
                pacer.wait(f.stamp, |d| {
                    base.spin(d.min(Duration::from_millis(1)));
                    !base.stopped()
                });
                let off = *offset.get_or_insert_with(|| {
                    unitac_core::Clock::now(&unitac_core::SystemClock).0 - f.stamp.0
                });
                f.stamp = f.stamp.saturating_add_nanos(off);
            } else {
                base.spin(Duration::ZERO);
            }
            let t1 = Instant::now();
            publisher.publish(&image::from_frame(&f))?;
            counters.latency(base.age_s(f.stamp));
            counters.frames_in += 1;
            counters.messages_out += 1;
            counters.busy_s += t1.elapsed().as_secs_f64();
            if let Some(a) = diag.tick(&mut counters, base.now(), &[("device", device.clone())]) {
                base.publish_diagnostics(&a)?;
            }
        }
        if !p.repeat || live {
            break;
        }
        source = open()?;
        last_seq = None;
    }
    linger(base);
    Ok(())
}

/// Bag: the image topic's messages as raw CDR, paced by their bag times, with /clock.
fn run_bag(base: &mut Base, p: &Params, scene: &Scene) -> anyhow::Result<()> {
    use unitac_bag::{BagReader, ReadOptions};
    let Some(path) = scene.source.path.clone() else {
        anyhow::bail!("source 'bag' needs the parameter bag (a rosbag2 directory, .mcap or .db3)");
    };
    let mut pacer = Pacer::new(Some(p.rate))?;
    const IMAGE: &str = "sensor_msgs/msg/Image";
    const COMPRESSED: &str = "sensor_msgs/msg/CompressedImage";
    let is_image = |t: &str| t == IMAGE || t == COMPRESSED;
    // The image topic and its type: the one named, else the first image topic the bag holds.
    let mut r = BagReader::open(&path, ReadOptions::default())?;
    let wanted = |t: &unitac_bag::TopicInfo| {
        (is_image(&t.type_name) && (p.bag_topic.is_empty() || t.name == p.bag_topic))
            .then(|| (t.name.clone(), t.type_name.clone()))
    };
    let mut found = r.declared_topics().iter().find_map(wanted);
    while found.is_none() {
        let next = r.next_with(&mut |t, _, _| wanted(t))?;
        match next {
            Some(Some(x)) => found = Some(x),
            Some(None) => {}
            None => break,
        }
    }
    drop(r);
    let (topic, type_name) = found.ok_or_else(|| {
        if p.bag_topic.is_empty() {
            anyhow::anyhow!("{}: no {IMAGE} or {COMPRESSED} topic", path.display())
        } else {
            anyhow::anyhow!(
                "{}: no {IMAGE} or {COMPRESSED} topic named {}",
                path.display(),
                p.bag_topic
            )
        }
    })?;
    // image_transport's names: raw on image_raw, compressed on image_raw/compressed.
    let out_topic = if type_name == IMAGE {
        "image_raw"
    } else {
        "image_raw/compressed"
    };
    let publisher = base
        .node
        .create_publisher_untyped(out_topic, &type_name, image_qos(p)?)?;
    let clock = base
        .node
        .create_publisher::<r2r::rosgraph_msgs::msg::Clock>("/clock", QosProfile::default())?;
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_sensor: {}", base.node.fully_qualified_name()?),
        &path.display().to_string(),
    );
    let mut counters = diagnostics::Counters::default();
    wait_for_subscribers(base, p.wait_subscribers, || {
        publisher
            .get_inter_process_subscription_count()
            .unwrap_or(0)
    })?;
    let opts = ReadOptions {
        topics: vec![topic.clone()],
        ..Default::default()
    };
    'outer: loop {
        let mut reader = BagReader::open(&path, opts.clone())?;
        pacer.restart();
        let mut buf = Vec::new();
        loop {
            if base.stopped() {
                break 'outer;
            }
            let next = reader.next_with(&mut |t, log_time, data| {
                buf.clear();
                buf.extend_from_slice(data);
                (t.type_name.clone(), log_time)
            })?;
            let Some((msg_type, log_time)) = next else {
                break;
            };
            if msg_type != type_name && !msg_type.is_empty() {
                anyhow::bail!("{topic} changes type from {type_name} to {msg_type}");
            }
            pacer.wait(unitac_core::Stamp(log_time), |d| {
                base.spin(d.min(Duration::from_millis(1)));
                !base.stopped()
            });
            if p.publish_clock {
                let c = r2r::rosgraph_msgs::msg::Clock {
                    clock: convert::time(unitac_core::Stamp(log_time)),
                };
                clock.publish(&c)?;
            }
            let t1 = Instant::now();
            publisher.publish_raw(&buf)?;
            counters.frames_in += 1;
            counters.messages_out += 1;
            counters.busy_s += t1.elapsed().as_secs_f64();
            if let Some(a) = diag.tick(&mut counters, base.now(), &[("topic", topic.clone())]) {
                base.publish_diagnostics(&a)?;
            }
        }
        for f in reader.truncated() {
            eprintln!(
                "unitac_sensor_node: {} ends early (truncated); replayed up to its last complete record",
                f.display()
            );
        }
        if !p.repeat {
            break;
        }
    }
    linger(base);
    Ok(())
}

/// Give subscribers a moment to take the last messages before the node goes away.
fn linger(base: &mut Base) {
    let t = Instant::now();
    while t.elapsed() < Duration::from_millis(200) {
        base.spin(Duration::from_millis(10));
    }
}

fn run() -> anyhow::Result<()> {
    let mut base = Base::new("unitac_sensor", &[])?;
    let p = base.params()?;
    let scene = scene_of(&p)?;
    match scene.source.kind {
        SourceKind::Mock | SourceKind::V4l => run_source(&mut base, &p, &scene),
        SourceKind::Bag => run_bag(&mut base, &p, &scene),
    }
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_sensor_node", run)
}
