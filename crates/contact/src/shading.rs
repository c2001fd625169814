//! Smooth shading against deformation, and the noise of the difference, from the frame itself.
//!
//! Between the background and a frame the whole gel changes a little and unevenly (LED drift
//! across the gel, gel stretch, exposure): a low-frequency field of some DN. A press is compact
//! and strong. The field is fitted per channel as a quartic surface in the image coordinates (15
//! terms) to the signed difference on a sparse lattice of cells, by iteratively reweighted least
//! squares with hard rejection: cells far from the current fit (the press, moving markers) are
//! left out of the next fit, so the press never bends the surface towards itself, and a quartic
//! cannot follow a compact press anyway. A press covering most of the gel is not compact, and
//! its inside is smooth: the least-squares start can end on it, so when the first fit leaves
//! out a quarter of the lattice or more, a second start from the cells that changed least (the
//! gel at rest) is tried and kept when its field is clearly smaller (see [`fit`]). On a noisy
//! frame the lattice holds box means of the difference (the box the threshold uses). The noise
//! comes from the same frame: a robust sigma per channel from differences of neighbouring cells
//! (a low quantile), with no assumption about the sensor.
//!
//! Cost: the fitting lattice holds ~600 cells whatever the frame size (an odd step each way,
//! rows staggered; the noise is measured on ~2,000); the normal matrix (15 x 15) of the lattice
//! less the masked marker cells is built once per frame size and marker mask, and only the rows
//! rejected on this frame are taken out of it; at most three iterations (fewer when the
//! inliers stop changing). Subtracting the surface is four multiply-adds per channel per cell
//! (Horner in x, the row's coefficients computed once per row), skipped when the fitted field is
//! below half the noise.

// Gaussian elimination and the symmetric fill read as index arithmetic on small fixed matrices.
#![allow(clippy::needless_range_loop)]

/// Terms of the quartic surface.
const TERMS: usize = 15;
/// Iterations of fit + rejection.
const ITERATIONS: usize = 3;
/// Cells further than this many (summed) sigmas from the fit are left out of the next fit.
const REJECT_K: f32 = 3.0;
/// The second start: the cells whose summed |difference| is at most this quantile (per mille).
const SECOND_START_PERMILLE: usize = 300;
/// The second start is tried when the first fit keeps fewer than NUM / DEN of the lattice.
const SECOND_LOOK_NUM: usize = 3;
const SECOND_LOOK_DEN: usize = 4;
/// Iterations of the second start.
const SECOND_ITERATIONS: usize = 6;
/// Largest per-channel noise [DN] left on the difference before it is fitted and thresholded:
/// noisier frames are averaged over a box of cells first.
const SMOOTH_TARGET_DN: f32 = 2.0;
/// Largest box radius [cells] of that averaging.
const MAX_SMOOTHING: u32 = 4;
/// Target size of the fitting lattice (cells).
const LATTICE_CELLS: usize = 600;
/// Target size of the lattice the noise is measured on (cells).
const NOISE_CELLS: usize = 2000;
/// Smallest per-channel sigma reported [DN] (an exactly repeated frame has none).
const MIN_SIGMA: f32 = 0.05;

/// Fitted shading and noise of one frame's difference.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ShadingFit {
    /// Quartic coefficients per channel, in `basis` order.
    pub coef: [[f32; TERMS]; 3],
    /// Robust noise sigma per channel of one cell of the difference \[DN].
    pub sigma: [f32; 3],
    /// Share of the lattice cells left out of the final fit (the press, markers that moved).
    pub rejected: f32,
    /// Largest sum over channels of |fitted field| on the lattice \[DN].
    pub peak: f32,
}

