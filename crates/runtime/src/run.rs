//! Wiring and running: source thread -> stage threads -> collector.

use crate::edge::{Edge, FramePolicy};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};
use unitac_core::msg::{ContactEpisode, PropertyComparison, TactileProperties};
use unitac_core::{Clock, ManualClock, Msg, Scene, Source, SourceError, Stage, Stamp, SystemClock};

/// Events of these kinds are kept whole in the report (up to this many each).
const MAX_KEPT_EVENTS: usize = 10_000;
/// Consecutive per-frame source errors after which a source is given up.
const MAX_SOURCE_ERRORS_IN_A_ROW: u32 = 1000;

#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Pace replay sources (mock, bag) to their stamps; false = as fast as possible, lossless.
    pub realtime: bool,
    /// Stop after this many frames from the source.
    pub max_frames: Option<u64>,
    /// Set to stop the run (Ctrl-C); the pipeline drains and finishes cleanly.
    pub stop: Arc<AtomicBool>,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            realtime: true,
            max_frames: None,
            stop: Arc::new(AtomicBool::new(false)),
        }
    }
}

#[derive(Debug, Default)]
struct Counters {
    input: AtomicU64,
    output: AtomicU64,
    errors: AtomicU64,
    busy_ns: AtomicU64,
    max_ns: AtomicU64,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct StageReport {
    pub name: String,
    /// Messages in (frames and events).
    pub input: u64,
    /// Messages the stage produced.
    pub output: u64,
    /// Frames dropped on the edge into this stage.
    pub dropped: u64,
    /// Inputs the stage rejected (bad input, model errors), each logged.
    pub errors: u64,
    /// Time inside `process`, total and per call.
    pub busy_s: f64,
    pub mean_us: f64,
    pub max_us: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct RunReport {
    pub scene: String,
    pub source: String,
    pub frame_policy: FramePolicy,
    pub frames: u64,
    pub source_errors: u64,
    /// Why the run ended: "source_end", "max_frames", "stopped", or "source_failed: ...".
    pub ended: String,
    pub wall_s: f64,
    /// Capture stamp of the first frame (episode times in the text summary are relative to it).
    pub stream_start: Stamp,
    /// Stream time from first to last frame.
    pub stream_s: f64,
    pub stages: Vec<StageReport>,
    /// Count of every event kind that reached the end of the chain.
    pub event_counts: BTreeMap<String, u64>,
    pub episodes: Vec<ContactEpisode>,
    pub properties: Vec<TactileProperties>,
    pub comparisons: Vec<PropertyComparison>,
    /// Tactile latents without their data (source, shape, solver, validity, guard report).
    pub latents: Vec<serde_json::Value>,
}

impl RunReport {
    /// Human summary, a few lines.
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "scene {} on {} ({} frames, {:.2} s of stream in {:.2} s, ended: {})",
            self.scene, self.source, self.frames, self.stream_s, self.wall_s, self.ended
        );
        for st in &self.stages {
            let _ = writeln!(
                s,
                "  stage {:<10} in {:>6} out {:>6} dropped {:>4} errors {:>4}  mean {:>8.1} us  max {:>8.1} us",
                st.name, st.input, st.output, st.dropped, st.errors, st.mean_us, st.max_us
            );
        }
        for e in &self.episodes {
            let _ = writeln!(
                s,
                "  episode {} {:<10} {:.2}-{:.2} s  {} frames  peak {:.0} px ({:.1} mm^2)",
                e.episode_id,
                if e.label.is_empty() { "-" } else { &e.label },
                e.start.secs_since(self.stream_start),
                e.end.secs_since(self.stream_start),
                e.frame_count,
                e.peak_area_px,
                e.peak_area_mm2
            );
        }
        for p in &self.properties {
            let _ = writeln!(
                s,
                "  properties {} {:<10} hardness {:.2}±{:.2}  roughness {:.2}±{:.2}  texture {:.2}±{:.2}",
                p.episode_id,
                p.label,
                p.hardness,
                p.hardness_std,
                p.roughness,
                p.roughness_std,
                p.texture,
                p.texture_std
            );
        }
        for l in &self.latents {
            let _ = writeln!(
                s,
                "  latent {} {} shape {} solver {} steps {} s {} valid {}{}",
                l["source"].as_str().unwrap_or(""),
                l["sensor_id"].as_str().unwrap_or(""),
                l["shape"],
                l["solver"].as_str().unwrap_or("-"),
                l["steps"],
                l["guidance"],
                l["valid"],
                l["guard_report"]
                    .as_str()
                    .filter(|r| !r.is_empty())
                    .map(|r| format!(" ({r})"))
                    .unwrap_or_default()
            );
        }
        for c in &self.comparisons {
            let _ = writeln!(s, "  comparison ({}): {}", c.property, c.sentence);
        }
        if self.stages.is_empty() {
            let _ = writeln!(s, "  (the scene runs no stages)");
        }
        s
    }
}

