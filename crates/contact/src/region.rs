//! The contact region inside the deformation mask.
//!
//! The noise threshold marks every cell the press changed: the contact and, around a press, the
//! gel's skirt (the surface slopes back to rest outside the contact: deformation, but not
//! contact). Area, centroid, bounding box and strength are taken from the contact region only:
//! per connected component of the deformation mask, the cells whose residual reaches `level`
//! times the component's own robust peak (the [`PEAK_QUANTILE`] of its residual over the cells
//! not masked as markers), grown from the component's cells at that level into the neighbouring
//! cells at that level (which may be below the noise threshold: the blurred rim of a light press
//! on a noisy frame; never below [`FLOOR`] of the threshold), closed by the closing radius (so
//! masked marker dots inside count), with the holes filled (a light press changes the gel most at
//! its rim, where the surface slopes most, and little at its centre; a rim cut by the frame's
//! edge is closed by it). One rule for every sensor and size: a level relative to the press's own
//! signal, like a half-maximum contour. Then (`peel_skirt`, on by default) the skirt's flank
//! outside the press's ridge is peeled off and the region closed again ([`peel_flank`]): how far
//! out the half-level contour lies depends on how fast the skirt's residual falls, which differs
//! between gels and optics; the ridge, where the slope peaks and a ball leaves the gel, does not.
//!
//! Why the peak is a high quantile: the residual follows the surface slope, which under a ball
//! grows to the contact edge and falls off outside it (on an elastic half-space to half its edge
//! value at 1.13 contact radii). The skirt holds many cells of low residual, so a lower quantile
//! (the 75th) is pulled down by it and the half-level contour moves out onto the skirt: on the
//! mock's Hertz ball presses that read 2-3.7x the contact disc, as real gels read 1.8-3.0x. At
//! the 90th percentile the same presses read 1.1-2.5x the Hertz disc, by skirt (`unitac-lab eval
//! contact`, the half-level rows); higher (the 95th) lets the moved marker dots of a gel whose
//! dots are not masked set the level (the generic profile on GelSight frames: 0.2x).

use crate::flank::{FlankScratch, peel_flank};
use crate::grid::BitMask;
use crate::shading::nth_non_negative;

/// The quantile of a component's residual taken as its peak: high, so that the skirt's many low
/// cells do not pull the level down, but not the maximum, so that a few noisy cells or moved
/// marker dots do not set it.
pub(crate) const PEAK_QUANTILE: f32 = 0.90;
/// The level never goes below this share of the noise threshold: growing into cells at half the
/// threshold (about two noise sigmas of the summed residual above its mean) cannot percolate
/// through pure noise.
pub(crate) const FLOOR: f32 = 0.5;

/// What the region is found from (one frame's grid, `gw` x `gh` cells).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RegionInputs<'a> {
    /// The deformation mask (0/1 per cell) after morphology and the component filter.
    pub mask: &'a [u8],
    /// Component label of every cell of `mask` (from `keep_components`).
    pub labels: &'a [u32],
    /// Residual of every cell (summed over the channels).
    pub resid: &'a [f32],
    /// Non-zero at masked marker cells.
    pub markers: &'a [u8],
    pub gw: usize,
    pub gh: usize,
}

/// Scratch buffers, reused across frames.
#[derive(Debug, Default)]
pub(crate) struct RegionScratch {
    /// Start of every label's residuals in `vals` (counting sort by label), and the fill cursor.
    start: Vec<usize>,
    cursor: Vec<usize>,
    /// Residuals as f32 bits (non-negative), grouped by label.
    vals: Vec<u32>,
    /// The robust peak and the level of every label.
    peak: Vec<f32>,
    level: Vec<f32>,
    /// The mask's cells that are not masked markers.
    cells: Vec<u32>,
    /// The core (0/1 per cell) and the growth's stack (cell, level).
    core: Vec<u8>,
    grow: Vec<(usize, f32)>,
    bits: BitMask,
    /// Hole filling: cells of the bounding box reached from outside, and the flood's stack.
    seen: Vec<u8>,
    stack: Vec<usize>,
    /// The bounding box's border, walked around (`edge_seeds`).
    ring: Vec<(usize, usize)>,
    flank: FlankScratch,
    /// The region before its flank was peeled, over the closing's rows.
    before: Vec<u8>,
}

