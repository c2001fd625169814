//! Peeling the skirt's flank off the contact region (`peel_skirt`).
//!
//! The residual follows the gel's slope. Under a pressed ball the slope grows to the contact
//! edge, where the ball leaves the gel, and falls off outside it over the gel's skirt. How fast
//! it falls depends on the gel and the optics: the region's half-level contour lies 1.22-1.25
//! Hertz radii out on the mock's finite-element skirt, 1.57 ridge radii out on a real GelSight
//! Mini ball press (the calibration frame published with gs_sdk, `assets/ball_image.png`), and
//! up to 1.6 Hertz radii out on a thin layer's steep skirt (crates/contact/README.md). So a level
//! alone reads a wide skirt as contact.
//!
//! The flank is what lies outside the ridge: along each ray from the component's centroid, from
//! the region's outer edge inward, the cells whose residual keeps rising, below the component's
//! robust peak. They are peeled off. Rays are radial, so that the walk climbs across the skirt
//! and never along the ridge around the press (the ridge is higher on the lights' side than
//! across them) nor into the inside of a press, where the residual falls again towards the
//! centre. Only each ray's outermost run in the region is walked (a region that is not star
//! shaped keeps its inner parts). The frame's edge is not outside: a ray that leaves the frame
//! inside the region peels nothing. Filled holes, closed gaps and masked marker dots stop the
//! walk (their residual says nothing of the slope). On a noisy frame the residual is a box
//! mean, which moves a small press's ridge inward by up to its radius: the caller gives that
//! many cells back (`region::Peel`).

use crate::region::RegionInputs;

/// Scratch buffers, reused across frames.
#[derive(Debug, Default)]
pub(crate) struct FlankScratch {
    /// Cells peeled (0/1) over the grid, and each label's region cells (`Extent`).
    gone: Vec<u8>,
    extent: Vec<Extent>,
}