/// Scratch buffers of the fit, reused across frames.
#[derive(Debug, Default)]
pub struct ShadingScratch {
    /// Lattice cell indices and their basis rows.
    idx: Vec<usize>,
    /// The denser lattice the noise is measured on, less the cells with no right neighbour.
    noise_idx: Vec<usize>,
    /// (As f64: exactly the f32 basis values, converted once per frame size.)
    rows: Vec<[f64; TERMS]>,
    /// The same basis term-major (term t of every lattice cell together), so that the model at
    /// the lattice is evaluated a term at a time over all cells (a loop the compiler vectorises).
    cols: Vec<f32>,
    /// The model at the lattice, channel-major.
    model: Vec<f32>,
    inlier: Vec<bool>,
    /// |neighbour difference| per channel, as f32 bits (see [`nth_non_negative`]).
    abs: [Vec<u32>; 3],
    /// The geometry the lattice was built for (gw, gh).
    built: (usize, usize),
    /// Normal matrix (upper triangle) of the lattice cells not skipped, and which those are:
    /// built again only when the skipped cells change (the marker mask, once per background).
    base: [[f64; TERMS]; TERMS],
    open: Vec<bool>,
    /// u of every cell column.
    us: Vec<f32>,
    /// The difference at the lattice cells of this frame.
    d: Vec<[f32; 3]>,
}

/// About `cells` cells spread over the grid: an odd step, and rows staggered, so that the lattice
/// does not alias with a regular pattern of the gel (marker dots every few cells).
fn lattice(gw: usize, gh: usize, cells: usize) -> Vec<usize> {
    let k = ((gw * gh) as f64 / cells as f64).sqrt().floor().max(1.0) as usize | 1;
    let mut out = Vec::new();
    for (row, y) in (k / 2..gh).step_by(k).enumerate() {
        for x in ((row * 3 + k / 2) % k..gw).step_by(k) {
            out.push(y * gw + x);
        }
    }
    out
}

/// Normalised coordinates: u across the width in [-1, 1], v with the same scale.
fn coords(x: usize, y: usize, gw: usize, gh: usize) -> (f32, f32) {
    let half = gw.max(2) as f32 / 2.0;
    (
        (x as f32 + 0.5 - half) / half,
        (y as f32 + 0.5 - gh as f32 / 2.0) / half,
    )
}

fn basis(u: f32, v: f32) -> [f32; TERMS] {
    [
        1.0,
        u,
        v,
        u * u,
        u * v,
        v * v,
        u * u * u,
        u * u * v,
        u * v * v,
        v * v * v,
        u * u * u * u,
        u * u * u * v,
        u * u * v * v,
        u * v * v * v,
        v * v * v * v,
    ]
}

/// `a += w * row row^T` on the upper triangle.
#[inline]
fn add_outer(a: &mut [[f64; TERMS]; TERMS], row: &[f64; TERMS], w: f64) {
    for (j, &rj) in row.iter().enumerate() {
        let rj = w * rj;
        for (k, &rk) in row.iter().enumerate().skip(j) {
            a[j][k] += rj * rk;
        }
    }
}

/// Solve the symmetric positive (semi-)definite system `a x = b` for three right-hand sides by
/// Gaussian elimination with partial pivoting; near-singular pivots give zero coefficients.
#[inline]
fn solve(mut a: [[f64; TERMS]; TERMS], mut b: [[f64; 3]; TERMS]) -> [[f32; TERMS]; 3] {
    for col in 0..TERMS {
        let piv = (col..TERMS)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap_or(col);
        a.swap(col, piv);
        b.swap(col, piv);
        let p = a[col][col];
        if p.abs() < 1e-9 {
            continue;
        }
        for row in col + 1..TERMS {
            let f = a[row][col] / p;
            if f == 0.0 {
                continue;
            }
            for k in col..TERMS {
                a[row][k] -= f * a[col][k];
            }
            for c in 0..3 {
                b[row][c] -= f * b[col][c];
            }
        }
    }
    let mut x = [[0f64; 3]; TERMS];
    for row in (0..TERMS).rev() {
        let p = a[row][row];
        if p.abs() < 1e-9 {
            continue;
        }
        for c in 0..3 {
            let mut s = b[row][c];
            for k in row + 1..TERMS {
                s -= a[row][k] * x[k][c];
            }
            x[row][c] = s / p;
        }
    }
    let mut out = [[0f32; TERMS]; 3];
    for (t, xr) in x.iter().enumerate() {
        for c in 0..3 {
            out[c][t] = xr[c] as f32;
        }
    }
    out
}

/// The `k`-th smallest (0-based) of non-negative floats given as their bits (`f32::to_bits`),
/// `None` when `k` is out of range. For non-negative floats the bits are in the order of the
/// values (that of `f32::total_cmp`), so an integer selection finds the same element as a float
/// one, at a fraction of the cost of the float comparisons.
pub fn nth_non_negative(bits: &mut [u32], k: usize) -> Option<f32> {
    if k >= bits.len() {
        return None;
    }
    Some(f32::from_bits(*bits.select_nth_unstable(k).1))
}

