//! Trilinear interpolation and vertex averages, evaluated in one fixed order.
//!
//! Corner `n` of a box is on the upper side of axis `a` when bit `a` of `n` is set. Both the
//! trilinear interpolant and the averages combine x pairs first, then y pairs, then z, and
//! `avg2(a, b) = (a + b) * 0.5` equals `lerp(a, b, 0.5) = a * 0.5 + b * 0.5` bit for bit (halving
//! is exact, so it commutes with rounding). A shared vertex value is therefore the same
//! whichever box computes it, and averages agree with interpolation at midpoints.

/// `a * (1 - t) + b * t`: exact at `t = 0` and `t = 1`.
#[inline]
pub fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a * (1.0 - t) + b * t
}

/// The mean of two values, `(a + b) * 0.5`; symmetric in its arguments.
#[inline]
pub fn avg2(a: f32, b: f32) -> f32 {
    (a + b) * 0.5
}

/// The mean of eight corner values, x pairs first, then y, then z.
#[inline]
pub fn avg8(v: &[f32; 8]) -> f32 {
    let x = [
        avg2(v[0], v[1]),
        avg2(v[2], v[3]),
        avg2(v[4], v[5]),
        avg2(v[6], v[7]),
    ];
    avg2(avg2(x[0], x[1]), avg2(x[2], x[3]))
}

/// Trilinear interpolation of corner values `v` at local coordinates `t` in `[0, 1]^3`.
#[inline]
pub fn trilinear(v: &[f32; 8], t: [f32; 3]) -> f32 {
    let x = [
        lerp(v[0], v[1], t[0]),
        lerp(v[2], v[3], t[0]),
        lerp(v[4], v[5], t[0]),
        lerp(v[6], v[7], t[0]),
    ];
    lerp(lerp(x[0], x[1], t[1]), lerp(x[2], x[3], t[1]), t[2])
}

/// The smallest and largest of eight values.
#[inline]
pub fn min_max(v: &[f32; 8]) -> (f32, f32) {
    let mut lo = v[0];
    let mut hi = v[0];
    for &x in &v[1..] {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    (lo, hi)
}

/// The activity rule: a voxel whose corner values span `[lo, hi]` holds part of the surface
/// at `iso` when `lo < iso <= hi`. See `docs/reconstruction.md`.
#[inline]
pub fn straddles(lo: f32, hi: f32, iso: f32) -> bool {
    lo < iso && iso <= hi
}

/// The activity rule for a voxel of corner values `v`: [`straddles`] of their range, or a
/// corner is NaN. No converter writes a NaN (only a file damaged after it was written holds
/// one), and it may stand for any value: such a voxel is kept, so that the tracer, decoding it,
/// reports the damage instead of leaving a hole in the surface.
#[inline]
pub fn corners_straddle(v: &[f32; 8], iso: f32) -> bool {
    let (lo, hi) = min_max(v);
    straddles(lo, hi, iso) || v.iter().any(|x| x.is_nan())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_match_interpolation_at_midpoints() {
        let v = [0.1f32, 1.7, -3.25, 9.0e3, 1.0e-3, 7.5, 2.0 / 3.0, -0.3];
        assert_eq!(avg8(&v).to_bits(), trilinear(&v, [0.5; 3]).to_bits());
        assert_eq!(avg2(v[1], v[2]).to_bits(), lerp(v[1], v[2], 0.5).to_bits());
        for n in 0..8 {
            let t = [0, 1, 2].map(|a| (n >> a & 1) as f32);
            assert_eq!(trilinear(&v, t), v[n]);
        }
    }
}
