//! The detector as a runtime [`Stage`]: frames in; ContactState per frame, ContactEpisode (and
//! ContactClip) on release, and the background announced downstream when it is learned.
//! Saved backgrounds come from an injected [`BackgroundStore`]: the stage does no file I/O.

use crate::depth::{DepthCalibration, DepthEstimator, DepthParams};
use crate::detector::ContactDetector;
use crate::overlay::{DepthPanel, Overlay, draw};
use crate::params::{ContactParams, ParamsError};
use crate::slip::{MarkerField, SlipParams};
use crate::store::{BackgroundStore, DirStore};
use unitac_core::msg::{DepthMap, Header};
use unitac_core::{Clock, Frame, Msg, SensorSpec, Stage, StageError};

/// The detector as a runtime stage: consumes frames, emits ContactState per frame and
/// ContactEpisode (plus an ContactClip when `clip_frames` > 0) on release.
#[derive(Debug)]
pub struct ContactStage {
    det: ContactDetector,
    sensor_id: String,
    /// Whether the current background was announced downstream (Msg::Background).
    announced: bool,
    store: Option<Box<dyn BackgroundStore>>,
    /// Whether the store was asked (once, on the first frame).
    store_asked: bool,
    /// Why the saved background was not used (asked once, on the first frame).
    store_error: Option<String>,
    /// Depth from the gel's shading (`with_depth`): the contact's area, centroid and box come
    /// from the depth's contact region.
    depth: Option<DepthUse>,
    /// With the overlay on a marker gel: the markers followed while in contact, drawn as arrows
    /// from rest (found and tracked as the slip stage does, with its default parameters).
    markers: Option<(MarkerField, SlipParams)>,
}

/// The depth calibration and its estimator on the current background.
#[derive(Debug)]
struct DepthUse {
    cal: DepthCalibration,
    est: Option<DepthEstimator>,
    /// Pixels of unknown depth (the background's marker dots), at the estimator's size.
    unknown: Vec<bool>,
    /// A background announced since the estimator was made.
    new_background: bool,
}

impl ContactStage {
    /// A stage whose saved backgrounds, if `background_dir` is set, are files in that directory
    /// ([`DirStore`]).
    pub fn new(p: ContactParams, spec: SensorSpec) -> Result<Self, ParamsError> {
        let store = p
            .background_dir
            .clone()
            .map(|d| Box::new(DirStore::new(d)) as Box<dyn BackgroundStore>);
        Self::with_store(p, spec, store)
    }

    /// A stage with its own store of saved backgrounds (None: always learn, never save).
    pub fn with_store(
        p: ContactParams,
        spec: SensorSpec,
        store: Option<Box<dyn BackgroundStore>>,
    ) -> Result<Self, ParamsError> {
        let slip = SlipParams::default();
        let markers = (p.overlay && slip.check_for(spec.kind).is_ok())
            .then(|| (MarkerField::default(), slip));
        Ok(Self {
            det: ContactDetector::new(p, spec)?,
            sensor_id: String::new(),
            announced: false,
            store,
            store_asked: false,
            store_error: None,
            depth: None,
            markers,
        })
    }

    /// Take the contact's area (px, mm^2), centroid and bounding box from the gel's depth
    /// (crate::depth): the half-depth contour of the press, not the colour residual's, which on
    /// a real gel takes in the skirt around a press. Entering and leaving contact (hysteresis,
    /// episodes) stay the detector's. The calibration must be for this sensor's aspect ratio
    /// (checked when the scene is loaded); the estimator follows each new background. Every
    /// frame after the background is known also gets its depth map ([`Msg::Depth`]).
    pub fn with_depth(mut self, cal: DepthCalibration) -> Self {
        self.depth = Some(DepthUse {
            cal,
            est: None,
            unknown: Vec::new(),
            new_background: false,
        });
        self
    }
    pub fn detector(&self) -> &ContactDetector {
        &self.det
    }
    /// Why the saved background could not be used, if it could not (the stage learned instead).
    pub fn store_error(&self) -> Option<&str> {
        self.store_error.as_deref()
    }

    /// Ask the store once, on the first frame (which tells the serial and size). Nothing saved
    /// means "learn"; an unreadable or mismatched background is warned about and the stage
    /// learns instead.
    fn load_saved_background(&mut self, f: &Frame) {
        let Some(store) = self.store.as_mut() else {
            return;
        };
        let stride = self.det.geometry_for(f.width, f.height).stride;
        match store.load(&f.sensor_id, f.width, f.height, stride) {
            Ok(Some(bg)) => self.det.set_background(bg),
            Ok(None) => {}
            Err(e) => {
                tracing::warn!("contact: saved background not used, learning instead: {e}");
                self.store_error = Some(e.to_string());
            }
        }
    }
}