/// Robust sigma of zero-mean Gaussian values from their absolute values (as f32 bits): the 30th
/// percentile of |x| is 0.3853 sigma. A low quantile, so that a press covering much of the gel
/// (its cells all far out) inflates it little.
fn robust_sigma(abs: &mut [u32]) -> f32 {
    let k = abs.len() * 3 / 10;
    nth_non_negative(abs, k).map_or(0.0, |v| v / 0.3853)
}

/// Radius \[cells] of the box the difference is averaged over for a frame with per-channel noise
/// `sigma` of one cell: the per-channel noise left is at most `SMOOTH_TARGET_DN` (presses are
/// larger than the box), `MAX_SMOOTHING` at most.
pub fn smoothing_radius(sigma: &[f32; 3]) -> u32 {
    let sum: f32 = sigma.iter().sum();
    let mut r = 0u32;
    while sum / 3.0 / (2 * r + 1) as f32 > SMOOTH_TARGET_DN && r < MAX_SMOOTHING {
        r += 1;
    }
    r
}

/// Fit the shading of the signed difference `diff(cell)` (RGB, cell = y gw + x of a `gw` x `gh`
/// grid), leaving out cells where `skip` is non-zero (masked markers). The difference is asked
/// for at the lattices only (a few thousand cells), so the caller need not compute it everywhere.
#[multiversion::multiversion(targets("x86_64+avx2"))]
pub fn fit(
    diff: impl Fn(usize) -> [f32; 3],
    skip: &[u8],
    gw: usize,
    gh: usize,
    s: &mut ShadingScratch,
) -> ShadingFit {
    if s.built != (gw, gh) {
        s.idx = lattice(gw, gh, LATTICE_CELLS);
        s.noise_idx = lattice(gw, gh, NOISE_CELLS);
        s.noise_idx
            .retain(|&i| (i + 1) % gw != 0 && i + 1 < gw * gh);
        s.rows = s
            .idx
            .iter()
            .map(|&i| {
                let (u, v) = coords(i % gw, i / gw, gw, gh);
                basis(u, v).map(f64::from)
            })
            .collect();
        let n = s.rows.len();
        s.cols = (0..TERMS * n)
            .map(|k| s.rows[k % n][k / n] as f32)
            .collect();
        s.open.clear();
        s.us = (0..gw).map(|x| coords(x, 0, gw, gh).0).collect();
        s.built = (gw, gh);
    }
    s.inlier.clear();
    s.inlier
        .extend(s.idx.iter().map(|&i| skip.get(i).is_none_or(|&m| m == 0)));
    if s.open != s.inlier {
        s.base = [[0f64; TERMS]; TERMS];
        for (row, _) in s.rows.iter().zip(&s.inlier).filter(|(_, ok)| **ok) {
            add_outer(&mut s.base, row, 1.0);
        }
        s.open.clone_from(&s.inlier);
    }
    let mut fit = ShadingFit::default();
    // The noise, from differences of horizontally neighbouring cells at the lattice: shading and
    // the inside of a press change little from one cell to the next, so even a press covering
    // half of the gel barely moves a low quantile of them.
    for v in s.abs.iter_mut() {
        v.clear();
    }
    for &i in &s.noise_idx {
        let j = i + 1;
        let masked = |k: usize| skip.get(k).is_some_and(|&m| m != 0);
        if masked(i) || masked(j) {
            continue;
        }
        let (dj, di) = (diff(j), diff(i));
        for c in 0..3 {
            s.abs[c].push((dj[c] - di[c]).abs().to_bits());
        }
    }
    for c in 0..3 {
        fit.sigma[c] = (robust_sigma(&mut s.abs[c]) / std::f32::consts::SQRT_2).max(MIN_SIGMA);
    }
    // On a noisy frame the lattice holds the difference averaged over the box the threshold
    // will use, so that the rejection separates what the threshold will.
    let r = smoothing_radius(&fit.sigma) as usize;
    let limit = REJECT_K * (fit.sigma[0] + fit.sigma[1] + fit.sigma[2]) / (2 * r + 1) as f32;
    s.d.clear();
    if r == 0 {
        s.d.extend(s.idx.iter().map(|&i| diff(i)));
    } else {
        for &i in &s.idx {
            let (x, y) = (i % gw, i / gw);
            let mut acc = [0f32; 3];
            let mut n = 0u32;
            for yy in y.saturating_sub(r)..(y + r + 1).min(gh) {
                for xx in x.saturating_sub(r)..(x + r + 1).min(gw) {
                    let j = yy * gw + xx;
                    if skip.get(j).is_some_and(|&m| m != 0) {
                        continue;
                    }
                    let d = diff(j);
                    for c in 0..3 {
                        acc[c] += d[c];
                    }
                    n += 1;
                }
            }
            let n = n.max(1) as f32;
            s.d.push(acc.map(|a| a / n));
        }
    }
    // First start: every cell not skipped (a least-squares fit of everything, then rejection).
    s.inlier.clone_from(&s.open);
    let open_cells = s.open.iter().filter(|&&o| o).count();
    let first = iterate(s, limit, ITERATIONS, open_cells);
    let mut chosen = first;
    // A press covering much of the gel can capture the first fit (its inside is smooth, and the
    // least-squares start sits between it and the gel at rest); the first fit then leaves out
    // much of the lattice. Then a second start: the cells that changed least.
    if first.kept * SECOND_LOOK_DEN < open_cells * SECOND_LOOK_NUM {
        let change = |d: &[f32; 3]| d[0].abs() + d[1].abs() + d[2].abs();
        s.abs[0].clear();
        for (di, &open) in s.d.iter().zip(&s.open) {
            if open {
                s.abs[0].push(change(di).to_bits());
            }
        }
        let k = s.abs[0].len() * SECOND_START_PERMILLE / 1000;
        let quiet = nth_non_negative(&mut s.abs[0], k).unwrap_or(0.0);
        for ((di, &open), ok) in s.d.iter().zip(&s.open).zip(s.inlier.iter_mut()) {
            *ok = open && change(di) <= quiet;
        }
        let second = iterate(s, limit, SECOND_ITERATIONS, open_cells);
        // Taken when it is no worse on both counts, or when its field is less than half the
        // first's while it keeps a third of the lattice: the gel at rest around a press that
        // covers most of it.
        if (second.kept >= first.kept && second.mean_field <= first.mean_field)
            || (second.kept * 3 >= open_cells && second.mean_field * 2.0 <= first.mean_field)
        {
            chosen = second;
        }
    }
    fit.coef = chosen.coef;
    fit.peak = chosen.peak;
    fit.rejected = (s.idx.len() - chosen.kept) as f32 / s.idx.len().max(1) as f32;
    fit
}

