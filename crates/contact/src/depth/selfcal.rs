//! A linear photometric model from the press itself, for a gel with no calibration and no
//! default model of its kind (`region: depth` on DIGIT, an older GelSight, `generic`).
//!
//! The physics: a GelSight-type gel's colour change is, to first order, linear in its surface
//! slope, `dI = M grad h` (M: 3 x 2, one row per colour channel, set by the lights; Johnson and
//! Adelson, "Retrographic sensing for the measurement of surface texture and shape", CVPR 2009,
//! take the same linear map for small slopes). So the colour changes of a press span a plane in
//! RGB: its two principal directions `P` (2 x 3) give `q = P dI = (P M) grad h`, the slope up to
//! an unknown 2 x 2 map `T`. A slope field is curl-free (`d gy / dx = d gx / dy`), and a 2 x 2 map
//! keeps every field of a non-degenerate surface curl-free only when it is a multiple of the
//! identity; so `T` is the map that makes `T q` most nearly curl-free, found up to scale as the
//! least singular vector of the curl's linear constraints over the press's pixels (4 unknowns).
//! "Non-degenerate" matters: a paraboloid alone is curved alike in every direction and keeps its
//! slopes curl-free under every symmetric map; the gel's skirt around a press, curved the other
//! way radially than around, pins the map, so the fit takes the whole deformation, skirt and all.
//! Its sign makes the press go into the gel (the slope points toward the press's middle). The
//! scale stays unknown: the depth it integrates to is in arbitrary units, which is enough for the
//! half-depth contour (a ratio of depths), not for a penetration in metres.

use nalgebra::{Matrix3, Matrix4, SymmetricEigen, Vector3, Vector4};

/// Fewest pixels a fit uses.
pub const MIN_PIXELS: usize = 64;
/// Half the span of the central differences the curl is taken from \[px].
const STEP: usize = 3;

/// The slopes per DN (`GradientModel::linear`'s form) of the press in `diff` (the prepared
/// difference, RGB interleaved, `w` x `h`) over the pixels of `mask`, unit-normed; None with
/// fewer than [`MIN_PIXELS`] pixels or a degenerate press (its colour changes along one line).
pub fn fit(diff: &[f32], w: usize, h: usize, mask: &[bool]) -> Option<[[f32; 3]; 2]> {
    if diff.len() < w * h * 3 || mask.len() < w * h || w <= 2 * STEP || h <= 2 * STEP {
        return None;
    }
    let px = |i: usize| {
        Vector3::new(
            f64::from(diff[i * 3]),
            f64::from(diff[i * 3 + 1]),
            f64::from(diff[i * 3 + 2]),
        )
    };
    // The plane of the colour changes.
    let (mut cov, mut n) = (Matrix3::<f64>::zeros(), 0usize);
    for i in (0..w * h).filter(|&i| mask[i]) {
        let d = px(i);
        cov += d * d.transpose();
        n += 1;
    }
    if n < MIN_PIXELS {
        return None;
    }
    let eig = SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let (l1, l2) = (eig.eigenvalues[order[0]], eig.eigenvalues[order[1]]);
    if !(l1 > 0.0 && l2 > 1e-6 * l1) {
        return None;
    }
    let p1: Vector3<f64> = eig.eigenvectors.column(order[0]).into_owned();
    let p2: Vector3<f64> = eig.eigenvectors.column(order[1]).into_owned();
    let q = |i: usize| {
        let d = px(i);
        (p1.dot(&d), p2.dot(&d))
    };
    // The curl's constraints at the press's inner pixels (central differences over STEP pixels:
    // the slope's change grows with the step, the camera noise in it does not):
    // t21 q1x + t22 q2x - t11 q1y - t12 q2y = 0.
    let mut ata = Matrix4::<f64>::zeros();
    let mut used = 0usize;
    let (xy, centre) = centroid(mask, w, h);
    let k = STEP;
    for y in k..h.saturating_sub(k) {
        for x in k..w.saturating_sub(k) {
            let i = y * w + x;
            if !(mask[i] && mask[i - k] && mask[i + k] && mask[i - k * w] && mask[i + k * w]) {
                continue;
            }
            let ((ax, bx), (cx, dx)) = (q(i + k), q(i - k));
            let ((ay, by), (cy, dy)) = (q(i + k * w), q(i - k * w));
            let (q1x, q2x) = (ax - cx, bx - dx);
            let (q1y, q2y) = (ay - cy, by - dy);
            let a = Vector4::new(-q1y, -q2y, q1x, q2x);
            ata += a * a.transpose();
            used += 1;
        }
    }
    if used < MIN_PIXELS || xy == 0 {
        return None;
    }
    let e = SymmetricEigen::new(ata);
    let k = (0..4).min_by(|&a, &b| e.eigenvalues[a].total_cmp(&e.eigenvalues[b]))?;
    let t = e.eigenvectors.column(k);
    let row0 = p1 * t[0] + p2 * t[1];
    let row1 = p1 * t[2] + p2 * t[3];
    // The sign: the slope (h into the gel) points toward the press's middle. Each pixel votes
    // with its slope along the unit direction to the middle, so the far skirt (whose colour the
    // smooth-shading fit can turn around when a press bends the whole gel) weighs no more than
    // the cap.
    let mut toward = 0.0;
    for i in (0..w * h).filter(|&i| mask[i]) {
        let d = px(i);
        let (x, y) = ((i % w) as f64 - centre.0, (i / w) as f64 - centre.1);
        let r = x.hypot(y);
        if r > 0.0 {
            toward += (row0.dot(&d) * x + row1.dot(&d) * y) / r;
        }
    }
    let s = if toward > 0.0 { -1.0 } else { 1.0 };
    let norm = (row0.norm_squared() + row1.norm_squared()).sqrt();
    if !(norm.is_finite() && norm > 0.0) {
        return None;
    }
    let r = |v: Vector3<f64>| [0, 1, 2].map(|c| (s * v[c] / norm) as f32);
    Some([r(row0), r(row1)])
}

