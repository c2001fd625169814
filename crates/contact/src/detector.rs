//! The per-frame detector: a frame against the background model, into a contact mask, area,
//! centroid, bounding box and strength, then the episode state machine.

use crate::background::{Background, Learner};
use crate::depth::{DepthCalibration, DepthEstimator, DepthSummary};
use crate::depth_region::{DepthRegion, ModelSource};
use crate::episodes::Episodes;
use crate::grid::{BitMask, BlockScratch, Geometry, block_means, keep_components};
use crate::params::{ContactParams, ParamsError, RegionRule};
use crate::region::{Peel, RegionInputs, RegionScratch, contact_region};
use crate::residual::{self, Inputs, ResidualScratch, residual_mask};
use crate::shading::{self, ShadingScratch};
use unitac_core::msg::{ContactState, Header};
use unitac_core::sensor::Markers;
use unitac_core::{Frame, Msg, SensorSpec, StageError};

/// Why the detector refused a frame (the cause of its [`StageError::BadInput`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameRefused {
    #[error(
        "frame {seq} is {width}x{height}, the background is {bg_width}x{bg_height} (learned again \
         after {after} frames in a row of a new size; {seen} so far)"
    )]
    SizeChanged {
        seq: u64,
        width: u32,
        height: u32,
        bg_width: u32,
        bg_height: u32,
        after: u32,
        seen: u32,
    },
    #[error("background not learned yet")]
    NoBackground,
    #[error("frame {seq} is saturated ({percent:.0} % of the gel at 250 DN or more)")]
    Saturated { seq: u64, percent: f32 },
    #[error("frame {seq} is dark ({percent:.0} % of the gel at 5 DN or less)")]
    Dark { seq: u64, percent: f32 },
    #[error("frame {seq}: illumination gain {gain:.2} on channel {channel} is implausible")]
    Gain { seq: u64, gain: f32, channel: usize },
    #[error("frame {seq}: region: depth, and {why}")]
    NoDepth { seq: u64, why: String },
    #[error("frame {seq}: depth: {why}")]
    Depth { seq: u64, why: String },
}

/// Plausible range of the per-channel illumination gain against the background.
const GAIN_RANGE: (f32, f32) = (0.2, 5.0);
/// Every n-th grid cell is sampled for the gain and the saturation check (13 is prime, so the
/// samples do not line up in columns): ~1500 samples on a 160x120 grid.
const SAMPLE_STEP: usize = 13;

/// Contact components smaller than this share of the largest are dropped.
const SHARE_OF_LARGEST: f32 = 0.1;
/// Frame area the pixel parameters are given for (320 x 240).
const REFERENCE_PX: f32 = 320.0 * 240.0;

/// Measurement of one frame against the background.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Contact area [input px].
    pub area_px: f32,
    /// Centroid [input px] (x, y); zeros when empty.
    pub centroid: [f32; 2],
    /// Bounding box [input px] x0, y0, x1, y1 (exclusive); zeros when empty.
    pub bbox: [u32; 4],
    /// 0..1, monotone in the mean residual over the contact.
    pub strength: f32,
    /// Per-channel illumination gain against the background.
    pub gain: [f32; 3],
    /// Cell threshold used \[DN].
    pub threshold: f32,
    /// Noise sigma per channel of one cell of the frame - background difference, measured on
    /// this frame after the smooth shading was removed \[DN].
    pub noise: [f32; 3],
    /// Radius \[cells] of the box the difference was averaged over before thresholding (0 on
    /// clean frames; larger on noisy ones).
    pub smoothing: u32,
    /// Share of the shading-fit lattice left out as not smooth (the press, moved markers).
    pub rejected: f32,
    /// Whether the area reaches `enter_area_px` (scaled to the frame size): what a single frame
    /// says, before hysteresis and debounce.
    pub contact: bool,
    /// The region (area, centroid, bbox, `mask_px`) is the gel's depth's, not the residual's.
    pub from_depth: bool,
}

#[derive(Debug, Default)]
struct Scratch {
    grid: Vec<f32>,
    /// Deformation: every cell over the noise threshold (after morphology and the component
    /// filter). The background is never updated under it.
    mask: Vec<u8>,
    /// Contact: the region found from `mask` (`region.rs`; it may grow a little past it) that
    /// area, centroid, bbox, strength and `mask_px` are measured on.
    region: Vec<u8>,
    resid: Vec<f32>,
    bits: BitMask,
    labels: Vec<u32>,
    stack: Vec<(usize, usize)>,
    /// Frame / background ratios per channel, as f32 bits (non-negative).
    ratios: [Vec<u32>; 3],
    residual: ResidualScratch,
    shading: ShadingScratch,
    block: BlockScratch,
    region_s: RegionScratch,
}