/// One robust fit from the inliers in `s.inlier`.
#[derive(Clone, Copy)]
struct Iterated {
    coef: [[f32; TERMS]; 3],
    peak: f32,
    /// Lattice cells in the final fit.
    kept: usize,
    /// Mean over the open lattice cells of the summed |fitted field| \[DN].
    mean_field: f32,
}

/// Fit + rejection from the inliers in `s.inlier`, at most `iterations` times (fewer when the
/// inliers stop changing); `s.inlier` holds the final inliers. `open_cells`: the lattice cells
/// not skipped.
#[inline(always)]
fn iterate(s: &mut ShadingScratch, limit: f32, iterations: usize, open_cells: usize) -> Iterated {
    let mut out = Iterated {
        coef: [[0f32; TERMS]; 3],
        peak: 0.0,
        kept: 0,
        mean_field: 0.0,
    };
    for it in 0..iterations {
        // The normal matrix is that of the cells not skipped less the rows rejected (few,
        // usually).
        let mut a = s.base;
        // Channel-major, so that a cell's terms are added to contiguous accumulators.
        let mut bc = [[0f64; TERMS]; 3];
        for (((di, row), &ok), &open) in s.d.iter().zip(&s.rows).zip(&s.inlier).zip(&s.open) {
            if !ok {
                if open {
                    add_outer(&mut a, row, -1.0);
                }
                continue;
            }
            for (bc, &d) in bc.iter_mut().zip(di) {
                let d = f64::from(d);
                for (bj, &rj) in bc.iter_mut().zip(row) {
                    *bj += rj * d;
                }
            }
        }
        let mut b = [[0f64; 3]; TERMS];
        for (j, bj) in b.iter_mut().enumerate() {
            *bj = [bc[0][j], bc[1][j], bc[2][j]];
        }
        for j in 0..TERMS {
            for k in 0..j {
                a[j][k] = a[k][j];
            }
        }
        out.coef = solve(a, b);
        // Residuals at the lattice, then the new inliers.
        let mut rejected = 0usize;
        let mut changed = false;
        let mut field_sum = 0f64;
        out.peak = 0.0;
        // The model at every lattice cell, summed term by term in the basis order.
        let n = s.idx.len();
        s.model.clear();
        s.model.resize(3 * n, 0.0);
        for (model, coef) in s.model.chunks_exact_mut(n.max(1)).zip(&out.coef) {
            for (col, &k) in s.cols.chunks_exact(n.max(1)).zip(coef) {
                for (m, &r) in model.iter_mut().zip(col) {
                    *m += r * k;
                }
            }
        }
        let (m0, rest) = s.model.split_at(n);
        let (m1, m2) = rest.split_at(n);
        let cells = s.d.iter().zip(&s.open).zip(s.inlier.iter_mut());
        for (k, ((di, &open), ok)) in cells.enumerate() {
            let (mut e, mut field) = (0f32, 0f32);
            for (c, model) in [m0[k], m1[k], m2[k]].into_iter().enumerate() {
                e += (di[c] - model).abs();
                field += model.abs();
            }
            out.peak = out.peak.max(field);
            if open {
                field_sum += f64::from(field);
            }
            let now = open && e < limit;
            changed |= now != *ok;
            *ok = now;
            rejected += usize::from(!now);
        }
        out.kept = s.idx.len() - rejected;
        out.mean_field = (field_sum / open_cells.max(1) as f64) as f32;
        // The same inliers would give the same fit again.
        if !changed || it + 1 == iterations {
            break;
        }
    }
    out
}

