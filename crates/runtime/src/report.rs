//! What a run reports: per-stage counters, the events kept, and a short text summary.

use crate::edge::FramePolicy;
use serde::Serialize;
use std::collections::BTreeMap;
use unitac_core::Stamp;
use unitac_core::chain::RunnerStats;
use unitac_core::msg::{ContactEpisode, PropertyComparison, TactileProperties};

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
    pub mean_s: f64,
    pub max_s: f64,
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
                st.name,
                st.input,
                st.output,
                st.dropped,
                st.errors,
                st.mean_s * 1e6,
                st.max_s * 1e6
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
                f64::from(e.peak_area_m2) * 1e6
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

impl StageReport {
    /// A stage's line of the report from its runner's counters.
    pub fn new(name: String, c: &RunnerStats, dropped: u64) -> Self {
        let busy = c.busy_ns as f64;
        Self {
            name,
            input: c.input,
            output: c.output,
            dropped,
            errors: c.errors,
            busy_s: busy * 1e-9,
            mean_s: if c.input > 0 {
                busy / c.input as f64 * 1e-9
            } else {
                0.0
            },
            max_s: c.max_ns as f64 * 1e-9,
        }
    }
}
