//! Fabric selection: touch A, touch B, wait for the PropertyComparison, grasp the one the task
//! asks for, lift.
//!
//! ```text
//! vtla_real:
//!   approach_a -> press_a (close lightly until contact, hold touch_hold_s) -> release_a
//!   -> approach_b -> press_b -> release_b -> compare (timeout) -> approach_grasp -> grasp
//!   -> lift -> done
//!   press_x closed on nothing -> reopen_x (open where it is) -> approach_x (lower), twice
//! vla / vtla_pred:
//!   look (the camera's <object>_<property> estimates) -> approach_grasp -> grasp -> lift -> done
//! any phase -> failed (a timeout, a tie): the error goes to the safety layer every tick
//! ```
//! vtla_real touches both and chooses from the live PropertyComparison; vla and vtla_pred
//! choose from the camera before any touch. vtla_pred reads no tactile input after it starts:
//! it waits at the look for its predicted latent (sampled once, from the background frame
//! before the approach). That latent would let it compare the fabrics if it knew them, but the
//! sampler's condition does not carry the object, so it carries nothing the choice or the grasp
//! could use: vtla_pred chooses and grasps as vla does, and its row measures what touch
//! predicted without the object is worth here (nothing), not a stand-in for it.
//!
//! Places: the fingertips go where the camera saw each object (`<object>_x_m`, `<object>_y_m`),
//! averaged over the frames seen while approaching it and kept from then on; never the truth.
//! Heights: the fingertips go to the camera's estimate of the object's folded-edge height
//! (`<object>_edge_height_m`, averaged over the camera frames seen while approaching it) plus
//! `touch_z_m` for a touch and `grasp_z_m` for the grasp (offsets, negative = below the top), so
//! that the grasp aims into the top layer whatever the fold's height. The approach phases need
//! a fresh visual observation; one without the object's edge height fails the controller.
//!
//! vtla_real grasps where its touch felt the fold. Each touch presses at the camera's height
//! (`touch_z_m` below its edge estimate), and the gel image shows where the fold's top crosses
//! the gel: fabric lies only below it, so the contact (a disc about the fingertip centre, the
//! fabric over the rounded gel) is cut off at the fold's top. From the contact state's bounding
//! box ([`fold_above_centre_m`]: its top row against the fingertip centre's row) the touch
//! reads how far the fold's top is above the fingertip centre, in mm through the state's own
//! area ratio (mm^2 per px). The grasp on the chosen fabric then goes to the fold's top so felt
//! plus `grasp_z_m` (into the top layer), from the height the fingertips had at that touch,
//! instead of from the camera's edge estimate. Where the touch did not see the fold (the whole
//! disc: the fold's top above the contact; no contact state) the grasp falls back to the
//! camera's height. vla and vtla_pred keep the camera's rule.

use super::{Estimate, Timed, action, arm, force, position};
use crate::error::PolicyLoadError;
use crate::mode::Mode;
use crate::observation::Observation;
use crate::params::PolicyParams;
use crate::policy::{Action, Policy, PolicyError};
use unitac_core::Stamp;
use unitac_core::msg::Winner;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Look,
    Approach(usize),
    Press(usize),
    Release(usize),
    /// A touch closed on nothing: open where it was, then approach again lower.
    Reopen(usize),
    Compare,
    ApproachGrasp,
    Grasp,
    Lift,
    Done,
    Failed,
}

#[derive(Debug)]
pub struct FabricController {
    p: PolicyParams,
    mode: Mode,
    property: &'static str,
    more: bool,
    /// The two objects touched, A and B.
    objects: [String; 2],
    t: Timed<Phase>,
    contact_at: Option<Stamp>,
    /// Comparisons stamped before the second touch began are not about this trial.
    second_touch_at: Option<Stamp>,
    chosen: Option<String>,
    failure: Option<PolicyError>,
    /// The camera's estimates of where A and B are (x, y) and of their edge heights: running
    /// means over the frames seen while approaching each.
    places: [Estimate<3>; 2],
    /// vtla_real: the fold's top of A and B as each touch felt it: the fingertip height of the
    /// touch plus the fold's height above the contact centre read from the contact state \[m]
    /// (None: not felt, see [`fold_above_centre_m`]).
    felt_top: [Option<f64>; 2],
    /// vtla_real: touches of A and B that closed on nothing so far; each lowers that object's
    /// next touch by `touch_z_m` (at most [`TOUCH_RETRIES`]).
    missed: [u32; 2],
}

