//! Ball presses with exact depth: what a depth calibration is made from, and its ground truth.
//!
//! A rigid ball of radius R pressed with approach d into the gel. The surface follows Hertz's
//! solution for a sphere on an elastic half-space (K. L. Johnson, *Contact Mechanics*, 1985,
//! eqs. 3.41a and 3.42a): the contact radius is `a = sqrt(R d)`, inside the contact the gel takes
//! the ball's shape (the exact sphere, `d - (R - sqrt(R^2 - r^2))`, which Hertz approximates by
//! the paraboloid `d - r^2 / 2R`), and outside it slopes back to rest as
//! `(d / pi) [(2 - r^2/a^2) asin(a/r) + sqrt(r^2/a^2 - 1)]` on a half-space: half the approach
//! at the contact edge, the same slope as the ball there, and a tail that falls off as `1/r`.
//! A real gel is a layer a few mm thick bonded to a rigid window, and comes back to rest much
//! sooner: by default ([`Skirt::Fem`]) the surface outside the contact is Hertz's pressure seen
//! through the point response of a GelSight gel that Taxim published from finite elements
//! (`FEM_POINT_RESPONSE`) instead of the half-space's `1/r`, scaled to the ball's depth at the
//! edge. [`Skirt`] also renders Hertz's profile faded over a layer, or the whole half-space. So the contact
//! radius lies at the Hertz value `sqrt(R d)`, below the geometric intersection
//! `sqrt(2 R d - d^2)` of the undeformed gel with the ball: the gel around a press is pulled down
//! with it (the "skirt"), and the ball meets it sooner. The scenario renderer
//! (`render.rs`, the goldens' frames) follows the geometric paraboloid `sqrt(2 R d)` instead,
//! with a drawn skirt that is not this shape: it is left as it is so that existing scenes keep
//! their bytes.
//!
//! The frame is drawn by the mock's photometric model from the height map's own gradients
//! ([`MockSensor::render_height`]), so the map is the exact depth of the frame. The truth stays
//! with the caller: what the stack sees is the frame and the background only.

use crate::degrade::{noisy, shading_field};
use crate::{MockConfig, MockSensor, Scenario, SplitMix64};
use unitac_core::{Frame, SensorSpec};

/// Vertical displacement of a GelSight gel's surface around a point load, as a share of the
/// displacement under the load, against the distance from it \[mm]: the radial means (0.1 mm
/// bins) of the finite-element response that Taxim ships for its gel (S. Si and W. Yuan,
/// "Taxim: An Example-based Simulation Model for GelSight Tactile Sensors", IEEE Robotics and
/// Automation Letters 7(2), 2022; github.com/Robo-Touch/Taxim, calibs/0705_dome_node_dz_0.3:
/// ANSYS, one surface node of the gel pressed 0.3 mm). Closer than 0.2 mm the mesh resolves
/// nothing; from 5 mm on the surface is at rest.
const FEM_POINT_RESPONSE: [(f64, f64); 11] = [
    (0.2, 0.7361),
    (0.3, 0.4351),
    (0.5, 0.2384),
    (0.7, 0.1455),
    (1.0, 0.0930),
    (1.5, 0.0521),
    (2.0, 0.0308),
    (2.5, 0.0188),
    (3.0, 0.0114),
    (4.0, 0.0033),
    (5.0, 0.0),
];

/// Radial step of a press's tabled [`Skirt::Fem`] profile \[mm].
const FEM_TABLE_STEP_MM: f64 = 0.01;

