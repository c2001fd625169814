//! Detector parameters (the `params:` of a `contact` stage in a scene file).

use serde::Deserialize;

/// Unknown keys are errors; every value is range-checked by [`ContactParams::check`].
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactParams {
    /// Frames averaged into the initial background (no contact allowed meanwhile).
    pub learn_frames: u32,
    /// Detection grid: the mean of each stride x stride block (1 = full resolution).
    pub stride: u32,
    /// Cell threshold on the 3-channel absolute difference, in units of the measured per-channel
    /// noise sigma of a grid cell.
    pub noise_k: f32,
    /// Lower bound of that threshold [DN, summed over channels].
    pub min_threshold: f32,
    /// Noise sigma per channel [DN] assumed when there was no sequence to measure it from
    /// (a single background image, as in `unitac contact`).
    pub default_noise_dn: f32,
    /// Contact starts when the contact area reaches this [px of the input image] ...
    pub enter_area_px: f32,
    /// ... and ends when it falls below this [px].
    pub exit_area_px: f32,
    /// Connected regions smaller than this are ignored [px].
    pub min_component_px: f32,
    /// Morphological opening radius [px] (removes specks), then closing radius [px] (fills the
    /// dark line a real contact can show, and masked marker dots). Rounded to grid cells, at least
    /// one cell when non-zero.
    pub open_radius_px: u32,
    pub close_radius_px: u32,
    /// Consecutive frames needed to enter contact ...
    pub debounce_frames: u32,
    /// ... and to leave it (the exit area is already a hysteresis band below the enter area).
    pub exit_debounce_frames: u32,
    /// Background EMA weight per no-contact frame (cells in the current mask are never updated).
    pub ema_alpha: f32,
    /// Ignore the gel's marker dots (dark spots of the background). None = by sensor kind
    /// (on for GelSight Mini).
    pub mask_markers: Option<bool>,
    /// Frames whose share of saturated (>= 250) or dark (<= 5) pixels exceeds this are rejected.
    pub max_bad_pixel_share: f32,
    /// Frames kept per episode for the encoder (0 = no clips are emitted).
    pub clip_frames: u32,
    /// Directory of saved backgrounds (`<serial>.unitac-bg`): loaded when the stage starts if one
    /// matches the sensor and frame size (no learning needed), saved when the stage finishes.
    pub background_dir: Option<std::path::PathBuf>,
    /// Labels given to episodes in order (e.g. [fabric_a, fabric_b]); later episodes get "".
    pub episode_labels: Vec<String>,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            learn_frames: 10,
            stride: 2,
            noise_k: 3.0,
            min_threshold: 3.0,
            default_noise_dn: 1.0,
            enter_area_px: 120.0,
            exit_area_px: 60.0,
            min_component_px: 40.0,
            open_radius_px: 2,
            close_radius_px: 4,
            debounce_frames: 2,
            exit_debounce_frames: 1,
            ema_alpha: 0.02,
            mask_markers: None,
            max_bad_pixel_share: 0.5,
            clip_frames: 0,
            background_dir: None,
            episode_labels: Vec::new(),
        }
    }
}

/// Largest episode clip (frames), whatever the scene says: bounds memory per episode.
pub const MAX_CLIP_FRAMES: u32 = 256;

impl ContactParams {
    pub fn check(&self) -> Result<(), String> {
        let finite_pos = |v: f32| v.is_finite() && v > 0.0;
        if !(1..=1000).contains(&self.learn_frames) {
            return Err(format!(
                "learn_frames {} is outside 1..=1000",
                self.learn_frames
            ));
        }
        if !(1..=16).contains(&self.stride) {
            return Err(format!("stride {} is outside 1..=16", self.stride));
        }
        if !(finite_pos(self.noise_k)
            && self.min_threshold.is_finite()
            && self.min_threshold >= 0.0)
        {
            return Err("noise_k must be > 0 and min_threshold >= 0".into());
        }
        if !finite_pos(self.default_noise_dn) {
            return Err("default_noise_dn must be > 0".into());
        }
        if !(self.exit_area_px.is_finite()
            && self.exit_area_px >= 0.0
            && self.exit_area_px <= self.enter_area_px
            && self.enter_area_px.is_finite())
        {
            return Err("need 0 <= exit_area_px <= enter_area_px".into());
        }
        if !(self.min_component_px.is_finite() && self.min_component_px >= 0.0) {
            return Err("min_component_px must be >= 0".into());
        }
        if self.open_radius_px > 32 || self.close_radius_px > 32 {
            return Err("open_radius_px and close_radius_px must be <= 32".into());
        }
        if !(self.ema_alpha >= 0.0 && self.ema_alpha < 1.0) {
            return Err(format!("ema_alpha {} is outside [0, 1)", self.ema_alpha));
        }
        if self.debounce_frames > 1000 || self.exit_debounce_frames > 1000 {
            return Err(format!(
                "debounce_frames {} and exit_debounce_frames {} must be <= 1000",
                self.debounce_frames, self.exit_debounce_frames
            ));
        }
        if let Some(d) = &self.background_dir {
            if !d.is_dir() {
                return Err(format!("background_dir {} is not a directory", d.display()));
            }
        }
        if !(self.max_bad_pixel_share > 0.0 && self.max_bad_pixel_share <= 1.0) {
            return Err("max_bad_pixel_share must be in (0, 1]".into());
        }
        if self.clip_frames > MAX_CLIP_FRAMES {
            return Err(format!(
                "clip_frames {} is above {MAX_CLIP_FRAMES}",
                self.clip_frames
            ));
        }
        Ok(())
    }
}
