//! The photometric renderer of the mock sensor: what a gel looks like with an object pressed
//! into it.
//!
//! An indenter height map (sphere cap plus a surface texture), its gradients lit by three coloured
//! lights from different directions (as in GelSight-style sensors), marker dots dragged by the
//! depression, a vignetted background, and per-pixel noise of about 1 DN. The output is a pure
//! function of the press, the gain and the noise stream.

use unitac_core::SensorSpec;

use crate::object::{Object, Shape};
use crate::rng::{GaussianTable, SplitMix64, quantise_f32};
use crate::tangential::{Field, MarkerTruth, Tangential};

/// Marker grid: spacing and dot radius in output pixels, darkening factor inside a dot.
pub(crate) const MARKER_SPACING: f64 = 24.0;
const MARKER_RADIUS: f64 = 2.6;
const MARKER_DARK: f64 = 0.35;
/// Lateral marker displacement per mm of local gel depression [px/mm].
const MARKER_SHIFT_PX_PER_MM: f64 = 6.0;

/// What a render produced besides the pixels.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Contact {
    /// Row-major mask of the pixels where the indenter touches the gel.
    pub mask: Vec<bool>,
    /// Number of `true` pixels in `mask`.
    pub contact_px: u32,
}

/// A sensor's lit background and marker pattern at rest, and its noise table: everything about
/// a frame that does not depend on the press.
#[derive(Debug)]
pub(crate) struct Renderer {
    spec: SensorSpec,
    markers: bool,
    background: Vec<f32>,
    /// Background times the marker dots at rest.
    base: Vec<f32>,
    /// Per-pixel noise, sigma = noise_dn.
    noise: GaussianTable,
}

impl Renderer {
    pub fn new(spec: SensorSpec, noise_dn: f64, markers: bool) -> Self {
        let background = render_background(&spec);
        let base = render_base(&spec, &background, markers);
        Self {
            spec,
            markers,
            background,
            base,
            noise: GaussianTable::new(noise_dn),
        }
    }

    pub fn spec(&self) -> &SensorSpec {
        &self.spec
    }

    /// Render into `data` (RGB8, the spec's size) the gel with `press` = (object, depth [mm])
    /// pressed at the centre (None: at rest), dragged sideways by `tangential` (markers only;
    /// None or zero: the plain press, byte for byte), times `gain`, plus noise drawn from `seed`.
    pub fn render_into(
        &self,
        data: &mut [u8],
        press: Option<(&Object, f64)>,
        tangential: Option<&Tangential>,
        gain: f64,
        seed: u64,
    ) -> Contact {
        let (w, h) = (self.spec.width as usize, self.spec.height as usize);
        let mut rng = self.noise.stream(SplitMix64::new(seed));
        let mut mask = vec![false; w * h];
        let mut contact_px = 0u32;
        let press = press.map(|(o, depth)| {
            Press::new(
                o,
                depth,
                &self.spec,
                w,
                h,
                tangential.filter(|_| self.markers),
            )
        });
        // Rows and columns the press can change (contact, skirt, dragged markers); everything
        // else is the lit background times the gain, plus noise.
        let (x0, x1, y0, y1) = press.as_ref().map_or((0, 0, 0, 0), |p| p.bbox);
        let g = gain as f32;
        let mut noise = vec![0f32; w * 3];
        for (y, ((out, base), bg)) in data
            .chunks_exact_mut(w * 3)
            .zip(self.base.chunks_exact(w * 3))
            .zip(self.background.chunks_exact(w * 3))
            .enumerate()
        {
            // This row's noise, in raster order.
            rng.fill(&mut noise);
            let pressed = match &press {
                Some(p) if y >= y0 && y < y1 => Some(p),
                _ => None,
            };
            let Some(p) = pressed else {
                quantise_row(out, base, &noise, g);
                continue;
            };
            let (a, b) = (x0 * 3, x1 * 3);
            quantise_row(&mut out[..a], &base[..a], &noise[..a], g);
            quantise_row(&mut out[b..], &base[b..], &noise[b..], g);
            let row_trig = p.row_trig(y);
            let mask_row = &mut mask[y * w + x0..y * w + x1];
            for (xi, ((((o, bs), bk), n), m)) in out[a..b]
                .chunks_exact_mut(3)
                .zip(base[a..b].chunks_exact(3))
                .zip(bg[a..b].chunks_exact(3))
                .zip(noise[a..b].chunks_exact(3))
                .zip(mask_row.iter_mut())
                .enumerate()
            {
                let Some(px) = p.pixel(x0 + xi, y, row_trig, self.markers) else {
                    // At rest: the background path.
                    quantise_row(o, bs, n, g);
                    continue;
                };
                if px.in_contact {
                    *m = true;
                    contact_px += 1;
                }
                let dg = (px.dark * gain) as f32;
                for c in 0..3 {
                    o[c] = quantise_f32((bk[c] + px.shade[c] as f32) * dg + n[c]);
                }
            }
        }
        Contact { mask, contact_px }
    }