#[derive(Debug)]
enum Model {
    Learning(Learner),
    Ready { bg: Background, markers: Vec<u8> },
}

#[derive(Debug)]
pub struct ContactDetector {
    p: ContactParams,
    spec: SensorSpec,
    markers: MarkerRule,
    geo: Option<Geometry>,
    model: Option<Model>,
    s: Scratch,
    episodes: Episodes,
    idle_frames: u64,
    /// A frame size other than the background's, and how many frames in a row had it.
    pending_size: Option<((u32, u32), u32)>,
    /// How often the background was learned again for a new frame size.
    size_changes: u64,
    /// The photometric model and its estimator (`region: auto` with a model, `depth`, or a
    /// depth calibration given).
    depth: Option<DepthRegion>,
    /// The last measured frame's region is the depth's: Some(whether its depth region was
    /// kept, which `mask_px` then reads from the estimator; else the region is empty).
    last_depth_region: Option<bool>,
}

impl Scratch {
    /// Steps 5 and 6 of [`ContactDetector::measure`] on the packed mask of cells over the
    /// threshold (`thr`, with the box radius `r`): morphology, the coherent components, the
    /// contact region within them (in `region`). False: nothing was over the threshold.
    fn contact_region(
        &mut self,
        p: &ContactParams,
        geo: &Geometry,
        k: f32,
        (thr, r): (f32, u32),
        markers: &[u8],
    ) -> bool {
        // 5. Morphology, then the coherent regions: components over the minimum size and not
        // much smaller than the largest, so scattered specks never add up to a contact.
        let cells = |px: u32| {
            if px == 0 {
                0
            } else {
                ((px as f32 * k / geo.stride as f32).round() as u32).max(1)
            }
        };
        let any = !self.bits.is_empty();
        if any {
            self.bits
                .open_close(cells(p.open_radius_px), cells(p.close_radius_px));
        }
        self.bits.to_bytes(&mut self.mask);
        // Nothing over the threshold (most frames): no components to look for.
        if any {
            let min_cells = (p.min_component_px * k * k / geo.cell_px()).ceil() as usize;
            keep_components(
                &mut self.mask,
                geo.gw,
                geo.gh,
                min_cells.max(1),
                SHARE_OF_LARGEST,
                &mut self.labels,
                &mut self.stack,
            );
        }
        // 6. The contact region within it: per component, the cells at or above `area_level` of
        // its own peak residual (the skirt of a deep press left out), holes filled.
        let close = cells(p.close_radius_px);
        if any {
            let inp = RegionInputs {
                mask: &self.mask,
                labels: &self.labels,
                resid: &self.resid,
                markers,
                gw: geo.gw,
                gh: geo.gh,
            };
            contact_region(
                &inp,
                thr,
                p.area_level,
                if p.peel_skirt {
                    Peel::On { give_back: r }
                } else {
                    Peel::Off
                },
                close,
                &mut self.region,
                &mut self.region_s,
            );
        } else {
            self.region.clear();
            self.region.resize(geo.cells(), 0);
        }
        any
    }
}

/// Frame quality and illumination gain on a sample of cells (every [`SAMPLE_STEP`]th): a
/// frame with more than `max_bad` of them saturated or dark is refused; the gain per channel is
/// the median ratio of frame to background over unmasked, unsaturated cells, refused outside
/// [`GAIN_RANGE`].
fn quality_gain(
    grid: &[f32],
    bg: &[f32],
    markers: &[u8],
    cells: usize,
    ratios: &mut [Vec<u32>; 3],
    max_bad: f32,
    seq: u64,
) -> Result<[f32; 3], StageError> {
    let (mut sat, mut dark, mut sampled) = (0usize, 0usize, 0usize);
    for r in ratios.iter_mut() {
        r.clear();
    }
    for i in (0..cells).step_by(SAMPLE_STEP) {
        let (g, b) = (&grid[i * 3..i * 3 + 3], &bg[i * 3..i * 3 + 3]);
        sampled += 1;
        if g.iter().any(|&v| v >= 250.0) {
            sat += 1;
        }
        if g.iter().all(|&v| v <= 5.0) {
            dark += 1;
        }
        if markers[i] == 0 {
            for c in 0..3 {
                if b[c] > 10.0 && g[c] < 250.0 {
                    ratios[c].push((g[c] / b[c]).to_bits());
                }
            }
        }
    }
    let share = |n: usize| n as f32 / sampled.max(1) as f32;
    if share(sat) > max_bad {
        return Err(StageError::bad_input(FrameRefused::Saturated {
            seq,
            percent: 100.0 * share(sat),
        }));
    }
    if share(dark) > max_bad {
        return Err(StageError::bad_input(FrameRefused::Dark {
            seq,
            percent: 100.0 * share(dark),
        }));
    }
    let mut gain = [1.0f32; 3];
    for (c, (g, r)) in gain.iter_mut().zip(ratios.iter_mut()).enumerate() {
        let mid = r.len() / 2;
        if let Some(m) = shading::nth_non_negative(r, mid) {
            *g = m;
        }
        if !(GAIN_RANGE.0..=GAIN_RANGE.1).contains(g) {
            return Err(StageError::bad_input(FrameRefused::Gain {
                seq,
                gain: *g,
                channel: c,
            }));
        }
    }
    Ok(gain)
}

