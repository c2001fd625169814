//! A small diagnostic updater (r2r has none): one DiagnosticStatus per node on /diagnostics once
//! a second, with rate, counters and timing.

use r2r::diagnostic_msgs::msg::{DiagnosticArray, DiagnosticStatus, KeyValue};
use std::time::Instant;

/// A latency beyond this is not a latency but a stamp from another time line \[s].
pub const MAX_LATENCY_S: f64 = 60.0;

/// Counters a node keeps for its diagnostics.
#[derive(Debug, Default, Clone)]
pub struct Counters {
    pub frames_in: u64,
    pub messages_out: u64,
    pub errors: u64,
    /// Frames known lost before processing (subscriber queue overflow, source gaps).
    pub dropped: u64,
    /// Events that are no error of the node's but a warning (the policy node: ticks on which
    /// the policy failed: an error, an inference over its time limit, a refused action).
    pub warnings: u64,
    /// Time spent processing \[s].
    pub busy_s: f64,
    pub last_error: String,
    /// Latencies that made no sense (a stamp more than a minute from the node's clock: a bag
    /// replayed without sim time, a stamp in the future); counted, never averaged in.
    pub latency_out_of_range: u64,
    /// Latencies since the last report [s]: sum, count, max (reset by each report).
    latency_sum: f64,
    latency_n: u64,
    latency_max: f64,
}

impl Counters {
    /// Count an input that was rejected (bad stamp, undecodable, refused by a stage).
    pub fn error(&mut self, e: impl Into<String>) {
        self.errors += 1;
        self.last_error = e.into();
    }

    /// Count a publish: one message out, or an error kept as the last error.
    pub fn published(&mut self, r: r2r::Result<()>) {
        match r {
            Ok(()) => self.messages_out += 1,
            Err(e) => {
                self.errors += 1;
                self.last_error = format!("publish: {e}");
            }
        }
    }

    /// Record one latency: the node's clock when an output went out minus the capture stamp of
    /// the frame it came from \[s].
    pub fn latency(&mut self, seconds: f64) {
        if !(-1.0..=MAX_LATENCY_S).contains(&seconds) {
            self.latency_out_of_range += 1;
        } else {
            self.latency_sum += seconds;
            self.latency_n += 1;
            self.latency_max = self.latency_max.max(seconds);
        }
    }
}

/// The policy's control ticks by what they sent, as diagnostic values (the counts
/// `unitac-lab trials --json` reports as `policy_ticks`): every tick, the policy's action, and the
/// safe action by why (the watchdog, a policy error, an inference over its time limit, a refused
/// action, the controller's `failed` phase), and the first failure's reason.
pub fn policy_ticks(c: &unitac_policy::TickCounts) -> Vec<(&'static str, String)> {
    vec![
        ("ticks", c.ticks.to_string()),
        ("ticks_acted", c.acted.to_string()),
        ("ticks_safe_watchdog", c.watchdog.to_string()),
        ("ticks_policy_error", c.policy_error.to_string()),
        ("ticks_over_budget", c.over_budget.to_string()),
        ("ticks_refused", c.refused.to_string()),
        ("ticks_ended", c.ended.to_string()),
        (
            "policy_first_failure",
            c.first_failure.clone().unwrap_or_else(|| "none".into()),
        ),
    ]
}

#[derive(Debug)]
pub struct Updater {
    name: String,
    hardware_id: String,
    last: Instant,
    last_frames: u64,
}

impl Updater {
    pub fn new(name: &str, hardware_id: &str) -> Self {
        Self {
            name: name.into(),
            hardware_id: hardware_id.into(),
            last: Instant::now(),
            last_frames: 0,
        }
    }

    /// A DiagnosticArray when a second has passed since the last one.
    pub fn tick(
        &mut self,
        c: &mut Counters,
        stamp: r2r::builtin_interfaces::msg::Time,
        extra: &[(&str, String)],
    ) -> Option<DiagnosticArray> {
        let dt = self.last.elapsed().as_secs_f64();
        if dt < 1.0 {
            return None;
        }
        let rate = (c.frames_in - self.last_frames) as f64 / dt;
        self.last = Instant::now();
        self.last_frames = c.frames_in;
        let mean = if c.frames_in > 0 {
            c.busy_s / c.frames_in as f64
        } else {
            0.0
        };
        // OK = 0, WARN = 1: errors, drops or warnings since start are a warning, not a failure.
        let level = u8::from(c.errors > 0 || c.dropped > 0 || c.warnings > 0);
        let kv = |k: &str, v: String| KeyValue {
            key: k.into(),
            value: v,
        };
        let mut values = vec![
            kv("rate_hz", format!("{rate:.2}")),
            kv("frames_in", c.frames_in.to_string()),
            kv("messages_out", c.messages_out.to_string()),
            kv("errors", c.errors.to_string()),
            kv("dropped", c.dropped.to_string()),
            kv("latency_out_of_range", c.latency_out_of_range.to_string()),
            kv("mean_process_us", format!("{:.1}", mean * 1e6)),
        ];
        if c.latency_n > 0 {
            let mean = c.latency_sum / c.latency_n as f64;
            values.push(kv("latency_mean_ms", format!("{:.3}", mean * 1e3)));
            values.push(kv("latency_max_ms", format!("{:.3}", c.latency_max * 1e3)));
        }
        (c.latency_sum, c.latency_n, c.latency_max) = (0.0, 0, 0.0);
        values.extend(extra.iter().map(|(k, v)| kv(k, v.clone())));
        let status = DiagnosticStatus {
            level: level as _,
            name: self.name.clone(),
            message: if c.last_error.is_empty() {
                "ok".into()
            } else {
                c.last_error.clone()
            },
            hardware_id: self.hardware_id.clone(),
            values,
        };
        let mut a = DiagnosticArray::default();
        a.header.stamp = stamp;
        a.status = vec![status];
        Some(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::msg::samples;

    #[test]
    fn policy_failures_are_in_the_values() {
        let mut c = unitac_policy::TickCounts::default();
        for msg in [
            "policy: inference over budget: learned policy p@1: the model ran past its budget",
            "policy: learned policy: the model predicted NaN",
        ] {
            c.count(&unitac_core::msg::PolicyStatus {
                safety_ok: false,
                phase: "act".into(),
                message: msg.into(),
                ..samples::policy_status()
            });
        }
        let v = policy_ticks(&c);
        let get = |k: &str| v.iter().find(|(n, _)| *n == k).map(|(_, x)| x.as_str());
        assert_eq!(get("ticks"), Some("2"));
        assert_eq!(get("ticks_acted"), Some("0"));
        assert_eq!(get("ticks_over_budget"), Some("1"));
        assert_eq!(get("ticks_policy_error"), Some("1"));
        assert!(get("policy_first_failure").unwrap().contains("over budget"));
    }
}
