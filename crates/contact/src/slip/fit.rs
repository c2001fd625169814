//! Least-squares motion of a set of marker pairs (where each marker was -> where it is), with
//! nalgebra: the rigid motion (rotation + translation, Kabsch/Umeyama by SVD of the
//! cross-covariance) and the affine motion (linear least squares by SVD of the centred design).
//! Both work on centred coordinates so that large pixel coordinates cost no precision. An input
//! that does not determine the fit is a typed error, never NaN.

use nalgebra::{DMatrix, Matrix2, Vector2};

/// Fewest pairs either fit accepts.
pub const MIN_POINTS: usize = 3;
/// Smallest over largest spread of the points (eigenvalues of their scatter matrix) below which
/// they count as collinear for the affine fit.
const COLLINEAR: f64 = 1e-10;
/// Largest spread (sum of squared distances to the centroid, px^2) below which the points
/// coincide.
const COINCIDENT: f64 = 1e-18;

/// Why a fit could not be made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FitError {
    #[error("{got} marker pairs, the fit needs at least {MIN_POINTS}")]
    TooFewPoints { got: usize },
    #[error("{from} points moved to {to} points: the lists differ in length")]
    LengthMismatch { from: usize, to: usize },
    #[error("a marker position is not finite")]
    NotFinite,
    #[error("the markers coincide: no rotation can be measured")]
    Coincident,
    #[error("the markers are collinear: an affine motion is not determined")]
    Collinear,
}

/// `q = R(rotation) p + translation`, and the rms distance of the pairs from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    pub rotation_rad: f64,
    pub translation: [f64; 2],
    pub rms: f64,
}

impl Rigid {
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.rotation_rad.sin_cos();
        [
            c * p[0] - s * p[1] + self.translation[0],
            s * p[0] + c * p[1] + self.translation[1],
        ]
    }
}

/// `q = matrix p + translation` (matrix row-major), and the rms distance of the pairs from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    pub matrix: [[f64; 2]; 2],
    pub translation: [f64; 2],
    pub rms: f64,
}

impl Affine {
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let m = &self.matrix;
        [
            m[0][0] * p[0] + m[0][1] * p[1] + self.translation[0],
            m[1][0] * p[0] + m[1][1] * p[1] + self.translation[1],
        ]
    }
}

/// Centroids of both lists, after the common checks.
fn centroids(from: &[[f64; 2]], to: &[[f64; 2]]) -> Result<(Vector2<f64>, Vector2<f64>), FitError> {
    if from.len() != to.len() {
        return Err(FitError::LengthMismatch {
            from: from.len(),
            to: to.len(),
        });
    }
    if from.len() < MIN_POINTS {
        return Err(FitError::TooFewPoints { got: from.len() });
    }
    if from.iter().chain(to).flatten().any(|v| !v.is_finite()) {
        return Err(FitError::NotFinite);
    }
    let n = from.len() as f64;
    let mean = |pts: &[[f64; 2]]| {
        pts.iter()
            .fold(Vector2::zeros(), |s, p| s + Vector2::new(p[0], p[1]))
            / n
    };
    Ok((mean(from), mean(to)))
}

/// Scatter matrix of the points about `c`: sum of (p - c)(p - c)^T.
fn scatter(pts: &[[f64; 2]], c: &Vector2<f64>) -> Matrix2<f64> {
    pts.iter().fold(Matrix2::zeros(), |s, p| {
        let d = Vector2::new(p[0], p[1]) - c;
        s + d * d.transpose()
    })
}

fn rms<F: Fn([f64; 2]) -> [f64; 2]>(from: &[[f64; 2]], to: &[[f64; 2]], f: F) -> f64 {
    let sum: f64 = from
        .iter()
        .zip(to)
        .map(|(&p, q)| {
            let m = f(p);
            (m[0] - q[0]).powi(2) + (m[1] - q[1]).powi(2)
        })
        .sum();
    (sum / from.len() as f64).sqrt()
}

