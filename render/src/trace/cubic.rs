//! Cubic polynomials along a ray segment: evaluation, root isolation with the derivative's
//! roots, and refinement of a bracketed root (Marmitt et al. 2004).

use crate::trace::ray::{larger, smaller};

#[cfg(target_arch = "x86_64")]
pub(crate) mod x4;

/// How close to the root [`Cubic::first_root`] refines it, as a fraction of the interval. For a
/// ray's segment in a voxel, a billionth of the segment (under 2e-9 of the voxel's size): 30
/// times finer than an `f32` resolves a quantity of the voxel's size, so that what the hit gives
/// (position, normal, shadow ray origin) moves in its last bits at most.
pub(crate) const ROOT_TOL: f64 = 1e-9;

/// Where a scan of a cubic found its first root: at a point, or inside a bracket.
#[derive(Debug, PartialEq)]
enum Bracket {
    /// A point where the value is within the tolerance of zero.
    Root(f64),
    /// A monotonic bracket `(x0, f(x0), x1, f(x1))` with a sign change.
    SignChange(f64, f64, f64, f64),
}

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

    /// The smallest `s` in the closed interval `[a, b]` where the cubic is zero (within
    /// [`ROOT_TOL`] of `b - a`), treating any
    /// value with `|value| <= tol` as zero (which catches grazing rays that touch the surface at an
    /// extremum, and surfaces through segment ends where two voxels meet).
    #[inline]
    pub fn first_root(&self, a: f64, b: f64, tol: f64) -> Option<f64> {
        self.first_bracket(a, b, tol)
            .map(|bracket| self.root_in(bracket, a, b))
    }

    /// The root `bracket` (found on `[a, b]`) holds: where it is, or its sign change refined.
    #[inline(always)]
    fn root_in(&self, bracket: Bracket, a: f64, b: f64) -> f64 {
        match bracket {
            Bracket::Root(x) => x,
            Bracket::SignChange(x0, f0, x1, f1) => self.refine(x0, f0, x1, f1, ROOT_TOL * (b - a)),
        }
    }

    /// [`Self::first_root`] on `[0, 1]`, given what its first step computes there: whether the
    /// cubic is monotonic on it (`monotonic_on(0, 1)`) and its values at 0 and 1 (`eval`), bit
    /// for bit (the packet test computes them four lanes at a time).
    #[inline(always)]
    pub fn first_root_on_unit(&self, monotonic: bool, f0: f64, f1: f64, tol: f64) -> Option<f64> {
        if !monotonic {
            return self.first_root(0.0, 1.0, tol);
        }
        monotonic_bracket((0.0, f0), (1.0, f1), tol).map(|bracket| self.root_in(bracket, 0.0, 1.0))
    }

    /// [`Self::has_root`] on `[0, 1]`, given the first step's values as
    /// [`Self::first_root_on_unit`] takes them.
    #[inline(always)]
    pub fn has_root_on_unit(&self, monotonic: bool, f0: f64, f1: f64, tol: f64) -> bool {
        if !monotonic {
            return self.has_root(0.0, 1.0, tol);
        }
        monotonic_bracket((0.0, f0), (1.0, f1), tol).is_some()
    }

    /// True exactly when [`Self::first_root`] finds a root, without refining it (for any-hit
    /// queries, which need no position).
    #[inline]
    pub fn has_root(&self, a: f64, b: f64, tol: f64) -> bool {
        self.first_bracket(a, b, tol).is_some()
    }

    /// True when the cubic provably stays beyond `tol` of zero on `[0, 1]`, so that
    /// [`Self::first_root`] on `[0, 1]` finds nothing: its Bernstein coefficients (whose hull
    /// bounds the cubic there) all lie on one side, beyond `tol` plus a bound on the rounding of
    /// their computation and of the evaluations `first_root` would make. A cheap test that most
    /// candidate voxels a ray crosses without meeting the surface fail to pass. (The thirds are
    /// multiplications by the rounded `1 / 3`: an ulp more error than a division, far inside the
    /// margin, for a fraction of a division's time.)
    #[inline]
    pub fn clear_of_zero_on_unit(&self, tol: f64) -> bool {
        let [c0, c1, c2, c3] = self.c;
        let third = 1.0 / 3.0;
        let b = [
            c0,
            c0 + c1 * third,
            c0 + (2.0 / 3.0) * c1 + c2 * third,
            c0 + c1 + c2 + c3,
        ];
        let margin = tol + 64.0 * f64::EPSILON * (c0.abs() + c1.abs() + c2.abs() + c3.abs());
        b.iter().all(|&x| x > margin) || b.iter().all(|&x| x < -margin)
    }

    /// The first point of `[a, b]` where the cubic is within `tol` of zero, or the first monotonic
    /// bracket of a sign change: `[a, b]` itself when the cubic is monotonic there, else the scan
    /// of the derivative's roots ([`Self::scan_brackets`]).
    #[inline]
    fn first_bracket(&self, a: f64, b: f64, tol: f64) -> Option<Bracket> {
        if !(a <= b) {
            return None;
        }
        if self.monotonic_on(a, b) {
            return monotonic_bracket((a, self.eval(a)), (b, self.eval(b)), tol);
        }
        self.scan_brackets(a, b, tol)
    }

    /// True when the derivative's Bernstein coefficients on `[a, b]` (whose hull bounds it there)
    /// lie on one side of zero, beyond `1e-9` of their magnitudes: the derivative keeps its sign
    /// on `[a, b]`, so the cubic is monotonic there, and its roots lie far enough outside for
    /// their computed values, which [`Self::critical_points`] would give [`Self::scan_brackets`],
    /// to fall outside too. Then `[a, b]` is the scan's only bracket: [`Self::first_bracket`]
    /// gives what the scan gives, without the derivative's roots. False on NaN, and for most
    /// cubics with an extremum in or near `[a, b]`.
    #[inline]
    fn monotonic_on(&self, a: f64, b: f64) -> bool {
        let half = 0.5 * (b - a);
        let d0 = self.slope(a);
        let d1 = d0 + half * (2.0 * self.c[2] + 6.0 * self.c[3] * a);
        let d2 = self.slope(b);
        let margin = 1e-9 * (d0.abs() + d1.abs() + d2.abs());
        (d0 > margin && d1 > margin && d2 > margin)
            || (d0 < -margin && d1 < -margin && d2 < -margin)
    }

    /// The first point of `[a, b]` where the cubic is within `tol` of zero, or the first monotonic
    /// bracket of a sign change, scanning the derivative's roots in order (`a <= b`).
    fn scan_brackets(&self, a: f64, b: f64, tol: f64) -> Option<Bracket> {
        let (crit, n) = self.critical_points(a, b);
        let mut x0 = a;
        let mut f0 = self.eval(a);
        for &x1 in crit[..n].iter().chain(std::iter::once(&b)) {
            if f0.abs() <= tol {
                return Some(Bracket::Root(x0));
            }
            let f1 = self.eval(x1);
            if (f0 < 0.0) != (f1 < 0.0) {
                return Some(Bracket::SignChange(x0, f0, x1, f1));
            }
            if f1.abs() <= tol {
                return Some(Bracket::Root(x1));
            }
            x0 = x1;
            f0 = f1;
        }
        None
    }

    /// Narrows a bracket `[x0, x1]` with `f(x0)` and `f(x1)` of opposite signs (or one of them
    /// zero) on which the cubic is monotonic, to the root within about `tol` (`0` for double
    /// precision): Newton steps from the regula falsi point, kept inside the shrinking bracket,
    /// with bisection whenever a Newton step would leave the bracket or does not at least halve
    /// the step before it (the safeguarded Newton of Numerical Recipes' `rtsafe`). Near a simple
    /// root the steps converge quadratically: a Newton step `h` from `x` lands within
    /// `|f''| h^2 / (2 |f'(x)|)` of the root, so the step that brings this estimate (with `|f''|`
    /// bounded over the bracket) within `tol` is the last one, its point not evaluated.
    pub fn refine(&self, mut x0: f64, mut f0: f64, mut x1: f64, mut f1: f64, tol: f64) -> f64 {
        if f0 == 0.0 {
            return x0;
        }
        if f1 == 0.0 {
            return x1;
        }
        let negative_at_x0 = f0 < 0.0;
        // Half a bound on `|f''| = |2 c2 + 6 c3 x|` over the bracket.
        let half_curvature = self.c[2].abs() + 3.0 * self.c[3].abs() * larger(x0.abs(), x1.abs());
        let mut x = (x0 * f1 - x1 * f0) / (f1 - f0);
        if !(x > smaller(x0, x1) && x < larger(x0, x1)) {
            x = 0.5 * (x0 + x1);
        }
        let mut step = (x1 - x0).abs();
        let mut step_before = step;
        for _ in 0..100 {
            let (f, slope) = self.eval_with_slope(x);
            if f == 0.0 {
                return x;
            }
            if (f < 0.0) == negative_at_x0 {
                x0 = x;
                f0 = f;
            } else {
                x1 = x;
                f1 = f;
            }
            let width = x1 - x0;
            if width.abs()
                <= 4.0 * f64::EPSILON * larger(larger(x0.abs(), x1.abs()), f64::MIN_POSITIVE)
            {
                break;
            }
            let newton = x - f / slope;
            let next = if newton > smaller(x0, x1)
                && newton < larger(x0, x1)
                && (2.0 * f).abs() <= (step_before * slope).abs()
            {
                let h = newton - x;
                if half_curvature * h * h <= tol * slope.abs() {
                    return newton;
                }
                newton
            } else {
                0.5 * (x0 + x1)
            };
            step_before = step;
            step = (next - x).abs();
            if step <= 2.0 * f64::EPSILON * larger(x.abs(), f64::MIN_POSITIVE) {
                return next;
            }
            x = next;
        }
        if f0.abs() <= f1.abs() {
            x0
        } else {
            x1
        }
    }

    /// The derivative at `s` (Horner).
    #[inline]
    fn slope(&self, s: f64) -> f64 {
        (3.0 * self.c[3] * s + 2.0 * self.c[2]) * s + self.c[1]
    }

    /// [`Self::eval`] and [`Self::slope`] at `s` together, bit for bit the same values.
    #[inline]
    fn eval_with_slope(&self, s: f64) -> (f64, f64) {
        (self.eval(s), self.slope(s))
    }
}

