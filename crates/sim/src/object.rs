//! Things pressed into the gel: fabrics (roughness, texture bumps, hardness), cups, indenters.
//!
//! An object is described by the gap between its surface and the plane of its lowest point,
//! `g(x, y) >= 0` [mm], plus a surface texture. The renderer presses it `depth` mm into the gel:
//! the gel is indented where `depth - g > 0`.
//!
//! Hardness: the object and the gel are two springs in series. With `hardness` h in (0, 1] the gel
//! takes the share h of the approach (1 = rigid, the model before hardness existed) and the soft
//! object's surface flattens around the contact, which this model renders as radii of curvature
//! divided by h: a soft fabric indents the gel less for the same approach and spreads the contact
//! over the area a rigid one of the same approach would cover (a^2 = 2 R d is kept).
//!
//! Units: the gel-side geometry here and in the renderer is in millimetres of gel, the mock
//! sensor's own scale (its image is `px_per_mm` pixels per millimetre). Everything else in the
//! workspace is SI; world quantities enter through [`MM_PER_M`] where a task hands an object to
//! the renderer.

/// Indenter shape. `Object::radius_mm` is the sphere's radius, the flat punch's radius, or the
/// edge's radius of curvature.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Shape {
    /// Spherical cap (fingertip, fabric over a rounded probe, a cup wall on a domed gel).
    #[default]
    Sphere,
    /// Flat circular punch with a rounded rim (fillet radius `FLAT_FILLET` x radius).
    Flat,
    /// A straight edge along the image's y axis (a cylinder of radius `radius_mm`).
    Edge,
}

impl Shape {
    pub fn as_str(self) -> &'static str {
        match self {
            Shape::Sphere => "sphere",
            Shape::Flat => "flat",
            Shape::Edge => "edge",
        }
    }
}

/// Millimetres of gel per metre: the one conversion between the world's SI quantities and the
/// renderer's gel geometry.
pub const MM_PER_M: f64 = 1e3;

/// Fillet of a flat punch's rim, as a share of its radius.
pub const FLAT_FILLET: f64 = 0.15;
/// Height of a texture bump as a share of its radius.
pub const BUMP_ASPECT: f64 = 0.35;

/// The folded edge of a fabric stack as the gel sees it: where the fold's top crosses the gel,
/// how thick a layer is and how many layers lie between the fold's top and the contact centre.
///
/// The gel (sensor plane: x along the fold, y down = world down) is pressed on the pinched
/// stack. Fabric lies only below the fold's top, so a press is cut off at the image row
/// `edge_mm` above the contact centre: material above it is absent, and the contact there is
/// the gel at rest. The top layer's fold is rounded: over the rim the fabric bends away from
/// the gel as a half-cylinder of radius half a layer (a fabric bent through 180 degrees around
/// itself, its bend radius taken as half its thickness: a modelling choice), so a light press
/// feels the fold's top a little below where it is. Below it the layers' boundaries (every
/// `layer_mm` down from the top) show as shallow grooves where one layer's rounded edge meets
/// the next (depth a tenth of a layer, at most 0.1 mm; a modelling choice, drawn so the layer
/// count is in the image). Robotic cloth work reads the same cues from touch: a GelSight finds
/// a cloth's edge in its image (N. Sunil et al., "Visuotactile Affordances for Cloth
/// Manipulation with Local Control", CoRL 2022) and a fingertip's signal tells how many layers
/// a pinch caught (S. Tirumala et al., "Learning to Singulate Layers of Cloth using Tactile
/// Feedback", IROS 2022).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FoldEdge {
    /// Height of the fold's top above the contact centre \[mm] (negative: below it).
    pub edge_mm: f64,
    /// Thickness of one layer \[mm] (positive).
    pub layer_mm: f64,
}

/// Depth of the groove between two layers, as a share of a layer and at most
/// [`GROOVE_MAX_MM`].
pub const GROOVE_SHARE: f64 = 0.1;
/// Deepest groove between layers \[mm].
pub const GROOVE_MAX_MM: f64 = 0.1;

impl FoldEdge {
    /// Radius of the rounded rim at the fold's top \[mm].
    pub fn rim_mm(&self) -> f64 {
        0.5 * self.layer_mm.max(0.0)
    }

    /// Extra gap between the fabric and the plane of its lowest point \[mm] at `u` mm below the
    /// fold's top, with its derivative in `u`; None above the top (no fabric there).
    pub fn gap(&self, u: f64) -> Option<(f64, f64)> {
        if u.is_nan() || u < 0.0 {
            return None;
        }
        let rf = self.rim_mm();
        let mut g = 0.0;
        let mut dg = 0.0;
        if u < rf {
            // Half-cylinder: g = rf - sqrt(rf^2 - (rf - u)^2), steepest at the top; the slope is
            // capped where the surface turns away from the gel.
            let w = rf - u;
            let root = (rf * rf - w * w).max(0.0).sqrt();
            g += rf - root;
            dg += if root > 0.0 {
                (-w / root).max(-RIM_MAX_SLOPE)
            } else {
                -RIM_MAX_SLOPE
            };
        }
        let t = self.layer_mm;
        if t > 0.0 && u >= 0.5 * t {
            // The nearest boundary between layers below the top, k t (k >= 1).
            let k = (u / t).round().max(1.0);
            let s = (u - k * t) / (GROOVE_WIDTH_SHARE * t);
            if s.abs() < 1.0 {
                let depth = (GROOVE_SHARE * t).min(GROOVE_MAX_MM);
                let q = 1.0 - s * s;
                g += depth * q * q;
                dg += depth * 2.0 * q * (-2.0 * s) / (GROOVE_WIDTH_SHARE * t);
            }
        }
        Some((g, dg))
    }
}