/// How the skirt's flank is peeled off the region ([`peel_flank`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Peel {
    /// Not at all: the half-level contour.
    Off,
    /// Up to the press's ridge, then this many cells given back: the box mean's radius on a
    /// noisy frame, which moves a small press's ridge inward by up to as much.
    On { give_back: u32 },
}

/// The contact region (0/1 per cell) into `out`: empty when `mask` is. With `peel`, the
/// skirt's flank outside the press's ridge is peeled off it ([`peel_flank`]).
pub(crate) fn contact_region(
    inp: &RegionInputs,
    thr: f32,
    level: f32,
    peel: Peel,
    close_cells: u32,
    out: &mut Vec<u8>,
    s: &mut RegionScratch,
) {
    let (gw, gh) = (inp.gw, inp.gh);
    out.clear();
    out.resize(gw * gh, 0);
    if gw == 0 || gh == 0 {
        return;
    }
    // The cells that count for a component's peak (in the mask and not a masked marker), past
    // the empty ones eight at a time (most of the grid).
    s.cells.clear();
    for (k, eight) in inp.mask.chunks(8).enumerate() {
        if eight.iter().fold(0u8, |a, &m| a | m) == 0 {
            continue;
        }
        for i in k * 8..k * 8 + eight.len() {
            if inp.mask[i] != 0 && inp.markers[i] == 0 {
                s.cells.push(i as u32);
            }
        }
    }
    let labels = inp.labels;
    let label = |i: u32| labels[i as usize] as usize;
    let n = s.cells.iter().map(|&i| label(i) + 1).max().unwrap_or(0);
    if n == 0 {
        return;
    }
    // Counting sort of the residuals by label, then a selection per label.
    s.start.clear();
    s.start.resize(n + 1, 0);
    for &i in &s.cells {
        s.start[label(i) + 1] += 1;
    }
    for l in 0..n {
        s.start[l + 1] += s.start[l];
    }
    s.cursor.clear();
    s.cursor.extend_from_slice(&s.start[..n]);
    s.vals.clear();
    s.vals.resize(s.start[n], 0);
    for &i in &s.cells {
        let c = &mut s.cursor[label(i)];
        s.vals[*c] = inp.resid[i as usize].max(0.0).to_bits();
        *c += 1;
    }
    s.peak.clear();
    s.level.clear();
    for l in 0..n {
        let v = &mut s.vals[s.start[l]..s.start[l + 1]];
        let k = (v.len().saturating_sub(1) as f32 * PEAK_QUANTILE) as usize;
        let peak = nth_non_negative(v, k).unwrap_or(0.0);
        s.peak.push(peak);
        s.level.push((level * peak).max(FLOOR * thr));
    }
    // The core: the component's cells at or above its level, grown into the neighbouring cells
    // at that level (4-connected, never into masked markers), then closed.
    s.core.clear();
    s.core.resize(gw * gh, 0);
    s.grow.clear();
    for &i in &s.cells {
        if inp.resid[i as usize] >= s.level[label(i)] {
            s.core[i as usize] = 1;
        }
    }
    // The growth starts from the seeds' neighbours (a seed inside the core pushes nothing).
    // `rows`: the rows the core spans (every core cell is a seed or popped from the stack).
    let mut rows = (usize::MAX, 0);
    let span = |r: (usize, usize), y: usize| (r.0.min(y), r.1.max(y + 1));
    for &i in &s.cells {
        let i = i as usize;
        if s.core[i] != 0 {
            let l = s.level[labels[i] as usize];
            rows = span(rows, grow_around(i, l, inp, &mut s.core, &mut s.grow));
        }
    }
    if rows.0 >= rows.1 {
        return;
    }
    while let Some((i, l)) = s.grow.pop() {
        rows = span(rows, grow_around(i, l, inp, &mut s.core, &mut s.grow));
    }
    // The closing only on the core's rows and twice its radius around them: its dilation sets
    // nothing further, and a cell it left unset stays unset whatever the rows beyond hold, so
    // the rows outside (empty) come out as on the whole grid.
    let margin = (close_cells as usize).saturating_mul(2);
    let (y0, y1) = (
        rows.0.saturating_sub(margin),
        rows.1.saturating_add(margin).min(gh),
    );
    let window = y0 * gw..y1 * gw;
    close_rows(&s.core[window.clone()], gw, close_cells, &mut s.bits);
    s.bits.set_ones(&mut out[window]);
    fill_holes(out, gw, (y0, y1), s);
    if let Peel::On { give_back } = peel {
        let window = y0 * gw..y1 * gw;
        s.before.clear();
        s.before.extend_from_slice(&out[window.clone()]);
        peel_flank(inp, &s.peak, (y0, y1), out, &mut s.flank);
        // Closed again (rays peel a little more or less each: a jagged edge), then grown back
        // by `give_back` cells within the region as it was.
        close_rows(&out[window.clone()], gw, close_cells, &mut s.bits);
        s.bits.set_ones(&mut out[window.clone()]);
        for _ in 0..give_back {
            grow_within(&mut out[window.clone()], &s.before, gw, &mut s.stack);
        }
    }
}