    /// Render into `data` (RGB8, the spec's size) the gel depressed by `height` \[mm, row-major,
    /// one value per pixel, positive into the gel]: the same lights, shading gain and darkening
    /// with depth as a press, from the height map's own gradients (central differences, one-sided
    /// at the border), marker dots at rest, times `gain`, plus noise drawn from `seed`. The shading
    /// is the exact gradient of the map, so the map is the depth truth of the frame.
    /// `height` must hold width x height values (`None` is returned otherwise).
    pub fn render_height_into(
        &self,
        data: &mut [u8],
        height: &[f32],
        gain: f64,
        seed: u64,
    ) -> Option<()> {
        let (w, h) = (self.spec.width as usize, self.spec.height as usize);
        if height.len() != w * h || data.len() != w * h * 3 || w < 2 || h < 2 {
            return None;
        }
        let mut rng = self.noise.stream(SplitMix64::new(seed));
        let mut noise = vec![0f32; w * 3];
        let inv = 1.0 / self.spec.mm_per_px;
        let g = gain as f32;
        for y in 0..h {
            rng.fill(&mut noise);
            let (ya, yb) = (y.saturating_sub(1), (y + 1).min(h - 1));
            let row = &height[y * w..(y + 1) * w];
            for x in 0..w {
                let (xa, xb) = (x.saturating_sub(1), (x + 1).min(w - 1));
                let gx = f64::from(row[xb] - row[xa]) * inv / (xb - xa) as f64;
                let gy =
                    f64::from(height[yb * w + x] - height[ya * w + x]) * inv / (yb - ya) as f64;
                let hh = f64::from(row[x]);
                let i = (y * w + x) * 3;
                let dark = if self.markers {
                    marker_dark(x as f64, y as f64) as f32
                } else {
                    1.0
                };
                for (c, l) in LIGHTS.iter().enumerate() {
                    let shade = SHADE_GAIN * (gx * l[0] + gy * l[1]) - DEPTH_DARK * hh;
                    data[i + c] = quantise_f32(
                        (self.background[i + c] + shade as f32) * dark * g + noise[x * 3 + c],
                    );
                }
            }
        }
        Some(())
    }

    /// The marker dots whose rest centre is in the frame, at rest and moved by `tangential` on
    /// `press` (empty without markers).
    pub fn marker_truth(
        &self,
        press: Option<(&Object, f64)>,
        tangential: Option<&Tangential>,
    ) -> Vec<MarkerTruth> {
        if !self.markers {
            return Vec::new();
        }
        let (w, h) = (self.spec.width as usize, self.spec.height as usize);
        let field = press
            .zip(tangential)
            .and_then(|((o, depth), t)| Press::new(o, depth, &self.spec, w, h, Some(t)).field);
        let (nx, ny) = (
            (w as f64 / MARKER_SPACING - 0.5).ceil().max(0.0) as usize,
            (h as f64 / MARKER_SPACING - 0.5).ceil().max(0.0) as usize,
        );
        let mut out = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let rest = [
                    (i as f64 + 0.5) * MARKER_SPACING,
                    (j as f64 + 0.5) * MARKER_SPACING,
                ];
                let d = field.as_ref().map_or([0.0; 2], |f| f.at(rest[0], rest[1]));
                out.push(MarkerTruth {
                    rest_px: rest,
                    moved_px: [rest[0] + d[0], rest[1] + d[1]],
                });
            }
        }
        out
    }
}

