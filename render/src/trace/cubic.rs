//! Cubic polynomials along a ray segment: evaluation, root isolation with the derivative's
//! roots, and refinement of a bracketed root (Marmitt et al. 2004).

/// The polynomial `c[0] + c[1] s + c[2] s^2 + c[3] s^3`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cubic {
    /// Coefficients, constant term first.
    pub c: [f64; 4],
}

impl Cubic {
    /// Value at `s` (Horner).
    #[inline]
    pub fn eval(&self, s: f64) -> f64 {
        ((self.c[3] * s + self.c[2]) * s + self.c[1]) * s + self.c[0]
    }

    /// Roots of the derivative `c1 + 2 c2 s + 3 c3 s^2` inside the open interval `(a, b)`, sorted.
    ///
    /// A vanishing leading coefficient (the cubic is really a quadratic, a line or a constant,
    /// as for rays parallel to voxel faces) gives one root or none.
    pub fn critical_points(&self, a: f64, b: f64) -> ([f64; 2], usize) {
        let (qa, qb, qc) = (3.0 * self.c[3], 2.0 * self.c[2], self.c[1]);
        let mut out = [0.0; 2];
        let mut n = 0;
        let mut push = |x: f64| {
            if x > a && x < b && x.is_finite() {
                out[n] = x;
                n += 1;
            }
        };
        let scale = qa.abs().max(qb.abs()).max(qc.abs());
        if scale == 0.0 {
            return (out, 0);
        }
        if qa.abs() <= 1e-14 * scale {
            if qb != 0.0 {
                push(-qc / qb);
            }
        } else {
            let disc = qb * qb - 4.0 * qa * qc;
            if disc >= 0.0 {
                let q = -0.5 * (qb + qb.signum() * disc.sqrt());
                if q == 0.0 {
                    push(0.0);
                } else {
                    let (r0, r1) = (q / qa, qc / q);
                    let (lo, hi) = if r0 <= r1 { (r0, r1) } else { (r1, r0) };
                    push(lo);
                    if hi != lo {
                        push(hi);
                    }
                }
            }
        }
        if n == 2 && out[0] > out[1] {
            out.swap(0, 1);
        }
        (out, n)
    }

    /// The smallest `s` in the closed interval `[a, b]` where the cubic is zero, treating any
    /// value with `|value| <= tol` as zero (which catches grazing rays that touch the surface at an
    /// extremum, and surfaces through segment ends where two voxels meet).
    pub fn first_root(&self, a: f64, b: f64, tol: f64) -> Option<f64> {
        if !(a <= b) {
            return None;
        }
        let (crit, n) = self.critical_points(a, b);
        let mut x0 = a;
        let mut f0 = self.eval(a);
        for &x1 in crit[..n].iter().chain(std::iter::once(&b)) {
            if f0.abs() <= tol {
                return Some(x0);
            }
            let f1 = self.eval(x1);
            if (f0 < 0.0) != (f1 < 0.0) && f1.abs() > tol {
                return Some(self.refine(x0, f0, x1, f1));
            }
            if f1.abs() <= tol {
                return Some(if (f0 < 0.0) != (f1 < 0.0) {
                    self.refine(x0, f0, x1, f1)
                } else {
                    x1
                });
            }
            x0 = x1;
            f0 = f1;
        }
        None
    }

    /// Narrows a bracket `[x0, x1]` with `f(x0)` and `f(x1)` of opposite signs (or one of them
    /// zero) on which the cubic is monotonic, to double precision (Illinois regula falsi with
    /// bisection as a safeguard).
    pub fn refine(&self, mut x0: f64, mut f0: f64, mut x1: f64, mut f1: f64) -> f64 {
        if f0 == 0.0 {
            return x0;
        }
        if f1 == 0.0 {
            return x1;
        }
        let mut side = 0i8;
        for i in 0..100 {
            let width = x1 - x0;
            if width.abs() <= 4.0 * f64::EPSILON * x0.abs().max(x1.abs()).max(f64::MIN_POSITIVE) {
                break;
            }
            let mut x = if i % 4 == 3 {
                0.5 * (x0 + x1)
            } else {
                (x0 * f1 - x1 * f0) / (f1 - f0)
            };
            if !(x > x0.min(x1) && x < x0.max(x1)) {
                x = 0.5 * (x0 + x1);
            }
            let f = self.eval(x);
            if f == 0.0 {
                return x;
            }
            if (f < 0.0) == (f1 < 0.0) {
                x1 = x;
                f1 = f;
                if side == -1 {
                    f0 *= 0.5;
                }
                side = -1;
            } else {
                x0 = x;
                f0 = f;
                if side == 1 {
                    f1 *= 0.5;
                }
                side = 1;
            }
        }
        if f0.abs() <= f1.abs() {
            x0
        } else {
            x1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_roots(r: [f64; 3]) -> Cubic {
        let (a, b, c) = (r[0], r[1], r[2]);
        Cubic {
            c: [-a * b * c, a * b + b * c + a * c, -(a + b + c), 1.0],
        }
    }

    #[test]
    fn finds_the_first_of_three_roots() {
        let p = from_roots([0.2, 0.5, 0.9]);
        let r = p.first_root(0.0, 1.0, 0.0).unwrap();
        assert!((r - 0.2).abs() < 1e-14, "{r}");
        let r = p.first_root(0.3, 1.0, 0.0).unwrap();
        assert!((r - 0.5).abs() < 1e-14, "{r}");
    }

    #[test]
    fn two_close_roots_between_samples_are_not_lost() {
        let p = from_roots([0.5, 0.5001, 3.0]);
        let r = p.first_root(0.0, 1.0, 0.0).unwrap();
        assert!((r - 0.5).abs() < 1e-12, "{r}");
    }

    #[test]
    fn degenerate_polynomials() {
        let line = Cubic {
            c: [-0.25, 1.0, 0.0, 0.0],
        };
        assert!((line.first_root(0.0, 1.0, 0.0).unwrap() - 0.25).abs() < 1e-15);
        let quad = Cubic {
            c: [0.16, -0.8, 1.0, 0.0],
        };
        assert!((quad.first_root(0.0, 1.0, 1e-15).unwrap() - 0.4).abs() < 1e-7);
        let constant = Cubic {
            c: [0.0, 0.0, 0.0, 0.0],
        };
        assert_eq!(constant.first_root(0.3, 0.6, 0.0), Some(0.3));
        let off = Cubic {
            c: [1.0, 0.0, 0.0, 0.0],
        };
        assert_eq!(off.first_root(0.0, 1.0, 0.0), None);
        assert_eq!(line.first_root(0.5, 0.5, 0.0), None);
        assert_eq!(line.first_root(0.25, 0.25, 0.0), Some(0.25));
    }

    #[test]
    fn grazing_double_root_counts_within_tolerance() {
        let p = from_roots([0.5, 0.5, 3.0]);
        let r = p.first_root(0.0, 1.0, 1e-12).unwrap();
        assert!((r - 0.5).abs() < 1e-9, "{r}");
    }
}
