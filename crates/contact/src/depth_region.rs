//! The contact region from the gel's depth (the detector's `region: auto | depth`): the
//! half-depth contour of the press ([`crate::depth`]) from a photometric model: the unit's depth
//! calibration, else the sensor kind's default (its profile's `photometric`), else one fitted on
//! each frame itself ([`crate::depth::selfcal`]: up to scale, which the contour does not need).
//!
//! Why depth and not the colour residual: the residual follows the gel's slope, and where its
//! contour lies depends on how fast the skirt around a press falls back to rest, which differs
//! between gels and optics (the contact README's skirt sweep, and real GelSight Mini units that
//! read 0.41x and 1.46x with one residual rule). The depth does not: for a ball pressed into a gel
//! that follows Hertz, the surface at the contact edge lies at half the approach (Johnson,
//! Contact Mechanics, 1985, section 4.2: a^2 = R delta, and inside the contact the surface lies at
//! delta - r^2 / 2R, which is delta / 2 at r = a), so the half-depth contour is the
//! contact edge whatever the skirt outside it; a flat-ended press reads its plateau's edge.
//!
//! The depth is taken only where the residual finds a deformation (entering and leaving
//! contact, and the background's updates, stay the residual's), and its region counts only
//! when at least half of it lies in that deformation: a depth peak elsewhere (a slow shading
//! drift that integrates to a bump) is no contact.

use crate::background::Background;
use crate::depth::{
    DepthCalibration, DepthError, DepthEstimator, DepthParams, DepthSummary, Prep, prepare, selfcal,
};
use crate::grid::Geometry;
use unitac_core::Frame;

/// Where a detector's photometric model comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelSource {
    /// The unit's depth calibration (`unitac calibrate depth`).
    Calibration,
    /// The sensor kind's profile (`photometric`).
    KindDefault,
    /// Fitted on each frame itself (`depth::selfcal`), up to scale: no penetration in metres.
    SelfCalibrated,
}

impl ModelSource {
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Calibration => "calibration",
            Self::KindDefault => "kind default",
            Self::SelfCalibrated => "self-calibrated",
        }
    }
}

/// Share of the depth region that must lie in the residual's deformation for it to count.
const MIN_INSIDE: f64 = 0.5;

/// A detector's depth: the model, and its estimator on the current background (made on first
/// use: a detector whose region is the residual's and that reports no depth never makes one).
#[derive(Debug)]
pub(crate) struct DepthRegion {
    cal: DepthCalibration,
    pub source: ModelSource,
    /// The self-calibration's prepared difference.
    prep: Prep,
    /// The current background, until the estimator is made from it.
    background: Option<Frame>,
    est: Option<DepthEstimator>,
    /// Why the current background has no estimator (another aspect ratio than the model's).
    pub unusable: Option<String>,
    /// The last measured frame's depth, when it was estimated.
    pub last: Option<DepthSummary>,
    /// Estimate every measured frame (a published depth map, a report), not only those whose
    /// region is taken from depth.
    pub every_frame: bool,
    /// The last frame's press gave no self-calibrated model (its colour changed along one line
    /// only: no gel's shading), so it has no depth and its region is the residual's.
    pub unfitted: bool,
}

/// The depth region of one frame, in input pixels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DepthArea {
    pub area_px: u32,
    pub centroid: [f32; 2],
    pub bbox: [u32; 4],
}

impl DepthRegion {
    pub fn new(cal: DepthCalibration, source: ModelSource) -> Self {
        Self {
            cal,
            source,
            prep: Prep::default(),
            background: None,
            est: None,
            unusable: None,
            last: None,
            every_frame: false,
            unfitted: false,
        }
    }

    /// A new background: its size checked against the model's aspect ratio (a size it does not
    /// fit has no depth, with the reason kept); the estimator is made when first needed.
    pub fn on_background(&mut self, bg: &Background) {
        self.clear();
        self.unusable = None;
        let (w, h) = (bg.geo.width, bg.geo.height);
        if self.source == ModelSource::SelfCalibrated && w > 0 && h > 0 {
            // A model fitted on the frames fits frames of any shape: the placeholder takes the
            // background's, the kind's scale per pixel scaled to its width.
            let m_per_px = self.cal.m_per_px * f64::from(self.cal.width) / f64::from(w);
            (self.cal.width, self.cal.height, self.cal.m_per_px) = (w, h, m_per_px);
        }
        if let Err(e) = self.cal.m_per_px_at(w, h) {
            let model = match self.source {
                ModelSource::Calibration => "depth calibration",
                ModelSource::KindDefault => "profile's photometric model",
                ModelSource::SelfCalibrated => "frames (self-calibrated)",
            };
            tracing::warn!(
                "contact: no depth from the {} {model}: {e}",
                self.cal.sensor
            );
            self.unusable = Some(e.to_string());
            return;
        }
        self.background = bg.frame("");
    }