fn stage_loop(
    mut stage: Box<dyn Stage>,
    input: &Edge,
    output: &Edge,
    counters: &Counters,
    replay: bool,
) {
    let name = stage.name().to_string();
    let span = tracing::info_span!("stage", name = %name);
    let _guard = span.enter();
    let manual = ManualClock::default();
    let clock: &dyn Clock = if replay { &manual } else { &SystemClock };
    let mut logged = 0u32;
    let mut last = Stamp::ZERO;
    while let Some(msg) = input.pop() {
        counters.input.fetch_add(1, Ordering::Relaxed);
        if replay {
            last = last.max(msg.stamp());
            manual.set(last);
        }
        let t0 = Instant::now();
        let result = {
            let _p = tracing::trace_span!("process", kind = msg.kind()).entered();
            stage.process(&msg, clock)
        };
        let ns = u64::try_from(t0.elapsed().as_nanos()).unwrap_or(u64::MAX);
        counters.busy_ns.fetch_add(ns, Ordering::Relaxed);
        counters.max_ns.fetch_max(ns, Ordering::Relaxed);
        let mut ok = true;
        match result {
            Ok(outs) => {
                counters
                    .output
                    .fetch_add(outs.len() as u64, Ordering::Relaxed);
                for o in outs {
                    ok &= output.push(o);
                }
            }
            Err(e) => {
                counters.errors.fetch_add(1, Ordering::Relaxed);
                if logged < 10 {
                    tracing::warn!(stage = %name, "input {} at {:?} rejected: {e}", msg.kind(), msg.stamp());
                    logged += 1;
                }
            }
        }
        ok &= output.push(msg);
        if !ok {
            break;
        }
    }
    match stage.finish(clock) {
        Ok(outs) => {
            counters
                .output
                .fetch_add(outs.len() as u64, Ordering::Relaxed);
            for o in outs {
                output.push(o);
            }
        }
        Err(e) => {
            counters.errors.fetch_add(1, Ordering::Relaxed);
            tracing::warn!(stage = %name, "finish failed: {e}");
        }
    }
    output.close();
}