/// The gel's surface outside the contact (its skirt): how far a press pulls the gel around it
/// down with it. Hertz's half-space solution is the widest; a thin layer bonded to a rigid window
/// comes back to rest within about its thickness (a GelSight Mini's gel is about 4 mm thick: the
/// FEATS project's finite-element mesh of it, github.com/feats-ai/feats,
/// src/calculix/obj/gelsight_mini). The default is the finite-element response of a GelSight
/// gel; gels differ (GelSight Mini, DIGIT and older GelSights), so `unitac-lab eval contact`
/// measures the contact region across these skirts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Skirt {
    /// Hertz's elastic half-space outside the contact, with its `1/r` tail.
    HalfSpace,
    /// Hertz's profile faded by `exp(-((r - a) / t)^2)` over a gel thickness t \[mm].
    Layer { thickness_mm: f64 },
    /// Hertz's pressure on a GelSight gel as finite elements see it (the default): the surface
    /// is the pressure seen through the gel's published point response (`FEM_POINT_RESPONSE`,
    /// Taxim's superposition) instead of the half-space's `1/r`, scaled to the ball's depth at
    /// the edge. No contact solve: the pressure stays Hertz's, and just outside the edge the
    /// surface lies a hair above the ball, which touches it up to 2 % beyond the Hertz radius.
    Fem,
}

impl Default for Skirt {
    /// The finite-element skirt, [`Skirt::Fem`].
    fn default() -> Self {
        Skirt::Fem
    }
}

impl std::fmt::Display for Skirt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Skirt::HalfSpace => write!(f, "half-space"),
            Skirt::Layer { thickness_mm } => write!(f, "layer {thickness_mm} mm"),
            Skirt::Fem => write!(f, "GelSight FEM"),
        }
    }
}

/// One press: where, which ball, how deep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallPress {
    /// Ball centre over the gel \[px] (x, y), in the frame's pixels.
    pub center_px: [f64; 2],
    /// Ball radius \[mm].
    pub radius_mm: f64,
    /// Approach (penetration at the centre) \[mm].
    pub approach_mm: f64,
}

impl BallPress {
    /// Hertz contact radius `sqrt(R d)` \[mm].
    pub fn contact_radius_mm(&self) -> f64 {
        (self.radius_mm * self.approach_mm.max(0.0)).sqrt()
    }

    /// Geometric intersection radius of the undeformed gel with the ball, `sqrt(2 R d - d^2)` \[mm].
    pub fn geometric_radius_mm(&self) -> f64 {
        let (r, d) = (self.radius_mm, self.approach_mm.max(0.0));
        (2.0 * r * d - d * d).max(0.0).sqrt()
    }

    /// Depth of the ball's surface at distance `r` \[mm] from the press centre (the exact
    /// sphere; negative outside the geometric radius).
    fn sphere_depth(&self, r: f64) -> f64 {
        let big_r = self.radius_mm;
        self.approach_mm - (big_r - (big_r * big_r - r * r).max(0.0).sqrt())
    }

    /// Depth of the gel surface at distance `r` \[mm] from the press centre \[mm, positive into
    /// the gel], with the default skirt.
    pub fn depth_at(&self, r: f64) -> f64 {
        self.depth_at_with(r, Skirt::default())
    }

    /// [`Self::depth_at`] with the given skirt outside the contact.
    pub fn depth_at_with(&self, r: f64, skirt: Skirt) -> f64 {
        let (big_r, d) = (self.radius_mm, self.approach_mm);
        if d <= 0.0 || big_r <= 0.0 {
            return 0.0;
        }
        let a = self.contact_radius_mm();
        if r < a {
            return self.sphere_depth(r);
        }
        // Hertz's skirt starts at d / 2, the paraboloid's depth at the edge; it is scaled to
        // start where the exact sphere is (a few % less), so the surface is continuous.
        let rho = r / a;
        let hertz = || {
            2.0 * self.sphere_depth(a) / std::f64::consts::PI
                * ((2.0 - rho * rho) * (1.0 / rho).asin() + (rho * rho - 1.0).max(0.0).sqrt())
        };
        match skirt {
            Skirt::HalfSpace => hertz(),
            Skirt::Layer { thickness_mm } => {
                let t = (r - a) / thickness_mm.max(1e-6);
                hertz() * (-t * t).exp()
            }
            Skirt::Fem => self.fem_depth(r, fem_surface(a, a)),
        }
    }

