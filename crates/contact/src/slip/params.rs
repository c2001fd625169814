//! Slip stage parameters (the `params:` of a `slip` stage in a scene file).

use serde::Deserialize;

use super::markers::DotParams;
use super::track::TrackParams;
use crate::params::ParamsError;

/// Unknown keys are errors; every value is range-checked by [`SlipParams::check`]. Pixel values
/// are in the input image's pixels.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlipParams {
    /// Half-width of the box a pixel is compared with to find dots \[px].
    pub box_radius_px: u32,
    /// A pixel darker than this fraction of its box's mean luminance is part of a dot.
    pub dot_ratio: f64,
    /// Dot area bounds \[px].
    pub min_dot_area_px: u32,
    pub max_dot_area_px: u32,
    /// Fewest dots the background must show; fewer and every SlipState is invalid.
    pub min_reference_markers: u32,
    /// Radius a marker is looked for in around where it was last seen \[px] (capped at half the
    /// marker pitch).
    pub search_px: f64,
    /// The second-nearest dot must be this many times farther than the nearest.
    pub ambiguity_ratio: f64,
    /// Frames in contact before the marker field is taken as the contact's reference (shear and
    /// slip are measured from it, so the press's own radial spread is not shear).
    pub onset_frames: u32,
    /// Markers within this many contact radii of the contact centroid are fitted (contact radius
    /// = sqrt(area / pi) of the ContactState).
    pub fit_radius: f64,
    /// Markers within this many contact radii form the stuck centre the rim is compared with
    /// (at least the three nearest).
    pub inner_radius: f64,
    /// Fewest fitted markers for a valid SlipState.
    pub min_markers: u32,
    /// Motion per rim marker added to the slip score's denominator \[px]: below this much
    /// motion, a lag is noise.
    pub motion_floor_px: f64,
    /// The slip flag rises when slip_score reaches `slip_on` and falls below `slip_off`.
    pub slip_on: f64,
    pub slip_off: f64,
}

impl Default for SlipParams {
    fn default() -> Self {
        Self {
            box_radius_px: 7,
            dot_ratio: 0.7,
            min_dot_area_px: 4,
            max_dot_area_px: 200,
            min_reference_markers: 8,
            search_px: 8.0,
            ambiguity_ratio: 2.0,
            onset_frames: 3,
            fit_radius: 1.0,
            inner_radius: 0.6,
            min_markers: 4,
            motion_floor_px: 1.5,
            slip_on: 0.08,
            slip_off: 0.05,
        }
    }
}

fn out_of_range(name: &'static str, value: impl ToString, range: &'static str) -> ParamsError {
    ParamsError::OutOfRange {
        name,
        value: value.to_string(),
        range,
    }
}

impl SlipParams {
    pub fn check(&self) -> Result<(), ParamsError> {
        let within = |name, v: f64, lo: f64, hi: f64, range| {
            if v.is_finite() && v > lo && v <= hi {
                Ok(())
            } else {
                Err(out_of_range(name, v, range))
            }
        };
        if !(1..=32).contains(&self.box_radius_px) {
            return Err(out_of_range("box_radius_px", self.box_radius_px, "1..=32"));
        }
        within("dot_ratio", self.dot_ratio, 0.0, 1.0, "(0, 1]")?;
        if !(1..=self.max_dot_area_px).contains(&self.min_dot_area_px)
            || self.max_dot_area_px > 10_000
        {
            return Err(out_of_range(
                "min_dot_area_px..max_dot_area_px",
                format!("{}..{}", self.min_dot_area_px, self.max_dot_area_px),
                "1 <= min <= max <= 10000",
            ));
        }
        if !(3..=4096).contains(&self.min_reference_markers) {
            return Err(out_of_range(
                "min_reference_markers",
                self.min_reference_markers,
                "3..=4096",
            ));
        }
        within("search_px", self.search_px, 0.0, 1000.0, "(0, 1000]")?;
        within(
            "ambiguity_ratio",
            self.ambiguity_ratio,
            0.0,
            100.0,
            "(0, 100]",
        )?;
        if !(1..=1000).contains(&self.onset_frames) {
            return Err(out_of_range("onset_frames", self.onset_frames, "1..=1000"));
        }
        within("fit_radius", self.fit_radius, 0.0, 10.0, "(0, 10]")?;
        within(
            "inner_radius",
            self.inner_radius,
            0.0,
            self.fit_radius,
            "(0, fit_radius]",
        )?;
        if !(4..=4096).contains(&self.min_markers) {
            return Err(out_of_range("min_markers", self.min_markers, "4..=4096"));
        }
        within(
            "motion_floor_px",
            self.motion_floor_px,
            0.0,
            100.0,
            "(0, 100]",
        )?;
        within("slip_on", self.slip_on, 0.0, 1.0, "(0, 1]")?;
        within("slip_off", self.slip_off, 0.0, self.slip_on, "(0, slip_on]")?;
        Ok(())
    }
    /// [`check`](Self::check), and that a `kind` gel has marker dots (DIGIT has none).
    pub fn check_for(&self, kind: unitac_core::SensorKind) -> Result<(), ParamsError> {
        self.check()?;
        if kind.markers() == unitac_core::sensor::Markers::No {
            return Err(ParamsError::NoMarkers {
                sensor: kind.to_string(),
            });
        }
        Ok(())
    }
    pub(crate) fn dots(&self) -> DotParams {
        DotParams {
            box_radius_px: self.box_radius_px,
            dot_ratio: self.dot_ratio,
            min_area_px: self.min_dot_area_px,
            max_area_px: self.max_dot_area_px,
        }
    }
    pub(crate) fn tracking(&self) -> TrackParams {
        TrackParams {
            search_px: self.search_px,
            ambiguity_ratio: self.ambiguity_ratio,
        }
    }
}
