//! The contact region from the gel's depth (the detector's `region: auto | depth`): the
//! half-depth contour of the press ([`crate::depth`]) from a photometric model, the unit's depth
//! calibration or else the sensor kind's default (its profile's `photometric`).
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
use crate::depth::{DepthCalibration, DepthError, DepthEstimator, DepthParams, DepthSummary};
use crate::grid::Geometry;
use unitac_core::Frame;

/// Share of the depth region that must lie in the residual's deformation for it to count.
const MIN_INSIDE: f64 = 0.5;

/// A detector's depth: the model, and its estimator on the current background (made on first
/// use: a detector whose region is the residual's and that reports no depth never makes one).
#[derive(Debug)]
pub(crate) struct DepthRegion {
    cal: DepthCalibration,
    /// The model is the sensor kind's default, not a unit's calibration.
    pub kind_default: bool,
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
}

/// The depth region of one frame, in input pixels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DepthArea {
    pub area_px: u32,
    pub centroid: [f32; 2],
    pub bbox: [u32; 4],
}

impl DepthRegion {
    pub fn new(cal: DepthCalibration, kind_default: bool) -> Self {
        Self {
            cal,
            kind_default,
            background: None,
            est: None,
            unusable: None,
            last: None,
            every_frame: false,
        }
    }

    /// A new background: its size checked against the model's aspect ratio (a size it does not
    /// fit has no depth, with the reason kept); the estimator is made when first needed.
    pub fn on_background(&mut self, bg: &Background) {
        self.clear();
        self.unusable = None;
        if let Err(e) = self.cal.m_per_px_at(bg.geo.width, bg.geo.height) {
            let model = if self.kind_default {
                "profile's photometric model"
            } else {
                "depth calibration"
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
    /// (`in_deformation(cell index)` on the grid `geo`). Ok(None): no contact by depth.
    pub fn measure(
        &mut self,
        f: &Frame,
        (wanted, deformed): (bool, bool),
        geo: &Geometry,
        in_deformation: impl Fn(usize) -> bool,
    ) -> Result<Option<DepthArea>, DepthError> {
        self.last = None;
        if !(wanted || self.every_frame) {
            return Ok(None);
        }
        if self.est.is_none() {
            let Some(bg) = self.background.take() else {
                return Ok(None);
            };
            self.est = Some(DepthEstimator::new(
                self.cal.clone(),
                bg,
                DepthParams::default(),
            )?);
        }
        let Some(est) = self.est.as_mut() else {
            return Ok(None);
        };
        let s = est.estimate(f)?;
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