    /// [`Skirt::Fem`]'s depth at `r` at or beyond the contact edge, given `fem_surface(a, a)`
    /// (the same for every radius of a press).
    fn fem_depth(&self, r: f64, at_edge: f64) -> f64 {
        let a = self.contact_radius_mm();
        self.sphere_depth(a) * fem_surface(a, r) / at_edge
    }

    /// The depth map \[mm] of a `width` x `height` frame at `mm_per_px`, row-major.
    pub fn depth_map(&self, width: u32, height: u32, mm_per_px: f64) -> Vec<f32> {
        self.depth_map_with(width, height, mm_per_px, Skirt::default())
    }

    /// [`Self::depth_map`] with the given skirt.
    pub fn depth_map_with(
        &self,
        width: u32,
        height: u32,
        mm_per_px: f64,
        skirt: Skirt,
    ) -> Vec<f32> {
        let (w, h) = (width as usize, height as usize);
        let mut out = vec![0f32; w * h];
        // The finite-element skirt is an integral per radius: tabled once per press.
        let fem = (skirt == Skirt::Fem).then(|| self.fem_table());
        let a = self.contact_radius_mm();
        for (y, row) in out.chunks_exact_mut(w.max(1)).enumerate() {
            let dy = (y as f64 - self.center_px[1]) * mm_per_px;
            for (x, v) in row.iter_mut().enumerate() {
                let dx = (x as f64 - self.center_px[0]) * mm_per_px;
                let r = dx.hypot(dy);
                *v = match &fem {
                    Some(t) if r >= a => table_at(t, (r - a) / FEM_TABLE_STEP_MM),
                    _ => self.depth_at_with(r, skirt),
                } as f32;
            }
        }
        out
    }

    /// [`Skirt::Fem`]'s depth from the contact edge out to rest, every [`FEM_TABLE_STEP_MM`].
    fn fem_table(&self) -> Vec<f64> {
        if self.approach_mm <= 0.0 || self.radius_mm <= 0.0 {
            return vec![0.0; 2];
        }
        let a = self.contact_radius_mm();
        let reach = FEM_POINT_RESPONSE[FEM_POINT_RESPONSE.len() - 1].0;
        let n = (reach / FEM_TABLE_STEP_MM).ceil() as usize;
        let at_edge = fem_surface(a, a);
        (0..=n)
            .map(|k| self.fem_depth(a + k as f64 * FEM_TABLE_STEP_MM, at_edge))
            .collect()
    }

    /// The true contact mask (r < a), row-major.
    pub fn contact_mask(&self, width: u32, height: u32, mm_per_px: f64) -> Vec<bool> {
        let (w, h) = (width as usize, height as usize);
        let a = self.contact_radius_mm() / mm_per_px;
        let mut out = vec![false; w * h];
        for (i, m) in out.iter_mut().enumerate() {
            let (x, y) = ((i % w.max(1)) as f64, (i / w.max(1)) as f64);
            *m = (x - self.center_px[0]).hypot(y - self.center_px[1]) < a;
        }
        out
    }
}

/// Linear interpolation in `t` at fractional index `x` (0 past its end).
fn table_at(t: &[f64], x: f64) -> f64 {
    let i = x.floor();
    match (t.get(i as usize), t.get(i as usize + 1)) {
        (Some(p), Some(q)) if i >= 0.0 => p + (q - p) * (x - i),
        _ => 0.0,
    }
}

/// The gel's point response over the half-space's `1/r` at distance `r` \[mm]: 1 near the load
/// (a layer is a half-space at distances well under its thickness), from the table's `r` times
/// its share beyond 0.2 mm (interpolated linearly), 0 from 5 mm on.
fn layer_factor(r: f64) -> f64 {
    let (r0, f0) = FEM_POINT_RESPONSE[0];
    if r <= r0 {
        return 1.0;
    }
    FEM_POINT_RESPONSE
        .windows(2)
        .find(|p| r <= p[1].0)
        .map_or(0.0, |p| {
            let ((ra, fa), (rb, fb)) = (p[0], p[1]);
            let t = (r - ra) / (rb - ra);
            (ra * fa * (1.0 - t) + rb * fb * t) / (r0 * f0)
        })
}

