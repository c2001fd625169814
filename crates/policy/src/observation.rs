//! Observation assembly: the latest message of each named input, its age against the control
//! tick and its validity, and one flat f32 vector with named slices (LeRobot naming).
//!
//! Inputs are one table, [`INPUTS`]: adding an input (e.g. the slip state once its message lands)
//! is one entry there and its name in [`crate::mode::Mode::inputs`].

use crate::error::{FeatureError, InputError};
use crate::schema;
use unitac_core::Stamp;
use unitac_core::msg::{
    ContactState, GripperStatus, LatentSource, Msg, PropertyComparison, TactileLatent,
    VisualObservation, Winner,
};

/// What the layout of the vector depends on besides the input table.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Layout {
    /// Values of `observation.tactile_latent` (the latent's data, row-major).
    pub latent_len: usize,
    /// Names read from the VisualObservation into `observation.visual`, in this order.
    pub visual_names: Vec<String>,
    /// The gripper's stroke \[m]: a GripperStatus whose opening is outside [0, stroke] is
    /// invalid (None: only a negative opening is).
    pub stroke_m: Option<f64>,
}

/// One named input.
#[derive(Debug)]
pub struct InputSpec {
    /// Its name in params (`budget_<name>_s`), the mode table and PolicyStatus messages.
    pub name: &'static str,
    /// What it is, for messages.
    pub what: &'static str,
    /// The scene stage kind that produces it; None: it comes from outside the scene (the
    /// gripper driver or the sim, the arm stack's camera model).
    pub produced_by: Option<&'static str>,
    /// Freshness budget when params name none \[s].
    pub default_budget_s: f64,
    /// Whether a message is this input.
    pub accepts: fn(&Msg) -> bool,
    /// Number of values in its slice.
    pub width: fn(&Layout) -> usize,
    /// Its values (exactly `width`) into `out`; Err: the message is invalid, with the reason.
    pub features: fn(&Msg, &Layout, &mut Vec<f32>) -> Result<(), FeatureError>,
}

fn finite(name: &str, v: f64) -> Result<f32, FeatureError> {
    if v.is_finite() {
        Ok(v as f32)
    } else {
        Err(FeatureError::NotFinite {
            name: name.to_string(),
            value: v,
        })
    }
}

/// NaN (unknown) -> (0, known = 0); finite -> (v, 1); inf -> error.
fn maybe(name: &str, v: f64, out: &mut Vec<f32>) -> Result<(), FeatureError> {
    if v.is_nan() {
        out.extend([0.0, 0.0]);
        return Ok(());
    }
    out.extend([finite(name, v)?, 1.0]);
    Ok(())
}

fn gripper_features(m: &Msg, l: &Layout, out: &mut Vec<f32>) -> Result<(), FeatureError> {
    let Msg::GripperStatus(g) = m else {
        return Err(FeatureError::WrongKind("gripper status"));
    };
    let opening = finite("opening_m", g.opening_m)?;
    let stroke = l.stroke_m.unwrap_or(f64::INFINITY);
    if !(0.0..=stroke).contains(&g.opening_m) {
        return Err(FeatureError::OpeningOutsideStroke {
            opening_m: g.opening_m,
            stroke_m: stroke,
        });
    }
    out.push(opening);
    maybe("target_m", g.target_m, out)?;
    maybe("force_n", g.force_n, out)?;
    maybe("current_a", g.current_a, out)?;
    out.push(if g.object_detected { 1.0 } else { 0.0 });
    if !g.fault.is_empty() {
        return Err(FeatureError::GripperFault(g.fault.clone()));
    }
    Ok(())
}

fn contact_features(m: &Msg, _: &Layout, out: &mut Vec<f32>) -> Result<(), FeatureError> {
    let Msg::ContactState(c) = m else {
        return Err(FeatureError::WrongKind("contact state"));
    };
    out.push(if c.in_contact { 1.0 } else { 0.0 });
    out.push(finite("area_m2", f64::from(c.area_m2))?);
    out.push(finite("strength", f64::from(c.strength))?);
    Ok(())
}