/// The number of set pixels of `mask` and their centroid.
fn centroid(mask: &[bool], w: usize, h: usize) -> (usize, (f64, f64)) {
    let (mut n, mut sx, mut sy) = (0usize, 0f64, 0f64);
    for i in (0..w * h).filter(|&i| mask[i]) {
        n += 1;
        sx += (i % w) as f64;
        sy += (i / w) as f64;
    }
    let nf = n.max(1) as f64;
    (n, (sx / nf, sy / nf))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Hertz press (the paraboloid inside the contact, the half-space's skirt outside it) seen
    /// through a linear colour map gives back that map's inverse up to scale and sign: the
    /// fitted slope at every pixel is the true one times one positive factor. (The paraboloid
    /// alone cannot: its curvature is the same in every direction, and every symmetric map keeps
    /// its slopes curl-free; the skirt, curved one way radially and the other around, pins it.)
    #[test]
    fn a_linear_gel_gives_back_its_slopes_up_to_scale() {
        let (w, h) = (120usize, 100usize);
        let (cx, cy, a, big_r) = (58.0f64, 47.0f64, 14.0f64, 60.0f64);
        let d = a * a / big_r;
        let depth = |x: f64, y: f64| {
            let r = (x - cx).hypot(y - cy);
            if r <= a {
                d - r * r / (2.0 * big_r)
            } else {
                let k = a / r;
                d / std::f64::consts::PI
                    * ((2.0 - 1.0 / (k * k)) * k.asin() + (1.0 / (k * k) - 1.0).sqrt())
            }
        };
        // Colour per slope: three lights 120 degrees apart, unequal gains.
        let m = [[60.0, 5.0], [-25.0, 48.0], [-30.0, -45.0]];
        let mut diff = vec![0f32; w * h * 3];
        let mut mask = vec![false; w * h];
        let mut truth = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                if (xf - cx).hypot(yf - cy) >= 3.0 * a {
                    continue;
                }
                let g = [
                    (depth(xf + 0.5, yf) - depth(xf - 0.5, yf)),
                    (depth(xf, yf + 0.5) - depth(xf, yf - 0.5)),
                ];
                let i = y * w + x;
                for c in 0..3 {
                    diff[i * 3 + c] = (m[c][0] * g[0] + m[c][1] * g[1]) as f32 * 20.0;
                }
                mask[i] = true;
                truth.push((i, g));
            }
        }
        let k = fit(&diff, w, h, &mask).unwrap();
        let fitted = |i: usize| {
            let d = &diff[i * 3..i * 3 + 3];
            let dot = |r: [f32; 3]| (0..3).map(|c| f64::from(r[c] * d[c])).sum::<f64>();
            [dot(k[0]), dot(k[1])]
        };
        let (num, den) = truth.iter().fold((0.0, 0.0), |(n, dd), (i, g)| {
            let f = fitted(*i);
            (
                n + f[0] * g[0] + f[1] * g[1],
                dd + g[0] * g[0] + g[1] * g[1],
            )
        });
        let scale = num / den;
        assert!(scale > 0.0, "the press goes into the gel: {scale}");
        let g_max = truth
            .iter()
            .map(|(_, g)| g[0].hypot(g[1]))
            .fold(0.0, f64::max);
        for (i, g) in &truth {
            let f = fitted(*i);
            for c in 0..2 {
                assert!((f[c] / scale - g[c]).abs() < 0.02 * g_max, "{f:?} {g:?}");
            }
        }
    }

    /// Colour per slope in the tests below: three lights 120 degrees apart, unequal gains.
    const M: [[f64; 2]; 3] = [[60.0, 5.0], [-25.0, 48.0], [-30.0, -45.0]];

    /// The slope (dh/dx, dh/dy) at (x, y) of a Hertz press of contact radius `a` and ball
    /// radius `big_r` centred at `c`: the paraboloid's -r / R inside, the half-space's skirt
    /// outside (Johnson, eq. 3.42a).
    fn hertz_slope(x: f64, y: f64, c: (f64, f64), a: f64, big_r: f64) -> [f64; 2] {
        let r = (x - c.0).hypot(y - c.1).max(1e-9);
        let dr = if r <= a {
            -r / big_r
        } else {
            let rho = r / a;
            2.0 * (a * a / big_r) / std::f64::consts::PI
                * ((rho * rho - 1.0).sqrt() / rho - rho * (1.0 / rho).asin())
                / a
        };
        [dr * (x - c.0) / r, dr * (y - c.1) / r]
    }

    /// A `w` x `h` press's colour difference (20 `M` times its slope, each channel's value then
    /// passed through `adjust(r, value)`, r the distance from the centre) and its mask, over the
    /// pixels within `reach` of the centre.
    fn press_diff(
        (w, h): (usize, usize),
        (c, a, big_r): ((f64, f64), f64, f64),
        reach: f64,
        mut adjust: impl FnMut(f64, f64) -> f64,
    ) -> (Vec<f32>, Vec<bool>) {
        let mut diff = vec![0f32; w * h * 3];
        let mut mask = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                let r = (xf - c.0).hypot(yf - c.1);
                if r >= reach {
                    continue;
                }
                let g = hertz_slope(xf, yf, c, a, big_r);
                let i = y * w + x;
                for (ch, m) in M.iter().enumerate() {
                    diff[i * 3 + ch] = adjust(r, (m[0] * g[0] + m[1] * g[1]) * 20.0) as f32;
                }
                mask[i] = true;
            }
        }
        (diff, mask)
    }

    /// Camera noise in the colour changes (here 1/6 of the press's largest change, one draw per
    /// pixel and channel) does not turn the map: the curl is taken over differences across
    /// 2 STEP pixels, over which the slope changes STEP times more than between neighbours while
    /// the noise does not.
    #[test]
    fn a_noisy_press_gives_back_its_slopes() {
        let (a, big_r) = (16.0, 60.0);
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut noise = || {
            // Sum of four uniforms: near-normal, sigma 1.
            let mut s = 0.0;
            for _ in 0..4 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            }
            s * 3f64.sqrt()
        };
        let peak = 20.0 * 75.0 * a / big_r;
        let (w, h) = (160, 140);
        let (diff, mask) = press_diff((w, h), ((80.0, 70.0), a, big_r), 3.0 * a, |_, v| {
            v + noise() * peak / 6.0
        });
        let k = fit(&diff, w, h, &mask).unwrap();
        // The fitted map times the true colour map is a positive multiple of the identity.
        let p = [0, 1]
            .map(|r| [0, 1].map(|col| (0..3).map(|c| f64::from(k[r][c]) * M[c][col]).sum::<f64>()));
        let scale = 0.5 * (p[0][0] + p[1][1]);
        assert!(scale > 0.0, "{p:?}");
        for (r, row) in p.iter().enumerate() {
            for (col, v) in row.iter().enumerate() {
                let want = if r == col { scale } else { 0.0 };
                assert!((v - want).abs() < 0.1 * scale, "{p:?}");
            }
        }
    }

    /// The sign holds when the far skirt's colour is wrong: a press that fills the frame leaves
    /// the smooth-shading fit little gel at rest, and it takes part of the press out, which
    /// turns the far skirt's colour change around. Each pixel votes by its direction to the
    /// middle, not by its distance, so the many far pixels do not outvote the cap.
    #[test]
    fn the_sign_follows_the_cap_when_the_far_skirt_is_turned_around() {
        let (w, h) = (160, 160);
        let (c, a) = ((80.0, 80.0), 12.0);
        let (diff, mask) = press_diff((w, h), (c, a, 60.0), 6.0 * a, |r, v| {
            if r > 2.0 * a { -v } else { v }
        });
        let k = fit(&diff, w, h, &mask).unwrap();
        // Within the contact the fitted slope points to the middle (h grows toward it).
        let mut toward = 0.0;
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x as f64 - c.0, y as f64 - c.1);
                if dx.hypot(dy) >= a {
                    continue;
                }
                let dd = &diff[(y * w + x) * 3..(y * w + x) * 3 + 3];
                let dot = |r: [f32; 3]| (0..3).map(|c| f64::from(r[c] * dd[c])).sum::<f64>();
                toward -= dot(k[0]) * dx + dot(k[1]) * dy;
            }
        }
        assert!(
            toward > 0.0,
            "the cap's slope points away from its middle: {toward}"
        );
    }

    #[test]
    fn too_few_pixels_or_one_colour_direction_fit_nothing() {
        let (w, h) = (20usize, 20usize);
        let diff = vec![1f32; w * h * 3];
        assert!(fit(&diff, w, h, &[false; 400]).is_none());
        // Every change along one colour direction: no plane.
        assert!(fit(&diff, w, h, &[true; 400]).is_none());
        assert!(fit(&diff[..10], w, h, &[true; 400]).is_none());
    }
}