impl ShadingFit {
    /// The fitted field along grid row `y`, per channel, as a quartic in u (coefficients of
    /// u^0..u^4): evaluate it with [`ShadingFit::at`] and the `us` of the scratch.
    #[inline]
    pub fn row(&self, y: usize, gw: usize, gh: usize) -> [[f32; 5]; 3] {
        let c = &self.coef;
        let (_, v) = coords(0, y, gw, gh);
        let mut p = [[0f32; 5]; 3];
        for ch in 0..3 {
            let k = &c[ch];
            p[ch] = [
                k[0] + v * (k[2] + v * (k[5] + v * (k[9] + v * k[14]))),
                k[1] + v * (k[4] + v * (k[8] + v * k[13])),
                k[3] + v * (k[7] + v * k[12]),
                k[6] + v * k[11],
                k[10],
            ];
        }
        p
    }

    /// One channel of a [`ShadingFit::row`] at `u` (Horner: four multiply-adds).
    #[inline]
    pub fn at(q: &[f32; 5], u: f32) -> f32 {
        q[0] + u * (q[1] + u * (q[2] + u * (q[3] + u * q[4])))
    }

    /// Subtract the fitted field from `diff` (RGB interleaved) in place (`s`: the scratch `fit`
    /// used).
    pub fn remove(&self, diff: &mut [f32], gw: usize, gh: usize, s: &ShadingScratch) {
        for (y, row) in diff.chunks_exact_mut(gw * 3).enumerate().take(gh) {
            let p = self.row(y, gw, gh);
            for (cell, &u) in row.chunks_exact_mut(3).zip(&s.us) {
                for ch in 0..3 {
                    cell[ch] -= Self::at(&p[ch], u);
                }
            }
        }
    }
}

