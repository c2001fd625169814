//! Contact node: sensor_msgs/Image in (or CompressedImage: `image_transport`; best-effort, REP 2003); ContactState per frame,
//! ContactEpisode on release, ContactClip (the episode's frames, for the inference node) and the
//! learned background (latched, for the sampler's sensor prior) out, reliable; /diagnostics once
//! a second. A thin driver of the same `ContactStage` the embedded runtime runs; its clock is the
//! images' capture stamps, so replays give the same answers as live runs.
//!
//! Topics (relative, so namespaces and remaps apply): `image` (or `image/compressed`) in; `contact_state`,
//! `contact_episode`, `contact_clip`, `background` out. Parameters
//! (`--ros-args --params-file x.yaml`): see `Params`.

use futures::{FutureExt, StreamExt};
use r2r::{QosProfile, RosParams};
use std::time::{Duration, Instant};
use unitac_contact::{ContactParams, ContactStage};
use unitac_core::{ManualClock, Msg, SensorKind, Stage};
use unitac_ros::drops::DropCounter;
use unitac_ros::node::NodeBase;
use unitac_ros::{convert, diagnostics, image};

#[derive(RosParams, Debug, Clone)]
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
    /// Frames per episode published on contact_clip for the encoder (0: no clips)
    clip_frames: i32,
    /// Labels given to episodes in order, comma-separated (e.g. "fabric_a,fabric_b")
    episode_labels: String,
    /// Directory of saved backgrounds per sensor (empty: learn at every start)
    background_dir: String,
    /// raw: sensor_msgs/Image on `image`; compressed: sensor_msgs/CompressedImage (jpeg, png) on
    /// `image/compressed`, as image_transport names it
    image_transport: String,
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
            clip_frames: 8,
            episode_labels: String::new(),
            background_dir: String::new(),
            image_transport: "raw".into(),
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
            clip_frames: nonneg(self.clip_frames, "clip_frames")?,
            episode_labels: unitac_ros::list_param(&self.episode_labels),
            background_dir: (!self.background_dir.is_empty())
                .then(|| self.background_dir.clone().into()),
            ..Default::default()
        };
        p.check().map_err(|e| e.to_string())?;
        Ok((p, kind))
    }
}

/// Everything queued on `sub`, converted (r2r's subscription buffer is small and drops silently).
fn drain<T>(
    sub: &mut (impl futures::Stream<Item = T> + Unpin),
    out: &mut Vec<Result<unitac_core::Frame, String>>,
    mut convert: impl FnMut(&T) -> Result<unitac_core::Frame, String>,
) {
    while let Some(Some(m)) = sub.next().now_or_never() {
        out.push(convert(&m));
    }
}

/// The sensor id of an image: the configured one, else its frame_id without "_optical_frame".
fn id_of(configured: &str, frame_id: &str) -> String {
    if configured.is_empty() {
        frame_id.trim_end_matches("_optical_frame").to_string()
    } else {
        configured.to_string()
    }
}

fn run() -> anyhow::Result<()> {
    let mut base = NodeBase::<Params>::new("unitac_contact")?;
    let p = base.params()?;
    let (cp, kind) = p
        .contact()
        .map_err(|e| anyhow::anyhow!("bad parameters: {e}"))?;
    let sensor_id = p.sensor_id;
    let mut stage = ContactStage::new(cp, kind.spec()).map_err(anyhow::Error::msg)?;

    let node = &mut base.node;
    // One of the two subscriptions, by `image_transport`.
    let (mut raw, mut compressed) = match p.image_transport.as_str() {
        "raw" => (
            Some(
                node.subscribe::<r2r::sensor_msgs::msg::Image>("image", QosProfile::sensor_data())?,
            ),
            None,
        ),
        "compressed" => (
            None,
            Some(node.subscribe::<r2r::sensor_msgs::msg::CompressedImage>(
                "image/compressed",
                QosProfile::sensor_data(),
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
    // Latched: an inference node started later still gets the sensor prior.
    let pub_bg = node.create_publisher::<r2r::sensor_msgs::msg::Image>(
        "background",
        QosProfile::default().keep_last(1).transient_local(),
    )?;
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_contact: {}", node.fully_qualified_name()?),
        &sensor_id,
    );
    let mut counters = diagnostics::Counters::default();
    let mut drops = DropCounter::default();
    let clock = ManualClock::default();
    let (mut seq, mut in_contact) = (0u64, false);
    let publish = |out: Vec<Msg>, in_contact: &mut bool, counters: &mut diagnostics::Counters| {
        for m in out {
            let r = match m {
                Msg::Contact(c) => {
                    *in_contact = c.in_contact;
                    pub_state.publish(&convert::contact_state(&c))
                }
                Msg::Episode(e) => pub_ep.publish(&convert::contact_episode(&e)),
                Msg::Clip(c) => pub_clip.publish(&convert::contact_clip(&c)),
                Msg::Background(f) => pub_bg.publish(&image::from_frame(&f)),
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
        if let Some(sub) = raw.as_mut() {
            drain(sub, &mut inputs, |m| {
                seq += 1;
                image::to_frame(m, &id_of(&sensor_id, &m.header.frame_id), seq)
            });
        }
        if let Some(sub) = compressed.as_mut() {
            drain(sub, &mut inputs, |m| {
                seq += 1;
                image::compressed_to_frame(m, &id_of(&sensor_id, &m.header.frame_id), seq)
            });
        }
        for f in inputs {
            counters.frames_in += 1;
            let t0 = Instant::now();
            let frame = match f {
                Ok(f) => f,
                Err(e) => {
                    counters.errors += 1;
                    counters.last_error = e;
                    continue;
                }
            };
            counters.dropped += drops.observe(frame.stamp.0);
            clock.set(frame.stamp);
            let captured = frame.stamp;
            match stage.process(&Msg::Frame(frame), &clock) {
                Ok(out) => {
                    publish(out, &mut in_contact, &mut counters);
                    counters.latency(base.age_s(captured));
                }
                Err(e) => {
                    counters.errors += 1;
                    counters.last_error = e.to_string();
                }
            }
            counters.busy_us += t0.elapsed().as_secs_f64() * 1e6;
        }
        let extra = [("in_contact", in_contact.to_string())];
        if let Some(a) = diag.tick(&mut counters, base.now(), &extra) {
            base.publish_diagnostics(&a)?;
        }
    }
    // Flush an open episode and save the background (background_dir).
    match stage.finish(&clock) {
        Ok(out) => publish(out, &mut in_contact, &mut counters),
        Err(e) => eprintln!("unitac_contact_node: finishing: {e}"),
    }
    base.spin(Duration::from_millis(50));
    Ok(())
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_contact_node", run)
}