/// Cell sums over the contact region: count, coordinate sums, residual-to-threshold sum and
/// bounding box (cells).
struct Sums {
    n: u64,
    sx: f64,
    sy: f64,
    sr: f64,
    bb: [u32; 4],
}

/// [`Sums`] of the set cells of `region` (rows of `gw` cells; `any`: something was over the
/// threshold `thr`, else nothing is set).
fn region_sums(region: &[u8], resid: &[f32], gw: usize, any: bool, thr: f32) -> Sums {
    let (mut n, mut sx, mut sy, mut sr) = (0u64, 0f64, 0f64, 0f64);
    let mut bb = [u32::MAX, u32::MAX, 0u32, 0u32];
    // Row by row (cell order), past the empty rows.
    let rows = region.chunks_exact(gw).zip(resid.chunks_exact(gw));
    // (An OR over the row rather than `any`: a loop the compiler vectorises; no row is set
    // when nothing was over the threshold.)
    let set_rows = rows
        .enumerate()
        .filter(|(_, (m, _))| any && m.iter().fold(0u8, |a, &m| a | m) != 0);
    let cells = set_rows.flat_map(|(gy, (m, res))| {
        let set = m.iter().zip(res).enumerate().filter(|(_, (m, _))| **m != 0);
        set.map(move |(gx, (_, &res))| (gx as u32, gy as u32, res))
    });
    for (gx, gy, res) in cells {
        n += 1;
        sx += f64::from(gx);
        sy += f64::from(gy);
        // Closing can add masked marker cells with no residual of their own: count them at
        // the threshold.
        sr += f64::from((res / thr).max(1.0));
        bb = [
            bb[0].min(gx),
            bb[1].min(gy),
            bb[2].max(gx + 1),
            bb[3].max(gy + 1),
        ];
    }
    Sums { n, sx, sy, sr, bb }
}

impl ContactDetector {
    pub fn new(p: ContactParams, spec: SensorSpec) -> Result<Self, ParamsError> {
        p.check()?;
        let markers = match (p.mask_markers, spec.kind.markers()) {
            (Some(true), _) | (None, Markers::Yes) => MarkerRule::Mask,
            (Some(false), _) | (None, Markers::No) => MarkerRule::Off,
            (None, Markers::Unknown) => MarkerRule::Detect,
        };
        // The kind's default model, also with `region: residual` (a depth to report); with
        // `region: depth` on a kind without one, a model fitted on each frame.
        let depth = match (p.region, DepthCalibration::kind_default(spec.kind)) {
            (_, Some(cal)) => Some(DepthRegion::new(cal, ModelSource::KindDefault)),
            (RegionRule::Residual | RegionRule::Auto, None) => None,
            (RegionRule::Depth, None) => Some(DepthRegion::new(
                DepthCalibration::self_calibrated(spec.kind),
                ModelSource::SelfCalibrated,
            )),
        };
        Ok(Self {
            p,
            spec,
            markers,
            geo: None,
            model: None,
            s: Scratch::default(),
            episodes: Episodes::default(),
            idle_frames: 0,
            pending_size: None,
            size_changes: 0,
            depth,
            last_depth_region: None,
        })
    }

    /// Depth from a unit's calibration instead of the kind's default (its sensor and aspect
    /// ratio checked by the caller): the region's, unless `region: residual`, and the depth of
    /// every frame with `every_frame` (a published depth map).
    pub fn set_depth_calibration(&mut self, cal: DepthCalibration, every_frame: bool) {
        let mut d = DepthRegion::new(cal, ModelSource::Calibration);
        d.every_frame = every_frame;
        if let Some(Model::Ready { bg, .. }) = &self.model {
            d.on_background(bg);
        }
        self.depth = Some(d);
    }

    /// Estimate the depth of every measured frame (for a picture or a report), not only of
    /// frames with a deformation; no effect without a photometric model.
    pub fn estimate_depth_every_frame(&mut self, on: bool) {
        if let Some(d) = self.depth.as_mut() {
            d.every_frame = on;
        }
    }