    /// Forget the background and the estimator (the background is learned again).
    pub fn clear(&mut self) {
        self.background = None;
        self.est = None;
        self.last = None;
    }

    /// The estimator, once it was made.
    pub fn estimator(&self) -> Option<&DepthEstimator> {
        self.est.as_ref()
    }

    /// Whether there is a background the model fits.
    pub fn ready(&self) -> bool {
        self.est.is_some() || self.background.is_some()
    }

    /// The depth of `f` when `wanted` or every frame is estimated; then, when `deformed` (the
    /// residual found a deformation), the depth's contact region if it lies in the deformation
    /// (`in_deformation(cell index)` on the grid `geo`; `marker(cell index)`: a masked marker
    /// dot, left out of a self-calibration). Ok(None): no contact by depth.
    pub fn measure(
        &mut self,
        f: &Frame,
        (wanted, deformed): (bool, bool),
        geo: &Geometry,
        in_deformation: impl Fn(usize) -> bool,
        marker: impl Fn(usize) -> bool,
    ) -> Result<Option<DepthArea>, DepthError> {
        self.last = None;
        self.unfitted = false;
        if !(wanted || self.every_frame) {
            return Ok(None);
        }
        let self_calibrated = self.source == ModelSource::SelfCalibrated;
        if self.est.is_none() {
            let Some(bg) = self.background.take() else {
                return Ok(None);
            };
            // Self-calibrated depth has no scale: any penetration counts.
            let params = if self_calibrated {
                DepthParams {
                    min_penetration_m: f32::MIN_POSITIVE,
                    ..DepthParams::default()
                }
            } else {
                DepthParams::default()
            };
            self.est = Some(DepthEstimator::new(self.cal.clone(), bg, params)?);
        }
        let Some(est) = self.est.as_mut() else {
            return Ok(None);
        };
        if self_calibrated {
            // The model from this frame's press: over the deformation (its skirt included,
            // which the fit needs) grown by one cell, less the masked marker dots (a moved dot's
            // colour change is the dot's, not the gel's slope).
            prepare(&mut self.prep, f, est.background())?;
            let (w, h) = est.size();
            let st = geo.stride as usize;
            let (gw, gh) = (geo.gw, geo.gh);
            let grown = |gx: usize, gy: usize| {
                (gx.saturating_sub(1)..=(gx + 1).min(gw - 1)).any(|x| {
                    (gy.saturating_sub(1)..=(gy + 1).min(gh - 1))
                        .any(|y| in_deformation(y * gw + x))
                })
            };
            let cells: Vec<bool> = (0..gw * gh)
                .map(|i| !marker(i) && grown(i % gw, i / gw))
                .collect();
            let mask: Vec<bool> = (0..w * h)
                .map(|i| {
                    let (gx, gy) = ((i % w) / st, (i / w) / st);
                    gx < gw && gy < gh && cells[gy * gw + gx]
                })
                .collect();
            match selfcal::fit(&self.prep.diff, w, h, &mask) {
                Some(k) => est.set_linear_model(k),
                None => {
                    self.unfitted = true;
                    return Ok(None);
                }
            }
        }
        let mut s = est.estimate(f)?;
        if self_calibrated {
            s.penetration_m = f32::NAN;
        }
        self.last = Some(s);
        if !(deformed && s.contact) {
            return Ok(None);
        }
        let (w, st) = (est.size().0, geo.stride as usize);
        let (mut n, mut inside) = (0u64, 0u64);
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0u32, 0u32);
        for (i, _) in est.mask().iter().enumerate().filter(|(_, m)| **m) {
            let (x, y) = (i % w, i / w);
            n += 1;
            let (gx, gy) = (x / st, y / st);
            if gx < geo.gw && gy < geo.gh && in_deformation(gy * geo.gw + gx) {
                inside += 1;
            }
            x0 = x0.min(x as u32);
            y0 = y0.min(y as u32);
            x1 = x1.max(x as u32 + 1);
            y1 = y1.max(y as u32 + 1);
        }
        if n == 0 || (inside as f64) < MIN_INSIDE * n as f64 {
            return Ok(None);
        }
        Ok(Some(DepthArea {
            area_px: s.area_px,
            centroid: s.centroid_px,
            bbox: [x0, y0, x1, y1],
        }))
    }
}
