//! Wiring and running: source thread -> stage threads -> collector.

use crate::edge::{Edge, FramePolicy};
use crate::report::{RunReport, StageReport};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use unitac_core::chain::{RunnerStats, StageRunner};
use unitac_core::{Msg, Pacer, Scene, Source, SourceError, Stage, Stamp};

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

/// One stage's thread: every input through the stage's runner (the one chain driver: outputs,
/// then the input, on the input-stamp clock), then its `finish`, then the next edge is closed.
fn stage_loop(stage: Box<dyn Stage>, input: &Edge, output: &Edge) -> RunnerStats {
    let mut runner = StageRunner::new(stage);
    let span = tracing::info_span!("stage", name = %runner.name());
    let _guard = span.enter();
    let mut open = true;
    while let Some(msg) = input.pop() {
        let rejected = runner.feed(msg, &mut |o| open &= output.push(o));
        if let Some(r) = rejected {
            if runner.stats().errors <= 10 {
                tracing::warn!("{r}");
            }
        }
        if !open {
            break;
        }
    }
    if let Some(r) = runner.finish(&mut |o| {
        output.push(o);
    }) {
        tracing::warn!("{r}");
    }
    output.close();
    runner.stats().clone()
}

/// How the source thread ended: frames pushed, errors, why it ended, and the stream's first
/// stamp and span.
struct SourceEnd {
    frames: u64,
    errors: u64,
    ended: String,
    stream_start: Stamp,
    stream_s: f64,
}

/// The source thread: frames from `source` into `first_edge`, paced, until the source ends,
/// `max_frames`, `stop`, or too many errors in a row; the edge is closed on the way out.
fn source_loop(
    source: &mut dyn Source,
    first_edge: &Edge,
    stop: &AtomicBool,
    max_frames: Option<u64>,
    pacer: &mut Pacer,
) -> SourceEnd {
    let _span = tracing::info_span!("source").entered();
    let (mut frames, mut errors, mut in_a_row) = (0u64, 0u64, 0u32);
    let (mut first, mut last) = (None::<Stamp>, Stamp::ZERO);
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
                first.get_or_insert(f.stamp);
                last = f.stamp;
                pacer.wait(f.stamp, |d| {
                    std::thread::sleep(d);
                    !stop.load(Ordering::SeqCst)
                });
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
    SourceEnd {
        frames,
        errors,
        ended,
        stream_start: first.unwrap_or(Stamp::ZERO),
        stream_s: first.map_or(0.0, |f| last.secs_since(f)),
    }
}

/// Run `stages` on `source` until the source ends, `max_frames` is reached or `stop` is set.
/// `on_message` sees every message that leaves the last stage, in order, frames included (with
/// a lossless `--fast` replay that is every frame of the source: `unitac run --out` records them).
pub fn run(
    scene: &Scene,
    mut source: Box<dyn Source>,
    stages: Vec<Box<dyn Stage>>,
    opts: &RunOptions,
    mut on_message: impl FnMut(&Msg),
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
    let source_name = source.name().to_string();
    let started = Instant::now();

    let mut handles = Vec::new();
    for (i, stage) in stages.into_iter().enumerate() {
        let (input, output) = (Arc::clone(&edges[i]), Arc::clone(&edges[i + 1]));
        handles.push(std::thread::spawn(move || {
            stage_loop(stage, &input, &output)
        }));
    }

    // Source thread.
    let first_edge = Arc::clone(&edges[0]);
    let stop = Arc::clone(&opts.stop);
    let max_frames = opts.max_frames;
    // Replay sources (mock, bag) are paced to their stamps unless --fast; live ones come at
    // their own pace.
    let mut pacer = if replay && opts.realtime {
        Pacer::real_time()
    } else {
        Pacer::fast()
    };
    let source_thread = std::thread::spawn(move || {
        source_loop(source.as_mut(), &first_edge, &stop, max_frames, &mut pacer)
    });

    // Collector: the end of the chain.
    let mut event_counts: BTreeMap<String, u64> = BTreeMap::new();
    let (mut episodes, mut properties, mut comparisons) = (Vec::new(), Vec::new(), Vec::new());
    let mut latents = Vec::new();
    let tail = Arc::clone(&edges[n]);
    while let Some(m) = tail.pop() {
        on_message(&m);
        if m.is_frame() {
            continue;
        }
        *event_counts.entry(m.kind().to_string()).or_default() += 1;
        match m {
            Msg::ContactEpisode(e) if episodes.len() < MAX_KEPT_EVENTS => episodes.push(e),
            Msg::TactileProperties(p) if properties.len() < MAX_KEPT_EVENTS => properties.push(p),
            Msg::PropertyComparison(c) if comparisons.len() < MAX_KEPT_EVENTS => {
                comparisons.push(c)
            }
            Msg::TactileLatent(l) if latents.len() < MAX_KEPT_EVENTS => {
                let mut j = Msg::TactileLatent(l).to_json();
                if let Some(o) = j.as_object_mut() {
                    o.remove("data");
                }
                latents.push(j);
            }
            _ => {}
        }
    }
    let SourceEnd {
        frames,
        errors: source_errors,
        ended,
        stream_start,
        stream_s,
    } = source_thread.join().unwrap_or_else(|_| SourceEnd {
        frames: 0,
        errors: 0,
        ended: "source_failed: source thread panicked".into(),
        stream_start: Stamp::ZERO,
        stream_s: 0.0,
    });
    let stages = names
        .into_iter()
        .zip(handles)
        .enumerate()
        .map(|(i, (name, h))| {
            let c = h.join().unwrap_or_else(|_| {
                tracing::error!("stage {name}: its thread panicked");
                RunnerStats::default()
            });
            StageReport::new(name, &c, edges[i].dropped())
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