/// The first bracket of a cubic monotonic on `[a, b]`, given its values `fa` at `a` and `fb`
/// at `b`: `a` or `b` where the value is within `tol` of zero (`a` first), else `[a, b]` itself
/// where the sign changes.
#[inline(always)]
fn monotonic_bracket((a, fa): (f64, f64), (b, fb): (f64, f64), tol: f64) -> Option<Bracket> {
    if fa.abs() <= tol {
        return Some(Bracket::Root(a));
    }
    if (fa < 0.0) != (fb < 0.0) {
        return Some(Bracket::SignChange(a, fa, b, fb));
    }
    (fb.abs() <= tol).then_some(Bracket::Root(b))
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
        assert!((r - 0.2).abs() <= ROOT_TOL, "{r}");
        let r = p.first_root(0.3, 1.0, 0.0).unwrap();
        assert!((r - 0.5).abs() <= 0.7 * ROOT_TOL, "{r}");
    }

    #[test]
    fn two_close_roots_between_samples_are_not_lost() {
        let p = from_roots([0.5, 0.5001, 3.0]);
        let r = p.first_root(0.0, 1.0, 0.0).unwrap();
        assert!((r - 0.5).abs() <= ROOT_TOL, "{r}");
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
    fn the_bernstein_test_and_the_root_test_agree_with_first_root() {
        // A small deterministic generator: cubics with roots in and around [0, 1], scaled over
        // many magnitudes, some shifted to graze zero.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut cleared = 0;
        for i in 0..200_000 {
            let scale = 10f64.powf(12.0 * next() - 6.0);
            let mut p = from_roots([3.0 * next() - 1.0, 3.0 * next() - 1.0, 3.0 * next() - 1.0]);
            p.c = p.c.map(|c| c * scale);
            if i % 3 == 0 {
                p.c[0] += scale * (0.2 * next() - 0.1);
            }
            let tol = if i % 2 == 0 { 0.0 } else { 1e-9 * scale };
            let first = p.first_root(0.0, 1.0, tol);
            assert_eq!(p.has_root(0.0, 1.0, tol), first.is_some(), "{p:?}");
            if p.clear_of_zero_on_unit(tol) {
                cleared += 1;
                assert_eq!(first, None, "{p:?} tol {tol}");
            }
        }
        assert!(
            cleared > 10_000,
            "the test should clear many cubics: {cleared}"
        );
    }

    #[test]
    fn the_monotonic_shortcut_finds_the_scan_s_bracket() {
        // Cubics as above, with roots in and around [0, 1] or far outside it, over many scales.
        let mut state = 0x1234_5678_9abc_def1u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut shortcuts = 0;
        for i in 0..200_000 {
            let scale = 10f64.powf(12.0 * next() - 6.0);
            let spread = if i % 4 == 0 { 30.0 } else { 3.0 };
            let mut p = from_roots([0, 1, 2].map(|_| spread * next() - spread / 3.0));
            p.c = p.c.map(|c| c * scale);
            if i % 5 == 0 {
                p.c[3] *= 1e-9 * next();
            }
            let tol = if i % 2 == 0 { 0.0 } else { 1e-9 * scale };
            let (a, b) = if i % 3 == 0 { (0.25, 0.75) } else { (0.0, 1.0) };
            shortcuts += usize::from(p.monotonic_on(a, b));
            assert_eq!(
                p.first_bracket(a, b, tol),
                p.scan_brackets(a, b, tol),
                "{p:?} on [{a}, {b}] tol {tol}"
            );
        }
        assert!(shortcuts > 50_000, "{shortcuts} shortcuts");
    }

    #[test]
    fn refine_reaches_the_bracketed_root_to_double_precision_or_the_tolerance() {
        // Cubics with three known roots; each root bracketed by the derivative's roots (or the
        // interval's ends) as `first_bracket` brackets them, refined from both orientations.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut worst = 0f64;
        for _ in 0..20_000 {
            let mut r = [next(), next(), next()];
            r.sort_by(f64::total_cmp);
            if r[1] - r[0] < 1e-6 || r[2] - r[1] < 1e-6 {
                continue;
            }
            let scale = 10f64.powf(8.0 * next() - 4.0);
            let mut p = from_roots(r);
            p.c = p.c.map(|c| c * scale);
            let (crit, n) = p.critical_points(-1.0, 2.0);
            assert_eq!(n, 2);
            let ends = [-1.0, crit[0], crit[1], 2.0];
            for k in 0..3 {
                let (a, b) = (ends[k], ends[k + 1]);
                for (x0, x1) in [(a, b), (b, a)] {
                    let x = p.refine(x0, p.eval(x0), x1, p.eval(x1), 0.0);
                    let near = p.refine(x0, p.eval(x0), x1, p.eval(x1), ROOT_TOL);
                    worst = worst.max((near - r[k]).abs());
                    // The coefficients' rounding alone moves the root by about
                    // `eps * sum |c| / |p'(root)|` (its condition number).
                    let moved = f64::EPSILON * p.c.iter().map(|c| c.abs()).sum::<f64>()
                        / p.slope(r[k]).abs();
                    assert!((x - r[k]).abs() <= 16.0 * moved, "{r:?} {k}: {x}");
                }
            }
        }
        // Roots 1e-6 apart make the Newton steps' estimate of their error only about right.
        assert!(worst <= ROOT_TOL, "{worst:e}");
    }

    #[test]
    fn grazing_double_root_counts_within_tolerance() {
        let p = from_roots([0.5, 0.5, 3.0]);
        let r = p.first_root(0.0, 1.0, 1e-12).unwrap();
        assert!((r - 0.5).abs() < 1e-9, "{r}");
    }
}
