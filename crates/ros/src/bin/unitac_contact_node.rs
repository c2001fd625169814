//! Contact node: sensor_msgs/Image in (best-effort, REP 2003), ContactState per frame and
//! ContactEpisode on release out (reliable), /diagnostics once a second. A thin driver of the
//! same `ContactStage` the embedded runtime runs; its clock is the images' capture stamps.
//!
//! Topics (relative, so namespaces and remaps apply): `image` in; `contact_state`,
//! `contact_episode` out. Parameters (`--ros-args --params-file x.yaml`): see `Params`.

use futures::{FutureExt, StreamExt};
use r2r::{QosProfile, RosParams};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use unitac_contact::{ContactParams, ContactStage};
use unitac_core::{ManualClock, Msg, SensorKind, Stage};
use unitac_ros::{convert, diagnostics, image};

#[derive(RosParams, Debug)]
struct Params {
    /// Sensor id used in messages (default: the image's frame_id without "_optical_frame")
    sensor_id: String,
    /// gelsight-mini | digit | generic (mm per pixel, marker masking)
    sensor_kind: String,
    /// Frames averaged into the initial background
    learn_frames: i32,
    /// Threshold in units of the measured noise sigma
    noise_k: f64,
    /// Lower bound of the threshold [DN, summed over channels]
    min_threshold: f64,
    /// Contact starts at this area [px]
    enter_area_px: f64,
    /// Contact ends below this area [px]
    exit_area_px: f64,
    /// Frames needed to enter contact
    debounce_frames: i32,
}

impl Default for Params {
    fn default() -> Self {
        let d = ContactParams::default();
        Self {
            sensor_id: String::new(),
            sensor_kind: "gelsight-mini".into(),
            learn_frames: d.learn_frames as i32,
            noise_k: f64::from(d.noise_k),
            min_threshold: f64::from(d.min_threshold),
            enter_area_px: f64::from(d.enter_area_px),
            exit_area_px: f64::from(d.exit_area_px),
            debounce_frames: d.debounce_frames as i32,
        }
    }
}

impl Params {
    fn contact(&self) -> Result<(ContactParams, SensorKind), String> {
        let kind: SensorKind = self.sensor_kind.parse()?;
        let nonneg = |v: i32, n: &str| u32::try_from(v).map_err(|_| format!("{n} must be >= 0"));
        let p = ContactParams {
            learn_frames: nonneg(self.learn_frames, "learn_frames")?,
            noise_k: self.noise_k as f32,
            min_threshold: self.min_threshold as f32,
            enter_area_px: self.enter_area_px as f32,
            exit_area_px: self.exit_area_px as f32,
            debounce_frames: nonneg(self.debounce_frames, "debounce_frames")?,
            ..Default::default()
        };
        p.check()?;
        Ok((p, kind))
    }
}

fn run() -> anyhow::Result<()> {
    let ctx = r2r::Context::create()?;
    let mut node = r2r::Node::create(ctx, "unitac_contact", "")?;
    let params = Arc::new(Mutex::new(Params::default()));
    let (handler, _events) = node.make_derived_parameter_handler(params.clone())?;
    let mut pool = futures::executor::LocalPool::new();
    futures::task::LocalSpawnExt::spawn_local(&pool.spawner(), handler)?;
    pool.run_until_stalled();
    let (cp, kind, sensor_id) = {
        let p = params
            .lock()
            .map_err(|_| anyhow::anyhow!("parameter lock poisoned"))?;
        let (cp, kind) = p
            .contact()
            .map_err(|e| anyhow::anyhow!("bad parameters: {e}"))?;
        (cp, kind, p.sensor_id.clone())
    };
    let mut stage = ContactStage::new(cp, kind.spec()).map_err(anyhow::Error::msg)?;

    let mut images =
        node.subscribe::<r2r::sensor_msgs::msg::Image>("image", QosProfile::sensor_data())?;
    let pub_state = node.create_publisher::<r2r::unitac_msgs::msg::ContactState>(
        "contact_state",
        QosProfile::default(),
    )?;
    let pub_ep = node.create_publisher::<r2r::unitac_msgs::msg::ContactEpisode>(
        "contact_episode",
        QosProfile::default(),
    )?;
    let pub_diag = node.create_publisher::<r2r::diagnostic_msgs::msg::DiagnosticArray>(
        "/diagnostics",
        QosProfile::default(),
    )?;
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_contact: {}", node.fully_qualified_name()?),
        &sensor_id,
    );
    let mut counters = diagnostics::Counters::default();
    let clock = ManualClock::default();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, std::sync::atomic::Ordering::SeqCst))?;
    }
    let (mut seq, mut in_contact) = (0u64, false);
    while !stop.load(std::sync::atomic::Ordering::SeqCst) {
        node.spin_once(Duration::from_millis(5));
        pool.run_until_stalled();
        // Drain everything queued (r2r's subscription buffer is small and drops silently).
        while let Some(Some(img)) = images.next().now_or_never() {
            let id = if sensor_id.is_empty() {
                img.header
                    .frame_id
                    .trim_end_matches("_optical_frame")
                    .to_string()
            } else {
                sensor_id.clone()
            };
            seq += 1;
            counters.frames_in += 1;
            let t0 = Instant::now();
            let frame = match image::to_frame(&img, &id, seq) {
                Ok(f) => f,
                Err(e) => {
                    counters.errors += 1;
                    counters.last_error = e;
                    continue;
                }
            };
            clock.set(frame.stamp);
            match stage.process(&Msg::Frame(frame), &clock) {
                Ok(out) => {
                    for m in out {
                        match m {
                            Msg::Contact(c) => {
                                in_contact = c.in_contact;
                                pub_state.publish(&convert::contact_state(&c))?;
                                counters.messages_out += 1;
                            }
                            Msg::Episode(e) => {
                                pub_ep.publish(&convert::contact_episode(&e))?;
                                counters.messages_out += 1;
                            }
                            _ => {}
                        }
                    }
                }
                Err(e) => {
                    counters.errors += 1;
                    counters.last_error = e.to_string();
                }
            }
            counters.busy_us += t0.elapsed().as_secs_f64() * 1e6;
        }
        let now = convert::time(unitac_core::Clock::now(&unitac_core::SystemClock));
        if let Some(a) = diag.tick(&counters, now, &[("in_contact", in_contact.to_string())]) {
            pub_diag.publish(&a)?;
        }
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("unitac_contact_node: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}
