//! Cup deformation: grasp a cup and squeeze its diameter by the target deformation d (1 cm by
//! default, the task may say otherwise), hold, lift. Each mode maps its observations to the
//! squeeze differently:
//!
//! ```text
//! vla:       approach (the camera's cup_width_m W, averaged over the approach) -> close
//!            (vla_rule position: to W + 2 pad - d - vla_offset_m, the gel surfaces at W - d,
//!            less the gels' own give, calibrated on training cups; vla_rule force: force mode,
//!            F = k(W) d, the stiffness the camera's width says by a law fitted on training
//!            cups) -> hold -> lift -> done
//! vtla_real: approach -> close (lightly, each tick to probe_release_m inside the measured
//!            opening, until the contact state says contact: D0 = opening)
//!            -> probe (press to D0 - probe_press_m for probe_press_s, then open to
//!            D0 + probe_release_m until the contact ends, so the episode's latent is encoded) -> await_latent (stiffness k from the live latent: force cap
//!            k d force_margin) -> squeeze (toward D0 - d - gel indentation; compression =
//!            D0 - opening - gel_indent_m_per_m2 x area growth, live) -> hold -> lift -> done
//! vtla_pred: approach (stiffness k from the predicted latent, before any touch: force F = k d,
//!            computed once) -> close (force mode, F) -> hold -> lift -> done
//! any phase -> failed (a timeout): the error goes to the safety layer every tick
//! ```
//! Every mode aims the fingertips where the camera saw the cup (`cup_x_m`, `cup_y_m`, averaged
//! over the approach and kept from then on), never at its true place.
//!
//! vtla_real's close asks for an opening just inside the measured one, never for the closed
//! gripper: the safety layer moves a command at most `max_step_m` per tick, so from a command of
//! the closed gripper the probe's release would take many ticks to come back, and the fingers
//! would press on meanwhile (several mm into the cup, a touch the stiffness readout was never
//! fitted on). Closing by a lead of `probe_release_m`, the release is one step, and the touch is
//! the demonstrations' touch (which close at the same speed without a safety layer).
//!
//! The stiffness a mode reads goes into its status message as `stiffness K N/m`
//! ([`stiffness_in`] reads it back), and a reading the readout had to clip to its range is
//! reported as clamped (`readout.stiffness`).

use super::{Estimate, Timed, action, arm, force, position};
use crate::mode::Mode;
use crate::observation::Observation;
use crate::params::{PolicyParams, VlaRule};
use crate::policy::{Action, GripperAction, Policy, PolicyError};
use crate::readout::Readout;
use unitac_core::Stamp;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Approach,
    Close,
    Probe,
    AwaitLatent,
    Squeeze,
    Hold,
    Lift,
    Done,
    Failed,
}

#[derive(Debug)]
pub struct CupController {
    p: PolicyParams,
    mode: Mode,
    /// Target loss of diameter \[m].
    d: f64,
    t: Timed<Phase>,
    /// vla: W - d; vtla_real: the opening where the squeeze stopped.
    target_opening: Option<f64>,
    /// vtla_pred: F = k d; vtla_real: the force cap k d margin.
    force_n: Option<f64>,
    /// vtla_real: opening and contact area at first contact, and when the probe began.
    d0: Option<(f64, f64)>,
    probe_at: Option<Stamp>,
    /// Last compression estimate \[m] (vtla_real).
    compression: f64,
    failure: Option<PolicyError>,
    /// Latent -> stiffness (the params' linear readout or a fitted model).
    readout: Readout,
    /// The stiffness read \[N/m] (vtla_real: of the probe touch; vtla_pred: the last prediction).
    stiffness: Option<f64>,
    /// vla's force rule: the camera's width the stiffness was read from \[m].
    camera_width: Option<f64>,
    /// The camera's cup: x, y and width, averaged over the approach.
    seen: Estimate<3>,
    /// Clamps inside the controller since the stage last asked.
    clamped: Vec<&'static str>,
}