/// Steepest slope of the rounded rim that is drawn (the surface turning away from the gel).
const RIM_MAX_SLOPE: f64 = 4.0;
/// Half-width of a groove between layers, as a share of a layer.
const GROOVE_WIDTH_SHARE: f64 = 0.2;

/// Something pressed into the gel.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    pub label: String,
    /// Indenter radius of curvature \[mm] (see [`Shape`]).
    pub radius_mm: f64,
    /// Surface texture amplitude \[mm] (rougher = larger).
    pub roughness_mm: f64,
    /// Texture period \[mm].
    pub period_mm: f64,
    pub shape: Shape,
    /// Share of the approach the gel takes, in (0, 1]: 1 = rigid, smaller = softer (see the
    /// module docs).
    pub hardness: f64,
    /// Radius of texture bumps (knots, pile, weave crossings) \[mm]; 0 = none.
    pub bump_mm: f64,
    /// Bumps per mm^2 (on a jittered grid; at most one bump per cell).
    pub bump_density: f64,
    /// A fabric's folded edge crossing the gel (None: the object covers the whole press).
    pub fold: Option<FoldEdge>,
}

impl Object {
    /// A rigid sphere with a sinusoidal texture and no bumps: the object model of the first mock.
    pub fn new(label: &str, radius_mm: f64, roughness_mm: f64, period_mm: f64) -> Self {
        Self {
            label: label.into(),
            radius_mm,
            roughness_mm,
            period_mm,
            shape: Shape::Sphere,
            hardness: 1.0,
            bump_mm: 0.0,
            bump_density: 0.0,
            fold: None,
        }
    }
    /// Smooth rigid indenters.
    pub fn sphere(label: &str, radius_mm: f64) -> Self {
        Self::new(label, radius_mm, 0.0, 1.0)
    }
    pub fn flat(label: &str, radius_mm: f64) -> Self {
        Self::new(label, radius_mm, 0.0, 1.0).with_shape(Shape::Flat)
    }
    pub fn edge(label: &str, radius_mm: f64) -> Self {
        Self::new(label, radius_mm, 0.0, 1.0).with_shape(Shape::Edge)
    }
    pub fn with_shape(mut self, shape: Shape) -> Self {
        self.shape = shape;
        self
    }
    /// Hardness in (0, 1]; values outside are clamped to [0.05, 1].
    pub fn with_hardness(mut self, hardness: f64) -> Self {
        self.hardness = clamp_hardness(hardness);
        self
    }
    /// Texture bumps of this radius \[mm] and density [1/mm^2].
    pub fn with_bumps(mut self, radius_mm: f64, per_mm2: f64) -> Self {
        self.bump_mm = radius_mm.max(0.0);
        self.bump_density = per_mm2.max(0.0);
        self
    }

    /// The press cut off at a fabric's folded edge (see [`FoldEdge`]).
    pub fn with_fold(mut self, fold: FoldEdge) -> Self {
        self.fold = Some(fold);
        self
    }

    /// Gel penetration \[mm] for an approach of `depth` mm (the soft object takes the rest).
    pub fn gel_depth(&self, depth: f64) -> f64 {
        depth * clamp_hardness(self.hardness)
    }
    /// Radius of curvature the gel sees \[mm] (softer objects flatten: R / h).
    pub fn effective_radius_mm(&self) -> f64 {
        self.radius_mm / clamp_hardness(self.hardness)
    }

    pub fn texture_height(&self, x_mm: f64, y_mm: f64) -> f64 {
        let k = std::f64::consts::TAU / self.period_mm;
        let wave = self.roughness_mm * (k * x_mm).sin() * (k * y_mm * 0.8 + 0.5).cos();
        wave + self.bump(x_mm, y_mm).0
    }