fn latent_features(m: &Msg, l: &Layout, out: &mut Vec<f32>) -> Result<(), FeatureError> {
    let Msg::TactileLatent(t) = m else {
        return Err(FeatureError::WrongKind("tactile latent"));
    };
    if !t.valid {
        return Err(FeatureError::LatentInvalid(t.guard_report.clone()));
    }
    if t.data.len() != l.latent_len {
        return Err(FeatureError::LatentLen {
            got: t.data.len(),
            want: l.latent_len,
        });
    }
    if let Some((index, &value)) = t.data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(FeatureError::LatentValue { index, value });
    }
    out.extend_from_slice(&t.data);
    Ok(())
}

fn comparison_features(m: &Msg, _: &Layout, out: &mut Vec<f32>) -> Result<(), FeatureError> {
    let Msg::PropertyComparison(c) = m else {
        return Err(FeatureError::WrongKind("property comparison"));
    };
    let one_hot = |w: Winner| if c.winner == w { 1.0 } else { 0.0 };
    out.extend([one_hot(Winner::A), one_hot(Winner::B), one_hot(Winner::Tie)]);
    out.push(finite("margin", f64::from(c.margin))?);
    out.push(finite("confidence", f64::from(c.confidence))?);
    Ok(())
}

fn visual_features(m: &Msg, l: &Layout, out: &mut Vec<f32>) -> Result<(), FeatureError> {
    let Msg::VisualObservation(v) = m else {
        return Err(FeatureError::WrongKind("visual observation"));
    };
    for name in &l.visual_names {
        let x = v
            .get(name)
            .ok_or_else(|| FeatureError::NoVisual(name.clone()))?;
        out.push(finite(name, x)?);
    }
    Ok(())
}

/// Every input a policy can read. Order = order of the slices in the vector.
pub static INPUTS: &[InputSpec] = &[
    InputSpec {
        name: "gripper",
        what: "gripper status",
        produced_by: None,
        default_budget_s: 0.2,
        accepts: |m| matches!(m, Msg::GripperStatus(_)),
        width: |_| schema::STATE_LEN,
        features: gripper_features,
    },
    InputSpec {
        name: "contact",
        what: "contact state",
        produced_by: Some("contact"),
        default_budget_s: 0.25,
        accepts: |m| matches!(m, Msg::ContactState(_)),
        width: |_| schema::CONTACT_LEN,
        features: contact_features,
    },
    InputSpec {
        name: "latent_real",
        what: "live tactile latent",
        produced_by: Some("encoder"),
        default_budget_s: 60.0,
        accepts: |m| matches!(m, Msg::TactileLatent(l) if l.source == LatentSource::Real),
        width: |l| l.latent_len,
        features: latent_features,
    },
    InputSpec {
        name: "latent_pred",
        what: "predicted tactile latent",
        produced_by: Some("sampler"),
        default_budget_s: 600.0,
        accepts: |m| matches!(m, Msg::TactileLatent(l) if l.source == LatentSource::Predicted),
        width: |l| l.latent_len,
        features: latent_features,
    },
    InputSpec {
        name: "comparison",
        what: "property comparison",
        produced_by: Some("compare"),
        default_budget_s: 600.0,
        accepts: |m| matches!(m, Msg::PropertyComparison(_)),
        width: |_| schema::COMPARISON_LEN,
        features: comparison_features,
    },
    InputSpec {
        name: "visual",
        what: "visual observation",
        produced_by: None,
        default_budget_s: 0.5,
        accepts: |m| matches!(m, Msg::VisualObservation(_)),
        width: |l| l.visual_names.len(),
        features: visual_features,
    },
];

impl InputSpec {
    /// The slice of the observation vector it fills (its LeRobot key in schema/policy.json; the
    /// input's own name for one the schema does not list, which the schema test rules out).
    pub fn feature(&self) -> &'static str {
        schema::input_feature(self.name).unwrap_or(self.name)
    }
}

/// The input named `name`.
pub fn input(name: &str) -> Option<&'static InputSpec> {
    INPUTS.iter().find(|i| i.name == name)
}

/// How far an input's stamp may be after the tick's (its own budget if smaller) \[s]: a message
/// captured a little after the gripper status that triggers the tick may be stored first; one
/// stamped further ahead is from a clock that cannot be trusted, an invalid input (`stamp ahead
/// by ...`) until a message with a plausible stamp replaces it.
pub const MAX_AHEAD_S: f64 = 0.1;

/// An input's state at a tick.
#[derive(Debug, Clone, PartialEq)]
pub enum InputStatus {
    Fresh,
    /// Nothing received yet.
    Missing,
    /// Older than its budget.
    Stale,
    /// The latest message is unusable (reason).
    Invalid(String),
}