impl CupController {
    /// `by_m`: the deformation the task names (None: the params').
    pub fn new(p: &PolicyParams, by_m: Option<f64>) -> Self {
        Self {
            mode: p.mode,
            d: by_m.unwrap_or(p.target_deformation_m),
            t: Timed::new(Phase::Approach),
            target_opening: None,
            force_n: None,
            d0: None,
            probe_at: None,
            compression: 0.0,
            failure: None,
            readout: Readout::Linear,
            stiffness: None,
            camera_width: None,
            seen: Estimate::default(),
            clamped: Vec::new(),
            p: p.clone(),
        }
    }

    /// Where the camera saw the cup (the origin before any frame; no tick asks before one).
    fn place(&self) -> [f64; 2] {
        self.seen.mean().map_or([0.0, 0.0], |[x, y, _]| [x, y])
    }

    /// Whether the squeeze is a force-mode close to `force_n` (vtla_pred, and vla's force rule).
    fn by_force(&self) -> bool {
        self.mode == Mode::VtlaPred || (self.mode == Mode::Vla && self.p.vla_rule == VlaRule::Force)
    }

    /// vla's force rule: the stiffness the camera's width `w` says \[N/m], clamped to the
    /// params' range (the clamp noted).
    fn camera_stiffness(&mut self, w: f64) -> f64 {
        let p = &self.p;
        let k = p.vla_stiffness_at_80mm_n_per_m * (w / 0.08).powf(p.vla_stiffness_exponent);
        let (lo, hi) = (p.min_stiffness_n_per_m, p.max_stiffness_n_per_m);
        if !(lo..=hi).contains(&k) {
            self.clamped.push("readout.stiffness");
        }
        let k = if k.is_finite() { k.clamp(lo, hi) } else { hi };
        self.stiffness = Some(k);
        k
    }

    /// The stiffness of latent `l`, its clamp noted.
    fn stiffness(
        &mut self,
        p: &PolicyParams,
        l: &unitac_core::msg::TactileLatent,
        now: Stamp,
    ) -> Result<f64, PolicyError> {
        let (k, clamped) = self.readout.stiffness(p, l, now)?;
        if clamped {
            self.clamped.push("readout.stiffness");
        }
        self.stiffness = Some(k);
        Ok(k)
    }

    /// The stiffness from `readout` instead of the params' linear one.
    pub fn with_readout(mut self, readout: Readout) -> Self {
        self.readout = readout;
        self
    }

    fn fail(&mut self, e: PolicyError) -> PolicyError {
        self.t.go(Phase::Failed);
        self.failure = Some(e.clone());
        e
    }

    fn timeout(&mut self, what: &str) -> PolicyError {
        let e = PolicyError::Timeout(format!("{what} within {} s", self.p.contact_timeout_s));
        self.fail(e)
    }

    /// Approach: the camera's cup (its mean over the approach) and, in VTLA-pred, the predicted
    /// stiffness; at the end of the approach VLA sets its target from the camera's width.
    fn approach(
        &mut self,
        obs: &Observation,
        p: &PolicyParams,
        elapsed: f64,
        now: Stamp,
    ) -> Result<(), PolicyError> {
        let v = obs
            .visual()
            .ok_or_else(|| PolicyError::Failed("no fresh visual observation".into()))?;
        let read = |n: &str| v.get(n).filter(|x| x.is_finite());
        let (Some(x), Some(y), Some(w)) = (read("cup_x_m"), read("cup_y_m"), read("cup_width_m"))
        else {
            return Err(self.fail(PolicyError::Failed(
                "the camera gives no cup_x_m / cup_y_m / cup_width_m (list them in \
                 visual_names)"
                    .into(),
            )));
        };
        self.seen.add(v.header.stamp, [x, y, w]);
        if self.mode == Mode::VtlaPred {
            let l = obs
                .latent()
                .ok_or_else(|| PolicyError::Failed("no fresh predicted latent".into()))?;
            self.force_n = Some(self.stiffness(p, l, now)? * self.d);
        }
        if elapsed >= p.approach_s {
            if self.mode == Mode::Vla {
                let w = self.seen.mean().map_or(p.limits.max_opening_m, |m| m[2]);
                match p.vla_rule {
                    VlaRule::Position => {
                        self.target_opening = Some(w + 2.0 * p.pad_m - self.d - p.vla_offset_m);
                    }
                    VlaRule::Force => {
                        self.force_n = Some(self.camera_stiffness(w) * self.d);
                        self.camera_width = Some(w);
                    }
                }
            }
            self.t.go(Phase::Close);
        }
        Ok(())
    }

