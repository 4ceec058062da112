//! [`Cubic::refine`] for four cubics at once, one per AVX2 lane: the same safeguarded Newton
//! steps, each lane computed with exactly the scalar code's `f64` operations in their order, so
//! that each lane's root is the scalar one bit for bit. A lane stops where the scalar loop
//! returns or breaks; the steps go on while any lane is left.

use std::arch::x86_64::*;

use crate::trace::lanes::{abs, larger, smaller, PerLane};

/// Per lane `i` of `lanes` (bit `i`), the root [`Cubic::refine`] gives the cubic whose
/// coefficients are lane `i` of `c` (constant term first) on the bracket `[x0, x1]` with values
/// `f0` and `f1` there, to `tol`; the other lanes' roots are unspecified.
///
/// [`Cubic::refine`]: super::Cubic::refine
#[target_feature(enable = "avx2")]
#[inline]
pub(in crate::trace) fn refine_lanes(
    c: &[PerLane; 4],
    (x0, f0): (&PerLane, &PerLane),
    (x1, f1): (&PerLane, &PerLane),
    tol: f64,
    lanes: i32,
) -> PerLane {
    let load = |v: &PerLane| {
        // SAFETY: `PerLane` is four `f64`s aligned to 32 bytes.
        unsafe { _mm256_load_pd(v.0.as_ptr()) }
    };
    let c = c.map(|v| load(&v));
    let (mut x0, mut f0, mut x1, mut f1) = (load(x0), load(f0), load(x1), load(f1));
    let zero = _mm256_setzero_pd();
    let ones = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    let bits = _mm256_setr_epi64x(1, 2, 4, 8);
    let asked = _mm256_cmpeq_epi64(
        _mm256_and_si256(_mm256_set1_epi64x(i64::from(lanes)), bits),
        bits,
    );
    // The lanes whose root is known (all ones), and their roots.
    let mut done = _mm256_xor_pd(_mm256_castsi256_pd(asked), ones);
    let mut out = zero;
    // The lanes of `now` not done yet take `root` as their root.
    let settle = |(out, done): (__m256d, __m256d), now: __m256d, root: __m256d| {
        let now = _mm256_andnot_pd(done, now);
        (_mm256_blendv_pd(out, root, now), _mm256_or_pd(done, now))
    };
    (out, done) = settle((out, done), _mm256_cmp_pd::<_CMP_EQ_OQ>(f0, zero), x0);
    (out, done) = settle((out, done), _mm256_cmp_pd::<_CMP_EQ_OQ>(f1, zero), x1);
    let negative_at_x0 = _mm256_cmp_pd::<_CMP_LT_OQ>(f0, zero);
    let half_curvature = _mm256_add_pd(
        abs(c[2]),
        _mm256_mul_pd(
            _mm256_mul_pd(_mm256_set1_pd(3.0), abs(c[3])),
            larger(abs(x0), abs(x1)),
        ),
    );
    let half = _mm256_set1_pd(0.5);
    let mid = |x0, x1| _mm256_mul_pd(half, _mm256_add_pd(x0, x1));
    let mut x = _mm256_div_pd(
        _mm256_sub_pd(_mm256_mul_pd(x0, f1), _mm256_mul_pd(x1, f0)),
        _mm256_sub_pd(f1, f0),
    );
    let inside = _mm256_and_pd(
        _mm256_cmp_pd::<_CMP_GT_OQ>(x, smaller(x0, x1)),
        _mm256_cmp_pd::<_CMP_LT_OQ>(x, larger(x0, x1)),
    );
    x = _mm256_blendv_pd(mid(x0, x1), x, inside);
    let mut step = abs(_mm256_sub_pd(x1, x0));
    let mut step_before = step;
    let (three_c3, two_c2) = (
        _mm256_mul_pd(_mm256_set1_pd(3.0), c[3]),
        _mm256_mul_pd(_mm256_set1_pd(2.0), c[2]),
    );
    let tiny = _mm256_set1_pd(f64::MIN_POSITIVE);
    // The end of a bracket whose value is nearer zero (the scalar code's answer after its loop).
    let nearer_end =
        |x0, f0, x1, f1| _mm256_blendv_pd(x1, x0, _mm256_cmp_pd::<_CMP_LE_OQ>(abs(f0), abs(f1)));
    for _ in 0..100 {
        if _mm256_movemask_pd(done) == 0xf {
            return PerLane::of(out);
        }
        let f = _mm256_add_pd(
            _mm256_mul_pd(
                _mm256_add_pd(
                    _mm256_mul_pd(_mm256_add_pd(_mm256_mul_pd(c[3], x), c[2]), x),
                    c[1],
                ),
                x,
            ),
            c[0],
        );
        let slope = _mm256_add_pd(
            _mm256_mul_pd(_mm256_add_pd(_mm256_mul_pd(three_c3, x), two_c2), x),
            c[1],
        );
        (out, done) = settle((out, done), _mm256_cmp_pd::<_CMP_EQ_OQ>(f, zero), x);
        let same_side = _mm256_xor_pd(
            _mm256_xor_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(f, zero), negative_at_x0),
            ones,
        );
        let live = _mm256_xor_pd(done, ones);
        let (to0, to1) = (
            _mm256_and_pd(live, same_side),
            _mm256_andnot_pd(same_side, live),
        );
        x0 = _mm256_blendv_pd(x0, x, to0);
        f0 = _mm256_blendv_pd(f0, f, to0);
        x1 = _mm256_blendv_pd(x1, x, to1);
        f1 = _mm256_blendv_pd(f1, f, to1);
        let width = _mm256_sub_pd(x1, x0);
        let least = _mm256_mul_pd(
            _mm256_set1_pd(4.0 * f64::EPSILON),
            larger(larger(abs(x0), abs(x1)), tiny),
        );
        (out, done) = settle(
            (out, done),
            _mm256_cmp_pd::<_CMP_LE_OQ>(abs(width), least),
            nearer_end(x0, f0, x1, f1),
        );
        let newton = _mm256_sub_pd(x, _mm256_div_pd(f, slope));
        let ok = _mm256_and_pd(
            _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(newton, smaller(x0, x1)),
                _mm256_cmp_pd::<_CMP_LT_OQ>(newton, larger(x0, x1)),
            ),
            _mm256_cmp_pd::<_CMP_LE_OQ>(
                abs(_mm256_mul_pd(_mm256_set1_pd(2.0), f)),
                abs(_mm256_mul_pd(step_before, slope)),
            ),
        );
        let h = _mm256_sub_pd(newton, x);
        let close = _mm256_cmp_pd::<_CMP_LE_OQ>(
            _mm256_mul_pd(_mm256_mul_pd(half_curvature, h), h),
            _mm256_mul_pd(_mm256_set1_pd(tol), abs(slope)),
        );
        (out, done) = settle((out, done), _mm256_and_pd(ok, close), newton);
        let next = _mm256_blendv_pd(mid(x0, x1), newton, ok);
        step_before = step;
        step = abs(_mm256_sub_pd(next, x));
        let least = _mm256_mul_pd(_mm256_set1_pd(2.0 * f64::EPSILON), larger(abs(x), tiny));
        (out, done) = settle((out, done), _mm256_cmp_pd::<_CMP_LE_OQ>(step, least), next);
        x = next;
    }
    (out, _) = settle((out, done), ones, nearer_end(x0, f0, x1, f1));
    PerLane::of(out)
}

