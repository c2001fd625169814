//! Detector parameters (the `params:` of a `contact` stage in a scene file).

use serde::Deserialize;

/// Unknown keys are errors; every value is range-checked by [`ContactParams::check`].
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
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
    /// Noise sigma per channel \[DN] assumed when there was no sequence to measure it from
    /// (a single background image, as in `unitac contact`).
    pub default_noise_dn: f32,
    /// Contact starts when the contact area reaches this [px of the input image] ...
    pub enter_area_px: f32,
    /// ... and ends when it falls below this \[px].
    pub exit_area_px: f32,
    /// Connected regions smaller than this are ignored \[px].
    pub min_component_px: f32,
    /// Morphological opening radius \[px] (removes specks), then closing radius \[px] (fills the
    /// dark line a real contact can show, and masked marker dots). Rounded to grid cells, at least
    /// one cell when non-zero.
    pub open_radius_px: u32,
    pub close_radius_px: u32,
    /// The contact region, from which area, centroid, bounding box and strength are measured:
    /// per connected region over the noise threshold, the cells whose residual reaches this share
    /// of the region's own peak (its 90th percentile), never below the threshold; closed, holes
    /// filled. 0.5 is a half-maximum contour: it leaves out most of the gel's skirt around a
    /// deep press (`peel_skirt` the rest). 0 = every cell over the noise threshold.
    pub area_level: f32,
    /// Peel the skirt's flank off the contact region: from its edge inward, the cells whose
    /// residual keeps rising, below the component's robust peak, are the gel sloping back to
    /// rest outside the contact, not contact (`flank.rs`). The region then ends at the press's
    /// ridge, where the gel's slope peaks and a ball leaves it, whatever the skirt's width:
    /// ball presses read 0.96-1.46x their Hertz disc on every skirt of `unitac-lab eval contact`,
    /// where the half-level contour alone reads 1.1-2.5x. On a noisy frame the region is grown
    /// back by the box mean's radius after the peel. False: the half-level contour.
    pub peel_skirt: bool,
    /// Where the contact region comes from: `auto` (default) the gel's depth (its half-depth
    /// contour, `crate::depth_region`) with a `depth_calibration`, else the colour residual
    /// (`area_level`, `peel_skirt`); `depth` the depth from the calibration, else the sensor
    /// kind's default photometric model (GelSight Mini's), else a linear model fitted on each
    /// frame's press itself (`depth::selfcal`); `residual` the residual whatever the model.
    pub region: RegionRule,
    /// Consecutive frames needed to enter contact ...
    pub debounce_frames: u32,
    /// ... and to leave it (the exit area is already a hysteresis band below the enter area).
    pub exit_debounce_frames: u32,
    /// Background EMA weight per no-contact frame (cells in the current mask are never updated).
    pub ema_alpha: f32,
    /// Ignore the gel's marker dots (dark spots of the background). None = by sensor kind: on for
    /// a kind with markers (GelSight Mini), off for one without, and for one whose markers are
    /// unknown (`generic`) the dots the background shows as a grid of small dark spots.
    pub mask_markers: Option<bool>,
    /// Frames whose share of saturated (>= 250) or dark (<= 5) pixels exceeds this are rejected.
    pub max_bad_pixel_share: f32,
    /// A frame of another size than the background's is rejected (an error, nothing else
    /// changes); this many in a row of one new size and the background is learned again at that
    /// size (the sensor changed resolution).
    pub new_size_frames: u32,
    /// The pixel parameters (areas, radii, stride) are for a 320x240 frame and scale with the
    /// frame: x2 linear (x4 area) at 640x480. False: taken as they are at every size.
    pub scale_with_size: bool,
    /// Frames kept per episode for the encoder (0 = no clips are emitted).
    pub clip_frames: u32,
    /// Directory of saved backgrounds (`<serial>.unitac-bg`): loaded when the stage starts if one
    /// matches the sensor and frame size (no learning needed), saved when the stage finishes.
    pub background_dir: Option<std::path::PathBuf>,
    /// Labels given to episodes in order (e.g. [fabric_a, fabric_b]); later episodes get "".
    pub episode_labels: Vec<String>,
    /// A depth calibration file (`unitac calibrate depth`): when set, the contact's area,
    /// centroid and box come from the gel's depth (its half-depth contour) instead of the
    /// colour residual. Loaded and checked against the sensor when the scene is loaded.
    pub depth_calibration: Option<std::path::PathBuf>,
    /// Emit a picture per frame for a person (`crate::overlay`: the frame with the contact
    /// outline and centroid, beside it the depth colour map with a depth calibration): the
    /// contact node's `contact_overlay` topic. Off by default (it costs a frame's copy).
    pub overlay: bool,
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
            area_level: 0.5,
            peel_skirt: true,
            region: RegionRule::Auto,
            debounce_frames: 2,
            exit_debounce_frames: 1,
            ema_alpha: 0.02,
            mask_markers: None,
            max_bad_pixel_share: 0.5,
            new_size_frames: 5,
            scale_with_size: true,
            clip_frames: 0,
            background_dir: None,
            episode_labels: Vec::new(),
            depth_calibration: None,
            overlay: false,
        }
    }
}

