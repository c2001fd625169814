//! Fabric selection: touch A, touch B, wait for the PropertyComparison, grasp the one the task
//! asks for, lift.
//!
//! ```text
//! vtla_real:
//!   approach_a -> press_a (close lightly until contact, hold touch_hold_s) -> release_a
//!   -> approach_b -> press_b -> release_b -> compare (timeout) -> approach_grasp -> grasp
//!   -> lift -> done
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
}

impl FabricController {
    /// `property`/`more`: from the task (which property, and whether the pick has more of it).
    pub fn new(
        p: &PolicyParams,
        property: &'static str,
        more: bool,
    ) -> Result<Self, PolicyLoadError> {
        let [a, b, ..] = p.objects.as_slice() else {
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
        Some((e + offset_m).max(self.p.min_z_m))
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

    /// Height of a touch on object `i`.
    fn touch_z(&self, i: usize) -> f64 {
        self.height(i, self.p.touch_z_m).unwrap_or(self.p.max_z_m)
    }

    /// Height of the grasp on the chosen object.
    fn grasp_z(&self) -> f64 {
        self.chosen
            .as_deref()
            .and_then(|c| self.index(c))
            .and_then(|i| self.height(i, self.p.grasp_z_m))
            .unwrap_or(self.p.max_z_m)
    }

    /// The object with more (or less) of the property: index 0 = A, 1 = B.
    fn pick(&self, more_a: bool) -> usize {
        match (more_a, self.more) {
            (true, true) | (false, false) => 0,
            _ => 1,
        }
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
            Phase::Press(i) => {
                if in_contact == Some(true) {
                    let at = *self.contact_at.get_or_insert(now);
                    if now.secs_since(at) >= p.touch_hold_s {
                        self.t.go(Phase::Release(i));
                    }
                } else if elapsed >= p.contact_timeout_s {
                    let e = PolicyError::Timeout(format!(
                        "no contact on {} within {} s",
                        self.objects[i], p.contact_timeout_s
                    ));
                    return Err(self.fail(e));
                }
            }
            Phase::Release(i) => {
                let open = opening.is_some_and(|o| o >= p.max_opening_m - p.max_step_m);
                if in_contact == Some(false) && (open || elapsed >= p.approach_s) {
                    self.t.go(if i == 0 {
                        Phase::Approach(1)
                    } else {
                        Phase::Compare
                    });
                }
            }
            Phase::Compare => {
                let after = self.second_touch_at.unwrap_or(Stamp::ZERO);
                let labels = |a: &str, b: &str| {
                    (a == self.objects[0] && b == self.objects[1])
                        || (a == self.objects[1] && b == self.objects[0])
                };
                let found = obs.comparison().filter(|c| {
                    c.header.stamp >= after
                        && c.property == self.property
                        && labels(&c.label_a, &c.label_b)
                });
                if let Some(c) = found {
                    let more_label = match c.winner {
                        Winner::A => &c.label_a,
                        Winner::B => &c.label_b,
                        Winner::Tie => {
                            let e = PolicyError::Failed(format!(
                                "the comparison is a tie: {}",
                                c.sentence
                            ));
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
            }
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
        let opening = obs.gripper().map_or(p.max_opening_m, |g| g.opening_m);
        let open = position(p.max_opening_m, p.max_speed_m_s, p.touch_force_n);
        let chosen = self.chosen.clone().unwrap_or_else(|| "home".into());
        let grasp_z = self.grasp_z();
        let at = self.chosen_place();
        let home = [0.0, 0.0];
        let grip = force(p.min_opening_m, p.max_speed_m_s, p.grasp_force_n);
        match self.t.phase {
            Phase::Look => action(
                open,
                arm("home", home, p.max_z_m, 0.0),
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
                    p.min_opening_m
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
            Phase::Compare => action(
                open,
                arm("home", home, p.max_z_m, 0.0),
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
                format!("grasping {chosen} ({:.2} N)", p.grasp_force_n),
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
            Phase::Press(_) | Phase::Release(_) => r.push("contact"),
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
            Phase::Approach(_) | Phase::Press(_) | Phase::Release(_) | Phase::Compare
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
