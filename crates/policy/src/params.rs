//! The policy stage's typed parameters (`kind: policy` in a scene; every key is also a
//! `policy.<key>` override). Flat on purpose: each key is one ROS parameter.

use crate::error::Problems;
use crate::mode::Mode;
use crate::observation::Layout;
use crate::safety::{Bounds, SafeAction};
use crate::schema;
use crate::task::Task;
use serde::{Deserialize, Serialize};
use unitac_core::profile::GripperProfile;

/// Most values in `observation.tactile_latent` (a latent is at most this long).
pub const MAX_LATENT_LEN: usize = 1 << 16;
/// Most objects or visual names a scene lists.
pub const MAX_NAMES: usize = 64;
/// The control rate's range \[Hz] (the scene's `control_rate_hz`, and an ONNX policy's).
pub const MIN_CONTROL_RATE_HZ: f64 = 0.1;
pub const MAX_CONTROL_RATE_HZ: f64 = 1000.0;
/// An inference's default time limit, in control periods: a model that needs longer has
/// missed ticks already; a model of tens of microseconds stays within it on a loaded machine,
/// so results do not depend on the load.
pub const DEFAULT_BUDGET_PERIODS: f64 = 3.0;
/// The range of `inference_budget_s` \[s].
pub const MIN_INFERENCE_BUDGET_S: f64 = 0.001;
pub const MAX_INFERENCE_BUDGET_S: f64 = 10.0;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PolicyParams {
    /// vla | vtla_real | vtla_pred.
    pub mode: Mode,
    /// scripted (the task's scene controller) | learned (the ONNX policy bundle the stage's
    /// `models:` names, trained on demonstrations: src/learned.rs).
    pub policy: PolicyKind,
    /// A learned policy reports done this long after its first tick (a timeout, which every
    /// mode observes) \[s].
    pub run_s: f64,
    /// The task string (grammar in task.rs); it also picks the scene controller.
    pub task: String,
    /// Control ticks per second: a GripperStatus closer than 0.9 / rate to the last tick is
    /// not a tick. [`MIN_CONTROL_RATE_HZ`]..=[`MAX_CONTROL_RATE_HZ`].
    pub control_rate_hz: f64,
    /// Wall-clock time one inference of an ONNX policy may take \[s]; a call still running then
    /// is stopped and its tick gets the safe action (`policy: inference over budget: ...`).
    /// None: [`DEFAULT_BUDGET_PERIODS`] control periods. [`MIN_INFERENCE_BUDGET_S`]..=
    /// [`MAX_INFERENCE_BUDGET_S`].
    pub inference_budget_s: Option<f64>,
    /// Freshness budgets per input \[s].
    pub budget_gripper_s: f64,
    pub budget_contact_s: f64,
    pub budget_latent_s: f64,
    pub budget_comparison_s: f64,
    pub budget_visual_s: f64,
    /// The gripper's profile (`grippers/<name>.yaml`, `unitac_core::profile`), empty for none:
    /// when named, the command bounds below are held inside its stroke, strongest grip and
    /// fastest speed, and `stroke_m` is its stroke.
    pub gripper: String,
    /// Bounds of every command, the scene's keys (`min_opening_m`, `max_force_n`, ...,
    /// `objects`): [`Self::bounds`] holds them inside the gripper's when `gripper` names one.
    #[serde(flatten)]
    pub limits: Bounds,
    /// The gripper's full stroke \[m] (not a command bound: the scene's `max_opening_m` may be
    /// narrower): a GripperStatus reporting an opening outside [0, stroke_m] is an invalid
    /// input. The default is the widest shipped profile's; a named `gripper` replaces it.
    pub stroke_m: f64,
    /// hold | open.
    pub safe_action: SafeAction,
    /// Force limit of the hold safe action \[N].
    pub hold_force_n: f64,
    /// The tactile reflex (src/reflex.rs): on slip while holding or lifting, raise the grip
    /// force by `reflex_force_step_n` per tick (to `max_force_n`), close a position-mode grip by
    /// `reflex_squeeze_m`, stop the lift; with `confirm_grasp`, hold a lift while the gripper's
    /// object-detect and the tactile contact do not both report the object.
    pub reflex: bool,
    pub reflex_force_step_n: f64,
    pub reflex_squeeze_m: f64,
    pub confirm_grasp: bool,
    /// Values in `observation.tactile_latent` (0 for vla).
    pub latent_len: usize,
    /// Names read from the VisualObservation into `observation.visual`.
    pub visual_names: Vec<String>,
    /// Time the arm gets to reach a target \[s].
    pub approach_s: f64,
    /// Fabric: fingertip height when touching / grasping, relative to the camera's estimate of
    /// the object's folded-edge height (`<object>_edge_height_m`, which `visual_names` must
    /// list), negative = below its top \[m]. Touch: 1 mm below, two of the camera's 0.5 mm
    /// sigmas, to meet the fabric whatever it is; grasp: 0.35 mm below, half the thinnest layer
    /// a towel-like fabric has (linen, 0.7 mm), so the fingers aim into the top layer only.
    pub touch_z_m: f64,
    pub grasp_z_m: f64,
    /// Closing speed while looking for contact \[m/s] and its force limit \[N].
    pub touch_speed_m_s: f64,
    pub touch_force_n: f64,
    /// How long a touch is held once in contact \[s].
    pub touch_hold_s: f64,
    /// Longest wait for contact, for the comparison, for a grasp to close \[s].
    pub contact_timeout_s: f64,
    pub compare_timeout_s: f64,
    /// Grip force of the fabric grasp \[N].
    pub grasp_force_n: f64,
    /// Lift height and speed after a grasp \[m], \[m/s].
    pub lift_m: f64,
    pub lift_speed_m_s: f64,
    /// Cup: loss of diameter to reach \[m] (the task may name another) and its tolerance \[m].
    pub target_deformation_m: f64,
    pub deformation_tolerance_m: f64,
    /// Cup: fingertip height at the grasp \[m], squeeze speed \[m/s], hold before lifting \[s].
    pub cup_z_m: f64,
    pub squeeze_speed_m_s: f64,
    pub hold_s: f64,
    /// Cup, vtla_real: opening added back after the probe touch to end its contact \[m].
    pub probe_release_m: f64,
    /// Cup, vtla_real: the probe's press after first contact: the opening closed further from
    /// the contact opening \[m], held this long \[s] before the release. A press the sensor sees
    /// as a steady image: a mere touch lasts a few frames, and what it shows depends on where
    /// the frames fall in it more than on the cup.
    pub probe_press_m: f64,
    pub probe_press_s: f64,
    /// Cup, vtla_real: gel indentation per square metre of contact area growth [m/m^2]
    /// (20 m/m^2 = 20 um per mm^2), subtracted from the finger travel to estimate the cup's own
    /// compression.
    pub gel_indent_m_per_m2: f64,
    /// Latent -> stiffness readout \[N/m]: bias + weights . (latent averaged over its leading
    /// dimension), clamped to [min, max]. Empty weights: the bias (a prior) alone.
    pub stiffness_bias_n_per_m: f64,
    pub stiffness_weights: Vec<f64>,
    pub min_stiffness_n_per_m: f64,
    pub max_stiffness_n_per_m: f64,
    /// Force cap of the squeeze = stiffness x deformation x this margin.
    pub force_margin: f64,
    /// Gel pad thickness per finger \[m]: openings are between the finger bodies, the gel
    /// surfaces meet at 2 x this (the gripper's geometry, known to every mode).
    pub pad_m: f64,
    /// Cup, vla: the closing rule's offset \[m] (the gels' own give at the squeeze), calibrated
    /// on the training cups alone (`unitac-lab trials --scene cup_deformation --modes vla --train
    /// --calibrate-vla`).
    pub vla_offset_m: f64,
    /// Cup, vla: which camera-only rule squeezes the cup: `position` (close to the camera's
    /// width + pads - d - `vla_offset_m`) or `force` (squeeze with F = k(W) d, the stiffness from
    /// the camera's width W by `vla_stiffness_at_80mm_n_per_m` x (W / 80 mm)^`vla_stiffness_exponent`,
    /// both fitted on the training cups alone: `unitac-lab trials --scene cup_deformation --modes
    /// vla --train --calibrate-vla`). The force rule is vtla_pred's squeeze with the camera's
    /// stiffness in place of the predicted touch's.
    pub vla_rule: VlaRule,
    pub vla_stiffness_at_80mm_n_per_m: f64,
    pub vla_stiffness_exponent: f64,
    /// Cup: the fingers open to the camera's width + 2 pads + this on the way to the cup \[m]
    /// (clears it with the camera's size and place errors: 2 cm against their ~4 mm).
    pub pregrasp_margin_m: f64,
}