    fn step(&mut self, obs: &Observation) -> Result<(), PolicyError> {
        let now = obs.stamp;
        let elapsed = self.t.elapsed(now);
        let p = self.p.clone();
        let g = obs.gripper();
        let opening = g.map(|g| g.opening_m);
        let contact = obs.contact();
        match self.t.phase {
            Phase::Approach => self.approach(obs, &p, elapsed, now)?,
            Phase::Close => match self.mode {
                Mode::Vla if !self.by_force() => {
                    let target = self.target_opening.unwrap_or(p.limits.max_opening_m);
                    let tol = p.deformation_tolerance_m / 2.0;
                    // Arrived, or stopped on the cup short of the target (the gripper's own
                    // object detection: what a position-controlled close on a real gripper ends on).
                    let stopped = g.is_some_and(|g| g.object_detected && g.motion != "moving");
                    if opening.is_some_and(|o| (o - target).abs() <= tol) || stopped {
                        self.t.go(Phase::Hold);
                    } else if elapsed >= p.contact_timeout_s {
                        return Err(self.timeout("the fingers did not reach the camera's target"));
                    }
                }
                Mode::Vla | Mode::VtlaPred => {
                    let f = self.force_n.unwrap_or(0.0);
                    // An object detected and the fingers no longer moving: the motion word is
                    // the driver's own ("stopped" from the sim, "caught" from the Robotiq and DH
                    // drivers, whose force is unknown), so only "moving" is ruled out.
                    let held = g.is_some_and(|g| {
                        (g.force_n.is_finite() && g.force_n >= 0.95 * f)
                            || (g.object_detected && g.motion != "moving")
                    });
                    if held {
                        self.t.go(Phase::Hold);
                    } else if elapsed >= p.contact_timeout_s {
                        return Err(self.timeout("the grip force was not reached"));
                    }
                }
                Mode::VtlaReal => match (contact, opening) {
                    (Some(c), Some(o)) if c.in_contact => {
                        self.d0 = Some((o, f64::from(c.area_m2)));
                        self.probe_at = Some(now);
                        self.t.go(Phase::Probe);
                    }
                    _ if elapsed >= p.contact_timeout_s => {
                        return Err(self.timeout("no contact with the cup"));
                    }
                    _ => {}
                },
            },
            Phase::Probe => {
                let pressed = elapsed >= p.probe_press_s;
                if pressed && contact.is_some_and(|c| !c.in_contact) {
                    self.t.go(Phase::AwaitLatent);
                } else if elapsed >= p.contact_timeout_s {
                    return Err(self.timeout("the probe contact did not end"));
                }
            }
            Phase::AwaitLatent => {
                let after = self.probe_at.unwrap_or(Stamp::ZERO);
                if let Some(l) = obs.latent().filter(|l| l.header.stamp >= after) {
                    let l = l.clone();
                    self.force_n = Some(self.stiffness(&p, &l, now)? * self.d * p.force_margin);
                    self.t.go(Phase::Squeeze);
                } else if elapsed >= p.contact_timeout_s {
                    return Err(self.timeout("no latent of the probe touch"));
                }
            }
            Phase::Squeeze => {
                let (d0, a0) = self.d0.unwrap_or((p.limits.max_opening_m, 0.0));
                if let (Some(c), Some(o)) = (contact, opening) {
                    let gel = p.gel_indent_m_per_m2 * (f64::from(c.area_m2) - a0).max(0.0);
                    self.compression = if c.in_contact { d0 - o - gel } else { 0.0 };
                    if self.compression >= self.d - p.deformation_tolerance_m / 2.0 {
                        self.target_opening = Some(o);
                        self.t.go(Phase::Hold);
                    } else if elapsed >= p.contact_timeout_s {
                        return Err(self.timeout("the target deformation was not reached"));
                    }
                }
            }
            Phase::Hold => {
                if elapsed >= p.hold_s {
                    self.t.go(Phase::Lift);
                }
            }
            Phase::Lift => {
                if elapsed * p.lift_speed_m_s >= p.lift_m {
                    self.t.go(Phase::Done);
                }
            }
            Phase::Done | Phase::Failed => {}
        }
        Ok(())
    }

