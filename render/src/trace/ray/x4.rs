//! The `f32` BVH rays of a packet's grid rays four at a time in AVX2 lanes: the reciprocal
//! directions, the clip to the padded domain, the lead and the `f32` ray with its inverse
//! direction, each lane computed with exactly the operations, in the same order, of the
//! single-ray [`GridRay::bvh_ray_with`] / [`GridRay::bvh_ray_ahead`] and obvhs's `Ray::new`, so
//! that every ray gets the same BVH ray bit for bit.

use std::arch::x86_64::*;

use glam::Vec3A;
use obvhs::ray::Ray;

use super::{any_hit_lead, GridRay, BVH_LEAD};
use crate::bvh::packet::Mask;
use crate::trace::lanes::{abs, larger, smaller, PerLane};
use crate::trace::source::GridFrame;

/// [`super::bvh_rays`] on a CPU with AVX2.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub(super) fn bvh_rays(
    rays: &[GridRay],
    frame: &GridFrame,
    pad: f64,
    tmin: &[f64],
    tmax: &[f64],
    recips: &mut [[f64; 3]],
    ray32: &mut [Ray],
    back: &mut [(f64, f64)],
) -> Mask {
    let n = rays.len();
    assert!(
        n <= Mask::BITS as usize
            && tmin.len() == n
            && tmax.len() == n
            && recips.len() >= n
            && ray32.len() >= n
            && back.len() >= n
    );
    let lo = _mm256_set1_pd(-pad);
    let hi = frame.extent.map(|e| _mm256_set1_pd(e + pad));
    let (lead_origin, lead_ahead) = (_mm256_set1_pd(BVH_LEAD), _mm256_set1_pd(any_hit_lead(pad)));
    let mut active: Mask = 0;
    for first in (0..n).step_by(4) {
        let count = (n - first).min(4);
        // A short group repeats its last ray in the spare lanes.
        let ks = [0, 1, 2, 3].map(|i| first + i.min(count - 1));
        let r = ks.map(|k| &rays[k]);
        let o = [0, 1, 2].map(|a| _mm256_setr_pd(r[0].o[a], r[1].o[a], r[2].o[a], r[3].o[a]));
        let d = [0, 1, 2].map(|a| _mm256_setr_pd(r[0].d[a], r[1].d[a], r[2].d[a], r[3].d[a]));
        let t_lo = _mm256_setr_pd(tmin[ks[0]], tmin[ks[1]], tmin[ks[2]], tmin[ks[3]]);
        let t_hi = _mm256_setr_pd(tmax[ks[0]], tmax[ks[1]], tmax[ks[2]], tmax[ks[3]]);
        // `GridRay::recip`.
        let inv = d.map(|d| _mm256_div_pd(_mm256_set1_pd(1.0), d));
        let inv_of = inv.map(|v| PerLane::of(v));
        for (i, &k) in ks[..count].iter().enumerate() {
            recips[k] = [inv_of[0].0[i], inv_of[1].0[i], inv_of[2].0[i]];
        }
        // `GridRay::clip_with` to the padded domain: an axis the ray is parallel to rejects the
        // lanes outside the slab and leaves the interval alone.
        let (mut t0, mut t1) = (t_lo, t_hi);
        let mut reject = _mm256_setzero_pd();
        for a in 0..3 {
            let flat = _mm256_cmp_pd::<_CMP_EQ_OQ>(d[a], _mm256_setzero_pd());
            let outside = _mm256_or_pd(
                _mm256_cmp_pd::<_CMP_LT_OQ>(o[a], lo),
                _mm256_cmp_pd::<_CMP_GT_OQ>(o[a], hi[a]),
            );
            reject = _mm256_or_pd(reject, _mm256_and_pd(flat, outside));
            let ta = _mm256_mul_pd(_mm256_sub_pd(lo, o[a]), inv[a]);
            let tb = _mm256_mul_pd(_mm256_sub_pd(hi[a], o[a]), inv[a]);
            let swap = _mm256_cmp_pd::<_CMP_GT_OQ>(ta, tb);
            let (ta, tb) = (
                _mm256_blendv_pd(ta, tb, swap),
                _mm256_blendv_pd(tb, ta, swap),
            );
            t0 = _mm256_blendv_pd(larger(t0, ta), t0, flat);
            t1 = _mm256_blendv_pd(smaller(t1, tb), t1, flat);
        }
        let inside = _mm256_andnot_pd(reject, _mm256_cmp_pd::<_CMP_LE_OQ>(t0, t1));
        // `GridRay::bvh_ray_led`: the direction's grid length, positive and finite.
        let scale = _mm256_sqrt_pd(_mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(d[0], d[0]), _mm256_mul_pd(d[1], d[1])),
            _mm256_mul_pd(d[2], d[2]),
        ));
        let usable = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GT_OQ>(scale, _mm256_setzero_pd()),
            _mm256_cmp_pd::<_CMP_LT_OQ>(abs(scale), _mm256_set1_pd(f64::INFINITY)),
        );
        let lanes = _mm256_movemask_pd(_mm256_and_pd(inside, usable)) as u32 & !(!0 << count);
        if lanes == 0 {
            continue;
        }
        // Behind a hit (`tmin > 0`) the walk starts just before `tmin` (`bvh_ray_ahead`).
        let ahead = _mm256_cmp_pd::<_CMP_GT_OQ>(t_lo, _mm256_setzero_pd());
        let lead = _mm256_blendv_pd(lead_origin, lead_ahead, ahead);
        let t_off = _mm256_sub_pd(t0, _mm256_div_pd(lead, scale));
        let dir = d.map(|d| _mm256_div_pd(d, scale));
        let start = [0, 1, 2].map(|a| {
            let p = _mm256_add_pd(o[a], _mm256_mul_pd(t0, d[a]));
            _mm256_sub_pd(p, _mm256_mul_pd(dir[a], lead))
        });
        let span = _mm256_mul_pd(
            _mm256_mul_pd(_mm256_sub_pd(t1, t_off), scale),
            _mm256_set1_pd(1.0 + 1e-6),
        );
        let span = _mm256_cvtpd_ps(span);
        let finite = _mm_cmplt_ps(abs_ps(span), _mm_set1_ps(f32::INFINITY));
        let span = PerLane32::of(_mm_blendv_ps(_mm_set1_ps(f32::MAX), span, finite));
        let start = rows(start.map(|x| _mm256_cvtpd_ps(x)));
        let dir32 = dir.map(|x| _mm256_cvtpd_ps(x));
        let inv32 = rows(dir32.map(|x| safe_inverse(x)));
        let dir32 = rows(dir32);
        let (t_off, scale) = (PerLane::of(t_off), PerLane::of(scale));
        let mut left = lanes;
        while left != 0 {
            let i = left.trailing_zeros() as usize;
            left &= left - 1;
            let k = first + i;
            ray32[k] = Ray {
                origin: start[i],
                direction: dir32[i],
                inv_direction: inv32[i],
                tmin: 0.0,
                tmax: span.0[i],
            };
            back[k] = (t_off.0[i], scale.0[i]);
        }
        active |= Mask::from(lanes) << first;
    }
    active
}

