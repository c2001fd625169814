//! The detector as a runtime [`Stage`]: frames in; ContactState per frame, ContactEpisode (and
//! EpisodeClip) on release, and the background announced downstream when it is learned.

use crate::background::{Background, BackgroundFileError};
use crate::detector::ContactDetector;
use crate::params::{ContactParams, ParamsError};
use unitac_core::{Clock, Frame, Msg, SensorSpec, Stage, StageError};

/// The detector as a runtime stage: consumes frames, emits ContactState per frame and
/// ContactEpisode (plus an EpisodeClip when `clip_frames` > 0) on release.
#[derive(Debug)]
pub struct ContactStage {
    det: ContactDetector,
    sensor_id: String,
    /// Whether the current background was announced downstream (Msg::Background).
    announced: bool,
}

impl ContactStage {
    pub fn new(p: ContactParams, spec: SensorSpec) -> Result<Self, ParamsError> {
        Ok(Self {
            det: ContactDetector::new(p, spec)?,
            sensor_id: String::new(),
            announced: false,
        })
    }
    pub fn detector(&self) -> &ContactDetector {
        &self.det
    }
    pub fn detector_mut(&mut self) -> &mut ContactDetector {
        &mut self.det
    }
}

impl ContactStage {
    /// Load `<background_dir>/<serial>.unitac-bg` once the first frame tells the serial and size.
    /// A missing file means "learn"; an unreadable or mismatched one is logged by the caller
    /// through the returned error and the stage learns instead.
    fn load_saved_background(&mut self, f: &Frame) -> Result<(), BackgroundFileError> {
        let Some(dir) = self.det.params().background_dir.clone() else {
            return Ok(());
        };
        let path = Background::path_for(&dir, &f.sensor_id);
        if !path.exists() {
            return Ok(());
        }
        let bg = Background::load(&path, f.width, f.height, self.det.params().stride)?;
        self.det.set_background(bg);
        Ok(())
    }
}

impl Stage for ContactStage {
    fn name(&self) -> &str {
        "contact"
    }
    fn process(&mut self, input: &Msg, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        match input {
            Msg::Frame(f) => {
                if self.sensor_id.is_empty() {
                    self.sensor_id.clone_from(&f.sensor_id);
                    if let Err(e) = self.load_saved_background(f) {
                        self.sensor_id.clear();
                        return Err(StageError::Other(format!("saved background not used: {e}")));
                    }
                }
                let mut out = self.det.step(f)?;
                if self.det.is_learned() != self.announced {
                    self.announced = self.det.is_learned();
                    if let Some(bg) = self.det.background_frame(&f.sensor_id) {
                        out.insert(0, Msg::Background(bg));
                    }
                }
                Ok(out)
            }
            _ => Ok(Vec::new()),
        }
    }
    /// Closes an open episode and, with `background_dir`, saves the current background.
    fn finish(&mut self, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        let out = self.det.flush(&self.sensor_id);
        if let (Some(dir), Some(bg)) = (&self.det.params().background_dir, self.det.background()) {
            let path = Background::path_for(dir, &self.sensor_id);
            bg.save(&path)
                .map_err(|e| StageError::Other(e.to_string()))?;
        }
        Ok(out)
    }
}