impl ContactStage {
    /// With a depth calibration: the depth of every frame with a ContactState (once the
    /// background is known), as a [`Msg::Depth`] after that ContactState, whose area, centroid and box it replaces
    /// while in contact. The depth is unknown (NaN) under the masked marker dots, where the
    /// gel's colour is the dots' and not its shading.
    fn apply_depth(
        &mut self,
        f: &Frame,
        out: &mut Vec<Msg>,
        new_background: bool,
    ) -> Result<(), StageError> {
        let Some(d) = self.depth.as_mut() else {
            return Ok(());
        };
        // A new background is taken at the next frame with a state (frames that learn the
        // background have no state, and no depth either).
        d.new_background |= new_background;
        if !out.iter().any(|m| matches!(m, Msg::ContactState(_))) {
            return Ok(());
        }
        let stale = d
            .est
            .as_ref()
            .is_none_or(|e| d.new_background || e.size() != (f.width as usize, f.height as usize));
        if stale {
            d.new_background = false;
            d.est = match self.det.background_frame(&f.sensor_id) {
                Some(bg) => Some(
                    DepthEstimator::new(d.cal.clone(), bg, DepthParams::default())
                        .map_err(StageError::bad_input)?,
                ),
                None => None,
            };
            d.unknown = self.det.marker_mask_px();
        }
        let Some(est) = d.est.as_mut() else {
            return Ok(());
        };
        let s = est.estimate(f).map_err(StageError::bad_input)?;
        for m in out.iter_mut() {
            let Msg::ContactState(cs) = m else { continue };
            if !cs.in_contact || !s.contact {
                continue;
            }
            let (w, mask) = (est.size().0, est.mask());
            let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0u32, 0u32);
            for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
                let (x, y) = ((i % w) as u32, (i / w) as u32);
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x + 1);
                y1 = y1.max(y + 1);
            }
            cs.area_px = s.area_px as f32;
            cs.area_m2 = s.area_m2 as f32;
            cs.centroid_px = s.centroid_px;
            cs.bbox_px = [x0, y0, x1, y1];
        }
        let depth_m = est
            .depth_m()
            .iter()
            .enumerate()
            .map(|(i, v)| {
                if d.unknown.get(i).copied().unwrap_or(false) {
                    f32::NAN
                } else {
                    *v
                }
            })
            .collect();
        out.push(Msg::Depth(DepthMap {
            header: Header::optical(f.stamp, &f.sensor_id),
            width: f.width,
            height: f.height,
            pixel_m: s.m_per_px,
            depth_m,
        }));
        Ok(())
    }

    /// The overlay's marker field: learned from each background announced, followed on frames
    /// in contact, forgotten out of contact. A background with too few markers, or a frame the
    /// markers cannot be found in, draws no arrows (the overlay is for a person; the slip stage
    /// reports such frames).
    fn follow_markers(&mut self, f: &Frame, out: &[Msg]) {
        let Some((field, p)) = self.markers.as_mut() else {
            return;
        };
        // The background this frame announced, if it announced one.
        for m in out {
            if let Msg::Background(bg) = m
                && let Err(e) = field.learn(bg, p)
            {
                tracing::warn!("contact overlay: no marker arrows: {e}");
            }
        }
        let in_contact = out
            .iter()
            .any(|m| matches!(m, Msg::ContactState(c) if c.in_contact));
        if !in_contact || field.follow(f, p).is_err() {
            field.reset();
        }
    }

    /// The overlay of this frame (`overlay` param) from what the stage saw: the detector's
    /// contact region, the ContactState's centroid and the markers' displacements from rest
    /// while in contact, the depth panel with a depth calibration.
    fn overlay(&self, f: &Frame, out: &[Msg]) -> Result<Frame, StageError> {
        let contact = self.det.mask_px();
        let centroid = out.iter().find_map(|m| match m {
            Msg::ContactState(c) if c.in_contact => Some(c.centroid_px),
            _ => None,
        });
        // With a calibration the depth panel is always there (the picture keeps its size), all
        // unknown until the first depth map.
        let n = f.width as usize * f.height as usize;
        let depth_m: Option<Vec<f32>> = self.depth.as_ref().map(|_| {
            out.iter()
                .find_map(|m| match m {
                    Msg::Depth(d) => Some(d.depth_m.clone()),
                    _ => None,
                })
                .unwrap_or_else(|| vec![f32::NAN; n])
        });
        let has_depth = out.iter().any(|m| matches!(m, Msg::Depth(_)));
        let mask = self
            .depth
            .as_ref()
            .and_then(|d| d.est.as_ref())
            .filter(|_| has_depth)
            .map(DepthEstimator::mask)
            .unwrap_or(&[]);
        let depth = depth_m
            .as_deref()
            .map(|depth_m| DepthPanel { depth_m, mask });
        let arrows = self
            .markers
            .as_ref()
            .map(|(field, _)| field.displacements())
            .unwrap_or_default();
        let o = Overlay {
            contact: &contact,
            centroid,
            arrows: &arrows,
            depth,
        };
        draw(f, &o).map_err(StageError::bad_input)
    }
}

impl Stage for ContactStage {
    fn name(&self) -> &str {
        "contact"
    }
    fn process(&mut self, input: &Msg, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        match input {
            Msg::Frame(f) => {
                if !self.store_asked {
                    self.store_asked = true;
                    self.sensor_id.clone_from(&f.sensor_id);
                    self.load_saved_background(f);
                }
                let mut out = self.det.step(f)?;
                let mut new_background = false;
                if self.det.is_learned() != self.announced {
                    self.announced = self.det.is_learned();
                    if let Some(bg) = self.det.background_frame(&f.sensor_id) {
                        out.insert(0, Msg::Background(bg));
                        new_background = true;
                    }
                }
                if self.depth.is_some() {
                    self.apply_depth(f, &mut out, new_background)?;
                }
                if self.det.params().overlay {
                    self.follow_markers(f, &out);
                    let o = self.overlay(f, &out)?;
                    out.push(Msg::ContactOverlay(o));
                }
                Ok(out)
            }
            _ => Ok(Vec::new()),
        }
    }
    /// Closes an open episode and hands the current background to the store.
    fn finish(&mut self, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        let out = self.det.flush(&self.sensor_id);
        if let (Some(store), Some(bg)) = (self.store.as_mut(), self.det.background()) {
            store
                .save(&self.sensor_id, bg)
                .map_err(|e| StageError::Storage {
                    what: "saving the background",
                    source: Box::new(e),
                })?;
        }
        Ok(out)
    }
}
