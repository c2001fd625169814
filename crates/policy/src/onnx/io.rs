//! What goes into an ONNX policy (named float32 feature slices) and what comes out (an action
//! chunk in SI units). Plain types with no ONNX Runtime in them, so the observation assembly
//! and the safety layer adapt to them in a few lines.

use std::collections::BTreeMap;
use unitac_core::Stamp;

/// Named observation features, borrowed: LeRobot names (`observation.state`,
/// `observation.images.<camera>`, `observation.<name>`) -> flat row-major float32 values (batch
/// excluded). Names the policy does not use are ignored, so one assembly serves every mode.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NamedInputs<'a> {
    map: BTreeMap<&'a str, &'a [f32]>,
}

impl<'a> NamedInputs<'a> {
    pub fn new() -> Self {
        Self::default()
    }

    /// Add or replace a feature (builder style).
    #[must_use]
    pub fn with(mut self, name: &'a str, values: &'a [f32]) -> Self {
        self.insert(name, values);
        self
    }

    /// Add or replace a feature.
    pub fn insert(&mut self, name: &'a str, values: &'a [f32]) {
        self.map.insert(name, values);
    }

    pub fn get(&self, name: &str) -> Option<&'a [f32]> {
        self.map.get(name).copied()
    }

    /// Feature names, sorted.
    pub fn names(&self) -> impl Iterator<Item = &'a str> + '_ {
        self.map.keys().copied()
    }
}

impl<'a> FromIterator<(&'a str, &'a [f32])> for NamedInputs<'a> {
    fn from_iter<I: IntoIterator<Item = (&'a str, &'a [f32])>>(iter: I) -> Self {
        Self {
            map: iter.into_iter().collect(),
        }
    }
}

/// The policy's plan from one control tick on, in SI units: row 0 is the action for `start`,
/// row r for `start + r * period_ns`. Every value is finite and within its action's bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct ActionChunk {
    /// Action names (A), e.g. "gripper.opening".
    pub names: Vec<String>,
    /// SI unit of each action.
    pub units: Vec<String>,
    /// Rows x A values, row-major.
    pub data: Vec<f32>,
    /// The tick's stamp (the `t` given to `act`).
    pub start: Stamp,
    /// Control period \[ns].
    pub period_ns: i64,
    /// Whether this call ran the model (false: the rows come from earlier inferences).
    pub inferred: bool,
    /// Values the model predicted outside their bounds and that were clamped to them, in the
    /// inference this call ran (0 when it ran none).
    pub clamped: usize,
    /// Actions (indices into `names`) the inference this call ran predicted beyond a bound by
    /// more than [`super::policy::FAR_FRACTION`] of the range, in any row; sorted.
    pub beyond: Vec<usize>,
}

impl ActionChunk {
    /// Actions per row (A).
    pub fn width(&self) -> usize {
        self.names.len()
    }

    /// Rows from `start` on.
    pub fn rows(&self) -> usize {
        self.data.len().checked_div(self.width()).unwrap_or(0)
    }

    /// Row `r` (the action for `start + r` ticks).
    pub fn row(&self, r: usize) -> Option<&[f32]> {
        let a = self.width();
        self.data.get(r * a..(r + 1) * a)
    }

    /// The value of action `name` for this tick (row 0).
    pub fn now(&self, name: &str) -> Option<f32> {
        let j = self.names.iter().position(|n| n == name)?;
        self.data.get(j).copied()
    }
}