/// `out = quantise(base * gain + noise)`, element-wise (vectorises).
#[inline]
fn quantise_row(out: &mut [u8], base: &[f32], noise: &[f32], gain: f32) {
    for ((o, &b), &n) in out.iter_mut().zip(base).zip(noise) {
        *o = quantise_f32(b * gain + n);
    }
}

/// Darkening factor of the marker dots at (sx, y) [px] (1 = no marker).
fn marker_dark(sx: f64, sy: f64) -> f64 {
    let mx = floor(sx / MARKER_SPACING) * MARKER_SPACING + MARKER_SPACING * 0.5;
    let my = floor(sy / MARKER_SPACING) * MARKER_SPACING + MARKER_SPACING * 0.5;
    let d2 = (sx - mx) * (sx - mx) + (sy - my) * (sy - my);
    let reach = MARKER_RADIUS + 1.0;
    if d2 < reach * reach {
        let edge = (reach - d2.sqrt()).clamp(0.0, 1.0);
        1.0 - (1.0 - MARKER_DARK) * edge
    } else {
        1.0
    }
}

/// floor() without a libm call (baseline x86-64 has no rounding instruction); exact for
/// |x| < 2^52.
#[inline]
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x { t - 1.0 } else { t }
}

/// The lights' directions in the image plane (GelSight-style R, G, B from 120 degrees apart).
const LIGHTS: [[f64; 2]; 3] = [[1.0, 0.0], [-0.5, 0.866], [-0.5, -0.866]];
/// DN per unit slope of the gel surface.
const SHADE_GAIN: f64 = 90.0;
/// DN per mm of depression (the pressed gel is a little darker).
const DEPTH_DARK: f64 = 25.0;

/// What one pixel of a pressed gel looks like before the background and noise.
struct PressPixel {
    in_contact: bool,
    /// Added to the background per channel [DN].
    shade: [f64; 3],
    /// Marker darkening.
    dark: f64,
}

/// One object pressed `depth` mm into the gel at the image centre, in pixel terms.
struct Press<'a> {
    obj: &'a Object,
    depth: f64,
    px_per_mm: f64,
    cx: f64,
    cy: f64,
    /// Contact half-width [px] (radius; half the band for an edge).
    a_px: f64,
    /// Width of the skirt outside the contact where the gel slopes back to rest [px].
    skirt_px: f64,
    /// Pixel box [x0, x1) x [y0, y1) outside which the gel is at rest.
    bbox: (usize, usize, usize, usize),
    /// Texture wave: k [1/mm], and (sin, cos) of k x per column of the box.
    k: f64,
    cols: Vec<(f64, f64)>,
    /// Precomputed reciprocals: mm per px, 1 / effective radius [1/mm], 1 / skirt [1/px].
    mm_per_px: f64,
    inv_r: f64,
    inv_skirt: f64,
    /// Outer radius of the deformed area [px].
    outer_px: f64,
    /// Tangential displacement of the gel (markers), if the object moved sideways.
    field: Option<Field>,
}