    /// Height and gradient of the bump field at (x, y) \[mm]: one dome (1 - d^2/r^2)^2 per grid
    /// cell of side 1/sqrt(density), placed at a hashed offset that keeps it inside its cell.
    pub fn bump(&self, x_mm: f64, y_mm: f64) -> (f64, f64, f64) {
        let r = self.bump_mm;
        if r <= 0.0 || self.bump_density <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let cell = self.bump_density.recip().sqrt().max(2.0 * r);
        let (ci, cj) = ((x_mm / cell).floor(), (y_mm / cell).floor());
        let h = hash2(ci as i64, cj as i64);
        let room = 0.5 - r / cell; // how far the centre may move from the cell centre (cells)
        let jx = ((h & 0xFFFF) as f64 / 65_535.0 - 0.5) * 2.0 * room;
        let jy = (((h >> 16) & 0xFFFF) as f64 / 65_535.0 - 0.5) * 2.0 * room;
        let (bx, by) = ((ci + 0.5 + jx) * cell, (cj + 0.5 + jy) * cell);
        let (dx, dy) = (x_mm - bx, y_mm - by);
        let q = (dx * dx + dy * dy) / (r * r);
        if q >= 1.0 {
            return (0.0, 0.0, 0.0);
        }
        let amp = BUMP_ASPECT * r;
        let s = 1.0 - q;
        // d/dx (1 - q)^2 = -2 (1 - q) * 2 dx / r^2
        let g = -4.0 * amp * s / (r * r);
        (amp * s * s, g * dx, g * dy)
    }

    /// Gap g(x, y) between the object's surface and its lowest point \[mm] at offset (dx, dy)
    /// \[mm] from the contact centre, with its gradient, as the gel sees it (hardness applied).
    /// Returns (g, dg/dx, dg/dy).
    pub fn gap(&self, dx: f64, dy: f64) -> (f64, f64, f64) {
        let r = self.effective_radius_mm();
        match self.shape {
            Shape::Sphere => (0.5 * (dx * dx + dy * dy) / r, dx / r, dy / r),
            Shape::Edge => (0.5 * dx * dx / r, dx / r, 0.0),
            Shape::Flat => {
                let rho = (dx * dx + dy * dy).sqrt();
                let f = FLAT_FILLET * r;
                let e = rho - self.radius_mm;
                if e <= 0.0 || rho <= 0.0 {
                    (0.0, 0.0, 0.0)
                } else {
                    let s = e / f / rho;
                    (0.5 * e * e / f, s * dx, s * dy)
                }
            }
        }
    }

    /// Half-width of the contact \[mm] at gel depth `d` (radius for sphere and flat punch,
    /// half-width of the band for an edge).
    pub fn contact_half_width_mm(&self, d: f64) -> f64 {
        if d <= 0.0 {
            return 0.0;
        }
        let r = self.effective_radius_mm();
        match self.shape {
            Shape::Sphere | Shape::Edge => (2.0 * d * r).sqrt(),
            Shape::Flat => self.radius_mm + (2.0 * d * FLAT_FILLET * r).sqrt(),
        }
    }
}

fn clamp_hardness(h: f64) -> f64 {
    if h.is_finite() {
        h.clamp(0.05, 1.0)
    } else {
        1.0
    }
}

/// Stable hash of a grid cell (SplitMix64 finaliser).
fn hash2(i: i64, j: i64) -> u64 {
    let mut z = (i as u64)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bump_gradient_matches_finite_differences() {
        let o = Object::new("f", 6.0, 0.02, 0.8).with_bumps(0.3, 1.5);
        let e = 1e-6;
        let mut seen = 0;
        for k in 0..400 {
            let (x, y) = (k as f64 * 0.037, k as f64 * 0.021 + 0.1);
            let (h, gx, gy) = o.bump(x, y);
            if h > 0.0 {
                seen += 1;
            }
            let nx = (o.bump(x + e, y).0 - o.bump(x - e, y).0) / (2.0 * e);
            let ny = (o.bump(x, y + e).0 - o.bump(x, y - e).0) / (2.0 * e);
            assert!((nx - gx).abs() < 1e-4 && (ny - gy).abs() < 1e-4, "{x} {y}");
        }
        assert!(seen > 10, "bumps are present: {seen}");
    }

    #[test]
    fn softer_objects_indent_less_and_spread() {
        let hard = Object::sphere("a", 6.0);
        let soft = Object::sphere("b", 6.0).with_hardness(0.5);
        assert_eq!(hard.gel_depth(0.6), 0.6);
        assert!((soft.gel_depth(0.6) - 0.3).abs() < 1e-12);
        // Contact radius at the gel depth each produces from the same approach: equal, whereas a
        // rigid sphere at the soft one's gel depth would touch a smaller area.
        let a_soft = soft.contact_half_width_mm(soft.gel_depth(0.6));
        let a_hard = hard.contact_half_width_mm(hard.gel_depth(0.6));
        assert!((a_soft - a_hard).abs() < 1e-9);
        assert!(a_soft > hard.contact_half_width_mm(0.3) * 1.3);
    }

    #[test]
    fn shapes_have_their_gaps() {
        let f = Object::flat("p", 2.0);
        assert_eq!(f.gap(1.0, 1.0).0, 0.0);
        assert!(f.gap(2.5, 0.0).0 > 0.0);
        let e = Object::edge("e", 1.0);
        assert_eq!(e.gap(0.0, 5.0).0, 0.0);
        assert!((e.gap(1.0, 5.0).0 - 0.5).abs() < 1e-12);
        assert!((f.contact_half_width_mm(0.01) - 2.0).abs() < 0.1);
    }
}