/// One input at a tick.
#[derive(Debug, Clone, PartialEq)]
pub struct InputReading {
    pub name: &'static str,
    /// Tick stamp minus the message stamp \[s]; None when missing.
    pub age_s: Option<f64>,
    pub budget_s: f64,
    pub status: InputStatus,
}

impl InputReading {
    /// Why it cannot be used (None when fresh), one phrase.
    pub fn problem(&self) -> Option<String> {
        match &self.status {
            InputStatus::Fresh => None,
            InputStatus::Missing => Some(format!("{}: nothing received", self.name)),
            InputStatus::Stale => Some(format!(
                "{}: stale ({:.3} s old, budget {} s)",
                self.name,
                self.age_s.unwrap_or(f64::INFINITY),
                self.budget_s
            )),
            InputStatus::Invalid(r) => Some(format!("{}: invalid ({r})", self.name)),
        }
    }
}

/// A named slice of the vector.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Slice {
    pub name: &'static str,
    pub start: usize,
    pub len: usize,
}

/// What a policy sees at one control tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// The tick's stamp (the GripperStatus that triggered it).
    pub stamp: Stamp,
    /// The task string (LeRobot `task`).
    pub task: String,
    /// Every slice, in [`INPUTS`] order; a slice whose input is not fresh is zeros. Never NaN.
    pub vector: Vec<f32>,
    pub slices: Vec<Slice>,
    pub inputs: Vec<InputReading>,
    latest: Vec<(&'static str, Option<Msg>)>,
}

impl Observation {
    /// The values of a slice by LeRobot key, e.g. `observation.state`.
    pub fn slice(&self, name: &str) -> Option<&[f32]> {
        let s = self.slices.iter().find(|s| s.name == name)?;
        self.vector.get(s.start..s.start + s.len)
    }
    /// The reading of an input by name.
    pub fn reading(&self, name: &str) -> Option<&InputReading> {
        self.inputs.iter().find(|r| r.name == name)
    }
    /// The latest message of a fresh input.
    fn fresh(&self, name: &str) -> Option<&Msg> {
        if self.reading(name)?.status != InputStatus::Fresh {
            return None;
        }
        self.latest
            .iter()
            .find(|(n, _)| *n == name)
            .and_then(|(_, m)| m.as_ref())
    }
    pub fn gripper(&self) -> Option<&GripperStatus> {
        match self.fresh("gripper")? {
            Msg::GripperStatus(g) => Some(g),
            _ => None,
        }
    }
    pub fn contact(&self) -> Option<&ContactState> {
        match self.fresh("contact")? {
            Msg::ContactState(c) => Some(c),
            _ => None,
        }
    }
    /// The fresh latent of the mode (real or predicted).
    pub fn latent(&self) -> Option<&TactileLatent> {
        match self
            .fresh("latent_real")
            .or_else(|| self.fresh("latent_pred"))?
        {
            Msg::TactileLatent(l) => Some(l),
            _ => None,
        }
    }
    pub fn comparison(&self) -> Option<&PropertyComparison> {
        match self.fresh("comparison")? {
            Msg::PropertyComparison(c) => Some(c),
            _ => None,
        }
    }
    pub fn visual(&self) -> Option<&VisualObservation> {
        match self.fresh("visual")? {
            Msg::VisualObservation(v) => Some(v),
            _ => None,
        }
    }
}

/// Keeps the latest message of each input of a mode and assembles observations.
#[derive(Debug, Clone)]
pub struct Assembler {
    layout: Layout,
    /// The mode's inputs in [`INPUTS`] order, with their budgets, and the latest message.
    inputs: Vec<(&'static InputSpec, f64, Option<Msg>)>,
}

impl Assembler {
    /// `names`: the inputs to keep (unknown names are an error); `budget`: an input's budget
    /// (None: its default).
    pub fn new(
        names: &[&str],
        budget: impl Fn(&str) -> Option<f64>,
        layout: Layout,
    ) -> Result<Self, InputError> {
        if let Some(n) = names.iter().find(|n| input(n).is_none()) {
            return Err(InputError::Unknown(n.chars().take(64).collect()));
        }
        let inputs = INPUTS
            .iter()
            .filter(|i| names.contains(&i.name))
            .map(|i| (i, budget(i.name).unwrap_or(i.default_budget_s), None))
            .collect();
        Ok(Self { layout, inputs })
    }