/// A label's region cells: sums for the centroid, count, bounding box.
#[derive(Debug, Clone, Copy)]
struct Extent {
    sx: f64,
    sy: f64,
    n: f64,
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

impl Default for Extent {
    fn default() -> Self {
        Self {
            sx: 0.0,
            sy: 0.0,
            n: 0.0,
            x0: usize::MAX,
            x1: 0,
            y0: usize::MAX,
            y1: 0,
        }
    }
}

/// Peel the flank off `region` (0/1 per cell) within rows `rows.0..rows.1`, where every set cell
/// lies; `peak[label]` is each component's robust peak residual.
pub(crate) fn peel_flank(
    inp: &RegionInputs,
    peak: &[f32],
    rows: (usize, usize),
    region: &mut [u8],
    s: &mut FlankScratch,
) {
    let (gw, gh) = (inp.gw, inp.gh);
    let (y0, y1) = (rows.0, rows.1.min(gh));
    if gw == 0 || y0 >= y1 || peak.is_empty() {
        return;
    }
    // A cell the walk may take: in the region, in the deformation mask, not a masked marker.
    let walkable = |i: usize| {
        region[i] != 0 && inp.mask[i] != 0 && inp.markers[i] == 0 && inp.resid[i].is_finite()
    };
    s.extent.clear();
    s.extent.resize(peak.len(), Extent::default());
    for y in y0..y1 {
        for x in 0..gw {
            let i = y * gw + x;
            if walkable(i) {
                if let Some(e) = s.extent.get_mut(inp.labels[i] as usize) {
                    e.sx += x as f64;
                    e.sy += y as f64;
                    e.n += 1.0;
                    (e.x0, e.x1) = (e.x0.min(x), e.x1.max(x + 1));
                    (e.y0, e.y1) = (e.y0.min(y), e.y1.max(y + 1));
                }
            }
        }
    }
    s.gone.clear();
    s.gone.resize(gw * gh, 0);
    for (l, e) in s.extent.iter().enumerate() {
        if e.n < 1.0 {
            continue;
        }
        let (cx, cy) = (e.sx / e.n + 0.5, e.sy / e.n + 0.5);
        // Rays from the centroid to one cell past the component's box, half a cell apart there.
        let far = |a: usize, b: usize, c: f64| (c - a as f64).abs().max((b as f64 - c).abs());
        let reach = far(e.x0, e.x1, cx).hypot(far(e.y0, e.y1, cy)) + 1.0;
        let n = ((std::f64::consts::TAU * reach * 2.0).ceil() as usize).clamp(16, 4096);
        let steps = (reach * 2.0).ceil() as usize;
        let cap = peak[l];
        for k in 0..n {
            let (sin, cos) = (std::f64::consts::TAU * k as f64 / n as f64).sin_cos();
            let cell = |t: usize| {
                let (x, y) = (cx + cos * t as f64 * 0.5, cy + sin * t as f64 * 0.5);
                (x >= 0.0 && y >= 0.0 && x < gw as f64 && y < gh as f64)
                    .then(|| y as usize * gw + x as usize)
            };
            // From the ray's far end inward to its outermost region cell: a ray that meets the
            // region just inside the frame's edge is cut by the frame there.
            let mut t = steps;
            let mut left_frame = false;
            let mut edge = None;
            while t > 0 {
                t -= 1;
                match cell(t) {
                    None => left_frame = true,
                    Some(i) if region[i] != 0 => {
                        edge = Some(i);
                        break;
                    }
                    Some(_) => left_frame = false,
                }
            }
            let Some(mut i) = edge else { continue };
            if left_frame {
                continue;
            }
            // Inward from it while the residual rises below the peak.
            while t > 0 {
                t -= 1;
                let Some(inner) = cell(t) else { break };
                if inner == i {
                    continue;
                }
                let rises = walkable(i)
                    && inp.labels[i] as usize == l
                    && inp.resid[i] < cap
                    && walkable(inner)
                    && inp.resid[inner] >= inp.resid[i];
                if !rises {
                    break;
                }
                s.gone[i] = 1;
                i = inner;
            }
        }
    }
    for (c, &g) in region[y0 * gw..y1 * gw]
        .iter_mut()
        .zip(&s.gone[y0 * gw..y1 * gw])
    {
        if g != 0 {
            *c = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::region::{Peel, RegionInputs, RegionScratch, contact_region};

    /// A press on a `gw` x `gh` grid centred at (cx, cy): residual rising from 20 at the centre
    /// to `rim(angle)` at the contact radius `a` cells, then falling as exp(-(r - a) / w) over
    /// the skirt; the deformation mask is where the residual exceeds the threshold 5.
    struct Press {
        gw: usize,
        gh: usize,
        mask: Vec<u8>,
        labels: Vec<u32>,
        resid: Vec<f32>,
        disc: usize,
    }

    fn press(gw: usize, gh: usize, (cx, cy): (f32, f32), a: f32, w: f32) -> Press {
        press_with(gw, gh, (cx, cy), a, w, |_| 80.0)
    }

    fn press_with(
        gw: usize,
        gh: usize,
        (cx, cy): (f32, f32),
        a: f32,
        w: f32,
        rim: impl Fn(f32) -> f32,
    ) -> Press {
        let (mut mask, mut resid, mut disc) = (vec![0u8; gw * gh], vec![0f32; gw * gh], 0);
        for y in 0..gh {
            for x in 0..gw {
                let (dx, dy) = (x as f32 - cx, y as f32 - cy);
                let r = dx.hypot(dy);
                let top = rim(dy.atan2(dx));
                let v = if r <= a {
                    disc += 1;
                    20.0 + (top - 20.0) * r / a
                } else {
                    top * (-(r - a) / w).exp()
                };
                let i = y * gw + x;
                resid[i] = v;
                mask[i] = u8::from(v > 5.0);
            }
        }
        let labels = mask.iter().map(|&m| u32::from(m)).collect();
        Press {
            gw,
            gh,
            mask,
            labels,
            resid,
            disc,
        }
    }

    fn region(p: &Press, peel: bool) -> Vec<u8> {
        let markers = vec![0u8; p.gw * p.gh];
        let inp = RegionInputs {
            mask: &p.mask,
            labels: &p.labels,
            resid: &p.resid,
            markers: &markers,
            gw: p.gw,
            gh: p.gh,
        };
        let (mut out, mut s) = (Vec::new(), RegionScratch::default());
        let peel = if peel {
            Peel::On { give_back: 0 }
        } else {
            Peel::Off
        };
        contact_region(&inp, 5.0, 0.5, peel, 1, &mut out, &mut s);
        out
    }

    fn area(m: &[u8]) -> usize {
        m.iter().filter(|&&v| v != 0).count()
    }

    #[test]
    fn the_peel_ends_the_region_at_the_ridge_whatever_the_skirt_width() {
        for w in [1.5f32, 3.0, 6.0] {
            let p = press(64, 60, (31.5, 29.5), 10.0, w);
            let (half, peeled) = (area(&region(&p, false)), area(&region(&p, true)));
            let d = p.disc as f32;
            // Within a ring of two cells of the disc on every skirt (on a wide one the skirt
            // just outside the ridge reaches the component's 90th percentile and stays).
            assert!(
                (0.95 * d..=1.3 * d).contains(&(peeled as f32)),
                "skirt {w}: peeled {peeled} cells, disc {d}"
            );
            if w >= 6.0 {
                // The half-level contour alone reads the wide skirt as contact.
                assert!(
                    half as f32 > 2.0 * d,
                    "skirt {w}: half level {half}, disc {d}"
                );
            }
        }
    }

    #[test]
    fn the_peel_does_not_walk_along_the_ridge() {
        // The rim is twice as high on one side as across it (the lights' direction):
        // a walk along the ridge from its low side would climb around it and peel it away.
        let p = press_with(64, 60, (31.5, 29.5), 10.0, 4.0, |t| {
            60.0 + 60.0 * t.cos().powi(2)
        });
        let peeled = area(&region(&p, true)) as f32;
        let d = p.disc as f32;
        assert!(
            (0.95 * d..=1.3 * d).contains(&peeled),
            "peeled {peeled}, disc {d}"
        );
    }

    #[test]
    fn a_press_cut_by_the_frame_keeps_its_cut_side() {
        // The press's centre lies off the frame: inward from the frame's edge the residual
        // rises to the rim through contact, which a walk from the edge would peel.
        let p = press(48, 40, (-3.0, 19.5), 9.0, 1.5);
        let out = region(&p, true);
        let d = p.disc as f32;
        assert!(
            (0.95 * d..=1.3 * d).contains(&(area(&out) as f32)),
            "{} vs {d}",
            area(&out)
        );
        for y in 14..26 {
            assert_eq!(out[y * 48], 1, "edge cell at row {y} peeled");
        }
    }

    #[test]
    fn a_sharp_edge_loses_nothing() {
        // Flat inside (a pressed plate), nothing outside but a low skirt: no rising flank.
        let (gw, gh) = (40, 40);
        let mut p = press(gw, gh, (19.5, 19.5), 8.0, 0.5);
        for (i, v) in p.resid.iter_mut().enumerate() {
            let r = ((i % gw) as f32 - 19.5).hypot((i / gw) as f32 - 19.5);
            *v = if r <= 8.0 {
                60.0
            } else if r <= 11.0 {
                12.0
            } else {
                0.0
            };
            p.mask[i] = u8::from(*v > 5.0);
            p.labels[i] = u32::from(p.mask[i]);
        }
        assert_eq!(region(&p, true), region(&p, false));
        assert_eq!(area(&region(&p, true)), p.disc);
    }
}
