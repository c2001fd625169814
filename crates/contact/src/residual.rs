//! The residual of each grid cell and the threshold: the frame's block means less the
//! gain-corrected background (zero at masked marker cells), less the fitted shading field, summed
//! over the channels as |R| + |G| + |B|, then compared with the threshold into the packed mask.
//!
//! On clean frames this is one pass over the grid, a row at a time: the field's row is evaluated
//! first (a loop over the cell columns the compiler vectorises), then each cell is a handful of
//! operations; the per-channel difference is never stored. Noisy frames need the difference
//! itself, averaged over a box of cells before the residual is taken.

use crate::grid::{BitMask, box_mean3};
use crate::shading::ShadingFit;

/// What one frame's residual is computed from.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Inputs<'a> {
    /// Block means of the frame and of the background, RGB interleaved.
    pub grid: &'a [f32],
    pub bg: &'a [f32],
    /// Non-zero at masked marker cells.
    pub markers: &'a [u8],
    pub gain: [f32; 3],
    pub gw: usize,
    pub gh: usize,
    /// The shading field to subtract (`None` when it is not worth it), and u of every column.
    pub field: Option<&'a ShadingFit>,
    pub us: &'a [f32],
}

/// Scratch buffers, reused across frames.
#[derive(Debug, Default)]
pub(crate) struct ResidualScratch {
    diff: Vec<f32>,
    tmp: Vec<f32>,
    /// The field along the current row, per channel.
    field: [Vec<f32>; 3],
    /// The current row: over the threshold (1) or not (0).
    over: Vec<u8>,
}

impl Inputs<'_> {
    /// The field along grid row `y` into `out` (one value per cell per channel); false if there
    /// is no field.
    #[inline(always)]
    fn field_row(&self, y: usize, out: &mut [Vec<f32>; 3]) -> bool {
        let Some(fit) = self.field else { return false };
        let p = fit.row(y, self.gw, self.gh);
        for (q, o) in p.iter().zip(out.iter_mut()) {
            o.clear();
            o.extend(self.us.iter().map(|&u| ShadingFit::at(q, u)));
        }
        true
    }

    /// Grid row `y`'s frame, background and marker slices.
    #[inline]
    fn row(&self, y: usize) -> (&[f32], &[f32], &[u8]) {
        let (a, b) = (y * self.gw, (y + 1) * self.gw);
        (
            &self.grid[a * 3..b * 3],
            &self.bg[a * 3..b * 3],
            &self.markers[a..b],
        )
    }
}

/// Signed difference of one cell, zero at a marker cell.
#[inline]
pub(crate) fn diff(g: &[f32], b: &[f32], marker: u8, gain: [f32; 3]) -> [f32; 3] {
    let d = [
        g[0] - gain[0] * b[0],
        g[1] - gain[1] * b[1],
        g[2] - gain[2] * b[2],
    ];
    if marker == 0 { d } else { [0.0; 3] }
}

/// Residual of every cell into `resid` and the cells over `thr` (markers never) into `bits`;
/// with `box_radius > 0` the difference is averaged over that box of cells first.
#[multiversion::multiversion(targets("x86_64+avx2"))]
pub(crate) fn residual_mask(
    inp: &Inputs,
    box_radius: usize,
    thr: f32,
    s: &mut ResidualScratch,
    resid: &mut Vec<f32>,
    bits: &mut BitMask,
) {
    let (gw, gh) = (inp.gw, inp.gh);
    resid.resize(gw * gh, 0.0);
    bits.reset(gw, gh);
    if gw == 0 {
        return;
    }
    if box_radius > 0 {
        s.diff.resize(gw * gh * 3, 0.0);
        for (y, out) in s.diff.chunks_exact_mut(gw * 3).enumerate() {
            let (grid, bg, marks) = inp.row(y);
            let cells = out
                .chunks_exact_mut(3)
                .zip(grid.chunks_exact(3))
                .zip(bg.chunks_exact(3))
                .zip(marks);
            for (((o, g), b), &m) in cells {
                o.copy_from_slice(&diff(g, b, m, inp.gain));
            }
            if inp.field_row(y, &mut s.field) {
                let [f0, f1, f2] = &s.field;
                for (((o, a), b), c) in out.chunks_exact_mut(3).zip(f0).zip(f1).zip(f2) {
                    o[0] -= a;
                    o[1] -= b;
                    o[2] -= c;
                }
            }
        }
        box_mean3(&mut s.diff, gw, gh, box_radius, &mut s.tmp);
    }
    s.over.resize(gw, 0);
    for (y, res) in resid.chunks_exact_mut(gw).enumerate() {
        let (grid, bg, marks) = inp.row(y);
        if box_radius > 0 {
            let d = &s.diff[y * gw * 3..(y + 1) * gw * 3];
            for (r, d) in res.iter_mut().zip(d.chunks_exact(3)) {
                *r = d[0].abs() + d[1].abs() + d[2].abs();
            }
        } else {
            let cells = res
                .iter_mut()
                .zip(grid.chunks_exact(3))
                .zip(bg.chunks_exact(3))
                .zip(marks);
            if inp.field_row(y, &mut s.field) {
                let [f0, f1, f2] = &s.field;
                let fields = f0.iter().zip(f1).zip(f2);
                for ((((r, g), b), &m), ((a, b1), c)) in cells.zip(fields) {
                    let d = diff(g, b, m, inp.gain);
                    *r = (d[0] - a).abs() + (d[1] - b1).abs() + (d[2] - c).abs();
                }
            } else {
                for (((r, g), b), &m) in cells {
                    let d = diff(g, b, m, inp.gain);
                    *r = d[0].abs() + d[1].abs() + d[2].abs();
                }
            }
        }
        for ((o, &v), &m) in s.over.iter_mut().zip(res.iter()).zip(marks) {
            *o = u8::from(v > thr) & u8::from(m == 0);
        }
        bits.set_row(y, &s.over);
    }
}