/// Touches that closed on nothing (the fingertips above the fold: the camera saw the edge too
/// high) are tried again this many times, each `touch_z_m` lower.
const TOUCH_RETRIES: u32 = 2;
/// A touch has closed on nothing when the fingers are this near the smallest opening without
/// a contact \[m].
const CLOSED_ON_NOTHING_M: f64 = 0.001;

/// Height over width of the tactile images this stack reads (GelSight Mini and DIGIT: 320 x 240,
/// DIGIT also 640 x 480): with the fingertip centre at the image's centre, its row is this times
/// its column.
const IMAGE_ASPECT: f64 = 0.75;
/// A fold's top read at least this share of the contact's half-width above the centre is the
/// disc's own top: the fold lies above the contact and its height is not seen.
const WHOLE_DISC: f64 = 0.9;
/// A contact box narrower than this shows no fold (a press a few pixels across) \[px].
const MIN_BOX_PX: f64 = 8.0;

/// How far a fabric's fold's top lies above the fingertip centre \[m], read from a contact
/// state, or None where the state does not show it (no contact, an empty box, no mm scale, the
/// whole disc).
///
/// The fabric over the rounded gel presses a disc about the fingertip centre, cut off where the
/// fabric ends, at the fold's top (crates/sim: `FoldEdge`): the top of the contact's bounding
/// box is the fold, a sharp edge in the image, while the disc's rim fades out (its detected
/// width and bottom move with the press depth and the detector's threshold). So the box's top is
/// read against the fingertip centre's row: the box is centred on the fingertip along the fold
/// (x), which is the image's centre column, and the images are `IMAGE_ASPECT` as tall as
/// wide, so the centre row is that times the box's mid column. The pixel size comes from the
/// state itself: `sqrt(area_m2 / area_px)`. A top as far above the centre as `WHOLE_DISC` of
/// the disc's half-width or of its reach below the centre is the disc's own top, not the fold;
/// a box narrower than `MIN_BOX_PX` shows none.
pub fn fold_above_centre_m(c: &unitac_core::msg::ContactState) -> Option<f64> {
    let [x0, y0, x1, y1] = c.bbox_px;
    let (w, h) = (
        f64::from(x1.saturating_sub(x0)),
        f64::from(y1.saturating_sub(y0)),
    );
    let (m2, px) = (f64::from(c.area_m2), f64::from(c.area_px));
    if !c.in_contact || w < MIN_BOX_PX || h <= 0.0 || !(m2 > 0.0 && px > 0.0) {
        return None;
    }
    let centre_row = IMAGE_ASPECT * 0.5 * (f64::from(x0) + f64::from(x1));
    let above_px = centre_row - f64::from(y0);
    let below_px = f64::from(y1) - centre_row;
    if above_px >= WHOLE_DISC * (0.5 * w).min(below_px) {
        return None;
    }
    let m = above_px * (m2 / px).sqrt();
    m.is_finite().then_some(m)
}

