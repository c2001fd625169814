//! The paper-style success table: per criterion and mode, our count beside the paper's. The rows
//! and the paper's figures are the task's ([`unitac_sim::task::Task::criteria`],
//! [`unitac_sim::task::Task::paper`]).

use serde::Serialize;
use unitac_sim::task::{TaskKind, TaskOutcome};

/// Trials per mode in the paper's tables.
pub const PAPER_TRIALS: u32 = 20;

/// One cell: our successes of `trials`, and the paper's of 20.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cell {
    pub mode: String,
    pub ours: u32,
    pub trials: u32,
    pub paper: Option<u32>,
    pub paper_trials: u32,
}

/// One criterion across the modes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    pub criterion: String,
    pub cells: Vec<Cell>,
}

/// The table of a task from each mode's outcomes (`(mode, outcomes)` in column order).
pub fn table(kind: TaskKind, modes: &[(String, Vec<TaskOutcome>)]) -> Vec<Row> {
    kind.criteria()
        .iter()
        .map(|&criterion| Row {
            criterion: criterion.to_string(),
            cells: modes
                .iter()
                .map(|(mode, outcomes)| Cell {
                    mode: mode.clone(),
                    ours: outcomes.iter().filter(|o| o.meets(criterion)).count() as u32,
                    trials: outcomes.len() as u32,
                    paper: kind.paper(criterion, mode),
                    paper_trials: PAPER_TRIALS,
                })
                .collect(),
        })
        .collect()
}

/// The table as text: a header with the modes, one line per criterion, each cell
/// `ours n/N (paper m/20)`.
pub fn render(rows: &[Row]) -> String {
    let Some(first) = rows.first() else {
        return String::new();
    };
    let cell = |c: &Cell| {
        let paper = c
            .paper
            .map_or("-".to_string(), |p| format!("{p}/{}", c.paper_trials));
        format!("{}/{} (paper {paper})", c.ours, c.trials)
    };
    let width = 20;
    let mut s = format!("{:<20}", "criterion");
    for c in &first.cells {
        s.push_str(&format!("  {:<width$}", c.mode));
    }
    s.push('\n');
    for r in rows {
        s.push_str(&format!("{:<20}", r.criterion));
        for c in &r.cells {
            s.push_str(&format!("  {:<width$}", cell(c)));
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_sim::task::{CupCriteria, CupOutcome};

    fn cup(lift: bool, deformation_m: f64) -> TaskOutcome {
        TaskOutcome::Cup(CupOutcome::judge(
            &CupCriteria::default(),
            lift,
            if lift { 0.05 } else { 0.0 },
            deformation_m,
            deformation_m,
            false,
        ))
    }

    #[test]
    fn counts_each_criterion_per_mode_beside_the_paper() {
        let modes = vec![
            ("vla".to_string(), vec![cup(true, 0.015), cup(true, 0.01)]),
            (
                "vtla_real".to_string(),
                vec![cup(true, 0.0095), cup(false, 0.0)],
            ),
        ];
        let rows = table(TaskKind::CUP, &modes);
        let got: Vec<(String, Vec<u32>)> = rows
            .iter()
            .map(|r| {
                (
                    r.criterion.clone(),
                    r.cells.iter().map(|c| c.ours).collect(),
                )
            })
            .collect();
        assert_eq!(
            got,
            [
                ("lift".to_string(), vec![2, 1]),
                ("target deformation".to_string(), vec![1, 1]),
                ("overall".to_string(), vec![1, 1]),
            ]
        );
        assert_eq!(rows[1].cells[0].paper, Some(0));
        assert_eq!(rows[1].cells[1].paper, Some(20));
        let text = render(&rows);
        assert!(
            text.contains("target deformation    1/2 (paper 0/20)"),
            "{text}"
        );
        assert_eq!(text.lines().count(), 4);
        assert_eq!(TaskKind::FABRIC.paper("selection", "vtla_pred"), Some(18));
        assert_eq!(TaskKind::FABRIC.paper("lift", "vla"), None);
    }
}
