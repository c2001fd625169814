//! Sensor node: publishes sensor_msgs/Image (rgb8, reliable, REP 2003) from the mock sensor at
//! its frame rate, stamped with capture time, frame_id `<sensor_id>_optical_frame`. The V4L2
//! source joins this node with the driver crate; bag replay publishes raw CDR instead.
//!
//! Topic: `image_raw` (relative). Parameters: see `Params`. Exits after the scenario unless
//! `loop` is true.

use r2r::{QosProfile, RosParams};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use unitac_core::{SensorKind, Source};
use unitac_ros::{convert, diagnostics, image};
use unitac_sim::{MockConfig, MockSensor, Scenario};

#[derive(RosParams, Debug, Clone)]
struct Params {
    /// mock (v4l and bag come with their issues)
    source: String,
    /// gelsight-mini | digit | generic
    sensor_kind: String,
    /// Sensor id (frame_id prefix); empty = mock_<kind>
    sensor_id: String,
    /// Mock scenario: fabric_selection | cup_deformation | idle
    scenario: String,
    /// Mock noise seed
    seed: i64,
    /// Frame rate [Hz]; 0 = the sensor's
    fps: f64,
    /// Start the scenario again when it ends
    r#loop: bool,
    /// Mock/replay: wait (up to 30 s) until this many subscribers matched before the first frame,
    /// so nodes started together see the scenario from its start (0 = do not wait)
    wait_subscribers: i32,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            source: "mock".into(),
            sensor_kind: "gelsight-mini".into(),
            sensor_id: String::new(),
            scenario: "fabric_selection".into(),
            seed: 7,
            fps: 0.0,
            r#loop: false,
            wait_subscribers: 0,
        }
    }
}

fn run() -> anyhow::Result<()> {
    let ctx = r2r::Context::create()?;
    let mut node = r2r::Node::create(ctx, "unitac_sensor", "")?;
    let params = Arc::new(Mutex::new(Params::default()));
    let (handler, _events) = node.make_derived_parameter_handler(params.clone())?;
    let mut pool = futures::executor::LocalPool::new();
    futures::task::LocalSpawnExt::spawn_local(&pool.spawner(), handler)?;
    pool.run_until_stalled();
    let Params {
        source,
        sensor_kind: kind,
        sensor_id,
        scenario,
        seed,
        fps,
        r#loop: looping,
        wait_subscribers,
    } = {
        let g = params
            .lock()
            .map_err(|_| anyhow::anyhow!("parameter lock poisoned"))?;
        g.clone()
    };
    if source != "mock" {
        anyhow::bail!(
            "source '{source}' is not in this build (mock only; v4l and bag come with their issues)"
        );
    }
    let kind: SensorKind = kind.parse().map_err(anyhow::Error::msg)?;
    let mut cfg = MockConfig::new(kind, u64::try_from(seed).unwrap_or(0));
    if !sensor_id.is_empty() {
        cfg.sensor_id = sensor_id;
    }
    if fps > 0.0 && fps <= 1000.0 {
        cfg.fps = fps;
    }
    let scenario = Scenario::by_name(&scenario)?;
    let publisher =
        node.create_publisher::<r2r::sensor_msgs::msg::Image>("image_raw", QosProfile::default())?;
    let pub_diag = node.create_publisher::<r2r::diagnostic_msgs::msg::DiagnosticArray>(
        "/diagnostics",
        QosProfile::default(),
    )?;
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_sensor: {}", node.fully_qualified_name()?),
        &cfg.sensor_id,
    );
    let mut counters = diagnostics::Counters::default();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, std::sync::atomic::Ordering::SeqCst))?;
    }
    let wanted = usize::try_from(wait_subscribers).unwrap_or(0);
    if wanted > 0 {
        let matched = unitac_ros::spin_until(&mut node, Duration::from_secs(30), || {
            publisher
                .get_inter_process_subscription_count()
                .unwrap_or(0)
                >= wanted
        });
        if !matched {
            anyhow::bail!("fewer than {wanted} subscribers matched within 30 s");
        }
    }
    'outer: loop {
        let mut sensor = MockSensor::new(cfg.clone(), scenario.clone());
        let t0 = Instant::now();
        // Stamps are wall-clock capture times: the mock's frame times shifted to now.
        let offset = unitac_core::Clock::now(&unitac_core::SystemClock).0 - unitac_sim::EPOCH.0;
        let mut k = 0u64;
        while let Some(mut f) = sensor.next_frame()? {
            if stop.load(std::sync::atomic::Ordering::SeqCst) {
                break 'outer;
            }
            let due = Duration::from_secs_f64(k as f64 / cfg.fps);
            while t0.elapsed() < due {
                node.spin_once(Duration::from_millis(1).min(due.saturating_sub(t0.elapsed())));
                pool.run_until_stalled();
            }
            f.stamp = f.stamp.saturating_add_nanos(offset);
            let t1 = Instant::now();
            publisher.publish(&image::from_frame(&f))?;
            counters.frames_in += 1;
            counters.messages_out += 1;
            counters.busy_us += t1.elapsed().as_secs_f64() * 1e6;
            k += 1;
            let now = convert::time(unitac_core::Clock::now(&unitac_core::SystemClock));
            if let Some(a) = diag.tick(&counters, now, &[]) {
                pub_diag.publish(&a)?;
            }
        }
        if !looping {
            break;
        }
    }
    // Give late subscribers' last messages a moment to go out.
    let t = Instant::now();
    while t.elapsed() < Duration::from_millis(200) {
        node.spin_once(Duration::from_millis(10));
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("unitac_sensor_node: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}