impl FabricController {
    /// `property`/`more`: from the task (which property, and whether the pick has more of it).
    pub fn new(
        p: &PolicyParams,
        property: &'static str,
        more: bool,
    ) -> Result<Self, PolicyLoadError> {
        let [a, b, ..] = p.limits.objects.as_slice() else {
            return Err(PolicyLoadError::PickNeedsTwoObjects);
        };
        Ok(Self {
            mode: p.mode,
            property,
            more,
            objects: [a.clone(), b.clone()],
            // Only vtla_real touches before it chooses; vla and vtla_pred choose from what they
            // have before any touch (the camera; vtla_pred also its predicted latent).
            t: Timed::new(if p.mode == Mode::VtlaReal {
                Phase::Approach(0)
            } else {
                Phase::Look
            }),

            contact_at: None,
            second_touch_at: None,
            chosen: None,
            failure: None,
            places: [Estimate::default(); 2],
            felt_top: [None; 2],
            missed: [0; 2],
            p: p.clone(),
        })
    }

    fn fail(&mut self, e: PolicyError) -> PolicyError {
        self.t.go(Phase::Failed);
        self.failure = Some(e.clone());
        e
    }

    /// Index of the object called `name` (A = 0, B = 1).
    fn index(&self, name: &str) -> Option<usize> {
        self.objects.iter().position(|o| o == name)
    }

    /// Add the camera's estimate of object `i` (x, y, edge height) from this tick's visual
    /// observation.
    fn see(&mut self, obs: &Observation, i: usize) -> Result<(), PolicyError> {
        let v = obs
            .visual()
            .ok_or_else(|| PolicyError::Failed("no fresh visual observation".into()))?;
        let o = &self.objects[i];
        let names = [
            format!("{o}_x_m"),
            format!("{o}_y_m"),
            format!("{o}_edge_height_m"),
        ];
        let read = |n: &str| v.get(n).filter(|x| x.is_finite());
        match (read(&names[0]), read(&names[1]), read(&names[2])) {
            (Some(x), Some(y), Some(h)) => {
                let stamp = v.header.stamp;
                self.places[i].add(stamp, [x, y, h]);
                Ok(())
            }
            _ => Err(self.fail(PolicyError::Failed(format!(
                "the camera gives no {} (list them in visual_names): the fingertips go where \
                 it sees the fold",
                names.join(" / ")
            )))),
        }
    }

    /// Fingertip height for object `i`: its edge estimate plus `offset_m`, not below the
    /// lowest height allowed (None before any estimate).
    fn height(&self, i: usize, offset_m: f64) -> Option<f64> {
        let e = self.places.get(i)?.mean()?[2];
        Some((e + offset_m).max(self.p.limits.min_z_m))
    }

    /// Where over the table object `i` is, as the camera saw it on the way (the origin before
    /// any estimate; no tick asks before the first).
    fn place(&self, i: usize) -> [f64; 2] {
        self.places
            .get(i)
            .and_then(Estimate::mean)
            .map_or([0.0, 0.0], |[x, y, _]| [x, y])
    }

    /// Where the chosen object is.
    fn chosen_place(&self) -> [f64; 2] {
        self.chosen
            .as_deref()
            .and_then(|c| self.index(c))
            .map_or([0.0, 0.0], |i| self.place(i))
    }

    /// Height of a touch on object `i` (lower by `touch_z_m` for each touch of it that closed on
    /// nothing).
    fn touch_z(&self, i: usize) -> f64 {
        let missed = f64::from(self.missed.get(i).copied().unwrap_or(0));
        self.height(i, self.p.touch_z_m * (1.0 + missed))
            .unwrap_or(self.p.limits.max_z_m)
    }

    /// Height of the grasp on the chosen object: `grasp_z_m` below the fold's top as the touch
    /// felt it (vtla_real), else as the camera sees it.
    fn grasp_z(&self) -> f64 {
        let Some(i) = self.chosen.as_deref().and_then(|c| self.index(c)) else {
            return self.p.limits.max_z_m;
        };
        if let Some(top) = self.felt_top.get(i).copied().flatten() {
            return (top + self.p.grasp_z_m).clamp(self.p.limits.min_z_m, self.p.limits.max_z_m);
        }
        self.height(i, self.p.grasp_z_m)
            .unwrap_or(self.p.limits.max_z_m)
    }