    /// The depth's estimator on the current background (None without a model, before the
    /// first estimate on the background, or at a frame size the model does not fit), and the
    /// last measured frame's depth when it was estimated.
    pub fn depth(&self) -> Option<(&DepthEstimator, Option<DepthSummary>)> {
        let d = self.depth.as_ref()?;
        Some((d.estimator()?, d.last))
    }

    /// The last measured frame's depth map for a picture or a topic \[m, into the gel], NaN
    /// where unknown: under the masked marker dots (the gel's colour is the dots' there), and
    /// everywhere for a self-calibrated model (its depth has no scale); None when the frame's
    /// depth was not estimated.
    pub fn depth_map_m(&self) -> Option<Vec<f32>> {
        let d = self.depth.as_ref()?;
        let (est, Some(_)) = (d.estimator()?, d.last) else {
            return None;
        };
        if d.source == ModelSource::SelfCalibrated {
            return Some(vec![f32::NAN; est.depth_m().len()]);
        }
        let unknown = self.marker_mask_px();
        Some(
            est.depth_m()
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    if unknown.get(i).copied().unwrap_or(false) {
                        f32::NAN
                    } else {
                        *v
                    }
                })
                .collect(),
        )
    }

    /// Where the depth's model comes from: "calibration" (a unit's), "kind default" (the
    /// profile's) or "self-calibrated" (fitted on each frame, up to scale: no penetration); None
    /// without depth.
    pub fn depth_model(&self) -> Option<&'static str> {
        self.depth.as_ref().map(|d| d.source.as_str())
    }

    /// Why the current background has no depth though there is a model (its frames are not of
    /// the model's aspect ratio).
    pub fn depth_unusable(&self) -> Option<&str> {
        self.depth.as_ref()?.unusable.as_deref()
    }

    /// Whether the region is taken from depth on this background.
    fn region_from_depth(&self) -> bool {
        let Some(d) = self.depth.as_ref().filter(|d| d.ready()) else {
            return false;
        };
        match self.p.region {
            RegionRule::Residual => false,
            RegionRule::Auto => d.source == ModelSource::Calibration,
            RegionRule::Depth => true,
        }
    }

    pub fn params(&self) -> &ContactParams {
        &self.p
    }
    pub fn is_learned(&self) -> bool {
        matches!(self.model, Some(Model::Ready { .. }))
    }
    pub fn in_contact(&self) -> bool {
        self.episodes.in_contact()
    }
    pub fn background(&self) -> Option<&Background> {
        background_of(&self.model)
    }
    /// The current non-contact frame (the sensor prior for inference), once learned.
    pub fn background_frame(&self, sensor_id: &str) -> Option<Frame> {
        self.background().and_then(|b| b.frame(sensor_id))
    }
    /// Per-channel noise sigma of one detection cell \[DN] measured while the background was
    /// learned (`default_noise_dn` for a single image). Detection itself uses the noise measured
    /// on each frame ([`Measurement::noise`]).
    pub fn cell_sigma(&self) -> f32 {
        self.background().map_or(0.0, |b| b.cell_sigma)
    }

    /// The contact region of the last measured frame (what its area is), in input pixels
    /// (row-major; empty before the first measurement). Pixels in the right/bottom remainder of
    /// a stride are never set.
    pub fn mask_px(&self) -> Vec<bool> {
        let Some(g) = self.geo else { return Vec::new() };
        if let Some(kept) = self.last_depth_region {
            let n = g.width as usize * g.height as usize;
            return match self.depth.as_ref().and_then(DepthRegion::estimator) {
                Some(e) if kept && e.mask().len() == n => e.mask().to_vec(),
                _ => vec![false; n],
            };
        }
        if self.s.region.len() != g.cells() {
            return Vec::new();
        }
        let (w, st) = (g.width as usize, g.stride as usize);
        let mut out = vec![false; w * g.height as usize];
        for (i, _) in self.s.region.iter().enumerate().filter(|(_, m)| **m != 0) {
            let (gx, gy) = (i % g.gw, i / g.gw);
            for y in gy * st..(gy + 1) * st {
                out[y * w + gx * st..y * w + (gx + 1) * st].fill(true);
            }
        }
        out
    }

    /// The masked marker dots (`mask_markers`) of the current background in input pixels of
    /// its size (row-major); empty before the background is known. Pixels in the right/bottom
    /// remainder of a stride are never set.
    pub fn marker_mask_px(&self) -> Vec<bool> {
        let Some(Model::Ready { bg, markers }) = &self.model else {
            return Vec::new();
        };
        let g = bg.geo;
        let (w, st) = (g.width as usize, g.stride as usize);
        let mut out = vec![false; w * g.height as usize];
        for (i, _) in markers.iter().enumerate().filter(|(_, m)| **m != 0) {
            let (gx, gy) = (i % g.gw, i / g.gw);
            for y in gy * st..(gy + 1) * st {
                if let Some(row) = out.get_mut(y * w + gx * st..y * w + (gx + 1) * st) {
                    row.fill(true);
                }
            }
        }
        out
    }

    /// The residual of every grid cell of the last measured frame (|R| + |G| + |B| of the
    /// difference less the shading field \[DN], row-major on the grid) with the grid's geometry;
    /// None before the first measurement. For diagnostics (the fixtures print radial profiles).
    pub fn residual_cells(&self) -> Option<(Geometry, &[f32])> {
        let g = self.geo?;
        (self.s.resid.len() == g.cells()).then_some((g, self.s.resid.as_slice()))
    }

    /// Forget the background and learn it again from the next frames (e.g. after the gel was
    /// changed). Episode numbering goes on.
    pub fn recapture(&mut self) {
        self.model = None;
        if let Some(d) = self.depth.as_mut() {
            d.clear();
        }
        self.episodes.reset();
    }

    /// Use a background captured elsewhere (a saved file, a single image).
    pub fn set_background(&mut self, bg: Background) {
        self.geo = Some(bg.geo);
        self.pending_size = None;
        let markers = match self.markers {
            MarkerRule::Mask => marker_cells(&bg),
            MarkerRule::Detect => dot_cells(&bg),
            MarkerRule::Off => vec![0; bg.geo.cells()],
        };
        if let Some(d) = self.depth.as_mut() {
            d.on_background(&bg);
        }
        self.model = Some(Model::Ready { bg, markers });
    }

    /// Use one image as the background; the noise is taken from `default_noise_dn`.
    pub fn set_background_frame(&mut self, f: &Frame) {
        let geo = self.geometry_for(f.width, f.height);
        let mut l = Learner::new(geo);
        l.add(f);
        // Block means of s*s pixels have sigma / s per channel.
        let sigma = self.p.default_noise_dn / geo.stride as f32;
        self.set_background(l.finish(f.stamp, sigma));
    }

    /// Linear scale of the pixel parameters for a frame of this size: 1 at 320x240 (and
    /// smaller), 2 at 640x480, ...; always 1 with `scale_with_size: false`.
    pub fn size_scale(&self, width: u32, height: u32) -> f32 {
        if !self.p.scale_with_size {
            return 1.0;
        }
        ((width as f32 * height as f32) / REFERENCE_PX)
            .sqrt()
            .round()
            .max(1.0)
    }

    /// Gel-surface m^2 per pixel of a `width` x `height` frame: the sensor spec's scale per pixel
    /// is for its published size, and a frame of another size covers the same field of view
    /// (GelSight Mini at 640x480: a quarter of the 320x240 figure).
    pub fn m2_per_px(&self, width: u32, height: u32) -> f64 {
        let px = f64::from(width) * f64::from(height);
        if px <= 0.0 {
            return self.spec.m2_per_px();
        }
        self.spec.m2_per_px() * f64::from(self.spec.width) * f64::from(self.spec.height) / px
    }

    /// The detection grid of a frame size: `stride` times the size scale.
    pub fn geometry_for(&self, width: u32, height: u32) -> Geometry {
        let k = self.size_scale(width, height) as u32;
        Geometry::new(width, height, self.p.stride.saturating_mul(k))
    }

    /// How often the background was learned again because the frames changed size.
    pub fn size_changes(&self) -> u64 {
        self.size_changes
    }

    fn size_error(&self, f: &Frame, g: Geometry) -> StageError {
        let seen = match self.pending_size {
            Some((s, n)) if s == (f.width, f.height) => n,
            _ => 0,
        };
        StageError::bad_input(FrameRefused::SizeChanged {
            seq: f.seq,
            width: f.width,
            height: f.height,
            bg_width: g.width,
            bg_height: g.height,
            after: self.p.new_size_frames,
            seen,
        })
    }

    /// The grid of a frame of the background's size (or of any size before there is one); an
    /// error for another size. Changes nothing.
    fn geometry_of(&self, f: &Frame) -> Result<Geometry, StageError> {
        match self.geo {
            Some(g) if (g.width, g.height) == (f.width, f.height) => Ok(g),
            Some(g) => Err(self.size_error(f, g)),
            None => Ok(self.geometry_for(f.width, f.height)),
        }
    }

    /// The first frame sets the size. A frame of another size is an error that changes nothing
    /// but a count, until `new_size_frames` in a row have one new size: then an open episode is
    /// closed (returned) and the background is learned again at the new size.
    fn admit_size(&mut self, f: &Frame) -> Result<(Geometry, Vec<Msg>), StageError> {
        let size = (f.width, f.height);
        let g = match self.geo {
            Some(g) => g,
            None => {
                let g = self.geometry_for(f.width, f.height);
                self.geo = Some(g);
                return Ok((g, Vec::new()));
            }
        };
        if (g.width, g.height) == size {
            self.pending_size = None;
            return Ok((g, Vec::new()));
        }
        let n = match self.pending_size {
            Some((s, n)) if s == size => n + 1,
            _ => 1,
        };
        self.pending_size = Some((size, n));
        if n < self.p.new_size_frames {
            return Err(self.size_error(f, g));
        }
        tracing::warn!(
            "contact: {} frames in a row are {}x{}, the background was {}x{}: learning it again",
            n,
            f.width,
            f.height,
            g.width,
            g.height
        );
        self.pending_size = None;
        self.size_changes += 1;
        let out = self.flush(&f.sensor_id);
        self.recapture();
        let g = self.geometry_for(f.width, f.height);
        self.geo = Some(g);
        Ok((g, out))
    }

    /// Measure a frame against the background without changing the detector's state (scratch
    /// buffers aside). The mask of contact cells is left in the scratch buffer.
    pub fn measure(&mut self, f: &Frame) -> Result<Measurement, StageError> {
        let geo = self.geometry_of(f)?;
        let from_depth = self.region_from_depth();
        let Some(Model::Ready { bg, markers }) = &self.model else {
            return Err(StageError::bad_input(FrameRefused::NoBackground));
        };
        if self.p.region == RegionRule::Depth && !from_depth {
            let why = self.depth.as_ref().and_then(|d| d.unusable.clone());
            return Err(StageError::bad_input(FrameRefused::NoDepth {
                seq: f.seq,
                why: why.unwrap_or_else(|| "the depth has no estimator".into()),
            }));
        }
        let k = self.size_scale(geo.width, geo.height);
        let s = &mut self.s;
        block_means(f, &geo, &mut s.grid, &mut s.block);

        // 1. Frame quality and illumination gain, on a sample of cells.
        let gain = quality_gain(
            &s.grid,
            &bg.grid,
            markers,
            geo.cells(),
            &mut s.ratios,
            self.p.max_bad_pixel_share,
            f.seq,
        )?;

        // 2. Signed difference per channel; masked marker cells count as unchanged. Computed
        // where it is needed: at the fit's lattices, then once per cell in the threshold pass.
        let (grid, bgrid) = (&s.grid, &bg.grid);
        let diff_at = |i: usize| {
            let (g, b) = (&grid[i * 3..i * 3 + 3], &bgrid[i * 3..i * 3 + 3]);
            residual::diff(g, b, markers[i], gain)
        };

        // 3. The smooth shading out, and the noise of what is left, from this frame.
        let fit = shading::fit(diff_at, markers, geo.gw, geo.gh, &mut s.shading);
        let sigma: f32 = fit.sigma.iter().sum();
        // A field far below the noise is not worth subtracting.
        let remove = fit.peak > 0.5 * sigma;
        // Noisy frames: average the difference over a box of cells (the fit did the same).
        let r = shading::smoothing_radius(&fit.sigma);
        let thr = (self.p.noise_k * sigma / (2 * r + 1) as f32).max(self.p.min_threshold);
        let (gw, gh) = (geo.gw, geo.gh);
        // 4. Residual and threshold, straight into a packed mask: in one pass from the frame's
        // grid on clean frames; through the difference and its box mean on noisy ones.
        let inputs = Inputs {
            grid,
            bg: bgrid,
            markers,
            gain,
            gw,
            gh,
            field: remove.then_some(&fit),
            us: s.shading.us(),
        };
        residual_mask(
            &inputs,
            r as usize,
            thr,
            &mut s.residual,
            &mut s.resid,
            &mut s.bits,
        );

        // 5-6. Morphology, the coherent components, the contact region within them.
        let st = geo.stride;
        let any = s.contact_region(&self.p, &geo, k, (thr, r), markers);

        // 7. Geometry of the contact region in input pixels: the residual's region, or with a
        // photometric model the depth's where the residual found a deformation.
        let Sums { n, sx, sy, sr, bb } = region_sums(&s.region, &s.resid, geo.gw, any, thr);
        let (noise, smoothing, rejected) = (fit.sigma, r, fit.rejected);
        let depth_area = match self.depth.as_mut() {
            Some(d) => {
                let (mask, region) = (&s.mask, &s.region);
                let inside = |i: usize| mask.get(i).is_some_and(|&m| m != 0) || region[i] != 0;
                let marker = |i: usize| markers.get(i).is_some_and(|&m| m != 0);
                let wanted = (from_depth && any && n > 0, any && n > 0);
                d.measure(f, wanted, &geo, inside, marker).map_err(|e| {
                    StageError::bad_input(FrameRefused::Depth {
                        seq: f.seq,
                        why: e.to_string(),
                    })
                })?
            }
            None => None,
        };
        // A frame the self-calibration found no model on takes the residual's region.
        let from_depth = from_depth && !self.depth.as_ref().is_some_and(|d| d.unfitted);
        self.last_depth_region = from_depth.then_some(depth_area.is_some());
        let empty = Measurement {
            area_px: 0.0,
            centroid: [0.0; 2],
            bbox: [0; 4],
            strength: 0.0,
            gain,
            threshold: thr,
            noise,
            smoothing,
            rejected,
            contact: false,
            from_depth,
        };
        if n == 0 {
            return Ok(empty);
        }
        let nf = n as f64;
        let mean_ratio = (sr / nf) as f32;
        let strength = 1.0 - (-(mean_ratio - 1.0) / 3.0).exp();
        let enter = self.p.enter_area_px * k * k;
        if from_depth {
            return Ok(match depth_area {
                Some(a) => Measurement {
                    area_px: a.area_px as f32,
                    centroid: a.centroid,
                    bbox: a.bbox,
                    strength,
                    contact: a.area_px as f32 >= enter,
                    ..empty
                },
                None => empty,
            });
        }
        let half = (st as f64 - 1.0) / 2.0;
        let area_px = n as f32 * geo.cell_px();
        Ok(Measurement {
            area_px,
            centroid: [
                (sx / nf * f64::from(st) + half) as f32,
                (sy / nf * f64::from(st) + half) as f32,
            ],
            bbox: [
                bb[0] * st,
                bb[1] * st,
                (bb[2] * st).min(geo.width),
                (bb[3] * st).min(geo.height),
            ],
            strength,
            contact: area_px >= enter,
            ..empty
        })
    }

    /// One frame in, zero or more events out. Nothing comes out while the background is learned.
    pub fn step(&mut self, f: &Frame) -> Result<Vec<Msg>, StageError> {
        let (geo, closed) = self.admit_size(f)?;
        if !self.is_learned() {
            let mut learner = match self.model.take() {
                Some(Model::Learning(l)) => l,
                _ => Learner::new(geo),
            };
            learner.add(f);
            if learner.frames() >= self.p.learn_frames {
                let sigma = self.p.default_noise_dn / geo.stride as f32;
                self.set_background(learner.finish(f.stamp, sigma));
            } else {
                self.model = Some(Model::Learning(learner));
            }
            return Ok(closed);
        }
        let m = self.measure(f)?;
        let m2_per_px = self.m2_per_px(geo.width, geo.height);
        let model = &self.model;
        let k = self.size_scale(geo.width, geo.height);
        let (raw, mut out) = self
            .episodes
            .update(f, m.area_px, k * k, &self.p, m2_per_px, || {
                background_of(model).and_then(|b| b.frame(&f.sensor_id))
            });
        if !self.episodes.in_contact() && !raw {
            self.update_background(f);
        }
        let bg_age = self
            .background()
            .map_or(0.0, |b| f.stamp.secs_since(b.captured_at));
        let state = ContactState {
            header: Header::optical(f.stamp, &f.sensor_id),
            sensor_id: f.sensor_id.clone(),
            frame_seq: f.seq,
            in_contact: self.episodes.in_contact(),
            area_px: m.area_px,
            area_m2: (f64::from(m.area_px) * m2_per_px) as f32,
            centroid_px: m.centroid,
            bbox_px: m.bbox,
            strength: m.strength,
            episode_id: self.episodes.last_episode(),
            background_age_s: bg_age,
        };
        out.insert(0, Msg::ContactState(state));
        if !closed.is_empty() {
            out.splice(0..0, closed);
        }
        Ok(out)
    }

    /// EMA on the cells outside the current mask (scratch from `measure`), and every 8th idle
    /// frame on the full-resolution background.
    fn update_background(&mut self, f: &Frame) {
        let a = self.p.ema_alpha;
        if a <= 0.0 {
            return;
        }
        self.idle_frames += 1;
        let Some(Model::Ready { bg, .. }) = self.model.as_mut() else {
            return;
        };
        // Run by run of cells outside the mask (on an idle frame usually one run, the whole
        // grid), each a flat loop over the run's values that the compiler vectorises.
        let (mask, grid) = (&self.s.mask, &self.s.grid);
        let ema = |start: usize, end: usize, b: &mut [f32]| {
            let (b, g) = (
                b.get_mut(start * 3..end * 3).unwrap_or_default(),
                grid.get(start * 3..end * 3).unwrap_or_default(),
            );
            for (b, &g) in b.iter_mut().zip(g) {
                *b += a * (g - *b);
            }
        };
        if mask.iter().fold(0u8, |acc, &m| acc | m) == 0 {
            ema(0, mask.len(), &mut bg.grid);
        } else {
            let mut x = 0;
            while x < mask.len() {
                let start = x + mask[x..].iter().take_while(|&&m| m != 0).count();
                let end = start + mask[start..].iter().take_while(|&&m| m == 0).count();
                ema(start, end, &mut bg.grid);
                x = end;
            }
        }
        if self.idle_frames % 8 == 0 {
            let a8 = (a * 8.0).min(0.5);
            for (b, &v) in bg.full.iter_mut().zip(f.data()) {
                *b += a8 * (f32::from(v) - *b);
            }
        }
    }

    /// Close an open episode (end of input).
    pub fn flush(&mut self, sensor_id: &str) -> Vec<Msg> {
        let m2_per_px = self
            .geo
            .map_or(self.spec.m2_per_px(), |g| self.m2_per_px(g.width, g.height));
        let model = &self.model;
        self.episodes.close(sensor_id, &self.p, m2_per_px, || {
            background_of(model).and_then(|b| b.frame(sensor_id))
        })
    }
}

