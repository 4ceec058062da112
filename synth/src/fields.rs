//! The analytic scalar fields behind the synthetic datasets, kept public as ground truth for tests.
//!
//! Every [`Case`] is defined on the unit cube `[0,1]^3`; [`Placed`] maps a physical domain
//! (`origin`, `size`) onto it, so values stay the same and lengths scale with `size`.

use std::fmt;
use std::str::FromStr;

/// A smooth scalar field with a surface of interest at [`AnalyticField::default_iso`].
pub trait AnalyticField {
    /// The field's value at `p`.
    fn value(&self, p: [f64; 3]) -> f64;

    /// The field's gradient at `p`.
    fn gradient(&self, p: [f64; 3]) -> [f64; 3];

    /// The isovalue whose surface the dataset is refined around.
    fn default_iso(&self) -> f64;

    /// The exact distance from `p` to the isosurface `value == iso`, where it is known in closed form.
    fn distance_to_surface(&self, _p: [f64; 3], _iso: f64) -> Option<f64> {
        None
    }

    /// A lower bound on the distance from `p` to the isosurface `value == iso` (0 when nothing
    /// better is known), from a Lipschitz bound on the field or on a function of it.
    fn distance_lower_bound(&self, _p: [f64; 3], _iso: f64) -> f64 {
        0.0
    }

    /// The distance from `p` to the isosurface `value == iso`: exact where known, otherwise the
    /// first-order estimate `|f - iso| / |grad f|` (infinite where the gradient vanishes away from `iso`).
    fn distance_estimate(&self, p: [f64; 3], iso: f64) -> f64 {
        match self.distance_to_surface(p, iso) {
            Some(d) => d,
            None => first_order_distance(self, p, iso),
        }
    }
}

/// `|f - iso| / |grad f|` at `p`: zero on the surface, infinite where the gradient vanishes off it.
pub fn first_order_distance<F: AnalyticField + ?Sized>(field: &F, p: [f64; 3], iso: f64) -> f64 {
    let df = (field.value(p) - iso).abs();
    let g = norm(field.gradient(p));
    if df == 0.0 {
        0.0
    } else if g > 0.0 {
        df / g
    } else {
        f64::INFINITY
    }
}

/// The built-in synthetic cases, each on the unit cube.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Case {
    /// Two merging `1/r` blobs: `f = 1/|p-c1| + 1/|p-c2|`; at the default isovalue 10 the two
    /// spheres of radius ~0.13 join through a neck of radius ~0.13.
    Blobs,
    /// The signed distance to a sphere of radius [`SPHERE_RADIUS`] around [`SPHERE_CENTRE`]
    /// (negative inside); the default isovalue 0 is the sphere itself.
    Sphere,
    /// `f = sin(kx) sin(ky) sin(kz)` with two periods per axis; the default isovalue 0.3 gives
    /// 32 separate closed surfaces, one in each positive half-period cube.
    Ripple,
}

/// Centres of the two blobs of [`Case::Blobs`].
pub const BLOB_CENTRES: [[f64; 3]; 2] = [[0.36, 0.44, 0.47], [0.64, 0.56, 0.53]];
/// Isovalue of [`Case::Blobs`].
pub const BLOB_ISO: f64 = 10.0;
/// Distances below this are clamped when evaluating a blob, so the value stays finite at a centre.
pub const BLOB_MIN_RADIUS: f64 = 1e-6;
/// Centre of [`Case::Sphere`].
pub const SPHERE_CENTRE: [f64; 3] = [0.47, 0.52, 0.5];
/// Radius of [`Case::Sphere`].
pub const SPHERE_RADIUS: f64 = 0.31;
/// Angular wave number of [`Case::Ripple`]: two full periods across the unit cube.
pub const RIPPLE_K: f64 = 4.0 * std::f64::consts::PI;
/// Isovalue of [`Case::Ripple`].
pub const RIPPLE_ISO: f64 = 0.3;

impl Case {
    /// Every case, in the order the command line lists them.
    pub const ALL: [Case; 3] = [Case::Blobs, Case::Sphere, Case::Ripple];

    /// The case's name on the command line and as the field name in the file.
    pub fn name(self) -> &'static str {
        match self {
            Case::Blobs => "blobs",
            Case::Sphere => "sphere",
            Case::Ripple => "ripple",
        }
    }
}

impl fmt::Display for Case {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Case {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Case::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Case::ALL.iter().map(|c| c.name()).collect();
                format!(
                    "unknown synthetic case '{s}' (expected one of: {})",
                    names.join(", ")
                )
            })
    }
}

