//! Scene controllers: explicit state machines implementing [`crate::policy::Policy`], one per
//! task family. Their phase is PolicyStatus.phase. They see observations only (never ground
//! truth) and know time only through the observation's stamp.

pub mod cup;
pub mod fabric;

use crate::policy::{Action, ArmAction, GripperAction};
use unitac_core::Stamp;
use unitac_core::msg::GripperMode;

pub use cup::CupController;
pub use fabric::FabricController;

/// A running mean of the camera's estimates of N values of one object, one sample per camera
/// frame (a frame seen on several ticks counts once).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Estimate<const N: usize> {
    sum: [f64; N],
    frames: u32,
    last: Option<Stamp>,
}

impl<const N: usize> Default for Estimate<N> {
    fn default() -> Self {
        Self {
            sum: [0.0; N],
            frames: 0,
            last: None,
        }
    }
}

impl<const N: usize> Estimate<N> {
    pub fn add(&mut self, stamp: Stamp, values: [f64; N]) {
        if self.last.is_some_and(|s| s >= stamp) {
            return;
        }
        self.last = Some(stamp);
        for (s, v) in self.sum.iter_mut().zip(values) {
            *s += v;
        }
        self.frames += 1;
    }
    pub fn mean(&self) -> Option<[f64; N]> {
        (self.frames > 0).then(|| self.sum.map(|s| s / f64::from(self.frames)))
    }
}

/// A phase and when it began.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Timed<P> {
    pub phase: P,
    pub since: Option<Stamp>,
}

impl<P: Copy + PartialEq> Timed<P> {
    pub fn new(phase: P) -> Self {
        Self { phase, since: None }
    }
    /// Seconds in the current phase at `now` (its first tick is 0).
    pub fn elapsed(&mut self, now: Stamp) -> f64 {
        let since = *self.since.get_or_insert(now);
        now.secs_since(since).max(0.0)
    }
    pub fn go(&mut self, phase: P) {
        self.phase = phase;
        self.since = None;
    }
}

pub(crate) fn arm(target: &str, [x_m, y_m]: [f64; 2], z_m: f64, lift_m: f64) -> ArmAction {
    ArmAction {
        target: target.to_string(),
        x_m,
        y_m,
        z_m,
        lift_m,
    }
}

pub(crate) fn position(position_m: f64, speed_m_s: f64, force_n: f64) -> GripperAction {
    GripperAction {
        mode: GripperMode::Position,
        position_m,
        speed_m_s,
        force_n,
    }
}

pub(crate) fn force(toward_m: f64, speed_m_s: f64, force_n: f64) -> GripperAction {
    GripperAction {
        mode: GripperMode::Force,
        position_m: toward_m,
        speed_m_s,
        force_n,
    }
}

pub(crate) fn action(gripper: GripperAction, arm: ArmAction, note: impl Into<String>) -> Action {
    Action {
        gripper,
        arm,
        note: note.into(),
    }
}