fn background_of(model: &Option<Model>) -> Option<&Background> {
    match model {
        Some(Model::Ready { bg, .. }) => Some(bg),
        _ => None,
    }
}

/// Which background cells are left out as marker dots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MarkerRule {
    /// Every dark cell (`marker_cells`): a kind with markers, or a scene that says so.
    Mask,
    /// Only a pattern of small dark spots, where the background has one (`dot_cells`): a kind
    /// that may or may not have markers (`generic`).
    Detect,
    Off,
}

/// Fewest dark spots that make a background a marker gel's (a printed grid has 40-100+).
const MIN_DOTS: usize = 20;
/// Largest dark spot taken for a dot, as a share of the grid's cells (a dot of 0.5 mm is 4-25
/// cells on the ~160 x 120 grid; a vignetted corner is hundreds).
const MAX_DOT_SHARE: usize = 400;

/// Marker dots of a gel not known to have them: the dark cells of `marker_cells` that form
/// small spots, when there are at least [`MIN_DOTS`] of them, dilated by one cell; else none
/// (a dark corner or a few specks are no marker grid, and leaving them out would hide gel).
fn dot_cells(bg: &Background) -> Vec<u8> {
    let g = bg.geo;
    let dark = dark_cells(bg);
    let max_dot = (g.cells() / MAX_DOT_SHARE).max(4);
    let (mut labels, mut stack) = (Vec::new(), Vec::new());
    let sizes = crate::grid::label_components(&dark, g.gw, g.gh, &mut labels, &mut stack);
    let is_dot = |l: u32| l != 0 && sizes[l as usize] <= max_dot;
    if sizes.iter().skip(1).filter(|&&n| n <= max_dot).count() < MIN_DOTS {
        return vec![0; g.cells()];
    }
    let dots: Vec<u8> = labels.iter().map(|&l| u8::from(is_dot(l))).collect();
    dilate1(&dots, g.gw, g.gh)
}