/// Where the contact region comes from ([`ContactParams::region`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionRule {
    /// Depth with a unit's depth calibration, else the residual.
    #[default]
    Auto,
    /// Depth from the unit's calibration, the kind's default model, or one fitted on the frame.
    Depth,
    /// The colour residual's region (`area_level`, `peel_skirt`).
    Residual,
}

impl RegionRule {
    pub const NAMES: [&'static str; 3] = ["auto", "depth", "residual"];
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Depth => "depth",
            Self::Residual => "residual",
        }
    }
}

impl std::str::FromStr for RegionRule {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "auto" => Ok(Self::Auto),
            "depth" => Ok(Self::Depth),
            "residual" => Ok(Self::Residual),
            _ => Err(format!("{s:?} is not one of {}", Self::NAMES.join(", "))),
        }
    }
}

/// Largest episode clip (frames), whatever the scene says: bounds memory per episode.
pub const MAX_CLIP_FRAMES: u32 = 256;

/// A parameter out of its range (scene file, ROS parameter, code).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamsError {
    #[error("{name} {value} is outside {range}")]
    OutOfRange {
        name: &'static str,
        value: String,
        range: &'static str,
    },
    #[error("need 0 <= exit_area_px <= enter_area_px, got exit {exit} and enter {enter}")]
    AreaBand { enter: f32, exit: f32 },
    #[error("background_dir {} is not a directory", .0.display())]
    NotADirectory(std::path::PathBuf),
    #[error("the slip stage tracks marker dots and a {sensor} gel has none")]
    NoMarkers { sensor: String },
}

fn out_of_range(name: &'static str, value: impl ToString, range: &'static str) -> ParamsError {
    ParamsError::OutOfRange {
        name,
        value: value.to_string(),
        range,
    }
}

impl ContactParams {
    pub fn check(&self) -> Result<(), ParamsError> {
        let finite_pos = |v: f32| v.is_finite() && v > 0.0;
        if !(1..=1000).contains(&self.learn_frames) {
            return Err(out_of_range("learn_frames", self.learn_frames, "1..=1000"));
        }
        if !(1..=16).contains(&self.stride) {
            return Err(out_of_range("stride", self.stride, "1..=16"));
        }
        if !finite_pos(self.noise_k) {
            return Err(out_of_range("noise_k", self.noise_k, "(0, inf)"));
        }
        if !(self.min_threshold.is_finite() && self.min_threshold >= 0.0) {
            return Err(out_of_range(
                "min_threshold",
                self.min_threshold,
                "[0, inf)",
            ));
        }
        if !finite_pos(self.default_noise_dn) {
            return Err(out_of_range(
                "default_noise_dn",
                self.default_noise_dn,
                "(0, inf)",
            ));
        }
        if !(self.exit_area_px.is_finite()
            && self.exit_area_px >= 0.0
            && self.exit_area_px <= self.enter_area_px
            && self.enter_area_px.is_finite())
        {
            return Err(ParamsError::AreaBand {
                enter: self.enter_area_px,
                exit: self.exit_area_px,
            });
        }
        if !(self.min_component_px.is_finite() && self.min_component_px >= 0.0) {
            return Err(out_of_range(
                "min_component_px",
                self.min_component_px,
                "[0, inf)",
            ));
        }
        if self.open_radius_px > 32 {
            return Err(out_of_range(
                "open_radius_px",
                self.open_radius_px,
                "0..=32",
            ));
        }
        if self.close_radius_px > 32 {
            return Err(out_of_range(
                "close_radius_px",
                self.close_radius_px,
                "0..=32",
            ));
        }
        if !(0.0..1.0).contains(&self.area_level) {
            return Err(out_of_range("area_level", self.area_level, "[0, 1)"));
        }
        if !(self.ema_alpha >= 0.0 && self.ema_alpha < 1.0) {
            return Err(out_of_range("ema_alpha", self.ema_alpha, "[0, 1)"));
        }
        if self.debounce_frames > 1000 {
            return Err(out_of_range(
                "debounce_frames",
                self.debounce_frames,
                "0..=1000",
            ));
        }
        if self.exit_debounce_frames > 1000 {
            return Err(out_of_range(
                "exit_debounce_frames",
                self.exit_debounce_frames,
                "0..=1000",
            ));
        }
        if let Some(d) = &self.background_dir {
            if !d.is_dir() {
                return Err(ParamsError::NotADirectory(d.clone()));
            }
        }
        if !(self.max_bad_pixel_share > 0.0 && self.max_bad_pixel_share <= 1.0) {
            return Err(out_of_range(
                "max_bad_pixel_share",
                self.max_bad_pixel_share,
                "(0, 1]",
            ));
        }
        if !(1..=1000).contains(&self.new_size_frames) {
            return Err(out_of_range(
                "new_size_frames",
                self.new_size_frames,
                "1..=1000",
            ));
        }
        if self.clip_frames > MAX_CLIP_FRAMES {
            return Err(out_of_range("clip_frames", self.clip_frames, "0..=256"));
        }
        Ok(())
    }
}