impl<'a> Press<'a> {
    fn new(
        obj: &'a Object,
        depth: f64,
        spec: &SensorSpec,
        w: usize,
        h: usize,
        tangential: Option<&Tangential>,
    ) -> Self {
        let px_per_mm = 1.0 / spec.mm_per_px;
        let a_px = obj.contact_half_width_mm(depth) * px_per_mm;
        let (cx, cy) = (spec.width as f64 * 0.5, spec.height as f64 * 0.5);
        let field = tangential
            .and_then(|t| Field::new(t, a_px, (cx, cy), obj.shape == Shape::Edge, spec.mm_per_px));
        let mut p = Self {
            obj,
            depth,
            px_per_mm,
            cx,
            cy,
            a_px,
            // The gel deforms a little past the contact: 60 % of the contact size plus 4 px.
            skirt_px: a_px * 0.6 + 4.0,
            bbox: (0, 0, 0, 0),
            k: std::f64::consts::TAU / obj.period_mm,
            cols: Vec::new(),
            mm_per_px: spec.mm_per_px,
            inv_r: 1.0 / obj.effective_radius_mm(),
            inv_skirt: 1.0 / (a_px * 0.6 + 4.0),
            outer_px: a_px * 1.6 + 4.0,
            field,
        };
        p.bbox = p.find_bbox(w, h);
        let (x0, x1, _, _) = p.bbox;
        p.cols = (x0..x1)
            .map(|x| (p.k * x as f64 / px_per_mm).sin_cos())
            .collect();
        p
    }

    /// (sin, cos) of the texture's row phase at row y.
    fn row_trig(&self, y: usize) -> (f64, f64) {
        (self.k * (y as f64 / self.px_per_mm) * 0.8 + 0.5).sin_cos()
    }

    /// Pixel box [x0, x1) x [y0, y1) outside which the gel is at rest.
    fn find_bbox(&self, w: usize, h: usize) -> (usize, usize, usize, usize) {
        // Reach of the deformation plus the farthest a marker dot can be dragged into view.
        // Beyond the skirt the gel is at rest (markers are sampled at the pixel, so a dragged
        // dot never shows outside the deformed area).
        let mut reach = self.a_px + self.skirt_px + 2.0;
        if let Some(f) = &self.field {
            // Dragged dots show within the field's reach (or the deformed disc) plus the
            // farthest sideways and outward drag.
            let outward = MARKER_SHIFT_PX_PER_MM * self.depth.max(0.0);
            reach =
                reach.max(f.reach.max(self.outer_px) + f.max_px + outward + MARKER_RADIUS + 2.0);
        }
        let span = |c: f64, n: usize| {
            let lo = (c - reach).floor().max(0.0) as usize;
            let hi = ((c + reach).ceil().max(0.0) as usize).min(n);
            (lo.min(n), hi)
        };
        let (x0, x1) = span(self.cx, w);
        let (y0, y1) = match self.obj.shape {
            Shape::Edge => (0, h),
            _ => span(self.cy, h),
        };
        (x0, x1, y0, y1)
    }

