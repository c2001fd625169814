//! `unitac-lab bench render`: time to render one mock frame (unitac_sim's mock sensor), on one
//! core.

use serde::Serialize;
use std::hint::black_box;
use std::time::Instant;
use unitac_core::{FrameError, SensorKind, SensorSpec, Timing, timing};

use unitac_sim::{MockConfig, MockSensor, Scenario};

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RenderRow {
    pub sensor: String,
    pub width: u32,
    pub height: u32,
    /// Frames from the whole fabric scenario (about half of them pressed).
    pub all: Timing,
    /// Frames in the middle of a press (the most work per frame).
    pub pressed: Timing,
    /// Frames without contact.
    pub free: Timing,
    pub frames_timed: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RenderBench {
    pub rows: Vec<RenderRow>,
    /// Published CPU GelSight-style optical simulators: per 640x480 frame \[s].
    pub published_s_640x480: [f64; 2],
    pub note: String,
}

fn time_frames(s: &MockSensor, idx: &[u64], repeat: usize) -> Timing {
    for &i in idx.iter().take(3) {
        black_box(s.render(i));
    }
    let mut v = Vec::with_capacity(idx.len() * repeat);
    for _ in 0..repeat {
        for &i in idx {
            let t0 = Instant::now();
            black_box(s.render(black_box(i)));
            v.push(t0.elapsed().as_secs_f64());
        }
    }
    timing(v)
}

fn row(name: &str, s: &MockSensor, repeat: usize) -> RenderRow {
    let n = s.frame_count();
    let fps = s.config().fps;
    let all: Vec<u64> = (0..n).collect();
    let mut pressed = Vec::new();
    let mut free = Vec::new();
    for i in 0..n {
        let (d, o) = s.scenario().at(i as f64 / fps);
        if o.is_some() && d > 0.3 {
            pressed.push(i);
        } else if o.is_none() {
            free.push(i);
        }
    }
    let spec = s.spec();
    RenderRow {
        sensor: name.into(),
        width: spec.width,
        height: spec.height,
        all: time_frames(s, &all, repeat),
        pressed: time_frames(s, &pressed, repeat),
        free: time_frames(s, &free, repeat),
        frames_timed: all.len() * repeat,
    }
}

/// Time GelSight Mini and DIGIT at 320x240 and DIGIT's VGA mode (640x480), each over the whole
/// fabric scenario, `repeat` passes.
pub fn render_bench(repeat: usize) -> Result<RenderBench, FrameError> {
    let repeat = repeat.max(1);
    let mut rows = Vec::new();
    for kind in [SensorKind::GELSIGHT_MINI, SensorKind::DIGIT] {
        let s = MockSensor::new(MockConfig::new(kind, 5), Scenario::fabric_selection());
        rows.push(row(kind.as_str(), &s, repeat));
    }
    let d = SensorKind::DIGIT.spec();
    let vga = SensorSpec {
        width: 640,
        height: 480,
        native_width: 640,
        native_height: 480,
        fps: 30.0,
        mm_per_px: d.mm_per_px * 0.5,
        ..d
    };
    let mut cfg = MockConfig::new(SensorKind::DIGIT, 5);
    cfg.fps = vga.fps;
    let s = MockSensor::with_spec(cfg, vga, Scenario::fabric_selection())?;
    rows.push(row("digit-vga", &s, repeat));
    Ok(RenderBench {
        rows,
        published_s_640x480: [0.028, 0.045],
        note: "one core; frame + ground-truth mask; published CPU GelSight-style optical \
               simulators take 28-45 ms per 640x480 frame (mock-sensor issue)"
            .into(),
    })
}

impl RenderBench {
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::from(
            "mock render per frame, one core (frame + ground truth); min / median [us]\n",
        );
        let _ = writeln!(
            s,
            "  {:<14} {:>9}  {:>15}  {:>15}  {:>15}",
            "sensor", "size", "whole scene", "pressed", "no contact"
        );
        let mm = |t: &Timing| format!("{:.0} / {:.0}", t.min_s * 1e6, t.median_s * 1e6);
        for r in &self.rows {
            let _ = writeln!(
                s,
                "  {:<14} {:>9}  {:>15}  {:>15}  {:>15}",
                r.sensor,
                format!("{}x{}", r.width, r.height),
                mm(&r.all),
                mm(&r.pressed),
                mm(&r.free)
            );
        }
        if let Some(v) = self.rows.iter().find(|r| r.width == 640) {
            let [a, b] = self.published_s_640x480;
            let (lo, med) = (v.pressed.min_s, v.pressed.median_s);
            let _ = writeln!(
                s,
                "  640x480 pressed: {:.2} ms min, {:.2} ms median, vs {:.0}-{:.0} ms for published \
                 CPU optical simulators: {:.0}-{:.0}x faster (median), {:.0}-{:.0}x (min)",
                lo * 1e3,
                med * 1e3,
                a * 1e3,
                b * 1e3,
                a / med,
                b / med,
                a / lo,
                b / lo
            );
        }
        s
    }
}