/// The surface at `r >= a` \[arbitrary unit] under Hertz's pressure `sqrt(1 - s^2/a^2)` on the
/// contact disc of radius `a`, through the gel's point response `layer_factor(d) / d`: the
/// half-space's closed form `(pi a / 2) [(2 - rho^2) asin(1/rho) + sqrt(rho^2 - 1)]` (the
/// integral with `1/d`, Johnson 3.42a) less the integral of the pressure times
/// `(1 - layer_factor(d)) / d`, which is 0 near the load, so a midpoint rule over the disc
/// (48 radii x 96 angles, the half disc twice) takes it without the `1/d` singularity.
fn fem_surface(a: f64, r: f64) -> f64 {
    const NS: usize = 48;
    const NT: usize = 96;
    if a <= 0.0 {
        return 0.0;
    }
    let rho = (r / a).max(1.0);
    let half = std::f64::consts::PI * a / 2.0
        * ((2.0 - rho * rho) * (1.0 / rho).asin() + (rho * rho - 1.0).sqrt());
    let (ds, dt) = (a / NS as f64, std::f64::consts::PI / NT as f64);
    let mut lost = 0.0;
    for i in 0..NS {
        let s = (i as f64 + 0.5) * ds;
        let p = (1.0 - (s / a) * (s / a)).max(0.0).sqrt();
        for j in 0..NT {
            let t = (j as f64 + 0.5) * dt;
            let d = (r - s * t.cos()).hypot(s * t.sin());
            if d > FEM_POINT_RESPONSE[0].0 {
                lost += p * (1.0 - layer_factor(d)) / d * s;
            }
        }
    }
    (half - 2.0 * lost * ds * dt).max(0.0)
}

/// How press frames are degraded beyond the mock's own noise (`crate::degrade`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressNoise {
    /// Camera noise sigma per channel \[DN] (the background gets its own draw).
    pub noise_dn: f64,
    /// Largest sum over channels of a smooth shading field on the press frame \[DN].
    pub shading_dn: f64,
    pub seed: u64,
}

/// A rendered press: frame, the press, and its exact depth map \[mm].
#[derive(Debug, Clone)]
pub struct RenderedPress {
    pub frame: Frame,
    pub press: BallPress,
    pub depth_mm: Vec<f32>,
}

/// Background and presses of a mock sensor of `spec`, degraded by `noise` (each press its own
/// noise and shading draw). None when the spec is not a valid frame size.
pub fn render_presses(
    cfg: &MockConfig,
    spec: SensorSpec,
    presses: &[BallPress],
    noise: PressNoise,
) -> Option<(Frame, Vec<RenderedPress>)> {
    render_presses_with(cfg, spec, presses, noise, Skirt::default())
}

/// [`render_presses`] on a gel with the given skirt.
pub fn render_presses_with(
    cfg: &MockConfig,
    spec: SensorSpec,
    presses: &[BallPress],
    noise: PressNoise,
    skirt: Skirt,
) -> Option<(Frame, Vec<RenderedPress>)> {
    let mut clean = cfg.clone();
    clean.noise_dn = 0.0;
    clean.drift = crate::Drift::default();
    let s = MockSensor::with_spec(clean, spec, Scenario::idle(1.0)).ok()?;
    let (w, h) = (spec.width, spec.height);
    let flat = vec![0f32; (w as usize) * (h as usize)];
    let bg_clean = s.render_height(0, &flat)?;
    let base: Vec<f32> = bg_clean.data().iter().map(|&v| f32::from(v)).collect();
    let background = noisy(&bg_clean, &base, None, noise.noise_dn, noise.seed ^ 0xBEEF).ok()?;
    let mut out = Vec::with_capacity(presses.len());
    for (k, p) in presses.iter().enumerate() {
        let depth = p.depth_map_with(w, h, spec.mm_per_px, skirt);
        let f = s.render_height(k as u64 + 1, &depth)?;
        let clean: Vec<f32> = f.data().iter().map(|&v| f32::from(v)).collect();
        let seed = noise.seed ^ (k as u64 + 1).wrapping_mul(0x2545_F491_4F6C_DD1D);
        let field = shading_field(w, h, noise.shading_dn, seed);
        let frame = noisy(&f, &clean, Some(&field), noise.noise_dn, seed ^ 0xF00D).ok()?;
        out.push(RenderedPress {
            frame,
            press: *p,
            depth_mm: depth,
        });
    }
    Some((background, out))
}

