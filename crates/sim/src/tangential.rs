//! Tangential (in-plane) displacement of the gel under a pressed object that is pulled or
//! twisted: the marker motion a marker-based slip detector measures, and its ground truth.
//!
//! # The model
//! The object has moved by a translation `T` and a rotation `theta` (about the optical axis, at
//! the contact centre `c`) since it pressed in. Its displacement at a gel point `p` is
//! `u_obj(p) = T + (R(theta) - I)(p - c)`. The gel surface moves by `u_gel(p) = u_obj(p) w(r)`,
//! with `r` the distance from the contact centre (`|x - c_x|` for an edge) and the weight
//! - `w = 1` in the stuck disc `r <= rho a` (`a` the contact radius, `rho` = `stick_ratio`): the
//!   gel moves with the object;
//! - falling smoothly (smoothstep) from 1 to `w_edge = (1 + rho) / 2` across the slip annulus
//!   `rho a < r <= a`: slipping gel lags the object, more so the smaller the stuck part
//!   (Cattaneo-Mindlin partial slip, with the annulus profile simplified);
//! - outside the contact, `w_edge` decaying to 0 over [`DECAY_RADII`] contact radii with the
//!   smooth C1 profile `(1 - t)^2 (1 + 2 t)`: the gel is dragged by the contact's edge and is at
//!   rest from `(1 + DECAY_RADII) a` on.
//!
//! Gross slip (`stick_ratio = 0`, nothing stuck): the weight falls from 1 at the centre to 1/2 at
//! the edge (the shape of the full-sliding traction field, like Johnson's `1 - r^2 / 2a^2`), and
//! friction cannot hold more than `limit_m` of displacement: the object's motion is scaled down
//! so that the translation, and the rotation's displacement at the contact edge, stay within
//! `limit_m` while the object slides on. The limit applies in every regime (a world keeps the
//! stuck motion below it). The texture and shading of the press do not move (markers only); the
//! press's own outward drag of the markers is carried along with the gel.

/// Contact radii over which the displacement outside the contact decays to zero.
pub const DECAY_RADII: f64 = 2.0;
/// Default friction limit of the gel's displacement \[m] (elastic pre-slide of a soft gel).
pub const DEFAULT_LIMIT_M: f64 = 0.5e-3;

/// A render input: how the pressed object moved across the gel since it touched. SI units, in
/// the sensor's optical frame (x right, y down in the image; rotation about z, from x towards y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tangential {
    /// Object translation in the gel plane \[m].
    pub shift_m: [f64; 2],
    /// Object rotation about the contact centre \[rad].
    pub rotation_rad: f64,
    /// Radius of the stuck region over the contact radius, 0..=1: 1 full stick, 0 gross slip.
    pub stick_ratio: f64,
    /// Largest displacement friction lets the gel follow \[m].
    pub limit_m: f64,
}

impl Default for Tangential {
    fn default() -> Self {
        Self {
            shift_m: [0.0; 2],
            rotation_rad: 0.0,
            stick_ratio: 1.0,
            limit_m: DEFAULT_LIMIT_M,
        }
    }
}

impl Tangential {
    /// The object moved by `shift_m` and `rotation_rad` with `stick_ratio` of the contact stuck
    /// (friction limit [`DEFAULT_LIMIT_M`]).
    pub fn new(shift_m: [f64; 2], rotation_rad: f64, stick_ratio: f64) -> Self {
        Self {
            shift_m,
            rotation_rad,
            stick_ratio,
            ..Self::default()
        }
    }
    /// True when the object did not move (the frame is the plain press).
    pub fn is_zero(&self) -> bool {
        self.shift_m == [0.0; 2] && self.rotation_rad == 0.0
    }
}

/// One marker dot: where it is at rest and where the tangential displacement took it, in output
/// pixels (the centre of the dot, before the radial drag of the press itself).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerTruth {
    pub rest_px: [f64; 2],
    pub moved_px: [f64; 2],
}

/// The displacement field of one press in pixels (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Field {
    cx: f64,
    cy: f64,
    edge: bool,
    a: f64,
    stick: f64,
    w_edge: f64,
    /// Zero displacement from this distance on [px].
    pub reach: f64,
    /// Largest displacement anywhere [px] (bounds how far a dot can be dragged).
    pub max_px: f64,
    t: [f64; 2],
    sin: f64,
    cos_m1: f64,
}