    /// Whether the grasp height comes from the touch.
    fn grasp_felt(&self) -> bool {
        self.chosen
            .as_deref()
            .and_then(|c| self.index(c))
            .is_some_and(|i| self.felt_top.get(i).copied().flatten().is_some())
    }

    /// The object with more (or less) of the property: index 0 = A, 1 = B.
    fn pick(&self, more_a: bool) -> usize {
        match (more_a, self.more) {
            (true, true) | (false, false) => 0,
            _ => 1,
        }
    }

    /// Pressing object `i`: hold the contact for the touch, reopen after closing on nothing
    /// (above the fold), or time out.
    fn press(&mut self, obs: &Observation, i: usize, elapsed: f64) -> Result<(), PolicyError> {
        let now = obs.stamp;
        let opening = obs.gripper().map(|g| g.opening_m);
        let in_contact = obs.contact().map(|c| c.in_contact);
        let p = &self.p;
        if in_contact == Some(true) {
            // The latest contact of the touch shows where the fold's top is (the press
            // is deepest at the end of the hold); the fingertips are at the touch height.
            let above = obs.contact().and_then(fold_above_centre_m);
            let z = self.touch_z(i);
            if let Some(slot) = self.felt_top.get_mut(i) {
                *slot = above.map(|a| z + a);
            }
            let at = *self.contact_at.get_or_insert(now);
            if now.secs_since(at) >= p.touch_hold_s {
                self.t.go(Phase::Release(i));
            }
        } else if self.contact_at.is_none()
            && opening.is_some_and(|o| o <= p.limits.min_opening_m + CLOSED_ON_NOTHING_M)
            && self.missed.get(i).is_some_and(|&m| m < TOUCH_RETRIES)
        {
            // Closed on nothing: above the fold. Open where the fingers are (closed
            // fingers lowered onto the fold would come down on it), then touch again
            // lower.
            self.t.go(Phase::Reopen(i));
        } else if elapsed >= p.contact_timeout_s {
            let e = PolicyError::Timeout(format!(
                "no contact on {} within {} s",
                self.objects[i], p.contact_timeout_s
            ));
            return Err(self.fail(e));
        }
        Ok(())
    }

    /// Waiting for the comparison of the two touches (newer than the second): the smoother or
    /// rougher one, as the task asks, is chosen; a tie fails.
    fn compare(&mut self, obs: &Observation, elapsed: f64) -> Result<(), PolicyError> {
        let p = &self.p;
        let after = self.second_touch_at.unwrap_or(Stamp::ZERO);
        let labels = |a: &str, b: &str| {
            (a == self.objects[0] && b == self.objects[1])
                || (a == self.objects[1] && b == self.objects[0])
        };
        let found = obs.comparison().filter(|c| {
            c.header.stamp >= after && c.property == self.property && labels(&c.label_a, &c.label_b)
        });
        if let Some(c) = found {
            let more_label = match c.winner {
                Winner::A => &c.label_a,
                Winner::B => &c.label_b,
                Winner::Tie => {
                    let e = PolicyError::Failed(format!("the comparison is a tie: {}", c.sentence));
                    return Err(self.fail(e));
                }
            };
            let i = self.pick(more_label == &self.objects[0]);
            self.chosen = Some(self.objects[i].clone());
            self.t.go(Phase::ApproachGrasp);
        } else if elapsed >= p.compare_timeout_s {
            let e = PolicyError::Timeout(format!(
                "no {} comparison of {} and {} within {} s",
                self.property, self.objects[0], self.objects[1], p.compare_timeout_s
            ));
            return Err(self.fail(e));
        }
        Ok(())
    }