    /// The grip once the squeeze is over.
    fn hold(&self) -> GripperAction {
        let p = &self.p;
        match self.by_force() {
            true => force(
                p.limits.min_opening_m,
                p.squeeze_speed_m_s,
                self.force_n.unwrap_or(0.0),
            ),
            false => position(
                self.target_opening.unwrap_or(p.limits.max_opening_m),
                p.squeeze_speed_m_s,
                self.force_n.unwrap_or(p.limits.max_force_n),
            ),
        }
    }

    fn command(&mut self, obs: &Observation) -> Action {
        let p = self.p.clone();
        let elapsed = self.t.elapsed(obs.stamp);
        let place = self.place();
        let at = |lift: f64| arm("cup", place, p.cup_z_m, lift);
        match self.t.phase {
            Phase::Approach => {
                // Every mode opens to the camera's width plus the pads and a margin on the way,
                // so that no mode spends its closing time on air.
                let pre = self.seen.mean().map_or(p.limits.max_opening_m, |m| {
                    (m[2] + 2.0 * p.pad_m + p.pregrasp_margin_m).min(p.limits.max_opening_m)
                });
                action(
                    position(pre, p.limits.max_speed_m_s, p.touch_force_n),
                    at(0.0),
                    format!("approaching the cup, fingers at {pre:.4} m"),
                )
            }
            Phase::Close => match self.mode {
                Mode::Vla if !self.by_force() => {
                    let t = self.target_opening.unwrap_or(p.limits.max_opening_m);
                    action(
                        position(t, p.squeeze_speed_m_s, p.limits.max_force_n),
                        at(0.0),
                        format!(
                            "closing to {t:.4} m (camera width + pads - {:.4} m - {:.4} m)",
                            self.d, p.vla_offset_m
                        ),
                    )
                }
                Mode::Vla | Mode::VtlaPred => {
                    let f = self.force_n.unwrap_or(0.0);
                    // Where the stiffness came from: the camera's width or the predicted touch.
                    let from = match self.camera_width {
                        Some(w) => format!("camera width {w:.4} m: stiffness"),
                        None => "predicted stiffness".into(),
                    };
                    action(
                        force(p.limits.min_opening_m, p.squeeze_speed_m_s, f),
                        at(0.0),
                        format!(
                            "squeezing with {f:.2} N ({from} {:.1} N/m x {:.4} m)",
                            self.stiffness.unwrap_or(f64::NAN),
                            self.d
                        ),
                    )
                }
                Mode::VtlaReal => {
                    // Just inside the measured opening: the release after contact is one step.
                    let o = obs
                        .gripper()
                        .map_or(p.limits.max_opening_m, |g| g.opening_m);
                    let t = (o - p.probe_release_m).max(p.limits.min_opening_m);
                    action(
                        position(t, p.touch_speed_m_s, p.touch_force_n),
                        at(0.0),
                        format!("closing until contact, fingers to {t:.4} m"),
                    )
                }
            },
            Phase::Probe | Phase::AwaitLatent => {
                let (d0, _) = self.d0.unwrap_or((p.limits.max_opening_m, 0.0));
                if self.t.phase == Phase::Probe && elapsed < p.probe_press_s {
                    let t = (d0 - p.probe_press_m).max(p.limits.min_opening_m);
                    action(
                        position(t, p.touch_speed_m_s, p.touch_force_n),
                        at(0.0),
                        format!("probe press to {t:.4} m from first contact at {d0:.4} m"),
                    )
                } else {
                    action(
                        position(d0 + p.probe_release_m, p.touch_speed_m_s, p.touch_force_n),
                        at(0.0),
                        format!("probe touch at {d0:.4} m, waiting for its latent"),
                    )
                }
            }
            Phase::Squeeze => {
                let (d0, a0) = self.d0.unwrap_or((p.limits.max_opening_m, 0.0));
                let area = obs.contact().map_or(a0, |c| f64::from(c.area_m2));
                let gel = p.gel_indent_m_per_m2 * (area - a0).max(0.0);
                let f = self.force_n.unwrap_or(p.touch_force_n);
                action(
                    position(d0 - self.d - gel, p.squeeze_speed_m_s, f),
                    at(0.0),
                    format!(
                        "squeezing: compression {:.4} of {:.4} m ({f:.2} N cap, stiffness {:.1} N/m)",
                        self.compression,
                        self.d,
                        self.stiffness.unwrap_or(f64::NAN)
                    ),
                )
            }
            Phase::Hold => action(self.hold(), at(0.0), "holding the squeeze"),
            Phase::Lift => action(
                self.hold(),
                at((elapsed * p.lift_speed_m_s).min(p.lift_m)),
                "lifting the cup",
            ),
            Phase::Done | Phase::Failed => action(self.hold(), at(p.lift_m), "cup lifted"),
        }
    }
}