impl ShadingScratch {
    /// u of every cell column of the grid the last fit was for.
    pub fn us(&self) -> &[f32] {
        &self.us
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fit of an RGB-interleaved difference with nothing skipped.
    fn fit_rgb(diff: &[f32], gw: usize, gh: usize, s: &mut ShadingScratch) -> ShadingFit {
        fit(
            |i| [diff[i * 3], diff[i * 3 + 1], diff[i * 3 + 2]],
            &[],
            gw,
            gh,
            s,
        )
    }

    /// A smooth field plus a compact strong press: the fit follows the field, not the press,
    /// and the noise estimate is the noise.
    #[test]
    fn fit_follows_shading_not_the_press() {
        let (gw, gh) = (160, 120);
        let mut seed = 7u64;
        let mut noise = || {
            let mut s = 0.0f32;
            for _ in 0..4 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += (seed >> 40) as f32 / (1u64 << 24) as f32;
            }
            (s - 2.0) * 3f32.sqrt()
        };
        let mut diff = vec![0f32; gw * gh * 3];
        let field = |x: usize, y: usize, c: usize| {
            let (u, v) = (x as f32 / gw as f32, y as f32 / gh as f32);
            (c as f32 + 1.0) * 4.0 * (-((u - 0.3).powi(2) + (v - 0.6).powi(2)) / 0.18).exp()
        };
        for y in 0..gh {
            for x in 0..gw {
                let press = (x as f32 - 100.0).hypot(y as f32 - 50.0) < 20.0;
                for c in 0..3 {
                    diff[(y * gw + x) * 3 + c] =
                        field(x, y, c) + 2.0 * noise() + if press { 30.0 } else { 0.0 };
                }
            }
        }
        let mut s = ShadingScratch::default();
        let f = fit_rgb(&diff, gw, gh, &mut s);
        for c in 0..3 {
            assert!((f.sigma[c] - 2.0).abs() < 0.4, "{:?}", f.sigma);
        }
        assert!(f.rejected > 0.03 && f.rejected < 0.15, "{}", f.rejected);
        f.remove(&mut diff, gw, gh, &s);
        // The field is gone outside the press (within the noise) and the press is still there.
        let at = |x: usize, y: usize| diff[(y * gw + x) * 3 + 2];
        let off: Vec<f32> = (0..gh)
            .step_by(7)
            .flat_map(|y| (0..60).step_by(7).map(move |x| (x, y)))
            .map(|(x, y)| at(x, y))
            .collect();
        let mean_off = off.iter().sum::<f32>() / off.len() as f32;
        assert!(mean_off.abs() < 1.0, "{mean_off}");
        assert!(at(100, 50) > 22.0, "{}", at(100, 50));
    }

    /// A press covering 60 % of the gel (a plateau with a sharp edge, cut by the frame's top and
    /// bottom, as DIGIT's large press) under a mild tilt: the fit follows the gel at rest around
    /// it, not the press (the least-squares start alone ends on the press's inside).
    #[test]
    fn a_press_over_most_of_the_gel_is_not_shading() {
        let (gw, gh) = (160, 120);
        let mut diff = vec![0f32; gw * gh * 3];
        let mut inside = 0usize;
        for y in 0..gh {
            for x in 0..gw {
                let press = (x as f32 - 80.0).hypot(y as f32 - 60.0) < 61.0;
                inside += usize::from(press);
                let tilt = 4.0 * (x as f32 / gw as f32 - 0.5);
                // A deterministic texture of +-1 DN for the noise.
                let n = if (x * 7 + y * 13) % 5 < 2 { 1.0 } else { -1.0 };
                for c in 0..3 {
                    let p = if press { [14.0, 12.0, 16.0][c] } else { 0.0 };
                    diff[(y * gw + x) * 3 + c] = tilt + n + p;
                }
            }
        }
        assert!(
            inside * 100 > gw * gh * 55,
            "the press covers {inside} cells"
        );
        let mut s = ShadingScratch::default();
        let f = fit_rgb(&diff, gw, gh, &mut s);
        f.remove(&mut diff, gw, gh, &s);
        let at = |x: usize, y: usize| {
            diff[(y * gw + x) * 3..(y * gw + x) * 3 + 3]
                .iter()
                .sum::<f32>()
        };
        // The press is all there in the middle and near its edge, and the corners are at rest.
        for (x, y) in [(80, 60), (40, 60), (120, 60), (80, 20), (80, 100)] {
            assert!(at(x, y) > 35.0, "press at ({x}, {y}): {}", at(x, y));
        }
        for (x, y) in [(2, 2), (157, 2), (2, 117), (157, 117)] {
            assert!(at(x, y).abs() < 8.0, "corner ({x}, {y}): {}", at(x, y));
        }
        assert!(f.rejected > 0.5, "{}", f.rejected);
    }
}