/// Four `f32`, one per lane, aligned for a register's store.
#[derive(Clone, Copy)]
#[repr(C, align(16))]
struct PerLane32([f32; 4]);

impl PerLane32 {
    /// The register's four lanes.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn of(v: __m128) -> PerLane32 {
        let mut out = PerLane32([0.0; 4]);
        // SAFETY: `out` is 16 bytes aligned to 16.
        unsafe { _mm_store_ps(out.0.as_mut_ptr(), v) };
        out
    }
}

/// The four vectors whose x, y and z are lane `i` of `v[0]`, `v[1]` and `v[2]`, as
/// [`Vec3A::new`] makes them (its fourth lane a copy of z).
#[target_feature(enable = "avx2")]
#[inline]
fn rows(v: [__m128; 3]) -> [Vec3A; 4] {
    let [x, y, z] = v;
    let xy_lo = _mm_unpacklo_ps(x, y);
    let xy_hi = _mm_unpackhi_ps(x, y);
    let zz_lo = _mm_unpacklo_ps(z, z);
    let zz_hi = _mm_unpackhi_ps(z, z);
    [
        _mm_movelh_ps(xy_lo, zz_lo),
        _mm_movehl_ps(zz_lo, xy_lo),
        _mm_movelh_ps(xy_hi, zz_hi),
        _mm_movehl_ps(zz_hi, xy_hi),
    ]
    .map(Vec3A::from)
}

/// obvhs's `safe_inverse` lane by lane: `1 / x`, or `signum(x) / EPSILON` where `|x|` is at
/// most `f32::EPSILON`.
#[target_feature(enable = "avx2")]
#[inline]
fn safe_inverse(x: __m128) -> __m128 {
    let eps = _mm_set1_ps(f32::EPSILON);
    let small = _mm_cmple_ps(abs_ps(x), eps);
    let signum = _mm_or_ps(_mm_and_ps(x, _mm_set1_ps(-0.0)), _mm_set1_ps(1.0));
    _mm_blendv_ps(
        _mm_div_ps(_mm_set1_ps(1.0), x),
        _mm_div_ps(signum, eps),
        small,
    )
}

/// `|x|` lane by lane, `f32`.
#[target_feature(enable = "avx2")]
#[inline]
fn abs_ps(x: __m128) -> __m128 {
    _mm_andnot_ps(_mm_set1_ps(-0.0), x)
}