/// Background cells darker than 0.7 of the median cell (1 = dark).
fn dark_cells(bg: &Background) -> Vec<u8> {
    let lum: Vec<f32> = bg
        .grid
        .chunks_exact(3)
        .map(|p| p[0] + p[1] + p[2])
        .collect();
    let mut sorted = lum.clone();
    let mid = sorted.len() / 2;
    let median = if sorted.is_empty() {
        0.0
    } else {
        *sorted.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    lum.iter().map(|&l| u8::from(l < 0.7 * median)).collect()
}

/// Marker dots: background cells much darker than the gel around them, dilated by one cell
/// (markers move a little with the gel).
fn marker_cells(bg: &Background) -> Vec<u8> {
    let g = bg.geo;
    let m = dark_cells(bg);
    // Only small dark spots are markers; a mask covering much of the gel means it is not a marker
    // gel (or the background is odd): then mask nothing.
    if m.iter().filter(|&&v| v != 0).count() * 5 > m.len() {
        return vec![0; g.cells()];
    }
    dilate1(&m, g.gw, g.gh)
}

/// `m` (gw x gh, 1 = set) grown by one cell in all eight directions.
fn dilate1(m: &[u8], gw: usize, gh: usize) -> Vec<u8> {
    let mut out = m.to_vec();
    for y in 0..gh {
        for x in 0..gw {
            if m[y * gw + x] == 0 {
                continue;
            }
            for (dx, dy) in [
                (-1i64, 0i64),
                (1, 0),
                (0, -1),
                (0, 1),
                (-1, -1),
                (1, 1),
                (-1, 1),
                (1, -1),
            ] {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx >= 0 && ny >= 0 && (nx as usize) < gw && (ny as usize) < gh {
                    out[ny as usize * gw + nx as usize] = 1;
                }
            }
        }
    }
    out
}