impl Field {
    /// The field of `tan` on a contact of radius `a_px` centred at (cx, cy); None when nothing
    /// moves (no contact, no motion, or non-finite input).
    pub fn new(
        tan: &Tangential,
        a_px: f64,
        (cx, cy): (f64, f64),
        edge: bool,
        mm_per_px: f64,
    ) -> Option<Self> {
        let finite = tan.shift_m.iter().all(|v| v.is_finite())
            && tan.rotation_rad.is_finite()
            && tan.stick_ratio.is_finite()
            && tan.limit_m.is_finite();
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if tan.is_zero() || !finite || !positive(a_px) || !positive(mm_per_px) {
            return None;
        }
        let px_per_m = 1e3 / mm_per_px;
        let limit = tan.limit_m.max(0.0) * px_per_m;
        let mut t = [tan.shift_m[0] * px_per_m, tan.shift_m[1] * px_per_m];
        let tn = t[0].hypot(t[1]);
        if tn > limit {
            let s = limit / tn;
            t = [t[0] * s, t[1] * s];
        }
        // Rotation: its displacement at the contact edge, |2 sin(theta / 2)| a, within the limit.
        let mut theta = tan
            .rotation_rad
            .clamp(-std::f64::consts::PI, std::f64::consts::PI);
        let edge_disp = 2.0 * (theta * 0.5).sin().abs() * a_px;
        if edge_disp > limit {
            let s = (limit / (2.0 * a_px)).clamp(0.0, 1.0);
            theta = theta.signum() * 2.0 * s.asin();
        }
        let rho = tan.stick_ratio.clamp(0.0, 1.0);
        let reach = a_px * (1.0 + DECAY_RADII);
        let (sin, cos) = theta.sin_cos();
        let rot_max = 2.0 * (theta * 0.5).sin().abs() * reach;
        Some(Self {
            cx,
            cy,
            edge,
            a: a_px,
            stick: rho * a_px,
            w_edge: 0.5 * (1.0 + rho),
            reach,
            max_px: t[0].hypot(t[1]) + rot_max,
            t,
            sin,
            cos_m1: cos - 1.0,
        })
    }

    /// The weight w(r) of the module docs.
    fn weight(&self, r: f64) -> f64 {
        if r <= self.stick {
            1.0
        } else if r <= self.a {
            let u = (r - self.stick) / (self.a - self.stick);
            1.0 - (1.0 - self.w_edge) * u * u * (3.0 - 2.0 * u)
        } else if r < self.reach {
            let u = (r - self.a) / (self.reach - self.a);
            self.w_edge * (1.0 - u) * (1.0 - u) * (1.0 + 2.0 * u)
        } else {
            0.0
        }
    }

    /// Displacement of the gel point at rest at (x, y) [px].
    pub fn at(&self, x: f64, y: f64) -> [f64; 2] {
        let (dx, dy) = (x - self.cx, y - self.cy);
        let r = if self.edge { dx.abs() } else { dx.hypot(dy) };
        let w = self.weight(r);
        if w == 0.0 {
            return [0.0; 2];
        }
        let ux = self.t[0] + self.cos_m1 * dx - self.sin * dy;
        let uy = self.t[1] + self.sin * dx + self.cos_m1 * dy;
        [ux * w, uy * w]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(tan: Tangential) -> Field {
        Field::new(&tan, 30.0, (160.0, 120.0), false, 0.0634).unwrap()
    }

    #[test]
    fn the_stuck_disc_moves_rigidly_with_the_object() {
        let t = Tangential::new([0.2e-3, -0.1e-3], 0.02, 0.6);
        let f = field(t);
        let (tx, ty) = (0.2 / 0.0634, -0.1 / 0.0634);
        for (x, y) in [(160.0, 120.0), (170.0, 125.0), (150.0, 110.0)] {
            let d = f.at(x, y);
            let (dx, dy) = (x - 160.0, y - 120.0);
            let (s, c) = 0.02f64.sin_cos();
            let want = [tx + (c - 1.0) * dx - s * dy, ty + s * dx + (c - 1.0) * dy];
            assert!((d[0] - want[0]).abs() < 1e-12 && (d[1] - want[1]).abs() < 1e-12);
        }
    }

    #[test]
    fn slipping_gel_lags_and_the_far_gel_is_at_rest() {
        let f = field(Tangential::new([0.3e-3, 0.0], 0.0, 0.3));
        let centre = f.at(160.0, 120.0)[0];
        let edge = f.at(190.0, 120.0)[0];
        assert!((edge / centre - 0.65).abs() < 1e-12, "{edge} {centre}");
        let out = f.at(160.0 + 45.0, 120.0)[0];
        assert!(out > 0.0 && out < edge);
        assert_eq!(f.at(160.0 + 90.0, 120.0), [0.0, 0.0]);
        assert_eq!(f.at(160.0, 120.0 + 95.0), [0.0, 0.0]);
    }

    #[test]
    fn gross_slip_holds_the_gel_at_the_friction_limit() {
        let limit_px = DEFAULT_LIMIT_M * 1e3 / 0.0634;
        let f = field(Tangential::new([3e-3, 0.0], 0.0, 0.0));
        assert!((f.at(160.0, 120.0)[0] - limit_px).abs() < 1e-9);
        let g = field(Tangential::new([30e-3, 0.0], 0.0, 0.0));
        for (x, y) in [(160.0, 120.0), (185.0, 110.0), (210.0, 140.0)] {
            let (a, b) = (f.at(x, y), g.at(x, y));
            // The object slid on, the gel did not follow.
            assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
        }
        // A big twist: the edge moves by the limit at most.
        let r = field(Tangential::new([0.0; 2], 1.0, 0.0));
        let e = r.at(190.0, 120.0);
        assert!((e[0].hypot(e[1]) - 0.5 * limit_px).abs() < 1e-9, "{e:?}");
    }

    #[test]
    fn no_motion_or_no_contact_or_nan_is_no_field() {
        let tan = Tangential::default();
        assert!(Field::new(&tan, 30.0, (0.0, 0.0), false, 0.06).is_none());
        let t = Tangential::new([1e-4, 0.0], 0.0, 1.0);
        assert!(Field::new(&t, 0.0, (0.0, 0.0), false, 0.06).is_none());
        let n = Tangential::new([f64::NAN, 0.0], 0.0, 1.0);
        assert!(Field::new(&n, 30.0, (0.0, 0.0), false, 0.06).is_none());
    }
}