    /// The names of the inputs kept, in [`INPUTS`] order.
    pub fn names(&self) -> Vec<&'static str> {
        self.inputs.iter().map(|(spec, _, _)| spec.name).collect()
    }

    /// Keep `m` if it is one of the inputs; true if kept.
    pub fn offer(&mut self, m: &Msg) -> bool {
        for (spec, _, latest) in &mut self.inputs {
            if (spec.accepts)(m) {
                *latest = Some(m.clone());
                return true;
            }
        }
        false
    }

    /// The slices of the vector (same for every observation of this assembler).
    pub fn slices(&self) -> Vec<Slice> {
        let mut start = 0;
        self.inputs
            .iter()
            .map(|(spec, _, _)| {
                let len = (spec.width)(&self.layout);
                let s = Slice {
                    name: spec.feature(),
                    start,
                    len,
                };
                start += len;
                s
            })
            .collect()
    }

    /// The observation at tick `now`.
    pub fn assemble(&self, now: Stamp, task: &str) -> Observation {
        let mut vector = Vec::new();
        let mut readings = Vec::new();
        for (spec, budget, latest) in &self.inputs {
            let width = (spec.width)(&self.layout);
            let start = vector.len();
            let (age_s, status) = match latest {
                None => (None, InputStatus::Missing),
                Some(m) => {
                    let age = now.secs_since(m.stamp());
                    let status = if age > *budget {
                        InputStatus::Stale
                    } else if age < -budget.min(MAX_AHEAD_S) {
                        InputStatus::Invalid(format!("stamp ahead by {:.3} s", -age))
                    } else {
                        match (spec.features)(m, &self.layout, &mut vector) {
                            Ok(()) if vector.len() == start + width => InputStatus::Fresh,
                            Ok(()) => InputStatus::Invalid(format!(
                                "{} values, the layout has {width}",
                                vector.len() - start
                            )),
                            Err(r) => InputStatus::Invalid(r.to_string()),
                        }
                    };
                    (Some(age), status)
                }
            };
            if status != InputStatus::Fresh {
                vector.truncate(start);
                vector.resize(start + width, 0.0);
            }
            readings.push(InputReading {
                name: spec.name,
                age_s,
                budget_s: *budget,
                status,
            });
        }
        Observation {
            stamp: now,
            task: task.to_string(),
            vector,
            slices: self.slices(),
            inputs: readings,
            latest: self
                .inputs
                .iter()
                .map(|(s, _, m)| (s.name, m.clone()))
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_core::msg::{Header, samples};

    fn at(ns: i64) -> Header {
        Header::new(Stamp(ns), "x")
    }

    fn assembler() -> Assembler {
        Assembler::new(
            &["gripper", "contact", "latent_real", "visual"],
            |n| (n == "contact").then_some(0.1),
            Layout {
                latent_len: 6,
                visual_names: vec!["cup_width_m".into()],
                stroke_m: Some(0.085),
            },
        )
        .unwrap()
    }

    #[test]
    fn slices_follow_the_table_with_lerobot_names() {
        let a = assembler();
        let names: Vec<(&str, usize, usize)> = a
            .slices()
            .iter()
            .map(|s| (s.name, s.start, s.len))
            .collect();
        assert_eq!(
            names,
            [
                ("observation.state", 0, 8),
                ("observation.contact", 8, 3),
                ("observation.tactile_latent", 11, 6),
                ("observation.visual", 17, 1),
            ]
        );
        assert!(Assembler::new(&["smell"], |_| None, Layout::default()).is_err());
    }

    #[test]
    fn ages_budgets_and_validity_per_input() {
        let mut a = assembler();
        let t = 10_000_000_000;
        let mut g = samples::gripper_status();
        g.header = at(t);
        g.fault.clear();
        g.current_a = f64::NAN;
        assert!(a.offer(&Msg::GripperStatus(g)));
        let mut c = samples::contact_state();
        c.header = at(t - 200_000_000); // 0.2 s old, budget 0.1 s
        assert!(a.offer(&Msg::ContactState(c)));
        let mut l = samples::tactile_latent();
        l.source = LatentSource::Real;
        l.header = at(t - 1_000_000_000);
        l.data[2] = f32::NAN;
        assert!(a.offer(&Msg::TactileLatent(l.clone())));
        // A predicted latent is not this mode's input.
        assert!(!a.offer(&Msg::TactileLatent(samples::tactile_latent())));
        let mut v = samples::visual_observation();
        v.header = at(t);
        assert!(a.offer(&Msg::VisualObservation(v)));

        let o = a.assemble(Stamp(t), "squeeze the cup");
        let st: Vec<_> = o.inputs.iter().map(|r| r.status.clone()).collect();
        assert_eq!(st[0], InputStatus::Fresh);
        assert_eq!(st[1], InputStatus::Stale);
        assert_eq!(st[2], InputStatus::Invalid("latent value 2 is NaN".into()));
        assert_eq!(st[3], InputStatus::Fresh);
        assert_eq!(o.inputs[1].age_s, Some(0.2));
        assert_eq!(
            o.inputs[1].problem().unwrap(),
            "contact: stale (0.200 s old, budget 0.1 s)"
        );
        // Unknown current: 0 with known = 0; invalid and stale slices are zeros; no NaN anywhere.
        assert_eq!(
            o.slice("observation.state").unwrap(),
            [0.0425, 0.03, 1.0, 6.5, 1.0, 0.0, 0.0, 1.0]
        );
        assert_eq!(o.slice("observation.contact").unwrap(), [0.0; 3]);
        assert_eq!(o.slice("observation.tactile_latent").unwrap(), [0.0; 6]);
        assert_eq!(o.slice("observation.visual").unwrap(), [0.081f32]);
        assert!(o.vector.iter().all(|v| v.is_finite()));
        assert!(o.contact().is_none() && o.latent().is_none());
        assert_eq!(o.visual().unwrap().get("cup_width_m"), Some(0.081));

        // A fresh valid latent replaces the bad one.
        l.data[2] = 2.25;
        a.offer(&Msg::TactileLatent(l));
        let o = a.assemble(Stamp(t), "");
        assert_eq!(o.reading("latent_real").unwrap().status, InputStatus::Fresh);
        assert_eq!(
            o.slice("observation.tactile_latent").unwrap(),
            [0.5, -1.0, 2.25, 3.0, -0.125, 8.0]
        );
    }

    #[test]
    fn wrong_latent_length_and_gripper_fault_are_invalid() {
        let mut a = Assembler::new(
            &["gripper", "latent_pred"],
            |_| None,
            Layout {
                latent_len: 4,
                ..Layout::default()
            },
        )
        .unwrap();
        let mut g = samples::gripper_status();
        g.header = at(0);
        a.offer(&Msg::GripperStatus(g));
        let mut l = samples::tactile_latent();
        l.header = at(0);
        a.offer(&Msg::TactileLatent(l));
        let o = a.assemble(Stamp(0), "");
        assert_eq!(
            o.reading("gripper").unwrap().problem().unwrap(),
            "gripper: invalid (gripper fault: overtemp)"
        );
        assert_eq!(
            o.reading("latent_pred").unwrap().problem().unwrap(),
            "latent_pred: invalid (latent has 6 values, the observation layout has 4 (latent_len))"
        );
        let o = Assembler::new(&["visual"], |_| None, Layout::default())
            .unwrap()
            .assemble(Stamp(5), "");
        assert_eq!(o.inputs[0].status, InputStatus::Missing);
    }

    #[test]
    fn an_opening_outside_the_stroke_is_an_invalid_gripper_input() {
        let mut a = Assembler::new(
            &["gripper"],
            |_| None,
            Layout {
                stroke_m: Some(0.085),
                ..Layout::default()
            },
        )
        .unwrap();
        let reading = |a: &mut Assembler, opening_m: f64| {
            let mut g = samples::gripper_status();
            g.header = at(0);
            g.fault.clear();
            g.opening_m = opening_m;
            a.offer(&Msg::GripperStatus(g));
            a.assemble(Stamp(0), "").inputs[0].clone()
        };
        // A Robotiq gPO of 230 read through the 0..227 calibration: -1.12 mm.
        assert_eq!(
            reading(&mut a, -0.00112).problem().unwrap(),
            "gripper: invalid (opening -0.00112 m outside the stroke [0, 0.085] m)"
        );
        assert_eq!(
            reading(&mut a, 0.0851).status,
            InputStatus::Invalid("opening 0.0851 m outside the stroke [0, 0.085] m".into())
        );
        for ok in [0.0, 0.04, 0.085] {
            assert_eq!(reading(&mut a, ok).status, InputStatus::Fresh, "{ok}");
        }
    }
}
