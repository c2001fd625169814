//! The report row of the policy tick benchmark, one format for every transport.
//!
//! `unitac-lab bench policy` (embedded: the policy stage ticked through `unitac_core::chain`)
//! prints these rows with transport `embedded`, and the Python baseline's rows with transport
//! `python`; a benchmark of the ROS policy node (GripperStatus published -> GripperCommand
//! received over DDS) prints the same rows with transport `ros`, so the tables line up. Statistics
//! come from `unitac_core::tail` (per-tick latency) and `unitac_core::period_jitter` (a paced
//! loop's achieved period), so every transport states the same order statistics under the same
//! names.

use serde::Serialize;
use unitac_core::{PeriodJitter, Tail};

/// One measured configuration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TickRow {
    /// `embedded`, `python` or `ros`.
    pub transport: String,
    /// The scene (`cup_deformation_vla`, ...), or `-` for a row that is not a scene's.
    pub scene: String,
    /// vla | vtla_real | vtla_pred, or `-`.
    pub mode: String,
    /// What one tick ran: `controller` (the scene's state machine behind the observation,
    /// watchdog and safety layer), `controller + onnx act` (and an ONNX policy's `act` in the
    /// same tick), `onnx act` (the ONNX policy alone), ...
    pub what: String,
    /// Observation -> command time per tick, unpaced.
    pub tick: Tail,
    /// Ticks that ran an inference (an ONNX policy infers every `n_action_steps` ticks), when
    /// the row has an ONNX policy.
    pub inferred: Option<Tail>,
    /// The same tick in a loop paced at the control rate in real time: achieved periods.
    pub period: Option<PeriodJitter>,
    /// Controller phases the ticks went through, in order of first appearance.
    pub phases: Vec<String>,
}

impl TickRow {
    /// The header of [`TickRow::line`]'s columns.
    pub fn header() -> String {
        format!(
            "{:<9} {:<27} {:<23} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} | {:>10} {:>9} {:>9}\n",
            "transport",
            "scene",
            "per tick",
            "ticks",
            "p50 us",
            "p99 us",
            "max us",
            "inf p50",
            "inf p99",
            "period p50",
            "p99 ms",
            "max dev"
        )
    }

    /// One line of the table (`-` for what the row does not have).
    pub fn line(&self) -> String {
        let opt = |v: Option<f64>, prec: usize| match v {
            Some(x) => format!("{x:.prec$}"),
            None => "-".into(),
        };
        let p = self.period.as_ref();
        format!(
            "{:<9} {:<27} {:<23} {:>6} {:>9.1} {:>9.1} {:>9.1} {:>9} {:>9} | {:>10} {:>9} {:>9}\n",
            self.transport,
            self.scene,
            self.what,
            self.tick.n,
            self.tick.p50_s * 1e6,
            self.tick.p99_s * 1e6,
            self.tick.max_s * 1e6,
            opt(self.inferred.map(|t| t.p50_s * 1e6), 1),
            opt(self.inferred.map(|t| t.p99_s * 1e6), 1),
            opt(p.map(|j| j.p50_s * 1e3), 3),
            opt(p.map(|j| j.p99_s * 1e3), 3),
            opt(p.map(|j| j.max_dev_s * 1e3), 3),
        )
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_line_has_every_column_and_dashes_for_what_is_missing() {
        let row = TickRow {
            transport: "embedded".into(),
            scene: "cup_deformation_vla".into(),
            mode: "vla".into(),
            what: "controller".into(),
            tick: unitac_core::tail(vec![2e-6, 4e-6]),
            inferred: None,
            period: Some(unitac_core::period_jitter(&[0.0, 0.034], 0.033333)),
            phases: vec!["approach".into()],
        };
        let line = row.line();
        let cols: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(
            cols,
            [
                "embedded",
                "cup_deformation_vla",
                "controller",
                "2",
                "2.0",
                "4.0",
                "4.0",
                "-",
                "-",
                "|",
                "34.000",
                "34.000",
                "0.667"
            ]
        );
        assert_eq!(
            TickRow::header().split('|').count(),
            line.split('|').count()
        );
    }
}
