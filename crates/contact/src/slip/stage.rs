//! The slip detector as a runtime [`Stage`]: after the contact stage, it learns the marker
//! reference from the background the contact stage announces, and for every frame the contact
//! stage says is in contact emits a [`SlipState`].
//!
//! Per frame in contact: find the dots ([`markers`](super::markers)), follow each reference
//! marker ([`track`](super::track)), and once `onset_frames` frames are in contact, compare the
//! field with the one at that onset (so the press's own radial spread is not shear). Over the
//! markers within `fit_radius` contact radii of the contact centroid ([`fit`](super::fit)):
//! - the rigid fit gives the shear (its translation at the centroid, in metres) and rotation;
//! - the affine fit's rms residual is `residual_px`;
//! - `slip_score` is the share of the stuck centre's motion the rim fails to follow: a rigid fit
//!   on the inner markers (within `inner_radius` contact radii, at least the three nearest)
//!   predicts each rim marker's motion; the rim's lag projected on that motion, summed, over the
//!   summed squared predicted motion plus `motion_floor_px`^2 per marker, clamped to [0, 1]. A
//!   stuck contact moves rigidly (score near 0); in partial slip the rim lags the centre; in
//!   gross slip the whole field falls off from the centre;
//! - `slip` rises at `slip_on` and falls below `slip_off`.
//!
//! Too few markers, no onset yet, or a fit that is not determined give `valid = false` with
//! every number 0: NaN never leaves the stage. A frame of another size than the background's is
//! rejected (an error; the state is as before). A sensor kind without markers (DIGIT) cannot be
//! built: the error names it.

use super::field::MarkerField;
use super::fit::{fit_affine, fit_rigid};
use super::params::SlipParams;
use super::track::Reference;
use crate::params::ParamsError;
use unitac_core::msg::{ContactState, Header, SlipState};
use unitac_core::{Clock, Frame, Msg, SensorSpec, Stage, StageError};

/// The slip detector stage.
#[derive(Debug)]
pub struct SlipStage {
    p: SlipParams,
    spec: SensorSpec,
    /// The reference markers and where each was last seen in contact.
    field: MarkerField,
    /// Why there is no usable reference (logged once).
    reference_error: Option<String>,
    /// The contact stage's state for the latest frame.
    contact: Option<ContactState>,
    /// The field at contact onset.
    onset: Option<Vec<Option<[f64; 2]>>>,
    frames_in_contact: u32,
    slip: bool,
}

/// What one frame's fit measured (pixels, about the contact centroid).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Measured {
    shear_px: [f64; 2],
    rotation_rad: f64,
    residual_px: f64,
    slip_score: f64,
    markers: u32,
}

impl SlipStage {
    /// A stage for sensors of `spec`; a sensor kind without marker dots is refused.
    pub fn new(p: SlipParams, spec: SensorSpec) -> Result<Self, ParamsError> {
        p.check_for(spec.kind)?;
        Ok(Self {
            p,
            spec,
            field: MarkerField::default(),
            reference_error: None,
            contact: None,
            onset: None,
            frames_in_contact: 0,
            slip: false,
        })
    }

    /// The marker reference learned from the background, if any.
    pub fn reference(&self) -> Option<&Reference> {
        self.field.reference()
    }
    /// Why the background gave no usable marker reference.
    pub fn reference_error(&self) -> Option<&str> {
        self.reference_error.as_deref()
    }

    fn learn_reference(&mut self, bg: &Frame) {
        self.reset_contact();
        match self.field.learn(bg, &self.p) {
            Ok(()) => self.reference_error = None,
            Err(e) => {
                let why = format!("background: {e}");
                tracing::warn!("slip: {why}; every SlipState is invalid");
                self.reference_error = Some(why);
            }
        }
    }

    fn reset_contact(&mut self) {
        self.field.reset();
        self.onset = None;
        self.frames_in_contact = 0;
        self.slip = false;
    }

    /// The state for a frame in contact (`c` is its ContactState).
    fn step(&mut self, f: &Frame, c: &ContactState) -> Result<SlipState, StageError> {
        let now = match self.field.follow(f, &self.p) {
            Ok(Some(now)) => now.to_vec(),
            Ok(None) => return Ok(self.state(f, None, 0)),
            Err(e) => return Err(StageError::bad_input(e)),
        };
        let tracked = now.iter().flatten().count() as u32;
        self.frames_in_contact = self.frames_in_contact.saturating_add(1);
        if self.frames_in_contact == self.p.onset_frames {
            self.onset = Some(now.clone());
        }
        let measured = self
            .onset
            .as_ref()
            .and_then(|onset| measure(&self.p, c, onset, &now));
        if let Some(m) = &measured {
            if !self.slip && m.slip_score >= self.p.slip_on {
                self.slip = true;
            } else if self.slip && m.slip_score < self.p.slip_off {
                self.slip = false;
            }
        }
        Ok(self.state(f, measured, tracked))
    }