    /// Advance the phase on what `obs` shows; Err: the controller failed.
    fn step(&mut self, obs: &Observation) -> Result<(), PolicyError> {
        let now = obs.stamp;
        let elapsed = self.t.elapsed(now);
        // On the way to an object the camera's view of its edge sets the fingertip height.
        let approached = match self.t.phase {
            Phase::Approach(i) => Some(i),
            Phase::ApproachGrasp => self.chosen.as_deref().and_then(|c| self.index(c)),
            _ => None,
        };
        if let Some(i) = approached {
            self.see(obs, i)?;
        }
        let p = &self.p;
        let opening = obs.gripper().map(|g| g.opening_m);
        let in_contact = obs.contact().map(|c| c.in_contact);
        match self.t.phase {
            Phase::Look => {
                let v = obs
                    .visual()
                    .ok_or_else(|| PolicyError::Failed("no fresh visual observation".into()))?;
                let name = |o: &str| format!("{o}_{}", self.property);
                let (Some(a), Some(b)) = (
                    v.get(&name(&self.objects[0])),
                    v.get(&name(&self.objects[1])),
                ) else {
                    return Err(self.fail(PolicyError::Failed(format!(
                        "the camera gives no {} for both objects",
                        self.property
                    ))));
                };
                let i = self.pick(a > b);
                self.chosen = Some(self.objects[i].clone());
                self.t.go(Phase::ApproachGrasp);
            }
            Phase::Approach(i) => {
                if elapsed >= p.approach_s {
                    if i == 1 {
                        self.second_touch_at = Some(now);
                    }
                    self.contact_at = None;
                    self.t.go(Phase::Press(i));
                }
            }
            Phase::Press(i) => self.press(obs, i, elapsed)?,
            Phase::Reopen(i) => {
                let open =
                    opening.is_some_and(|o| o >= p.limits.max_opening_m - p.limits.max_step_m);
                if open || elapsed >= p.approach_s {
                    if let Some(m) = self.missed.get_mut(i) {
                        *m += 1;
                    }
                    self.t.go(Phase::Approach(i));
                }
            }
            Phase::Release(i) => {
                let open =
                    opening.is_some_and(|o| o >= p.limits.max_opening_m - p.limits.max_step_m);
                if in_contact == Some(false) && (open || elapsed >= p.approach_s) {
                    self.t.go(if i == 0 {
                        Phase::Approach(1)
                    } else {
                        Phase::Compare
                    });
                }
            }
            Phase::Compare => self.compare(obs, elapsed)?,
            Phase::ApproachGrasp => {
                if elapsed >= p.approach_s {
                    self.t.go(Phase::Grasp);
                }
            }
            Phase::Grasp => {
                let g = obs.gripper();
                let held = g.is_some_and(|g| {
                    g.object_detected
                        || (g.force_n.is_finite() && g.force_n >= 0.9 * p.grasp_force_n)
                });
                if held {
                    self.t.go(Phase::Lift);
                } else if elapsed >= p.contact_timeout_s {
                    let e = PolicyError::Timeout(format!(
                        "the grasp did not close on {} within {} s",
                        self.chosen.as_deref().unwrap_or("?"),
                        p.contact_timeout_s
                    ));
                    return Err(self.fail(e));
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

    /// The action of the current phase.
    fn command(&mut self, obs: &Observation) -> Action {
        let p = &self.p;
        let elapsed = self.t.elapsed(obs.stamp);
        let opening = obs
            .gripper()
            .map_or(p.limits.max_opening_m, |g| g.opening_m);
        let open = position(
            p.limits.max_opening_m,
            p.limits.max_speed_m_s,
            p.touch_force_n,
        );
        let chosen = self.chosen.clone().unwrap_or_else(|| "home".into());
        let grasp_z = self.grasp_z();
        let at = self.chosen_place();
        let home = [0.0, 0.0];
        let grip = force(
            p.limits.min_opening_m,
            p.limits.max_speed_m_s,
            p.grasp_force_n,
        );
        match self.t.phase {
            Phase::Look => action(
                open,
                arm("home", home, p.limits.max_z_m, 0.0),
                "looking at both fabrics",
            ),
            Phase::Approach(i) => action(
                open,
                arm(&self.objects[i], self.place(i), self.touch_z(i), 0.0),
                format!("approaching {}", self.objects[i]),
            ),
            Phase::Press(i) => {
                // Close lightly; once in contact, stay where the fingers are.
                let target = if self.contact_at.is_some() {
                    opening
                } else {
                    p.limits.min_opening_m
                };
                action(
                    position(target, p.touch_speed_m_s, p.touch_force_n),
                    arm(&self.objects[i], self.place(i), self.touch_z(i), 0.0),
                    format!(
                        "touching {} ({:.2} N limit)",
                        self.objects[i], p.touch_force_n
                    ),
                )
            }
            Phase::Release(i) => action(
                open,
                arm(&self.objects[i], self.place(i), self.touch_z(i), 0.0),
                format!("releasing {}", self.objects[i]),
            ),
            Phase::Reopen(i) => action(
                open,
                arm(&self.objects[i], self.place(i), self.touch_z(i), 0.0),
                format!(
                    "the touch closed on nothing above {}: opening to touch lower",
                    self.objects[i]
                ),
            ),
            Phase::Compare => action(
                open,
                arm("home", home, p.limits.max_z_m, 0.0),
                format!("waiting for the {} comparison", self.property),
            ),
            Phase::ApproachGrasp => action(
                open,
                arm(&chosen, at, grasp_z, 0.0),
                format!("approaching {chosen} to grasp it"),
            ),
            Phase::Grasp => action(
                grip,
                arm(&chosen, at, grasp_z, 0.0),
                format!(
                    "grasping {chosen} ({:.2} N) at {:.2} mm, {}",
                    p.grasp_force_n,
                    grasp_z * 1e3,
                    if self.grasp_felt() {
                        "below the fold's top felt by touch"
                    } else {
                        "below the camera's edge height"
                    }
                ),
            ),
            Phase::Lift => action(
                grip,
                arm(
                    &chosen,
                    at,
                    grasp_z,
                    (elapsed * p.lift_speed_m_s).min(p.lift_m),
                ),
                format!("lifting {chosen}"),
            ),
            Phase::Done | Phase::Failed => action(
                grip,
                arm(&chosen, at, grasp_z, p.lift_m),
                format!("holding {chosen}"),
            ),
        }
    }
}

impl Policy for FabricController {
    fn phase(&self) -> &str {
        match self.t.phase {
            Phase::Look => "look",
            Phase::Approach(0) => "approach_a",
            Phase::Approach(_) => "approach_b",
            Phase::Press(0) => "press_a",
            Phase::Press(_) => "press_b",
            Phase::Release(0) => "release_a",
            Phase::Release(_) => "release_b",
            Phase::Reopen(0) => "reopen_a",
            Phase::Reopen(_) => "reopen_b",
            Phase::Compare => "compare",
            Phase::ApproachGrasp => "approach_grasp",
            Phase::Grasp => "grasp",
            Phase::Lift => "lift",
            Phase::Done => "done",
            Phase::Failed => "failed",
        }
    }

    fn required(&self) -> Vec<&'static str> {
        let mut r = vec!["gripper"];
        match self.t.phase {
            Phase::Look if self.mode == Mode::VtlaPred => {
                r.push("visual");
                r.push("latent_pred");
            }
            Phase::Look | Phase::ApproachGrasp | Phase::Approach(_) => r.push("visual"),
            Phase::Press(_) | Phase::Release(_) | Phase::Reopen(_) => r.push("contact"),
            _ => {}
        }
        r
    }

    fn awaited(&self) -> Vec<&'static str> {
        let mut r = self.required();
        // The touching modes choose from the comparison: its producer must be alive until the
        // choice is made.
        let choosing = matches!(
            self.t.phase,
            Phase::Approach(_)
                | Phase::Press(_)
                | Phase::Release(_)
                | Phase::Reopen(_)
                | Phase::Compare
        );
        if self.mode == Mode::VtlaReal && choosing {
            r.push("comparison");
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
}