impl AnalyticField for Case {
    fn value(&self, p: [f64; 3]) -> f64 {
        match self {
            Case::Blobs => BLOB_CENTRES
                .iter()
                .map(|c| 1.0 / norm(sub(p, *c)).max(BLOB_MIN_RADIUS))
                .sum(),
            Case::Sphere => norm(sub(p, SPHERE_CENTRE)) - SPHERE_RADIUS,
            Case::Ripple => p.iter().map(|&x| (RIPPLE_K * x).sin()).product(),
        }
    }

    fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        match self {
            Case::Blobs => {
                let mut g = [0.0; 3];
                for c in BLOB_CENTRES {
                    let d = sub(p, c);
                    let r = norm(d).max(BLOB_MIN_RADIUS);
                    let s = -1.0 / (r * r * r);
                    for a in 0..3 {
                        g[a] += s * d[a];
                    }
                }
                g
            }
            Case::Sphere => {
                let d = sub(p, SPHERE_CENTRE);
                let r = norm(d);
                if r == 0.0 {
                    [0.0; 3]
                } else {
                    d.map(|x| x / r)
                }
            }
            Case::Ripple => {
                let s = p.map(|x| (RIPPLE_K * x).sin());
                let c = p.map(|x| (RIPPLE_K * x).cos());
                [
                    RIPPLE_K * c[0] * s[1] * s[2],
                    RIPPLE_K * s[0] * c[1] * s[2],
                    RIPPLE_K * s[0] * s[1] * c[2],
                ]
            }
        }
    }

    fn default_iso(&self) -> f64 {
        match self {
            Case::Blobs => BLOB_ISO,
            Case::Sphere => 0.0,
            Case::Ripple => RIPPLE_ISO,
        }
    }

    fn distance_to_surface(&self, p: [f64; 3], iso: f64) -> Option<f64> {
        match self {
            Case::Sphere if SPHERE_RADIUS + iso > 0.0 => Some((self.value(p) - iso).abs()),
            _ => None,
        }
    }

    /// The sphere is a distance field; for the blobs `1/f = r1 r2 / (r1 + r2)` has a gradient of
    /// length at most 1; the ripple's squared gradient over `k^2` is multilinear in the squared
    /// sines, so its maximum, 1, sits at a corner of `[0,1]^3`.
    fn distance_lower_bound(&self, p: [f64; 3], iso: f64) -> f64 {
        match self {
            Case::Sphere => (self.value(p) - iso).abs(),
            Case::Blobs if iso > 0.0 => (1.0 / self.value(p) - 1.0 / iso).abs(),
            Case::Blobs => 0.0,
            Case::Ripple => (self.value(p) - iso).abs() / RIPPLE_K,
        }
    }

    /// For the blobs, the first-order estimate of `1/f`, which is exact for one blob and stays
    /// well-behaved near the centres, where `f`'s own estimate collapses.
    fn distance_estimate(&self, p: [f64; 3], iso: f64) -> f64 {
        match self {
            Case::Blobs if iso > 0.0 => {
                let f = self.value(p);
                (1.0 / f - 1.0 / iso).abs() * f * f / norm(self.gradient(p))
            }
            _ => match self.distance_to_surface(p, iso) {
                Some(d) => d,
                None => first_order_distance(self, p, iso),
            },
        }
    }
}

/// A unit-cube field placed on the physical cube `[origin, origin + size]^3`.
///
/// `value(p)` is the inner field's value at `(p - origin) / size`; gradients and distances are
/// in physical units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placed<F> {
    /// The field on the unit cube.
    pub field: F,
    /// Physical position of the unit cube's corner `(0, 0, 0)`.
    pub origin: [f64; 3],
    /// Physical edge length of the unit cube.
    pub size: f64,
}

impl<F: AnalyticField> Placed<F> {
    /// Unit-cube coordinates of the physical point `p`.
    pub fn to_unit(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| (p[a] - self.origin[a]) / self.size)
    }

    /// Physical coordinates of the unit-cube point `u`.
    pub fn to_physical(&self, u: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.origin[a] + u[a] * self.size)
    }
}

impl<F: AnalyticField> AnalyticField for Placed<F> {
    fn value(&self, p: [f64; 3]) -> f64 {
        self.field.value(self.to_unit(p))
    }

    fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        self.field.gradient(self.to_unit(p)).map(|g| g / self.size)
    }

    fn default_iso(&self) -> f64 {
        self.field.default_iso()
    }

    fn distance_to_surface(&self, p: [f64; 3], iso: f64) -> Option<f64> {
        self.field
            .distance_to_surface(self.to_unit(p), iso)
            .map(|d| d * self.size)
    }

    fn distance_estimate(&self, p: [f64; 3], iso: f64) -> f64 {
        self.field.distance_estimate(self.to_unit(p), iso) * self.size
    }

    fn distance_lower_bound(&self, p: [f64; 3], iso: f64) -> f64 {
        self.field.distance_lower_bound(self.to_unit(p), iso) * self.size
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points() -> impl Iterator<Item = [f64; 3]> {
        (0..200u32).map(|i| {
            let h = |k: u32| {
                ((i.wrapping_mul(2654435761).wrapping_add(k * 40503)) % 1000) as f64 / 1000.0
            };
            [h(1), h(2), h(3)]
        })
    }

    #[test]
    fn gradients_match_finite_differences() {
        for case in Case::ALL {
            for p in points() {
                let g = case.gradient(p);
                let h = 1e-6;
                for a in 0..3 {
                    let (mut lo, mut hi) = (p, p);
                    lo[a] -= h;
                    hi[a] += h;
                    let fd = (case.value(hi) - case.value(lo)) / (2.0 * h);
                    let tol = 1e-4 * (1.0 + fd.abs());
                    assert!(
                        (fd - g[a]).abs() < tol,
                        "{case} at {p:?} axis {a}: {fd} vs {}",
                        g[a]
                    );
                }
            }
        }
    }

    #[test]
    fn surfaces_lie_inside_the_unit_cube() {
        for case in Case::ALL {
            let iso = case.default_iso();
            let n = 40;
            let outside = case.value([0.0; 3]) > iso;
            let mut crossed = false;
            for i in 0..=n {
                for j in 0..=n {
                    for k in 0..=n {
                        let p = [i, j, k].map(|x| x as f64 / n as f64);
                        let above = case.value(p) > iso;
                        if [i, j, k].iter().any(|&x| x == 0 || x == n) {
                            assert_eq!(
                                above, outside,
                                "{case} surface reaches the boundary at {p:?}"
                            );
                        }
                        crossed |= above != outside;
                    }
                }
            }
            assert!(crossed, "{case} has no surface");
        }
    }

    #[test]
    fn lower_bounds_never_exceed_the_distance_to_a_crossing() {
        for case in Case::ALL {
            let iso = case.default_iso();
            for p in points() {
                let lb = case.distance_lower_bound(p, iso);
                let above = case.value(p) > iso;
                for q in points() {
                    let d = norm(sub(p, q));
                    if d < lb {
                        let msg = format!("{case}: {p:?} has bound {lb}, but {q:?} at {d} crosses");
                        assert_eq!(case.value(q) > iso, above, "{msg}");
                    }
                }
            }
        }
    }

    #[test]
    fn blobs_merge_at_the_default_iso() {
        let mid = [0, 1, 2].map(|a| 0.5 * (BLOB_CENTRES[0][a] + BLOB_CENTRES[1][a]));
        assert!(Case::Blobs.value(mid) > BLOB_ISO);
        assert!(Case::Blobs.value([0.5, 0.5, 0.95]) < BLOB_ISO);
    }

    #[test]
    fn sphere_distance_is_exact_and_placed_scales_it() {
        let p = [0.9, 0.1, 0.3];
        let d = Case::Sphere.distance_to_surface(p, 0.0).unwrap();
        assert!((d - (norm(sub(p, SPHERE_CENTRE)) - SPHERE_RADIUS).abs()).abs() < 1e-15);
        let placed = Placed {
            field: Case::Sphere,
            origin: [1e6, -3.0, 0.5],
            size: 1e-3,
        };
        let q = placed.to_physical(p);
        assert!((placed.value(q) - Case::Sphere.value(p)).abs() < 1e-6);
        let dq = placed.distance_to_surface(q, 0.0).unwrap();
        assert!((dq - d * 1e-3).abs() < 1e-9);
        assert!((norm(placed.gradient(q)) - 1e3).abs() < 1e-3);
    }

    #[test]
    fn names_round_trip() {
        for case in Case::ALL {
            assert_eq!(case.name().parse::<Case>().unwrap(), case);
        }
        assert!("cube".parse::<Case>().unwrap_err().contains("blobs"));
    }
}
