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
use std::path::PathBuf;
use std::time::{Duration, Instant};
use unitac_core::{SensorKind, Source, SourceError};
use unitac_ros::node::NodeBase;
use unitac_ros::{convert, diagnostics, image};
use unitac_sim::{MockConfig, MockSensor, Scenario};

/// Consecutive frame errors after which a live source is given up (about 40 s at 25 fps).
const MAX_ERRORS_IN_A_ROW: u32 = 1000;

#[derive(RosParams, Debug, Clone)]
struct Params {
    /// mock | v4l | bag
    source: String,
    /// gelsight-mini | digit | generic
    sensor_kind: String,
    /// Sensor id (frame_id prefix); empty = mock_KIND (mock), the serial (v4l)
    sensor_id: String,
    /// v4l: serial of the sensor (empty: the only one of sensor_kind on the bus)
    serial: String,
    /// mock: scenario (fabric_selection | cup_deformation | idle)
    scenario: String,
    /// mock: noise seed
    seed: i64,
    /// mock: frame rate (Hz); 0 = the sensor's
    fps: f64,
    /// mock, bag: start again at the end (`loop` is a Rust keyword r2r cannot name)
    repeat: bool,
    /// mock, bag: wait (up to 30 s) until this many subscribers matched before the first frame,
    /// so nodes started together see the scenario from its start (0 = do not wait)
    wait_subscribers: i32,
    /// bag: path of a rosbag2 directory, .mcap or .db3
    bag: String,
    /// bag: the image topic to republish (empty: the first Image or CompressedImage topic)
    bag_topic: String,
    /// bag: playback rate (1 = recorded pace)
    rate: f64,
    /// bag: publish /clock with the bag time
    publish_clock: bool,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            source: "mock".into(),
            sensor_kind: "gelsight-mini".into(),
            sensor_id: String::new(),
            serial: String::new(),
            scenario: "fabric_selection".into(),
            seed: 7,
            fps: 0.0,
            repeat: false,
            wait_subscribers: 0,
            bag: String::new(),
            bag_topic: String::new(),
            rate: 1.0,
            publish_clock: true,
        }
    }
}

type Base = NodeBase<Params>;

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
fn run_source(base: &mut Base, p: &Params) -> anyhow::Result<()> {
    let kind: SensorKind = p.sensor_kind.parse().map_err(anyhow::Error::msg)?;
    let live = p.source == "v4l";
    let mut cfg = MockConfig::new(kind, u64::try_from(p.seed).unwrap_or(0));
    if !p.sensor_id.is_empty() {
        cfg.sensor_id = p.sensor_id.clone();
    }
    if p.fps > 0.0 && p.fps <= 1000.0 {
        cfg.fps = p.fps;
    }
    let scenario = Scenario::by_name(&p.scenario)?;
    let open = |cfg: &MockConfig| -> anyhow::Result<Box<dyn Source>> {
        if live {
            let serial = (!p.serial.is_empty()).then_some(p.serial.as_str());
            unitac_runtime::registry::open_v4l(kind, serial)
                .map_err(|(field, msg)| anyhow::anyhow!("{field}: {msg}"))
        } else {
            Ok(Box::new(MockSensor::new(cfg.clone(), scenario.clone())))
        }
    };
    let mut source = open(&cfg)?;
    let publisher = base
        .node
        .create_publisher::<r2r::sensor_msgs::msg::Image>("image_raw", QosProfile::default())?;
    let hardware_id = if live {
        p.serial.clone()
    } else {
        cfg.sensor_id.clone()
    };
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
        let t0 = Instant::now();
        // Mock stamps are wall-clock capture times: the mock's frame times shifted to now.
        let offset = unitac_core::Clock::now(&unitac_core::SystemClock).0 - unitac_sim::EPOCH.0;
        let mut k = 0u64;
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
                let due = Duration::from_secs_f64(k as f64 / cfg.fps);
                while t0.elapsed() < due && !base.stopped() {
                    base.spin(Duration::from_millis(1).min(due.saturating_sub(t0.elapsed())));
                }
                f.stamp = f.stamp.saturating_add_nanos(offset);
            } else {
                base.spin(Duration::ZERO);
            }
            let t1 = Instant::now();
            publisher.publish(&image::from_frame(&f))?;
            counters.latency(base.age_s(f.stamp));
            counters.frames_in += 1;
            counters.messages_out += 1;
            counters.busy_us += t1.elapsed().as_secs_f64() * 1e6;
            k += 1;
            if let Some(a) = diag.tick(&mut counters, base.now(), &[("device", device.clone())]) {
                base.publish_diagnostics(&a)?;
            }
        }
        if !p.repeat || live {
            break;
        }
        source = open(&cfg)?;
        last_seq = None;
    }
    linger(base);
    Ok(())
}

/// Bag: the image topic's messages as raw CDR, paced by their bag times, with /clock.
fn run_bag(base: &mut Base, p: &Params) -> anyhow::Result<()> {
    use unitac_bag::{BagReader, ReadOptions};
    if p.bag.is_empty() {
        anyhow::bail!("source 'bag' needs the parameter bag (a rosbag2 directory, .mcap or .db3)");
    }
    if !(p.rate > 0.0 && p.rate <= 1000.0) {
        anyhow::bail!("rate must be in (0, 1000], got {}", p.rate);
    }
    let path = PathBuf::from(&p.bag);
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
            anyhow::anyhow!("{}: no {IMAGE} or {COMPRESSED} topic", p.bag)
        } else {
            anyhow::anyhow!(
                "{}: no {IMAGE} or {COMPRESSED} topic named {}",
                p.bag,
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
    let publisher =
        base.node
            .create_publisher_untyped(out_topic, &type_name, QosProfile::default())?;
    let clock = base
        .node
        .create_publisher::<r2r::rosgraph_msgs::msg::Clock>("/clock", QosProfile::default())?;
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_sensor: {}", base.node.fully_qualified_name()?),
        &p.bag,
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
        let (t0, mut first) = (Instant::now(), None::<i64>);
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
            let start = *first.get_or_insert(log_time);
            let due =
                Duration::from_nanos(u64::try_from(log_time.saturating_sub(start)).unwrap_or(0))
                    .div_f64(p.rate);
            while t0.elapsed() < due && !base.stopped() {
                base.spin(Duration::from_millis(1).min(due.saturating_sub(t0.elapsed())));
            }
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
            counters.busy_us += t1.elapsed().as_secs_f64() * 1e6;
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
    let mut base = Base::new("unitac_sensor")?;
    let p = base.params()?;
    match p.source.as_str() {
        "mock" | "v4l" => run_source(&mut base, &p),
        "bag" => run_bag(&mut base, &p),
        other => anyhow::bail!("source '{other}' is not one of mock, v4l, bag"),
    }
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_sensor_node", run)
}
