//! Behaviour of the embedded runtime: edge policies, shutdown, per-message errors, determinism.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use unitac_core::scene::SceneContext;
use unitac_core::{Clock, Frame, Msg, Scene, Source, SourceError, Stage, StageError, Stamp};
use unitac_pipeline::{KNOWN_STAGES, build_source, build_stages};
use unitac_runtime::{FramePolicy, RunOptions, run};

fn scene(text: &str) -> Scene {
    let ctx = SceneContext {
        known_stages: KNOWN_STAGES.iter().map(|s| s.to_string()).collect(),
        ..Default::default()
    };
    Scene::parse(text, Path::new("test.yaml"), &ctx).unwrap()
}

const FABRIC: &str = "scene: fabric_selection\nsource: {kind: mock, sensor: gelsight-mini, seed: 7}\n\
stages:\n  - kind: contact\n    params: {episode_labels: [fabric_a, fabric_b]}\n";

/// A live-like source (not replay): `n` tiny frames at 2 kHz, every 10th one corrupt.
struct Burst {
    n: u64,
    i: u64,
}
impl Source for Burst {
    fn name(&self) -> &str {
        "burst"
    }
    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        if self.i == self.n {
            return Ok(None);
        }
        self.i += 1;
        std::thread::sleep(Duration::from_micros(500));
        if self.i % 10 == 0 {
            return Err(SourceError::frame("corrupt buffer"));
        }
        Ok(Some(
            Frame::new("burst", self.i, Stamp(self.i as i64), 1, 1, vec![0; 3]).unwrap(),
        ))
    }
    fn is_replay(&self) -> bool {
        false
    }
}

/// Slow stage that fails on every 7th frame and emits one event per frame it accepts.
struct Slow {
    delay: Duration,
    finished: Arc<AtomicBool>,
}
impl Stage for Slow {
    fn name(&self) -> &str {
        "slow"
    }
    fn process(&mut self, input: &Msg, clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        let Msg::Frame(f) = input else {
            return Ok(Vec::new());
        };
        std::thread::sleep(self.delay);
        if f.seq % 7 == 0 {
            return Err(StageError::bad_input(format!("frame {}", f.seq)));
        }
        let _ = clock.now();
        Ok(vec![Msg::PolicyStatus(unitac_core::msg::PolicyStatus {
            header: unitac_core::msg::Header::new(f.stamp, ""),
            scene: String::new(),
            mode: String::new(),
            phase: format!("{}", f.seq),
            safety_ok: true,
            message: String::new(),
            clamped: Vec::new(),
        })])
    }
    fn finish(&mut self, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        self.finished.store(true, Ordering::SeqCst);
        Ok(Vec::new())
    }
}

#[test]
fn slow_consumer_drops_oldest_frames_counts_them_and_keeps_every_event() {
    let sc = scene("scene: t\nsource: {kind: mock}\nedges: {frame_capacity: 2}\n");
    let finished = Arc::new(AtomicBool::new(false));
    let stages: Vec<Box<dyn Stage>> = vec![Box::new(Slow {
        delay: Duration::from_millis(2),
        finished: Arc::clone(&finished),
    })];
    let mut statuses = 0u64;
    let report = run(
        &sc,
        Box::new(Burst { n: 300, i: 0 }),
        stages,
        &RunOptions::default(),
        |m| {
            if matches!(m, Msg::PolicyStatus(_)) {
                statuses += 1;
            }
        },
    );
    assert_eq!(report.frame_policy, FramePolicy::DropOldest);
    assert_eq!(report.ended, "source_end");
    assert_eq!((report.frames, report.source_errors), (270, 30));
    let st = &report.stages[0];
    assert!(
        st.dropped > 0,
        "a 2 ms stage behind a burst source must drop frames: {st:?}"
    );
    assert_eq!(
        st.input + st.dropped,
        270,
        "every frame is either processed or counted as dropped"
    );
    // Every accepted frame's event reached the end: events are lossless.
    assert_eq!(statuses, st.output);
    assert_eq!(st.output + st.errors, st.input);
    assert!(st.errors > 0);
    assert!(finished.load(Ordering::SeqCst), "finish() runs at the end");
}

#[test]
fn stop_flag_ends_the_run_cleanly_and_flushes_open_episodes() {
    let sc = scene(FABRIC);
    let source = build_source(&sc, None).unwrap();
    let stages = build_stages(&sc).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let opts = RunOptions {
        realtime: true,
        max_frames: None,
        stop: Arc::clone(&stop),
    };
    // Stop in the middle of the first press (real-time pacing: ~1.6 s in).
    let stopper = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(1700));
            stop.store(true, Ordering::SeqCst);
        })
    };
    let report = run(&sc, source, stages, &opts, |_| {});
    stopper.join().unwrap();
    assert_eq!(report.ended, "stopped");
    assert!(
        report.frames > 30 && report.frames < 100,
        "{}",
        report.frames
    );
    assert_eq!(
        report.episodes.len(),
        1,
        "the open episode is closed by finish()"
    );
    assert_eq!(report.episodes[0].label, "fabric_a");
}

fn events_json(max_frames: Option<u64>) -> Vec<String> {
    let sc = scene(FABRIC);
    let opts = RunOptions {
        realtime: false,
        max_frames,
        ..Default::default()
    };
    let mut out = Vec::new();
    let report = run(
        &sc,
        build_source(&sc, None).unwrap(),
        build_stages(&sc).unwrap(),
        &opts,
        |m| {
            if !m.is_frame() {
                out.push(m.to_json().to_string());
            }
        },
    );
    assert_eq!(report.frame_policy, FramePolicy::Lossless);
    assert_eq!(report.stages[0].dropped, 0);
    out
}

#[test]
fn fast_replay_is_deterministic_and_finds_both_fabrics() {
    let a = events_json(None);
    let b = events_json(None);
    assert_eq!(a, b);
    let episodes: Vec<&String> = a
        .iter()
        .filter(|l| l.contains("\"contact_episode\""))
        .collect();
    assert_eq!(episodes.len(), 2);
    assert!(episodes[0].contains("fabric_a") && episodes[1].contains("fabric_b"));
    let short = events_json(Some(20));
    assert_eq!(
        short.iter().filter(|l| l.contains("contact_state")).count(),
        10,
        "10 learning frames"
    );
}