/// The closing of `rows` (0/1, `gw` cells a row) into `bits`.
fn close_rows(rows: &[u8], gw: usize, close_cells: u32, bits: &mut BitMask) {
    bits.reset(gw, rows.len() / gw);
    for (y, row) in rows.chunks_exact(gw).enumerate() {
        bits.set_row(y, row);
    }
    bits.open_close(0, close_cells);
}

/// Set every unset cell of `m` that is set in `within` and 4-adjacent to a set cell of `m`
/// (one step of a dilation inside `within`; `m` and `within` `gw` cells a row).
fn grow_within(m: &mut [u8], within: &[u8], gw: usize, add: &mut Vec<usize>) {
    add.clear();
    let n = m.len();
    for i in 0..n {
        if m[i] != 0 || within[i] == 0 {
            continue;
        }
        let x = i % gw;
        let near = (x > 0 && m[i - 1] != 0)
            || (x + 1 < gw && m[i + 1] != 0)
            || (i >= gw && m[i - gw] != 0)
            || (i + gw < n && m[i + gw] != 0);
        if near {
            add.push(i);
        }
    }
    for &i in add.iter() {
        m[i] = 1;
    }
}

/// Add the 4-neighbours of cell `i` at or above `l` (not masked markers) to the core and to the
/// growth's stack; returns the row of `i` (one division per cell).
#[inline(always)]
fn grow_around(
    i: usize,
    l: f32,
    inp: &RegionInputs,
    core: &mut [u8],
    grow: &mut Vec<(usize, f32)>,
) -> usize {
    let (gw, y) = (inp.gw, i / inp.gw);
    let x = i - y * gw;
    let mut visit = |j: usize| {
        if core[j] == 0 && inp.markers[j] == 0 && inp.resid[j] >= l {
            core[j] = 1;
            grow.push((j, l));
        }
    };
    if x > 0 {
        visit(i - 1);
    }
    if x + 1 < gw {
        visit(i + 1);
    }
    if y > 0 {
        visit(i - gw);
    }
    if y + 1 < inp.gh {
        visit(i + gw);
    }
    y
}