    /// The pressed gel at pixel (x, y); None where it is at rest.
    fn pixel(&self, x: usize, y: usize, (sy, cy): (f64, f64), markers: bool) -> Option<PressPixel> {
        let o = self.obj;
        let (dxp, dyp) = (x as f64 - self.cx, y as f64 - self.cy);
        // Distance outside the contact boundary [px] and the outward direction.
        let (r, nx, ny) = match o.shape {
            Shape::Edge => (dxp.abs(), dxp.signum(), 0.0),
            _ => {
                let r2 = dxp * dxp + dyp * dyp;
                if r2 >= self.outer_px * self.outer_px {
                    return self.dragged_marker(x, y, markers);
                }
                let r = r2.sqrt();
                // The outward direction (skirt slope, marker drag), normalised below if used.
                (r, dxp, dyp)
            }
        };
        if r >= self.outer_px {
            return self.dragged_marker(x, y, markers);
        }
        let unit = || -> (f64, f64) {
            match o.shape {
                Shape::Edge => (nx, ny),
                _ if r > 0.0 => (nx / r, ny / r),
                _ => (0.0, 0.0),
            }
        };
        let mut dz = [0.0f64; 2];
        let mut height = 0.0;
        let mut in_contact = false;
        {
            let (dx, dy) = (dxp * self.mm_per_px, dyp * self.mm_per_px);
            let gap = self.gap_at(dx, dy);
            let (g, gx, gy) = gap.unwrap_or((f64::INFINITY, 0.0, 0.0));
            let cap = self.depth - g;
            if cap > 0.0 {
                // Texture (Object::texture_height and its gradient, with the trigonometry
                // per row and column).
                let (sx, cx) = self
                    .cols
                    .get(x - self.bbox.0)
                    .copied()
                    .unwrap_or((0.0, 1.0));
                let amp = o.roughness_mm;
                let mut th = amp * sx * cy;
                let mut tx = amp * self.k * cx * cy;
                let mut ty = -amp * self.k * 0.8 * sx * sy;
                if o.bump_mm > 0.0 {
                    let (bh, bx, by) = o.bump(x as f64 * self.mm_per_px, y as f64 * self.mm_per_px);
                    th += bh;
                    tx += bx;
                    ty += by;
                }
                let s = cap.min(0.2) * 5.0;
                height = cap + th * s;
                dz = [-gx + tx * s, -gy + ty * s];
                in_contact = true;
            } else if self.a_px > 0.0 {
                // Outside the contact the gel slopes back up to rest (smooth skirt); above a
                // fold's top, from the top's row upward.
                let (out_px, (ux, uy)) = match self.above_fold_px(dy) {
                    Some(above) if r < self.a_px => (above, (0.0, -1.0)),
                    _ => (r - self.a_px, unit()),
                };
                let u = (out_px * self.inv_skirt).clamp(0.0, 1.0);
                height = (1.0 - u) * (1.0 - u) * self.depth * 0.15;
                let slope = 2.0 * (1.0 - u) * self.depth * 0.15 * self.inv_skirt * 0.05;
                dz = [-ux * slope, -uy * slope];
            }
        }
        let mut dark = 1.0;
        if markers {
            // Markers are dragged outward by the local depression (sampled at the pixel: render
            // the dot that would have moved here).
            let shift = MARKER_SHIFT_PX_PER_MM * height.max(0.0);
            let (ux, uy) = unit();
            dark = match &self.field {
                // The gel here came from (mx, my), dragged by the press and sideways.
                Some(f) => {
                    let (mx, my) = self.material_source(f, x as f64, y as f64);
                    marker_dark(mx, my)
                }
                None => marker_dark(x as f64 - ux * shift, y as f64 - uy * shift),
            };
        }
        let mut shade = [0.0; 3];
        for (c, l) in LIGHTS.iter().enumerate() {
            shade[c] = SHADE_GAIN * (dz[0] * l[0] + dz[1] * l[1]) - DEPTH_DARK * height;
        }
        Some(PressPixel {
            in_contact,
            shade,
            dark,
        })
    }
}