/// `n` calibration presses of a ball of `radius_mm` at random places (the contact disc and a
/// margin of half its radius inside the frame) and approaches in `approach_mm` (min, max), drawn
/// from `seed`.
pub fn random_presses(
    spec: SensorSpec,
    n: usize,
    radius_mm: f64,
    approach_mm: (f64, f64),
    seed: u64,
) -> Vec<BallPress> {
    let mut rng = SplitMix64::new(seed ^ 0xBA11);
    let (w, h) = (f64::from(spec.width), f64::from(spec.height));
    (0..n)
        .map(|_| {
            let d = approach_mm.0 + (approach_mm.1 - approach_mm.0) * rng.uniform();
            let p = BallPress {
                center_px: [0.0, 0.0],
                radius_mm,
                approach_mm: d,
            };
            let a = p.contact_radius_mm() / spec.mm_per_px * 1.5 + 2.0;
            let (sx, sy) = ((w - 2.0 * a).max(0.0), (h - 2.0 * a).max(0.0));
            BallPress {
                center_px: [a + sx * rng.uniform(), a + sy * rng.uniform()],
                ..p
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::SensorKind;

    /// Radius \[mm] out to which the ball touches the gel surface of `skirt`: the outermost `r`
    /// where the ball reaches at least as deep as the surface (the rendered surface's contact).
    fn touch_radius_mm(p: &BallPress, skirt: Skirt) -> f64 {
        let (a, g) = (p.contact_radius_mm(), p.geometric_radius_mm());
        const STEPS: usize = 2_000;
        (0..=STEPS)
            .map(|k| a + (g - a) * k as f64 / STEPS as f64)
            .filter(|&r| p.sphere_depth(r) >= p.depth_at_with(r, skirt) - 1e-12)
            .fold(a, f64::max)
    }

    #[test]
    fn a_layer_skirt_fades_from_the_edge_and_the_half_space_keeps_its_one_over_r_tail() {
        let p = BallPress {
            center_px: [0.0, 0.0],
            radius_mm: 2.0,
            approach_mm: 0.5,
        };
        let a = p.contact_radius_mm();
        let edge = p.depth_at_with(a, Skirt::HalfSpace);
        for t in [0.5, 1.0, 2.0, 4.0] {
            let layer = Skirt::Layer { thickness_mm: t };
            // The same at the edge (the fade is 1 there), below the half-space outside, and at
            // rest within a few thicknesses.
            assert!((p.depth_at_with(a, layer) - edge).abs() < 1e-12);
            let (half, lay) = (
                p.depth_at_with(a + t, Skirt::HalfSpace),
                p.depth_at_with(a + t, layer),
            );
            assert!(
                (lay / half - (-1f64).exp()).abs() < 1e-9,
                "{t}: {lay} {half}"
            );
            assert!(p.depth_at_with(a + 3.0 * t, layer) < 1e-3 * edge);
        }
        // The half-space's tail: (2 d_e / pi) (4/3) a / r far out (d_e: the depth at the edge).
        let r = 200.0 * a;
        let tail = 2.0 * edge / std::f64::consts::PI * 4.0 / 3.0 * a / r;
        let far = p.depth_at_with(r, Skirt::HalfSpace);
        assert!((far / tail - 1.0).abs() < 1e-3, "{far} vs {tail}");
        // The ball leaves every skirt of the sweep (a layer of 0.5 mm or more, the half-space) at
        // the Hertz radius: outside it the surface lies below the ball, so the Hertz disc is the
        // rendered surface's contact whatever the skirt.
        for approach in [0.05, 0.2, 0.6, 1.0] {
            let p = BallPress {
                approach_mm: approach,
                ..p
            };
            let a = p.contact_radius_mm();
            for skirt in [0.5, 1.0, 2.0, 4.0]
                .map(|t| Skirt::Layer { thickness_mm: t })
                .into_iter()
                .chain([Skirt::HalfSpace, Skirt::Fem])
            {
                let t = touch_radius_mm(&p, skirt);
                // The finite-element skirt is not solved for contact (the pressure stays
                // Hertz's): just outside the edge it lies a hair above the ball, which touches
                // it up to 2 % further out.
                let tol = if skirt == Skirt::Fem { 0.02 } else { 1e-3 };
                assert!((t - a).abs() < tol * a, "{approach} {skirt}: {t} vs {a}");
            }
        }
        // A fade much thinner than the contact would lift the surface through the ball: there
        // the ball touches further out (such a skirt is not one the sweep renders).
        let deep = BallPress {
            approach_mm: 0.6,
            ..p
        };
        let thin = touch_radius_mm(&deep, Skirt::Layer { thickness_mm: 0.25 });
        assert!(thin > 1.1 * deep.contact_radius_mm(), "{thin}");
        assert!(thin <= deep.geometric_radius_mm());
        // The default is the finite-element skirt.
        assert_eq!(p.depth_at(1.7 * a), p.depth_at_with(1.7 * a, Skirt::Fem));
        assert_eq!(Skirt::default(), Skirt::Fem);
    }

    /// Where the surface of `skirt` (falling outside the contact) comes up to `share` of the
    /// approach \[mm], by bisection to 1 um.
    fn radius_at_share(p: &BallPress, skirt: Skirt, share: f64) -> f64 {
        let (mut lo, mut hi) = (p.contact_radius_mm(), 100.0);
        while hi - lo > 1e-3 {
            let mid = 0.5 * (lo + hi);
            if p.depth_at_with(mid, skirt) < share * p.approach_mm {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        hi
    }

    #[test]
    fn the_finite_element_skirt_falls_faster_than_the_half_space_and_near_a_2_mm_layer() {
        for approach in [0.2, 0.5, 1.0] {
            let p = BallPress {
                center_px: [0.0, 0.0],
                radius_mm: 2.0,
                approach_mm: approach,
            };
            let a = p.contact_radius_mm();
            // The finite-element skirt starts at the ball's depth at the edge, falls faster than
            // the half-space's, and is at rest where the point response is (5 mm out): there the
            // closed form and the integral that takes the response off it agree.
            let edge = p.sphere_depth(a);
            assert!((p.depth_at_with(a, Skirt::Fem) - edge).abs() < 1e-12);
            for dr in [0.25, 0.5, 1.0, 2.0] {
                let (fem, half) = (
                    p.depth_at_with(a + dr, Skirt::Fem),
                    p.depth_at_with(a + dr, Skirt::HalfSpace),
                );
                assert!(0.0 < fem && fem < half, "{approach} {dr}: {fem} {half}");
            }
            assert!(p.depth_at_with(a + 5.5, Skirt::Fem) < 1e-3 * edge);
            // A 2 mm fade's 10 % radius within 12 % of the finite elements' (it reads 9-11 %
            // further out: the fade keeps Hertz's shape near the edge, where the finite elements
            // fall faster) and its 3 % radius within 5 %; the half-space's 1.5 and 3 times
            // further out.
            let layer = Skirt::Layer { thickness_mm: 2.0 };
            let fem10 = radius_at_share(&p, Skirt::Fem, 0.1);
            let fem3 = radius_at_share(&p, Skirt::Fem, 0.03);
            let ours10 = radius_at_share(&p, layer, 0.1);
            let ours3 = radius_at_share(&p, layer, 0.03);
            let half10 = radius_at_share(&p, Skirt::HalfSpace, 0.1);
            let half3 = radius_at_share(&p, Skirt::HalfSpace, 0.03);
            assert!((ours10 / fem10 - 1.0).abs() < 0.12, "{ours10} {fem10}");
            assert!((ours3 / fem3 - 1.0).abs() < 0.05, "{ours3} {fem3}");
            assert!(
                half10 > 1.5 * fem10 && half3 > 3.0 * fem3,
                "{half10} {half3}"
            );
            // The frame's table is the profile.
            let mm = 0.05;
            let map = p.depth_map_with(200, 1, mm, Skirt::Fem);
            for x in [10usize, 33, 57, 120] {
                let r = x as f64 * mm;
                let exact = p.depth_at_with(r, Skirt::Fem);
                assert!(
                    (f64::from(map[x]) - exact).abs() < 1e-5,
                    "{x}: {} {exact}",
                    map[x]
                );
            }
        }
    }

    #[test]
    fn hertz_profile_is_continuous_with_the_ball_and_half_deep_at_the_edge() {
        let p = BallPress {
            center_px: [0.0, 0.0],
            radius_mm: 4.0,
            approach_mm: 0.5,
        };
        // Hertz's profile outside the contact, faded over a 2 mm layer.
        let depth = |r: f64| p.depth_at_with(r, Skirt::Layer { thickness_mm: 2.0 });
        let a = p.contact_radius_mm();
        assert!((a - 2f64.sqrt()).abs() < 1e-12);
        assert!(p.geometric_radius_mm() > a);
        let inside = depth(a - 1e-9);
        let outside = depth(a + 1e-9);
        // Half the approach at the edge (Hertz's paraboloid), less the sphere's few %.
        assert!((outside - 0.25).abs() < 0.02 * 0.5, "{outside}");
        assert!((inside - outside).abs() < 1e-6, "{inside} {outside}");
        assert_eq!(depth(0.0), 0.5);
        // Slopes meet at the edge (a/R for the paraboloid Hertz assumes).
        let e = 1e-4;
        let s_out = (depth(a + 2.0 * e) - depth(a + e)) / e;
        assert!((s_out + a / 4.0).abs() < 0.04, "{s_out}");
        // The tail decays, never below zero, and is gone a few gel thicknesses out.
        assert!(depth(2.0 * a) > 0.0 && depth(2.0 * a) < 0.25);
        assert!(depth(a + 6.0) < 1e-4);
    }

    #[test]
    fn a_rendered_press_differs_from_the_background_only_around_it() {
        let spec = SensorKind::GELSIGHT_MINI.spec();
        let mut cfg = MockConfig::new(SensorKind::GELSIGHT_MINI, 3);
        cfg.markers = false;
        let p = BallPress {
            center_px: [100.0, 120.0],
            radius_mm: 3.0,
            approach_mm: 0.6,
        };
        let noise = PressNoise {
            noise_dn: 0.0,
            shading_dn: 0.0,
            seed: 1,
        };
        let (bg, presses) = render_presses(&cfg, spec, &[p], noise).unwrap();
        let f = &presses[0].frame;
        let diff = |x: u32, y: u32| -> i32 {
            let (a, b) = (bg.pixel(x, y).unwrap(), f.pixel(x, y).unwrap());
            (0..3)
                .map(|c| (i32::from(a[c]) - i32::from(b[c])).abs())
                .sum()
        };
        let a_px = p.contact_radius_mm() / spec.mm_per_px;
        assert!(diff(100 + (a_px * 0.8) as u32, 120) > 40);
        assert!(diff(310, 10) <= 3);
        assert_eq!(presses[0].depth_mm.len(), 320 * 240);
    }
}