/// The rigid motion taking `from` to `to` in the least-squares sense. Collinear points are fine
/// (a rotation is still determined); coincident ones are not.
pub fn fit_rigid(from: &[[f64; 2]], to: &[[f64; 2]]) -> Result<Rigid, FitError> {
    let (pc, qc) = centroids(from, to)?;
    if scatter(from, &pc).trace() <= COINCIDENT {
        return Err(FitError::Coincident);
    }
    // Cross-covariance H = sum (p - pc)(q - qc)^T; R = V diag(1, det) U^T (no reflection).
    let h = from.iter().zip(to).fold(Matrix2::zeros(), |s, (p, q)| {
        let dp = Vector2::new(p[0], p[1]) - pc;
        let dq = Vector2::new(q[0], q[1]) - qc;
        s + dp * dq.transpose()
    });
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(FitError::Coincident);
    };
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix2::new(1.0, 0.0, 0.0, d) * u.transpose();
    let rotation_rad = r[(1, 0)].atan2(r[(0, 0)]);
    let t = qc - r * pc;
    let mut fit = Rigid {
        rotation_rad,
        translation: [t.x, t.y],
        rms: 0.0,
    };
    fit.rms = rms(from, to, |p| fit.apply(p));
    Ok(fit)
}

/// The affine motion taking `from` to `to` in the least-squares sense (needs three points not on
/// one line).
pub fn fit_affine(from: &[[f64; 2]], to: &[[f64; 2]]) -> Result<Affine, FitError> {
    let (pc, qc) = centroids(from, to)?;
    let s = scatter(from, &pc);
    if s.trace() <= COINCIDENT {
        return Err(FitError::Coincident);
    }
    let eig = s.symmetric_eigenvalues();
    let (lo, hi) = (eig.min(), eig.max());
    if lo <= COLLINEAR * hi {
        return Err(FitError::Collinear);
    }
    // Centred design X (n x 2) and targets Y (n x 2): X M^T = Y.
    let n = from.len();
    let x = DMatrix::from_fn(n, 2, |i, j| from[i][j] - pc[j]);
    let y = DMatrix::from_fn(n, 2, |i, j| to[i][j] - qc[j]);
    let mt = x
        .svd(true, true)
        .solve(&y, 0.0)
        .map_err(|_| FitError::Collinear)?;
    let matrix = [[mt[(0, 0)], mt[(1, 0)]], [mt[(0, 1)], mt[(1, 1)]]];
    let m = Matrix2::new(matrix[0][0], matrix[0][1], matrix[1][0], matrix[1][1]);
    let t = qc - m * pc;
    let mut fit = Affine {
        matrix,
        translation: [t.x, t.y],
        rms: 0.0,
    };
    if matrix
        .iter()
        .flatten()
        .chain(&fit.translation)
        .any(|v| !v.is_finite())
    {
        return Err(FitError::Collinear);
    }
    fit.rms = rms(from, to, |p| fit.apply(p));
    Ok(fit)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scattered, non-symmetric point set at sensor-like pixel coordinates.
    fn points() -> Vec<[f64; 2]> {
        (0..17)
            .map(|i| {
                let k = i as f64;
                [
                    100.0 + 37.0 * (k * 1.3).sin() + 3.0 * k,
                    80.0 + 29.0 * (k * 0.7).cos(),
                ]
            })
            .collect()
    }

    #[test]
    fn a_known_affine_motion_is_recovered_to_1e9() {
        let a = Affine {
            matrix: [[1.03, -0.07], [0.05, 0.96]],
            translation: [4.25, -2.5],
            rms: 0.0,
        };
        let from = points();
        let to: Vec<_> = from.iter().map(|&p| a.apply(p)).collect();
        let f = fit_affine(&from, &to).unwrap();
        for (g, w) in f.matrix.iter().flatten().zip(a.matrix.iter().flatten()) {
            assert!((g - w).abs() < 1e-9, "{f:?}");
        }
        for (g, w) in f.translation.iter().zip(&a.translation) {
            assert!((g - w).abs() < 1e-9, "{f:?}");
        }
        assert!(f.rms < 1e-9);
    }

    #[test]
    fn a_known_rigid_motion_is_recovered_to_1e9_by_both_fits() {
        let r = Rigid {
            rotation_rad: -0.31,
            translation: [-7.5, 3.125],
            rms: 0.0,
        };
        let from = points();
        let to: Vec<_> = from.iter().map(|&p| r.apply(p)).collect();
        let f = fit_rigid(&from, &to).unwrap();
        assert!((f.rotation_rad - r.rotation_rad).abs() < 1e-9, "{f:?}");
        assert!((f.translation[0] - r.translation[0]).abs() < 1e-9);
        assert!((f.translation[1] - r.translation[1]).abs() < 1e-9);
        assert!(f.rms < 1e-9);
        let a = fit_affine(&from, &to).unwrap();
        let (s, c) = r.rotation_rad.sin_cos();
        let want = [[c, -s], [s, c]];
        for (g, w) in a.matrix.iter().flatten().zip(want.iter().flatten()) {
            assert!((g - w).abs() < 1e-9);
        }
    }

    #[test]
    fn the_residual_is_the_rms_of_what_the_motion_cannot_explain() {
        // A translation plus a +-1 px pattern along y that no rotation or shift explains (its
        // signs sum to zero and are uncorrelated with x): the rigid fit keeps the translation
        // and leaves an rms of exactly 1 px.
        let signs = [1.0, -1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0];
        let from: Vec<[f64; 2]> = (0..8).map(|i| [10.0 * i as f64, (i % 3) as f64]).collect();
        let to: Vec<[f64; 2]> = from
            .iter()
            .zip(signs)
            .map(|(p, s)| [p[0] + 2.0, p[1] + 5.0 + s])
            .collect();
        let f = fit_rigid(&from, &to).unwrap();
        assert!((f.rms - 1.0).abs() < 1e-9, "{f:?}");
        assert!((f.translation[0] - 2.0).abs() < 1e-9 && (f.translation[1] - 5.0).abs() < 1e-9);
    }

    #[test]
    fn degenerate_inputs_are_typed_errors_not_nan() {
        let two = [[0.0, 0.0], [1.0, 1.0]];
        assert_eq!(
            fit_rigid(&two, &two),
            Err(FitError::TooFewPoints { got: 2 })
        );
        assert_eq!(
            fit_affine(&two, &two),
            Err(FitError::TooFewPoints { got: 2 })
        );
        assert_eq!(fit_affine(&[], &[]), Err(FitError::TooFewPoints { got: 0 }));
        let line: Vec<[f64; 2]> = (0..6).map(|i| [i as f64, 2.0 * i as f64 + 1.0]).collect();
        assert_eq!(fit_affine(&line, &line), Err(FitError::Collinear));
        // A rigid motion is determined by collinear points.
        let moved: Vec<[f64; 2]> = line.iter().map(|p| [p[0] + 1.0, p[1]]).collect();
        let r = fit_rigid(&line, &moved).unwrap();
        assert!(r.rotation_rad.abs() < 1e-12 && (r.translation[0] - 1.0).abs() < 1e-12);
        let same = [[3.0, 4.0]; 5];
        assert_eq!(fit_rigid(&same, &same), Err(FitError::Coincident));
        assert_eq!(fit_affine(&same, &same), Err(FitError::Coincident));
        let mut nan = line.clone();
        nan[2][1] = f64::NAN;
        assert_eq!(fit_rigid(&nan, &line), Err(FitError::NotFinite));
        assert_eq!(
            fit_affine(&line, &line[..4]),
            Err(FitError::LengthMismatch { from: 6, to: 4 })
        );
    }
}