/// The cup VLA mode's closing rule (see [`PolicyParams::vla_rule`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VlaRule {
    #[default]
    Position,
    Force,
}

impl VlaRule {
    pub fn as_str(self) -> &'static str {
        match self {
            VlaRule::Position => "position",
            VlaRule::Force => "force",
        }
    }
}

/// Which policy the stage runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PolicyKind {
    /// The task's scene controller (src/controller).
    Scripted,
    /// An ONNX policy learned from demonstrations (src/learned.rs).
    Learned,
}

impl Default for PolicyParams {
    fn default() -> Self {
        Self {
            mode: Mode::VtlaReal,
            policy: PolicyKind::Scripted,
            run_s: 30.0,
            task: "pick the smoother fabric".into(),
            control_rate_hz: 30.0,
            inference_budget_s: None,
            budget_gripper_s: 0.2,
            budget_contact_s: 0.25,
            budget_latent_s: 60.0,
            budget_comparison_s: 600.0,
            budget_visual_s: 0.5,
            gripper: String::new(),
            limits: Bounds::default(),
            stroke_m: unitac_core::profile::SHIPPED_GRIPPERS
                .iter()
                .map(|p| p.stroke_m)
                .fold(0.0, f64::max),
            safe_action: SafeAction::Hold,
            hold_force_n: 5.0,
            reflex: true,
            reflex_force_step_n: 1.0,
            reflex_squeeze_m: 0.0005,
            confirm_grasp: true,
            latent_len: 0,
            visual_names: Vec::new(),
            approach_s: 0.5,
            touch_z_m: -0.001,
            grasp_z_m: -0.00035,
            touch_speed_m_s: 0.01,
            touch_force_n: 3.0,
            touch_hold_s: 1.0,
            contact_timeout_s: 8.0,
            compare_timeout_s: 10.0,
            grasp_force_n: 15.0,
            lift_m: 0.05,
            lift_speed_m_s: 0.05,
            target_deformation_m: 0.01,
            deformation_tolerance_m: 0.002,
            cup_z_m: 0.04,
            squeeze_speed_m_s: 0.005,
            hold_s: 1.0,
            probe_release_m: 0.002,
            probe_press_m: 0.002,
            probe_press_s: 0.4,
            gel_indent_m_per_m2: 20.0,
            stiffness_bias_n_per_m: schema::STIFFNESS_PRIOR_N_PER_M,
            stiffness_weights: Vec::new(),
            min_stiffness_n_per_m: schema::STIFFNESS_MIN_N_PER_M,
            max_stiffness_n_per_m: schema::STIFFNESS_MAX_N_PER_M,
            force_margin: 1.5,
            pad_m: 0.003,
            vla_offset_m: 0.0,
            vla_rule: VlaRule::Position,
            // The thin-ring law of a paper cup (lateral stiffness ~ 1 / d^3) as the prior.
            vla_stiffness_at_80mm_n_per_m: 300.0,
            vla_stiffness_exponent: -3.0,
            pregrasp_margin_m: 0.02,
        }
    }
}

