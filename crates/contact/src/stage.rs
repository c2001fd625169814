//! The detector as a runtime [`Stage`]: frames in; ContactState per frame, ContactEpisode (and
//! ContactClip) on release, and the background announced downstream when it is learned.
//! Saved backgrounds come from an injected [`BackgroundStore`]: the stage does no file I/O.

use crate::depth::DepthCalibration;
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
    /// Publish every frame's depth map (`with_depth`: a unit's depth calibration given).
    publish_depth: bool,
    /// With the overlay on a marker gel: the markers followed while in contact, drawn as arrows
    /// from rest (found and tracked as the slip stage does, with its default parameters).
    markers: Option<(MarkerField, SlipParams)>,
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
        let mut det = ContactDetector::new(p, spec)?;
        // The overlay's depth panel: every frame's depth, where there is a model.
        det.estimate_depth_every_frame(det.params().overlay);
        Ok(Self {
            det,
            sensor_id: String::new(),
            announced: false,
            store,
            store_asked: false,
            store_error: None,
            publish_depth: false,
            markers,
        })
    }

    /// Depth from a unit's calibration (`unitac calibrate depth`) instead of the sensor kind's
    /// default photometric model: the contact region's (its half-depth contour, unless
    /// `region: residual`), and every frame after the background is known gets its depth map
    /// ([`Msg::Depth`]). The calibration must be for this sensor's aspect ratio (checked when
    /// the scene is loaded); the estimator follows each new background.
    pub fn with_depth(mut self, cal: DepthCalibration) -> Self {
        self.det.set_depth_calibration(cal, true);
        self.publish_depth = true;
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
    /// background is known), as a [`Msg::Depth`] after that ContactState. The depth is unknown
    /// (NaN) under the masked marker dots, where the gel's colour is the dots' and not its
    /// shading.
    fn publish_depth(&self, f: &Frame, out: &mut Vec<Msg>) {
        if !out.iter().any(|m| matches!(m, Msg::ContactState(_))) {
            return;
        }
        let Some(depth_m) = self.det.depth_map_m() else {
            return;
        };
        let Some((_, Some(s))) = self.det.depth() else {
            return;
        };
        out.push(Msg::Depth(DepthMap {
            header: Header::optical(f.stamp, &f.sensor_id),
            width: f.width,
            height: f.height,
            pixel_m: s.m_per_px,
            depth_m,
        }));
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
        // With a depth model the depth panel is always there (the picture keeps its size), all
        // unknown until the first depth map.
        let n = f.width as usize * f.height as usize;
        let estimated = self.det.depth().filter(|(_, s)| s.is_some());
        let depth_m: Option<Vec<f32>> = self
            .det
            .depth_model()
            .map(|_| self.det.depth_map_m().unwrap_or_else(|| vec![f32::NAN; n]));
        let mask = estimated.map_or(&[][..], |(e, _)| e.mask());
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
                if self.det.is_learned() != self.announced {
                    self.announced = self.det.is_learned();
                    if let Some(bg) = self.det.background_frame(&f.sensor_id) {
                        out.insert(0, Msg::Background(bg));
                    }
                }
                if self.publish_depth {
                    self.publish_depth(f, &mut out);
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