/// Set every cell of `m` (0/1, `gw` cells a row) that is not connected to the outside of the
/// grid through unset cells (4-connected), where the frame's edge closes a region it cuts
/// ([`edge_seeds`]). Its set cells lie within rows `rows.0..rows.1`. Works
/// within the bounding box of the set cells plus one cell.
fn fill_holes(m: &mut [u8], gw: usize, rows: (usize, usize), s: &mut RegionScratch) {
    let gh = m.len() / gw;
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    let set_rows = m[rows.0 * gw..rows.1 * gw].chunks_exact(gw);
    for (y, row) in (rows.0..).zip(set_rows) {
        if let (Some(a), Some(b)) = (
            row.iter().position(|&v| v != 0),
            row.iter().rposition(|&v| v != 0),
        ) {
            x0 = x0.min(a);
            x1 = x1.max(b + 1);
            y0 = y0.min(y);
            y1 = y1.max(y + 1);
        }
    }
    if x0 >= x1 {
        return;
    }
    // One cell of margin where the grid has it: the box's side is then outside the region
    // ("open"), or else the grid's own edge.
    let open = [y0 > 0, x1 < gw, y1 < gh, x0 > 0];
    let (x0, y0, x1, y1) = (
        x0.saturating_sub(1),
        y0.saturating_sub(1),
        (x1 + 1).min(gw),
        (y1 + 1).min(gh),
    );
    let (bw, bh) = (x1 - x0, y1 - y0);
    s.seen.clear();
    s.seen.resize(bw * bh, 0);
    s.stack.clear();
    let cell = |bx: usize, by: usize| (y0 + by) * gw + x0 + bx;
    let set = |bx: usize, by: usize| m[cell(bx, by)] != 0;
    edge_seeds(bw, bh, open, set, &mut s.ring, &mut s.stack);
    for &j in &s.stack {
        s.seen[j] = 1;
    }
    while let Some(j) = s.stack.pop() {
        let (bx, by) = (j % bw, j / bw);
        let mut visit = |nx: usize, ny: usize| {
            let k = ny * bw + nx;
            if s.seen[k] == 0 && m[cell(nx, ny)] == 0 {
                s.seen[k] = 1;
                s.stack.push(k);
            }
        };
        if bx > 0 {
            visit(bx - 1, by);
        }
        if bx + 1 < bw {
            visit(bx + 1, by);
        }
        if by > 0 {
            visit(bx, by - 1);
        }
        if by + 1 < bh {
            visit(bx, by + 1);
        }
    }
    for by in 0..bh {
        for bx in 0..bw {
            if s.seen[by * bw + bx] == 0 {
                m[cell(bx, by)] = 1;
            }
        }
    }
}