impl PolicyParams {
    /// The numeric settings' rules (positive, non-negative, within their ranges), each broken
    /// one a line in `bad`.
    fn range_problems(&self, bad: &mut Vec<String>) {
        let positive = [
            ("budget_gripper_s", self.budget_gripper_s),
            ("budget_contact_s", self.budget_contact_s),
            ("budget_latent_s", self.budget_latent_s),
            ("budget_comparison_s", self.budget_comparison_s),
            ("budget_visual_s", self.budget_visual_s),
            ("contact_timeout_s", self.contact_timeout_s),
            ("compare_timeout_s", self.compare_timeout_s),
            ("lift_speed_m_s", self.lift_speed_m_s),
            ("touch_speed_m_s", self.touch_speed_m_s),
            ("squeeze_speed_m_s", self.squeeze_speed_m_s),
            ("target_deformation_m", self.target_deformation_m),
            ("deformation_tolerance_m", self.deformation_tolerance_m),
            ("min_stiffness_n_per_m", self.min_stiffness_n_per_m),
            ("stroke_m", self.stroke_m),
            ("force_margin", self.force_margin),
            ("run_s", self.run_s),
        ];
        for (k, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                bad.push(format!("{k} = {v} must be finite and > 0"));
            }
        }
        let non_negative = [
            ("hold_force_n", self.hold_force_n),
            ("reflex_force_step_n", self.reflex_force_step_n),
            ("reflex_squeeze_m", self.reflex_squeeze_m),
            ("approach_s", self.approach_s),
            ("touch_force_n", self.touch_force_n),
            ("touch_hold_s", self.touch_hold_s),
            ("grasp_force_n", self.grasp_force_n),
            ("lift_m", self.lift_m),
            ("cup_z_m", self.cup_z_m),
            ("hold_s", self.hold_s),
            ("probe_release_m", self.probe_release_m),
            ("probe_press_m", self.probe_press_m),
            ("probe_press_s", self.probe_press_s),
            ("gel_indent_m_per_m2", self.gel_indent_m_per_m2),
            ("stiffness_bias_n_per_m", self.stiffness_bias_n_per_m),
            ("pad_m", self.pad_m),
            ("pregrasp_margin_m", self.pregrasp_margin_m),
        ];
        if !(self.vla_stiffness_at_80mm_n_per_m.is_finite()
            && self.vla_stiffness_at_80mm_n_per_m > 0.0
            && self.vla_stiffness_exponent.is_finite()
            && self.vla_stiffness_exponent.abs() <= 10.0)
        {
            bad.push(format!(
                "vla_stiffness_at_80mm_n_per_m = {} must be finite and > 0, vla_stiffness_exponent = {} finite and within +-10",
                self.vla_stiffness_at_80mm_n_per_m, self.vla_stiffness_exponent
            ));
        }
        if !(self.vla_offset_m.is_finite() && self.vla_offset_m.abs() <= 1.0) {
            bad.push(format!(
                "vla_offset_m = {} must be finite and within +-1 m",
                self.vla_offset_m
            ));
        }
        for (k, v) in [("touch_z_m", self.touch_z_m), ("grasp_z_m", self.grasp_z_m)] {
            if !(v.is_finite() && v.abs() <= self.limits.max_z_m.abs()) {
                bad.push(format!("{k} = {v} must be finite and within +-max_z_m"));
            }
        }
        for (k, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                bad.push(format!("{k} = {v} must be finite and >= 0"));
            }
        }
        if !(self.max_stiffness_n_per_m.is_finite()
            && self.max_stiffness_n_per_m >= self.min_stiffness_n_per_m)
        {
            bad.push("max_stiffness_n_per_m must be finite and >= min_stiffness_n_per_m".into());
        }
        if self.stiffness_weights.iter().any(|w| !w.is_finite())
            || self.stiffness_weights.len() > MAX_LATENT_LEN
        {
            bad.push(format!(
                "stiffness_weights must be finite, at most {MAX_LATENT_LEN}"
            ));
        }
        if self.latent_len > MAX_LATENT_LEN {
            bad.push(format!(
                "latent_len {} exceeds {MAX_LATENT_LEN}",
                self.latent_len
            ));
        }
    }

    /// The parsed task, the bounds and every range rule; all problems in one line.
    pub fn check(&self) -> Result<Task, Problems> {
        let mut bad = Vec::new();
        let task = Task::parse(&self.task);
        if let Err(e) = &task {
            bad.push(e.to_string());
        }
        if let Err(e) = self.profile() {
            bad.push(e.to_string());
        }
        if let Err(e) = self.bounds().check() {
            bad.extend(e.0);
        }
        if !(self.control_rate_hz.is_finite()
            && (MIN_CONTROL_RATE_HZ..=MAX_CONTROL_RATE_HZ).contains(&self.control_rate_hz))
        {
            bad.push(format!(
                "control_rate_hz = {} is outside [{MIN_CONTROL_RATE_HZ}, {MAX_CONTROL_RATE_HZ}]",
                self.control_rate_hz
            ));
        }
        if let Some(b) = self.inference_budget_s
            && !(b.is_finite() && (MIN_INFERENCE_BUDGET_S..=MAX_INFERENCE_BUDGET_S).contains(&b))
        {
            bad.push(format!(
                "inference_budget_s = {b} is outside [{MIN_INFERENCE_BUDGET_S}, {MAX_INFERENCE_BUDGET_S}]"
            ));
        }
        self.range_problems(&mut bad);
        let uses_latent = self
            .mode
            .inputs(matches!(task, Ok(Task::Pick { .. })))
            .iter()
            .any(|i| i.starts_with("latent"));
        if uses_latent && self.latent_len == 0 {
            bad.push(format!(
                "mode {} reads a tactile latent: set latent_len to its number of values",
                self.mode.as_str()
            ));
        }
        for (k, list) in [
            ("objects", &self.limits.objects),
            ("visual_names", &self.visual_names),
        ] {
            if list.len() > MAX_NAMES {
                bad.push(format!(
                    "{k} has {} names (at most {MAX_NAMES})",
                    list.len()
                ));
            }
        }
        match &task {
            Ok(Task::Pick { property, .. }) => {
                if self.limits.objects.len() < 2 {
                    bad.push("a pick task needs two objects (A and B)".into());
                } else if self.mode == Mode::Vla {
                    for o in &self.limits.objects[..2] {
                        let n = format!("{o}_{property}");
                        if !self.visual_names.contains(&n) {
                            bad.push(format!(
                                "mode vla picks from the camera: visual_names must list {n}"
                            ));
                        }
                    }
                }
            }
            Ok(Task::Squeeze { .. }) => {
                if !self.limits.objects.iter().any(|o| o == "cup") {
                    bad.push("a squeeze task needs the object 'cup' in objects".into());
                }
                if self.mode == Mode::Vla && !self.visual_names.iter().any(|n| n == "cup_width_m") {
                    bad.push(
                        "mode vla sizes the cup from the camera: visual_names must list cup_width_m"
                            .into(),
                    );
                }
            }
            Err(_) => {}
        }
        match task {
            Ok(t) if bad.is_empty() => Ok(t),
            _ => Err(Problems(bad)),
        }
    }

    /// The time limit of one inference: `inference_budget_s`, or [`DEFAULT_BUDGET_PERIODS`]
    /// control periods (within the budget's range).
    pub fn inference_budget(&self) -> std::time::Duration {
        let s = self
            .inference_budget_s
            .unwrap_or(DEFAULT_BUDGET_PERIODS / self.control_rate_hz);
        let s = if s.is_finite() {
            s
        } else {
            MAX_INFERENCE_BUDGET_S
        };
        std::time::Duration::from_secs_f64(s.clamp(MIN_INFERENCE_BUDGET_S, MAX_INFERENCE_BUDGET_S))
    }

    /// The profile `gripper` names (None: it names none).
    pub fn profile(
        &self,
    ) -> Result<Option<&'static GripperProfile>, unitac_core::profile::ProfileError> {
        if self.gripper.is_empty() {
            return Ok(None);
        }
        unitac_core::profile::gripper_profile(&self.gripper).map(Some)
    }

    /// The command bounds: the scene's, inside the named gripper's stroke, strongest grip and
    /// fastest speed (a profile that cannot be read is reported by [`Self::check`]).
    /// The gripper's stroke: the named profile's, else `stroke_m`.
    pub fn stroke(&self) -> f64 {
        match self.profile() {
            Ok(Some(p)) => p.stroke_m,
            _ => self.stroke_m,
        }
    }

    pub fn bounds(&self) -> Bounds {
        let g = self.profile().ok().flatten();
        let inside = |v: f64, limit: Option<f64>| limit.map_or(v, |l| v.min(l));
        let l = &self.limits;
        Bounds {
            max_opening_m: inside(l.max_opening_m, g.map(|p| p.stroke_m)),
            max_speed_m_s: inside(l.max_speed_m_s, g.map(|p| p.speed_m_s[1])),
            max_force_n: inside(l.max_force_n, g.map(|p| p.force_n[1])),
            ..l.clone()
        }
    }

    pub fn reflex(&self) -> crate::reflex::ReflexParams {
        crate::reflex::ReflexParams {
            enabled: self.reflex,
            force_step_n: self.reflex_force_step_n,
            squeeze_m: self.reflex_squeeze_m,
            confirm_grasp: self.confirm_grasp,
        }
    }

    pub fn layout(&self) -> Layout {
        Layout {
            latent_len: self.latent_len,
            visual_names: self.visual_names.clone(),
            stroke_m: Some(self.stroke()),
        }
    }

    /// The budget of an input by name (latent_real and latent_pred share budget_latent_s).
    pub fn budget(&self, input: &str) -> Option<f64> {
        Some(match input {
            "gripper" => self.budget_gripper_s,
            "contact" => self.budget_contact_s,
            "latent_real" | "latent_pred" => self.budget_latent_s,
            "comparison" => self.budget_comparison_s,
            "visual" => self.budget_visual_s,
            _ => return None,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn parse(yaml: &str) -> Result<PolicyParams, serde_yaml::Error> {
        serde_yaml::from_str(yaml)
    }

    #[test]
    fn defaults_check_and_errors_are_one_line_with_every_problem() {
        assert!(PolicyParams::default().check().is_ok());
        let p = parse("{task: pick the nicer fabric, max_force_n: -1, mode: vtla_pred}").unwrap();
        let e = p.check().unwrap_err().to_string();
        assert!(!e.contains('\n'));
        assert!(
            e.starts_with("task 'pick the nicer fabric' is not understood"),
            "{e}"
        );
        assert!(
            e.contains("max_force_n = -1 must be finite and >= 0"),
            "{e}"
        );
        let e = parse("{mode: vtla_pred}")
            .unwrap()
            .check()
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "mode vtla_pred reads a tactile latent: set latent_len to its number of values"
        );
        let e = parse("{mode: vla}")
            .unwrap()
            .check()
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "mode vla picks from the camera: visual_names must list fabric_a_roughness; mode vla picks from the camera: visual_names must list fabric_b_roughness"
        );
        let e = parse("{task: squeeze the cup, latent_len: 4}")
            .unwrap()
            .check()
            .unwrap_err()
            .to_string();
        assert_eq!(e, "a squeeze task needs the object 'cup' in objects");
        assert!(
            parse("{no_such_key: 1}")
                .unwrap_err()
                .to_string()
                .contains("no_such_key")
        );
        // The bounds are the scene's flat keys, typed as strictly as the rest.
        let p = parse("{max_reach_m: 0.5, objects: [cup], run_s: 9}").unwrap();
        assert_eq!((p.limits.max_reach_m, p.run_s), (0.5, 9.0));
        assert_eq!(p.limits.objects, vec!["cup".to_string()]);
        assert_eq!(p.limits.max_force_n, Bounds::default().max_force_n);
        assert!(
            parse("{max_force_n: strong}")
                .unwrap_err()
                .to_string()
                .contains("strong")
        );
        assert!(
            parse("{mode: vlx}")
                .unwrap_err()
                .to_string()
                .contains("vlx")
        );
    }
}