/// The stiffness \[N/m] a cup controller's status message names (`stiffness K N/m`), if any.
pub fn stiffness_in(message: &str) -> Option<f64> {
    value_in(message, "stiffness ", " N/m")
}

/// The camera width \[m] vla's force rule read its stiffness from (`camera width W m`), if any.
pub fn camera_width_in(message: &str) -> Option<f64> {
    value_in(message, "camera width ", " m")
}

fn value_in(message: &str, key: &str, unit: &str) -> Option<f64> {
    let (_, rest) = message.split_once(key)?;
    let (v, _) = rest.split_once(unit)?;
    v.parse().ok().filter(|v: &f64| v.is_finite())
}

impl Policy for CupController {
    fn phase(&self) -> &str {
        match self.t.phase {
            Phase::Approach => "approach",
            Phase::Close => "close",
            Phase::Probe => "probe",
            Phase::AwaitLatent => "await_latent",
            Phase::Squeeze => "squeeze",
            Phase::Hold => "hold",
            Phase::Lift => "lift",
            Phase::Done => "done",
            Phase::Failed => "failed",
        }
    }

    fn required(&self) -> Vec<&'static str> {
        let mut r = vec!["gripper"];
        match (self.t.phase, self.mode) {
            (Phase::Approach, Mode::VtlaPred) => {
                r.push("visual");
                r.push("latent_pred");
            }
            (Phase::Approach, _) => r.push("visual"),
            (Phase::Close | Phase::Probe | Phase::Squeeze, Mode::VtlaReal) => r.push("contact"),
            _ => {}
        }
        r
    }

    fn awaited(&self) -> Vec<&'static str> {
        let mut r = self.required();
        // The latent that sets the squeeze force: its producer must be alive until it came.
        let waiting = matches!(
            self.t.phase,
            Phase::Approach | Phase::Close | Phase::Probe | Phase::AwaitLatent
        );
        match self.mode {
            Mode::VtlaReal if waiting => r.push("latent_real"),
            Mode::VtlaPred if self.t.phase == Phase::Approach && !r.contains(&"latent_pred") => {
                r.push("latent_pred");
            }
            _ => {}
        }
        r
    }

    fn act(&mut self, obs: &Observation) -> Result<Vec<Action>, PolicyError> {
        if let Some(e) = &self.failure {
            return Err(e.clone());
        }
        self.step(obs)?;
        Ok(vec![self.command(obs)])
    }

    fn take_clamped(&mut self) -> Vec<&'static str> {
        std::mem::take(&mut self.clamped)
    }
}