/// The cells of a `bw` x `bh` box's border where the flood from outside starts (box indices,
/// row-major), given which sides are open (top, right, bottom, left: not the grid's edge) and
/// which cells are set. Walking the border around, every run of unset cells between two set
/// cells is outside when it touches an open side. A run lying on the grid's edge only is the
/// frame's edge closing the region (a ring cut by the frame encloses the part of the press inside
/// the frame, along one side or around a corner), and starts no flood; where no side is open
/// (the region reaches all four edges), only a run along one side is closed, so that a band
/// from corner to corner does not enclose half the frame.
fn edge_seeds(
    bw: usize,
    bh: usize,
    open: [bool; 4],
    set: impl Fn(usize, usize) -> bool,
    ring: &mut Vec<(usize, usize)>,
    seeds: &mut Vec<usize>,
) {
    seeds.clear();
    ring.clear();
    if bw == 0 || bh == 0 {
        return;
    }
    // The border clockwise from the top-left corner, each cell with the sides it lies on.
    let (top, right, bottom, left) = (1u8, 2u8, 4u8, 8u8);
    let side = |bx: usize, by: usize| {
        let mut b = 0;
        b |= if by == 0 { top } else { 0 };
        b |= if bx + 1 == bw { right } else { 0 };
        b |= if by + 1 == bh { bottom } else { 0 };
        b |= if bx == 0 { left } else { 0 };
        b
    };
    ring.extend((0..bw).map(|x| (x, 0)));
    ring.extend((1..bh).map(|y| (bw - 1, y)));
    if bh > 1 {
        ring.extend((0..bw.saturating_sub(1)).rev().map(|x| (x, bh - 1)));
    }
    if bw > 1 {
        ring.extend((1..bh.saturating_sub(1)).rev().map(|y| (0, y)));
    }
    let open_bits = [top, right, bottom, left]
        .iter()
        .zip(open)
        .filter(|(_, o)| *o)
        .fold(0u8, |a, (b, _)| a | b);
    let Some(start) = ring.iter().position(|&(x, y)| set(x, y)) else {
        seeds.extend(ring.iter().map(|&(x, y)| y * bw + x));
        return;
    };
    let n = ring.len();
    let mut k = 0;
    while k < n {
        let (x, y) = ring[(start + k) % n];
        if set(x, y) {
            k += 1;
            continue;
        }
        // A run of unset cells: which sides it lies on.
        let first = k;
        let mut sides = 0u8;
        while k < n && !set(ring[(start + k) % n].0, ring[(start + k) % n].1) {
            let (x, y) = ring[(start + k) % n];
            sides |= side(x, y);
            k += 1;
        }
        let closed = sides & open_bits == 0 && (open_bits != 0 || sides.count_ones() == 1);
        if !closed {
            seeds.extend((first..k).map(|j| {
                let (x, y) = ring[(start + j) % n];
                y * bw + x
            }));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 24x20 grid with one component: a disc of radius 6 whose residual is a ring (60 at the
    /// rim, 10 at the centre) inside a skirt of radius 9 at 12, threshold 5.
    fn ring_with_skirt() -> (Vec<u8>, Vec<u32>, Vec<f32>, usize, usize) {
        let (gw, gh) = (24, 20);
        let (mut mask, mut resid) = (vec![0u8; gw * gh], vec![0f32; gw * gh]);
        for y in 0..gh {
            for x in 0..gw {
                let r = ((x as f32 - 12.0).powi(2) + (y as f32 - 10.0).powi(2)).sqrt();
                let i = y * gw + x;
                if r <= 6.0 {
                    resid[i] = 10.0 + 50.0 * r / 6.0;
                    mask[i] = 1;
                } else if r <= 9.0 {
                    resid[i] = 12.0;
                    mask[i] = 1;
                }
            }
        }
        let labels = mask.iter().map(|&m| u32::from(m)).collect();
        (mask, labels, resid, gw, gh)
    }

    fn area(m: &[u8]) -> usize {
        m.iter().filter(|&&v| v != 0).count()
    }

    #[test]
    fn the_region_is_the_disc_not_the_skirt_nor_the_ring() {
        let (mask, labels, resid, gw, gh) = ring_with_skirt();
        let markers = vec![0u8; gw * gh];
        let inp = RegionInputs {
            mask: &mask,
            labels: &labels,
            resid: &resid,
            markers: &markers,
            gw,
            gh,
        };
        let (mut out, mut s) = (Vec::new(), RegionScratch::default());
        contact_region(&inp, 5.0, 0.5, Peel::Off, 0, &mut out, &mut s);
        let disc = (0..gw * gh)
            .filter(|&i| ((i % gw) as f32 - 12.0).hypot((i / gw) as f32 - 10.0) <= 6.0)
            .count();
        // Cells of the disc at or above half the peak form a ring; the hole is filled.
        assert_eq!(area(&out), disc, "{} vs {disc}", area(&out));
        assert_eq!(out[10 * gw + 12], 1, "centre filled");
        assert_eq!(out[10 * gw + 12 + 8], 0, "skirt left out");
        // Level 0: everything over the threshold (the skirt too).
        contact_region(&inp, 5.0, 0.0, Peel::Off, 0, &mut out, &mut s);
        assert_eq!(area(&out), area(&mask));
    }

    #[test]
    fn the_region_grows_below_the_threshold_and_holes_are_filled() {
        let (gw, gh) = (24, 20);
        let (mut mask, mut resid) = (vec![0u8; gw * gh], vec![0f32; gw * gh]);
        let mut markers = vec![0u8; gw * gh];
        let mut rim = 0;
        for y in 0..gh {
            for x in 0..gw {
                let r = ((x as f32 - 12.0).powi(2) + (y as f32 - 10.0).powi(2)).sqrt();
                let i = y * gw + x;
                if r <= 6.0 {
                    // Over the threshold (12): the mask.
                    resid[i] = 20.0;
                    mask[i] = 1;
                } else if r <= 8.0 {
                    // Below the threshold, above half the peak: grown into.
                    resid[i] = 11.0;
                    rim += 1;
                }
            }
        }
        // An isolated cell at the level, not connected: left out. A marker inside: filled.
        resid[gw + 1] = 15.0;
        markers[10 * gw + 14] = 1;
        let labels: Vec<u32> = mask.iter().map(|&m| u32::from(m)).collect();
        let inp = RegionInputs {
            mask: &mask,
            labels: &labels,
            resid: &resid,
            markers: &markers,
            gw,
            gh,
        };
        let (mut out, mut s) = (Vec::new(), RegionScratch::default());
        contact_region(&inp, 12.0, 0.5, Peel::Off, 0, &mut out, &mut s);
        assert_eq!(area(&out), area(&mask) + rim);
        assert_eq!((out[gw + 1], out[10 * gw + 14]), (0, 1));
        // At a level of 0.6 of the peak (12) the rim stays out.
        contact_region(&inp, 12.0, 0.6, Peel::Off, 0, &mut out, &mut s);
        assert_eq!(area(&out), area(&mask));
    }

    #[test]
    fn the_closing_on_the_core_rows_matches_the_whole_grid() {
        // A tall grid; blobs (uniform residual, so the core is the mask) with gaps the closing
        // bridges and a ring whose hole the closing leaves open, at rows near and far from the
        // grid's edges, for several radii: the region is the whole grid's closing, holes filled.
        let (gw, gh) = (40, 60);
        for (close, top) in [(1, 0), (2, 0), (2, 5), (3, 20), (4, 40), (2, 55)] {
            let mut mask = vec![0u8; gw * gh];
            let mut put = |x: usize, y: usize| {
                if y < gh {
                    mask[y * gw + x] = 1;
                }
            };
            for y in top..top + 4 {
                for x in 2..8 {
                    put(x, y);
                }
                for x in 10..16 {
                    put(x, y + 1);
                }
            }
            for y in top..top + 5 {
                for x in 20..27 {
                    if !(22..25).contains(&x) || !(top + 1..top + 4).contains(&y) {
                        put(x, y);
                    }
                }
            }
            let labels: Vec<u32> = mask.iter().map(|&m| u32::from(m)).collect();
            let resid: Vec<f32> = mask.iter().map(|&m| f32::from(m) * 30.0).collect();
            let markers = vec![0u8; gw * gh];
            let inp = RegionInputs {
                mask: &mask,
                labels: &labels,
                resid: &resid,
                markers: &markers,
                gw,
                gh,
            };
            let (mut out, mut s) = (Vec::new(), RegionScratch::default());
            contact_region(&inp, 5.0, 0.5, Peel::Off, close, &mut out, &mut s);
            let mut want = mask.clone();
            crate::grid::open_close(&mut want, &mut BitMask::default(), gw, gh, 0, close);
            fill_holes(&mut want, gw, (0, gh), &mut RegionScratch::default());
            assert_eq!(out, want, "close {close}, top {top}");
            assert!(
                area(&out) > area(&mask),
                "close {close}: the gaps are bridged"
            );
        }
    }

    #[test]
    fn each_component_has_its_own_level() {
        let (gw, gh) = (30, 10);
        let (mut mask, mut labels, mut resid) =
            (vec![0u8; gw * gh], vec![0u32; gw * gh], vec![0f32; gw * gh]);
        // Component 1: 6x6 at 100 with a 1-cell rim at 20; component 2: 6x6 at 10 (threshold 5).
        for y in 1..9 {
            for x in 1..9 {
                let i = y * gw + x;
                mask[i] = 1;
                labels[i] = 1;
                let rim = x == 1 || x == 8 || y == 1 || y == 8;
                resid[i] = if rim { 20.0 } else { 100.0 };
            }
            for x in 15..21 {
                let i = y * gw + x;
                if (2..8).contains(&y) {
                    mask[i] = 1;
                    labels[i] = 2;
                    resid[i] = 10.0;
                }
            }
        }
        let markers = vec![0u8; gw * gh];
        let inp = RegionInputs {
            mask: &mask,
            labels: &labels,
            resid: &resid,
            markers: &markers,
            gw,
            gh,
        };
        let (mut out, mut s) = (Vec::new(), RegionScratch::default());
        contact_region(&inp, 5.0, 0.5, Peel::Off, 0, &mut out, &mut s);
        assert_eq!(area(&out), 36 + 36);
        assert_eq!(
            out[gw + 1],
            0,
            "the strong component's rim is below its level"
        );
        assert_eq!(out[2 * gw + 15], 1, "the weak component is whole");
    }

    /// `fill_holes` on a 0/1 mask drawn by `set(x, y)`, all rows.
    fn filled(gw: usize, gh: usize, set: impl Fn(f32, f32) -> bool) -> (Vec<u8>, usize) {
        let mut m: Vec<u8> = (0..gw * gh)
            .map(|i| u8::from(set((i % gw) as f32, (i / gw) as f32)))
            .collect();
        let before = area(&m);
        fill_holes(&mut m, gw, (0, gh), &mut RegionScratch::default());
        (m, before)
    }

    #[test]
    fn a_ring_cut_by_the_frame_encloses_the_press_inside_the_frame() {
        let (gw, gh) = (40, 30);
        let ring =
            |cx: f32, cy: f32| move |x: f32, y: f32| (8.0..=10.0).contains(&(x - cx).hypot(y - cy));
        let disc = |cx: f32, cy: f32| {
            (0..gw * gh)
                .filter(|&i| ((i % gw) as f32 - cx).hypot((i / gw) as f32 - cy) <= 10.0)
                .count()
        };
        // Whole, cut by the left edge, cut by the left edge and the bottom (around a corner).
        for (cx, cy) in [(20.0, 15.0), (3.0, 15.0), (3.0, 26.0)] {
            let (m, ring_cells) = filled(gw, gh, ring(cx, cy));
            assert_eq!(
                area(&m),
                disc(cx, cy),
                "centre ({cx}, {cy}), ring {ring_cells}"
            );
        }
    }

    #[test]
    fn open_shapes_on_the_frame_edge_enclose_nothing() {
        let (gw, gh) = (40, 30);
        // A band from corner to corner touches all four edges: neither half is enclosed.
        let band = |x: f32, y: f32| (x * 30.0 / 40.0 - y).abs() <= 1.5;
        let (m, before) = filled(gw, gh, band);
        assert_eq!(area(&m), before);
        // An arc whose ends meet the left edge and an open side (the top is the grid's edge, the
        // arc's other end stops inside): the part beyond the open side is outside.
        let hook = |x: f32, y: f32| (8.0..=10.0).contains(&(x - 3.0).hypot(y - 15.0)) && y <= 15.0;
        let (m, before) = filled(gw, gh, hook);
        assert_eq!(area(&m), before);
        // A band along the top edge with a notch: the notch is open to the side below.
        let notch = |x: f32, y: f32| y <= 3.0 && !(10.0..=14.0).contains(&x) || y == 0.0;
        let (m, before) = filled(gw, gh, notch);
        assert_eq!(area(&m), before);
    }
}