/// Run `stages` on `source` until the source ends, `max_frames` is reached or `stop` is set.
/// `on_event` sees every non-frame message that leaves the last stage, in order.
pub fn run(
    scene: &Scene,
    mut source: Box<dyn Source>,
    stages: Vec<Box<dyn Stage>>,
    opts: &RunOptions,
    mut on_event: impl FnMut(&Msg),
) -> RunReport {
    let replay = source.is_replay();
    let policy = if replay && !opts.realtime {
        FramePolicy::Lossless
    } else {
        FramePolicy::DropOldest
    };
    let n = stages.len();
    let edges: Vec<Arc<Edge>> = (0..=n)
        .map(|_| {
            Arc::new(Edge::new(
                scene.edges.frame_capacity,
                scene.edges.event_capacity,
                policy,
            ))
        })
        .collect();
    let names: Vec<String> = stages.iter().map(|s| s.name().to_string()).collect();
    let counters: Vec<Arc<Counters>> = (0..n).map(|_| Arc::new(Counters::default())).collect();
    let source_name = source.name().to_string();
    let started = Instant::now();

    let mut handles = Vec::new();
    for (i, stage) in stages.into_iter().enumerate() {
        let (input, output, c) = (
            Arc::clone(&edges[i]),
            Arc::clone(&edges[i + 1]),
            Arc::clone(&counters[i]),
        );
        handles.push(std::thread::spawn(move || {
            stage_loop(stage, &input, &output, &c, replay)
        }));
    }

    // Source thread.
    let first_edge = Arc::clone(&edges[0]);
    let stop = Arc::clone(&opts.stop);
    let (realtime, max_frames) = (opts.realtime, opts.max_frames);
    let source_thread = std::thread::spawn(move || {
        let _span = tracing::info_span!("source").entered();
        let (mut frames, mut errors, mut in_a_row) = (0u64, 0u64, 0u32);
        let (mut first, mut last) = (None::<Stamp>, Stamp::ZERO);
        let t0 = Instant::now();
        let ended = loop {
            if stop.load(Ordering::SeqCst) {
                break "stopped".to_string();
            }
            if max_frames.is_some_and(|m| frames >= m) {
                break "max_frames".to_string();
            }
            match source.next_frame() {
                Ok(Some(f)) => {
                    in_a_row = 0;
                    let f0 = *first.get_or_insert(f.stamp);
                    last = f.stamp;
                    if replay && realtime {
                        let due = Duration::from_secs_f64(f.stamp.secs_since(f0).max(0.0));
                        while let Some(wait) = due.checked_sub(t0.elapsed()) {
                            if stop.load(Ordering::SeqCst) {
                                break;
                            }
                            std::thread::sleep(wait.min(Duration::from_millis(50)));
                        }
                    }
                    frames += 1;
                    if !first_edge.push(Msg::Frame(f)) {
                        break "stopped".to_string();
                    }
                }
                Ok(None) => break "source_end".to_string(),
                Err(SourceError::Frame(e)) | Err(SourceError::Unavailable(e)) => {
                    errors += 1;
                    in_a_row += 1;
                    if errors <= 10 {
                        tracing::warn!("source: {e}");
                    }
                    if in_a_row >= MAX_SOURCE_ERRORS_IN_A_ROW {
                        break format!("source_failed: {in_a_row} errors in a row, last: {e}");
                    }
                }
                Err(SourceError::Fatal(e)) => break format!("source_failed: {e}"),
            }
        };
        first_edge.close();
        (
            frames,
            errors,
            ended,
            first.unwrap_or(Stamp::ZERO),
            first.map_or(0.0, |f| last.secs_since(f)),
        )
    });

    // Collector: the end of the chain.
    let mut event_counts: BTreeMap<String, u64> = BTreeMap::new();
    let (mut episodes, mut properties, mut comparisons) = (Vec::new(), Vec::new(), Vec::new());
    let mut latents = Vec::new();
    let tail = Arc::clone(&edges[n]);
    while let Some(m) = tail.pop() {
        if m.is_frame() {
            continue;
        }
        *event_counts.entry(m.kind().to_string()).or_default() += 1;
        on_event(&m);
        match m {
            Msg::Episode(e) if episodes.len() < MAX_KEPT_EVENTS => episodes.push(e),
            Msg::Properties(p) if properties.len() < MAX_KEPT_EVENTS => properties.push(p),
            Msg::Comparison(c) if comparisons.len() < MAX_KEPT_EVENTS => comparisons.push(c),
            Msg::Latent(l) if latents.len() < MAX_KEPT_EVENTS => {
                let mut j = Msg::Latent(l).to_json();
                if let Some(o) = j.as_object_mut() {
                    o.remove("data");
                }
                latents.push(j);
            }
            _ => {}
        }
    }
    let (frames, source_errors, ended, stream_start, stream_s) =
        source_thread.join().unwrap_or_else(|_| {
            (
                0,
                0,
                "source_failed: source thread panicked".into(),
                Stamp::ZERO,
                0.0,
            )
        });
    for h in handles {
        if h.join().is_err() {
            tracing::error!("a stage thread panicked");
        }
    }
    let stages = names
        .into_iter()
        .zip(&counters)
        .enumerate()
        .map(|(i, (name, c))| {
            let input = c.input.load(Ordering::Relaxed);
            let busy = c.busy_ns.load(Ordering::Relaxed) as f64;
            StageReport {
                name,
                input,
                output: c.output.load(Ordering::Relaxed),
                dropped: edges[i].dropped(),
                errors: c.errors.load(Ordering::Relaxed),
                busy_s: busy * 1e-9,
                mean_us: if input > 0 {
                    busy / input as f64 * 1e-3
                } else {
                    0.0
                },
                max_us: c.max_ns.load(Ordering::Relaxed) as f64 * 1e-3,
            }
        })
        .collect();
    RunReport {
        scene: scene.name.clone(),
        source: source_name,
        frame_policy: policy,
        frames,
        source_errors,
        ended,
        wall_s: started.elapsed().as_secs_f64(),
        stream_start,
        stream_s,
        stages,
        event_counts,
        episodes,
        properties,
        comparisons,
        latents,
    }
}
