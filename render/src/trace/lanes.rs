//! Lane-wise helpers of the AVX2 paths over four `f64` lanes, shared by the exact voxel tests
//! (`octant::x4`) and the BVH-walk rays (`ray::x4`), and their lanes read back as `f64`s.

use std::arch::x86_64::*;

/// `a` where `b` is not greater, `b` where it is: [`crate::trace::ray::larger`] lane by lane
/// (`a` when `b` is NaN).
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn larger(a: __m256d, b: __m256d) -> __m256d {
    _mm256_blendv_pd(a, b, _mm256_cmp_pd::<_CMP_GT_OQ>(b, a))
}

/// [`crate::trace::ray::smaller`] lane by lane (`a` when `b` is NaN).
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn smaller(a: __m256d, b: __m256d) -> __m256d {
    _mm256_blendv_pd(a, b, _mm256_cmp_pd::<_CMP_LT_OQ>(b, a))
}

/// `|x|` lane by lane (the sign bit cleared, as [`f64::abs`]).
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn abs(x: __m256d) -> __m256d {
    _mm256_andnot_pd(_mm256_set1_pd(-0.0), x)
}

/// Four `f64`, one per lane, aligned for a register's store.
#[derive(Clone, Copy)]
#[repr(C, align(32))]
pub(super) struct PerLane(pub(super) [f64; 4]);

impl PerLane {
    /// The register's four lanes.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn of(v: __m256d) -> PerLane {
        let mut out = PerLane([0.0; 4]);
        // SAFETY: `out` is 32 bytes aligned to 32.
        unsafe { _mm256_store_pd(out.0.as_mut_ptr(), v) };
        out
    }
}