#[cfg(test)]
mod tests {
    use super::super::Cubic;
    use super::*;
    use crate::shade::sampling::Rng;

    #[test]
    fn four_lanes_refine_each_cubic_to_its_scalar_root_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = Rng::for_pixel(3, 1, 0);
        let mut r = || rng.next_f64() * 2.0 - 1.0;
        let mut compared = 0;
        for round in 0..20_000 {
            let mut c = [[0.0; 4]; 4];
            let (mut x0, mut f0, mut x1, mut f1) = ([0.0; 4], [0.0; 4], [0.0; 4], [0.0; 4]);
            let mut lanes = 0;
            for i in 0..4 {
                let mut cubic = Cubic {
                    c: [r(), r(), r(), r()],
                };
                // Some lanes with a tiny or zero leading coefficient, a double root, a value
                // of zero at an end, or a NaN.
                match (round + i) % 7 {
                    1 => cubic.c[3] *= 1e-12,
                    2 => cubic.c = [0.25, -1.0, 1.0, 0.0],
                    3 => cubic.c[0] = 0.0,
                    4 if round % 50 == 0 => cubic.c[1] = f64::NAN,
                    _ => {}
                }
                let (a, b) = if round % 3 == 0 {
                    (0.0, 1.0)
                } else {
                    (r().min(0.0), r().max(0.0) + 0.1)
                };
                let (fa, fb) = (cubic.eval(a), cubic.eval(b));
                for j in 0..4 {
                    c[j][i] = cubic.c[j];
                }
                (x0[i], f0[i], x1[i], f1[i]) = (a, fa, b, fb);
                if (fa < 0.0) != (fb < 0.0) || fa == 0.0 || fb == 0.0 || round % 11 == 0 {
                    lanes |= 1 << i;
                }
            }
            let tol = if round % 2 == 0 { 1e-9 } else { 0.0 };
            let (p, q) = (PerLane(x0), PerLane(f0));
            let (s, t) = (PerLane(x1), PerLane(f1));
            // SAFETY: the CPU has AVX2 (checked above).
            let got = unsafe { refine_lanes(&c.map(PerLane), (&p, &q), (&s, &t), tol, lanes) };
            for i in 0..4 {
                if lanes >> i & 1 == 0 {
                    continue;
                }
                let cubic = Cubic {
                    c: [0, 1, 2, 3].map(|j| c[j][i]),
                };
                let want = cubic.refine(x0[i], f0[i], x1[i], f1[i], tol);
                assert_eq!(
                    got.0[i].to_bits(),
                    want.to_bits(),
                    "round {round} lane {i}: {cubic:?} on [{}, {}]",
                    x0[i],
                    x1[i]
                );
                compared += 1;
            }
        }
        assert!(compared > 20_000, "{compared} lanes compared");
    }
}