impl Press<'_> {
    /// The object's gap [mm] and its gradient at (dx, dy) mm from the contact centre (y down):
    /// [`Object::gap`] (the common shapes with the reciprocal precomputed) plus a fold's rim and
    /// grooves; None above a fold's top, where there is no material.
    fn gap_at(&self, dx: f64, dy: f64) -> Option<(f64, f64, f64)> {
        let o = self.obj;
        let (g, gx, gy) = match o.shape {
            Shape::Sphere => (
                0.5 * (dx * dx + dy * dy) * self.inv_r,
                dx * self.inv_r,
                dy * self.inv_r,
            ),
            Shape::Edge => (0.5 * dx * dx * self.inv_r, dx * self.inv_r, 0.0),
            Shape::Flat => o.gap(dx, dy),
        };
        match &o.fold {
            None => Some((g, gx, gy)),
            // y down: the top lies `edge_mm` above the centre, so `dy + edge_mm` below it.
            Some(f) => f
                .gap(dy + f.edge_mm)
                .map(|(fg, fdg)| (g + fg, gx, gy + fdg)),
        }
    }

    /// How far above a fold's top the row `dy` mm from the centre lies [px] (None: no fold, or
    /// at or below the top).
    fn above_fold_px(&self, dy: f64) -> Option<f64> {
        let f = self.obj.fold.as_ref()?;
        let u = dy + f.edge_mm;
        (u < 0.0).then(|| -u * self.px_per_mm)
    }

    /// Outward drag of the gel point at rest at (mx, my) by the press [px]: the depression's
    /// smooth part (cap or skirt, no texture) times MARKER_SHIFT_PX_PER_MM, as the plain press
    /// drags its markers, but carried by the gel (so a stuck pull moves it along rigidly).
    fn radial_drag(&self, mx: f64, my: f64) -> [f64; 2] {
        let (dxp, dyp) = (mx - self.cx, my - self.cy);
        let edge = self.obj.shape == Shape::Edge;
        let r = if edge { dxp.abs() } else { dxp.hypot(dyp) };
        if r >= self.outer_px || r == 0.0 {
            return [0.0; 2];
        }
        let (dx, dy) = (dxp * self.mm_per_px, dyp * self.mm_per_px);
        // Without a fold, Object::gap itself (the bytes of every existing tangential render).
        let gap = match self.obj.fold {
            None => Some(self.obj.gap(dx, dy)),
            Some(_) => self.gap_at(dx, dy),
        };
        let cap = self.depth - gap.map_or(f64::INFINITY, |g| g.0);
        let height = if cap > 0.0 {
            cap
        } else {
            let out_px = match self.above_fold_px(dy) {
                Some(above) if r < self.a_px => above,
                _ => r - self.a_px,
            };
            let u = (out_px * self.inv_skirt).clamp(0.0, 1.0);
            (1.0 - u) * (1.0 - u) * self.depth * 0.15
        };
        let shift = MARKER_SHIFT_PX_PER_MM * height.max(0.0);
        if edge {
            [dxp.signum() * shift, 0.0]
        } else {
            [dxp / r * shift, dyp / r * shift]
        }
    }

    /// Where the gel now at pixel (x, y) was at rest: m with m + press drag(m) + field(m) =
    /// (x, y), by fixed-point iteration.
    fn material_source(&self, f: &Field, x: f64, y: f64) -> (f64, f64) {
        let (mut mx, mut my) = (x, y);
        for _ in 0..10 {
            let (d, g) = (f.at(mx, my), self.radial_drag(mx, my));
            (mx, my) = (x - d[0] - g[0], y - d[1] - g[1]);
        }
        (mx, my)
    }

    /// A pixel outside the pressed area: at rest (None), or showing a marker dot dragged there by
    /// the tangential field.
    fn dragged_marker(&self, x: usize, y: usize, markers: bool) -> Option<PressPixel> {
        let f = self.field.as_ref().filter(|_| markers)?;
        let (mx, my) = self.material_source(f, x as f64, y as f64);
        Some(PressPixel {
            in_contact: false,
            shade: [0.0; 3],
            dark: marker_dark(mx, my),
        })
    }
}

/// Background with the marker dots at rest (what every pixel away from a press shows).
fn render_base(spec: &SensorSpec, background: &[f32], markers: bool) -> Vec<f32> {
    let w = spec.width as usize;
    let mut base = background.to_vec();
    if markers {
        for (p, px) in base.chunks_exact_mut(3).enumerate() {
            let dark = marker_dark((p % w) as f64, (p / w) as f64) as f32;
            for v in px {
                *v *= dark;
            }
        }
    }
    base
}

/// Lit, vignetted gel without contact (float DN per channel, RGB): the kind's lighting from its
/// profile (`mock_light`: DIGIT's strong colour gradients from LEDs at the edges, GelSight Mini's
/// bright, mostly uniform, slightly tinted gel).
fn render_background(spec: &SensorSpec) -> Vec<f32> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    let mut bg = vec![0f32; w * h * 3];
    let light = spec.kind.profile().mock_light;
    for y in 0..h {
        for x in 0..w {
            let u = x as f32 / w as f32;
            let v = y as f32 / h as f32;
            let r2 = (u - 0.5).powi(2) + (v - 0.5).powi(2);
            let vig = 1.0 - 0.6 * r2;
            let rgb = light.map(|c| c.at(u, v));
            let i = (y * w + x) * 3;
            for c in 0..3 {
                bg[i + c] = rgb[c] * vig;
            }
        }
    }
    bg
}