    fn state(&self, f: &Frame, m: Option<Measured>, tracked: u32) -> SlipState {
        // Metres per pixel of this frame (the spec's scale is for its own output width).
        let m_per_px =
            self.spec.m_per_px() * f64::from(self.spec.width.max(1)) / f64::from(f.width.max(1));
        let mut s = SlipState {
            header: Header::optical(f.stamp, &f.sensor_id),
            sensor_id: f.sensor_id.clone(),
            shear_x_m: 0.0,
            shear_y_m: 0.0,
            rotation_rad: 0.0,
            residual_px: 0.0,
            slip_score: 0.0,
            slip: false,
            markers_tracked: tracked,
            valid: false,
        };
        if let Some(m) = m {
            let v = [
                m.shear_px[0] * m_per_px,
                m.shear_px[1] * m_per_px,
                m.rotation_rad,
                m.residual_px,
                m.slip_score,
            ];
            if v.iter().all(|x| x.is_finite()) {
                [
                    s.shear_x_m,
                    s.shear_y_m,
                    s.rotation_rad,
                    s.residual_px,
                    s.slip_score,
                ] = v;
                s.markers_tracked = m.markers;
                s.slip = self.slip;
                s.valid = true;
            }
        }
        s
    }
}

/// The fits of the module docs, on the markers near the contact that were tracked both at onset
/// and now; None when they do not determine them.
fn measure(
    p: &SlipParams,
    c: &ContactState,
    onset: &[Option<[f64; 2]>],
    now: &[Option<[f64; 2]>],
) -> Option<Measured> {
    let centre = [f64::from(c.centroid_px[0]), f64::from(c.centroid_px[1])];
    let radius = (f64::from(c.area_px).max(0.0) / std::f64::consts::PI).sqrt();
    let fit_r = p.fit_radius * radius;
    // (distance from the centroid, onset, now), centred on the centroid.
    let mut pairs: Vec<(f64, [f64; 2], [f64; 2])> = onset
        .iter()
        .zip(now)
        .filter_map(|(a, b)| {
            let (a, b) = ((*a)?, (*b)?);
            let from = [a[0] - centre[0], a[1] - centre[1]];
            let d = from[0].hypot(from[1]);
            (d <= fit_r).then_some((d, from, [b[0] - centre[0], b[1] - centre[1]]))
        })
        .collect();
    if pairs.len() < p.min_markers as usize {
        return None;
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let from: Vec<[f64; 2]> = pairs.iter().map(|x| x.1).collect();
    let to: Vec<[f64; 2]> = pairs.iter().map(|x| x.2).collect();
    let rigid = fit_rigid(&from, &to).ok()?;
    let affine = fit_affine(&from, &to).ok()?;
    // The stuck centre: markers within inner_radius, at least three, leaving one for the rim.
    let inner_r = p.inner_radius * radius;
    let n_in = pairs
        .iter()
        .filter(|x| x.0 <= inner_r)
        .count()
        .clamp(3, pairs.len() - 1);
    let centre_fit = fit_rigid(&from[..n_in], &to[..n_in]).ok()?;
    // How much of the centre's rigid motion the rim fails to follow, motion-weighted: the lag
    // projected on the predicted motion, over the predicted motion (plus the floor per marker).
    let (mut lag, mut motion) = (0.0, 0.0);
    for (f, t) in from[n_in..].iter().zip(&to[n_in..]) {
        let q = centre_fit.apply(*f);
        let pm = [q[0] - f[0], q[1] - f[1]];
        lag -= (t[0] - q[0]) * pm[0] + (t[1] - q[1]) * pm[1];
        motion += pm[0] * pm[0] + pm[1] * pm[1];
    }
    let rim = (pairs.len() - n_in) as f64;
    let score = lag / (motion + rim * p.motion_floor_px * p.motion_floor_px);
    Some(Measured {
        // The rigid motion's displacement of the centroid (the origin of the centred frame).
        shear_px: rigid.translation,
        rotation_rad: rigid.rotation_rad,
        residual_px: affine.rms,
        slip_score: score.clamp(0.0, 1.0),
        markers: pairs.len() as u32,
    })
}

impl Stage for SlipStage {
    fn name(&self) -> &str {
        "slip"
    }
    fn process(&mut self, input: &Msg, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        match input {
            Msg::Background(bg) => {
                self.learn_reference(bg);
                Ok(Vec::new())
            }
            Msg::ContactState(c) => {
                if !c.in_contact {
                    self.reset_contact();
                }
                self.contact = Some(c.clone());
                Ok(Vec::new())
            }
            Msg::Frame(f) => {
                let Some(c) = self.contact.as_ref().filter(|c| c.frame_seq == f.seq) else {
                    return Ok(Vec::new());
                };
                if !c.in_contact {
                    return Ok(Vec::new());
                }
                let c = c.clone();
                // On a rejected frame the tracking state is left as it was.
                Ok(vec![Msg::SlipState(self.step(f, &c)?)])
            }
            _ => Ok(Vec::new()),
        }
    }
}
