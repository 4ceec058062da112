//! The rays of a packet that reach one voxel, four at a time in AVX2 lanes: the box clip, the
//! segment's widening and local coordinates, the cubic and its Bernstein hull test, each lane
//! computed with exactly the `f64` operations, in the same order, of the single-ray
//! [`Segment::new`] (but for the local coordinates' divisions by the voxel's extents, which
//! become multiplications by their reciprocals when those are exact, bit for bit the same), so
//! that every ray gets the same candidate segment bit for bit. Only the
//! root finding of the segments that pass ([`Segment::first_hit`]) stays one ray at a time.
//!
//! A candidate's test is a long chain of dependent operations (clip, widening, local coordinates,
//! cubic, hull); four independent chains in one register replace four chains one after the other.

use std::arch::x86_64::*;

use super::{exact_recips, Segment, VoxelHit, VoxelSetup, SEGMENT_WIDEN};
use crate::bvh::packet::{rays_of, Mask};
use crate::trace::cubic::x4::refine_lanes;
use crate::trace::cubic::{Cubic, ROOT_TOL};
use crate::trace::lanes::{abs, larger, smaller, PerLane};
use crate::trace::ray::GridRay;
use crate::trace::source::Voxel;

/// [`super::intersect_voxel_packet`] on a CPU with AVX2, the voxel's set-up included: the rays
/// of `m` with a hit, each in `hits[k]` (the other rays' entries are not written).
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub(super) fn hits(
    voxel: &Voxel,
    iso: f32,
    rays: &[GridRay],
    recips: &[[f64; 3]],
    m: Mask,
    tmin: &[f64],
    tmax: &[f64],
    hits: &mut [Option<VoxelHit>],
) -> Mask {
    let Some(setup) = VoxelSetup::new(voxel, iso) else {
        return 0;
    };
    let setup = &setup;
    // One past the last ray of `m`: every ray the groups below read lies below it, so their
    // reads go unchecked.
    let end = (Mask::BITS - m.leading_zeros()) as usize;
    assert!(
        end <= rays.len()
            && end <= recips.len()
            && end <= tmin.len()
            && end <= tmax.len()
            && end <= hits.len()
    );
    let w = [0, 1, 2].map(|a| voxel.hi[a] - voxel.lo[a]);
    let extent = Extent {
        w,
        recip: exact_recips(w),
    };
    let mut out: Mask = 0;
    each_group(m, |ks, n| {
        // SAFETY: each `ks[i]` is a ray of `m`, below `end`, which all five slices reach.
        let lanes = unsafe { Lanes::new(rays, recips, tmin, tmax, ks) };
        // Borrowed where it lies: moving the segments out of the `Option` copies them whole.
        let segs = lanes.segments(voxel, &extent, setup);
        let Some(segs) = segs.as_ref() else {
            return;
        };
        let refined = segs.refined();
        for (i, &k) in ks[..n].iter().enumerate() {
            if let Some(hit) = segs.first_hit(i, &refined) {
                // SAFETY: as above.
                unsafe { *hits.get_unchecked_mut(k) = Some(hit) };
                out |= 1 << k;
            }
        }
    });
    out
}

/// [`super::voxel_occluders_packet`] on a CPU with AVX2, the voxel's set-up included: the rays
/// of `m` for which [`super::voxel_occludes`] is true, each segment built four rays at a time as
/// [`hits`] builds it and asked only whether it has a root.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
pub(super) fn occluders(
    voxel: &Voxel,
    iso: f32,
    rays: &[GridRay],
    recips: &[[f64; 3]],
    m: Mask,
    tmin: &[f64],
    tmax: &[f64],
) -> Mask {
    let Some(setup) = VoxelSetup::new(voxel, iso) else {
        return 0;
    };
    let setup = &setup;
    let end = (Mask::BITS - m.leading_zeros()) as usize;
    assert!(end <= rays.len() && end <= recips.len() && end <= tmin.len() && end <= tmax.len());
    let w = [0, 1, 2].map(|a| voxel.hi[a] - voxel.lo[a]);
    let extent = Extent {
        w,
        recip: exact_recips(w),
    };
    let mut out: Mask = 0;
    each_group(m, |ks, n| {
        // SAFETY: each `ks[i]` is a ray of `m`, below `end`, which all four slices reach.
        let lanes = unsafe { Lanes::new(rays, recips, tmin, tmax, ks) };
        if let Some(segs) = lanes.segments(voxel, &extent, setup) {
            for (i, &k) in ks[..n].iter().enumerate() {
                if segs.has_root(i) {
                    out |= 1 << k;
                }
            }
        }
    });
    out
}

/// Calls `f(ks, n)` for the rays of `m` four at a time, in order: `ks[..n]` are the group's
/// rays, and a short group repeats its first ray in the spare lanes.
#[inline(always)]
fn each_group(m: Mask, mut f: impl FnMut([usize; 4], usize)) {
    let mut left = rays_of(m);
    while let Some(first) = left.next() {
        let mut ks = [first; 4];
        let mut n = 1;
        for k in left.by_ref().take(3) {
            ks[n] = k;
            n += 1;
        }
        f(ks, n);
    }
}

/// The voxel's extent on each axis, and their reciprocals when those are exact.
struct Extent {
    w: [f64; 3],
    recip: Option<[f64; 3]>,
}

/// Four rays, each quantity one register with ray `i` in lane `i`.
struct Lanes {
    o: [__m256d; 3],
    d: [__m256d; 3],
    recip: [__m256d; 3],
    tmin: __m256d,
    tmax: __m256d,
}

/// The four rays' segments in one voxel, lane by lane: `pass` has bit `i` when ray `i` has one.
struct Segments {
    pass: i32,
    ta: PerLane,
    tb: PerLane,
    p0: [PerLane; 3],
    q: [PerLane; 3],
    c: [PerLane; 4],
    tol: f64,
    /// The lanes whose cubic is monotonic on `[0, 1]` (`Cubic::monotonic_on`), and each
    /// cubic's values at 0 and 1 (`Cubic::eval`): the first step of [`Cubic::first_root`].
    monotonic: i32,
    /// The lanes whose value at 0 is beyond the tolerance of zero and whose values at 0 and 1
    /// differ in sign: with `monotonic`, those whose bracket is the whole of `[0, 1]`.
    changing: i32,
    f0: PerLane,
    f1: PerLane,
}

impl Segments {
    /// The lanes whose root [`Cubic::first_root_on_unit`] refines from the whole of `[0, 1]`
    /// (a segment whose cubic is monotonic there, changes sign, and is not within the
    /// tolerance of zero at 0), and those roots, refined four lanes at a time
    /// ([`refine_lanes`]), bit for bit the scalar ones.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn refined(&self) -> (i32, PerLane) {
        let lanes = self.changing & self.pass & self.monotonic;
        if lanes == 0 {
            return (0, PerLane([0.0; 4]));
        }
        let (zeros, ones) = (PerLane([0.0; 4]), PerLane([1.0; 4]));
        let roots = refine_lanes(
            &self.c,
            (&zeros, &self.f0),
            (&ones, &self.f1),
            // `Cubic::root_in`'s tolerance on `[0, 1]`, a bracket of width 1.
            ROOT_TOL,
            lanes,
        );
        (lanes, roots)
    }

    /// Lane `i`'s first hit with the surface ([`Segment::first_hit`] of its segment), if it has
    /// a segment; `refined` is [`Segments::refined`].
    #[inline(always)]
    fn first_hit(&self, i: usize, (lanes, roots): &(i32, PerLane)) -> Option<VoxelHit> {
        if self.pass >> i & 1 == 0 {
            return None;
        }
        let s = if lanes >> i & 1 != 0 {
            roots.0[i]
        } else {
            let cubic = Cubic {
                c: [0, 1, 2, 3].map(|j| self.c[j].0[i]),
            };
            let monotonic = self.monotonic >> i & 1 != 0;
            cubic.first_root_on_unit(monotonic, self.f0.0[i], self.f1.0[i], self.tol)?
        };
        Some(Segment::hit_at(
            s,
            (self.ta.0[i], self.tb.0[i]),
            [0, 1, 2].map(|a| self.p0[a].0[i]),
            [0, 1, 2].map(|a| self.q[a].0[i]),
        ))
    }
}

impl Segments {
    /// Whether lane `i` has a segment whose cubic has a root ([`Cubic::has_root`], the any-hit
    /// test of [`super::voxel_occludes`]).
    #[inline(always)]
    fn has_root(&self, i: usize) -> bool {
        self.pass >> i & 1 != 0
            && Cubic {
                c: [0, 1, 2, 3].map(|j| self.c[j].0[i]),
            }
            .has_root_on_unit(
                self.monotonic >> i & 1 != 0,
                self.f0.0[i],
                self.f1.0[i],
                self.tol,
            )
    }
}

impl Lanes {
    /// The rays `ks` of the packet, ray `ks[i]` in lane `i`.
    ///
    /// # Safety
    /// Each `ks[i]` must index all four slices.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn new(
        rays: &[GridRay],
        recips: &[[f64; 3]],
        tmin: &[f64],
        tmax: &[f64],
        ks: [usize; 4],
    ) -> Lanes {
        // SAFETY: the caller's promise.
        let (r, v, t0, t1) = unsafe {
            (
                ks.map(|k| rays.get_unchecked(k)),
                ks.map(|k| recips.get_unchecked(k)),
                ks.map(|k| *tmin.get_unchecked(k)),
                ks.map(|k| *tmax.get_unchecked(k)),
            )
        };
        let mut lanes = Lanes {
            o: [_mm256_setzero_pd(); 3],
            d: [_mm256_setzero_pd(); 3],
            recip: [_mm256_setzero_pd(); 3],
            tmin: _mm256_setr_pd(t0[0], t0[1], t0[2], t0[3]),
            tmax: _mm256_setr_pd(t1[0], t1[1], t1[2], t1[3]),
        };
        for a in 0..3 {
            lanes.o[a] = _mm256_setr_pd(r[0].o[a], r[1].o[a], r[2].o[a], r[3].o[a]);
            lanes.d[a] = _mm256_setr_pd(r[0].d[a], r[1].d[a], r[2].d[a], r[3].d[a]);
            lanes.recip[a] = _mm256_setr_pd(v[0][a], v[1][a], v[2][a], v[3][a]);
        }
        lanes
    }

    /// Each lane's segment in `voxel`, as [`Segment::new`] makes it (after the set-up's range
    /// test, which `setup` passed); `None` when no lane has one.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn segments(&self, voxel: &Voxel, extent: &Extent, setup: &VoxelSetup) -> Option<Segments> {
        let lo = voxel.lo.map(|x| _mm256_set1_pd(x));
        let hi = voxel.hi.map(|x| _mm256_set1_pd(x));
        // The box clip (`GridRay::clip_with`): an axis the ray is parallel to rejects the lanes
        // outside the slab and leaves the interval alone.
        let (mut t0, mut t1) = (self.tmin, self.tmax);
        let mut reject = _mm256_setzero_pd();
        for a in 0..3 {
            let (o, inv) = (self.o[a], self.recip[a]);
            let flat = _mm256_cmp_pd::<_CMP_EQ_OQ>(self.d[a], _mm256_setzero_pd());
            let outside = _mm256_or_pd(
                _mm256_cmp_pd::<_CMP_LT_OQ>(o, lo[a]),
                _mm256_cmp_pd::<_CMP_GT_OQ>(o, hi[a]),
            );
            reject = _mm256_or_pd(reject, _mm256_and_pd(flat, outside));
            let ta = _mm256_mul_pd(_mm256_sub_pd(lo[a], o), inv);
            let tb = _mm256_mul_pd(_mm256_sub_pd(hi[a], o), inv);
            let swap = _mm256_cmp_pd::<_CMP_GT_OQ>(ta, tb);
            let (ta, tb) = (
                _mm256_blendv_pd(ta, tb, swap),
                _mm256_blendv_pd(tb, ta, swap),
            );
            t0 = _mm256_blendv_pd(larger(t0, ta), t0, flat);
            t1 = _mm256_blendv_pd(smaller(t1, tb), t1, flat);
        }
        let inside = _mm256_andnot_pd(reject, _mm256_cmp_pd::<_CMP_LE_OQ>(t0, t1));
        let clipped = _mm256_movemask_pd(inside);
        if clipped == 0 {
            return None;
        }
        // The widened segment (`Segment::in_box`).
        let widen = _mm256_add_pd(
            _mm256_mul_pd(_mm256_set1_pd(SEGMENT_WIDEN), _mm256_sub_pd(t1, t0)),
            _mm256_mul_pd(_mm256_set1_pd(8.0 * f64::EPSILON), larger(abs(t0), abs(t1))),
        );
        let ta = larger(self.tmin, _mm256_sub_pd(t0, widen));
        let tb = smaller(self.tmax, _mm256_add_pd(t1, widen));
        let mut p0 = [_mm256_setzero_pd(); 3];
        let mut q = [_mm256_setzero_pd(); 3];
        for a in 0..3 {
            let w = _mm256_set1_pd(extent.w[a]);
            let rel = _mm256_sub_pd(self.o[a], lo[a]);
            let local = |t: __m256d| {
                let x = _mm256_add_pd(rel, _mm256_mul_pd(t, self.d[a]));
                match extent.recip {
                    Some(r) => _mm256_mul_pd(x, _mm256_set1_pd(r[a])),
                    None => _mm256_div_pd(x, w),
                }
            };
            p0[a] = local(ta);
            q[a] = _mm256_sub_pd(local(tb), p0[a]);
        }
        let c = along_segment(&setup.c, p0, q);
        // The Bernstein hull (`Cubic::clear_of_zero_on_unit`).
        let third = _mm256_set1_pd(1.0 / 3.0);
        let b = [
            c[0],
            _mm256_add_pd(c[0], _mm256_mul_pd(c[1], third)),
            _mm256_add_pd(
                _mm256_add_pd(c[0], _mm256_mul_pd(_mm256_set1_pd(2.0 / 3.0), c[1])),
                _mm256_mul_pd(c[2], third),
            ),
            _mm256_add_pd(_mm256_add_pd(_mm256_add_pd(c[0], c[1]), c[2]), c[3]),
        ];
        let sum = _mm256_add_pd(
            _mm256_add_pd(_mm256_add_pd(abs(c[0]), abs(c[1])), abs(c[2])),
            abs(c[3]),
        );
        let margin = _mm256_add_pd(
            _mm256_set1_pd(setup.tol),
            _mm256_mul_pd(_mm256_set1_pd(64.0 * f64::EPSILON), sum),
        );
        let below = _mm256_xor_pd(margin, _mm256_set1_pd(-0.0));
        let (mut above_all, mut below_all) = (inside, inside);
        for x in b {
            above_all = _mm256_and_pd(above_all, _mm256_cmp_pd::<_CMP_GT_OQ>(x, margin));
            below_all = _mm256_and_pd(below_all, _mm256_cmp_pd::<_CMP_LT_OQ>(x, below));
        }
        let pass = clipped & !_mm256_movemask_pd(_mm256_or_pd(above_all, below_all));
        if pass == 0 {
            return None;
        }
        let (monotonic, f0, f1) = first_step(&c);
        // `f0.abs() > tol && (f0 < 0.0) != (f1 < 0.0)` lane by lane.
        let zero = _mm256_setzero_pd();
        let changing = _mm256_movemask_pd(_mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GT_OQ>(abs(f0), _mm256_set1_pd(setup.tol)),
            _mm256_xor_pd(
                _mm256_cmp_pd::<_CMP_LT_OQ>(f0, zero),
                _mm256_cmp_pd::<_CMP_LT_OQ>(f1, zero),
            ),
        ));
        Some(Segments {
            pass,
            ta: PerLane::of(ta),
            tb: PerLane::of(tb),
            p0: p0.map(|v| PerLane::of(v)),
            q: q.map(|v| PerLane::of(v)),
            c: c.map(|v| PerLane::of(v)),
            tol: setup.tol,
            monotonic,
            changing,
            f0: PerLane::of(f0),
            f1: PerLane::of(f1),
        })
    }
}

/// The first step of [`Cubic::first_root`] on `[0, 1]` lane by lane, with the scalar code's
/// operations in its order (`Cubic::monotonic_on(0, 1)`, `Cubic::eval` at 0 and 1): the lanes
/// whose cubic `c` is monotonic there, and the values at 0 and 1.
#[target_feature(enable = "avx2")]
#[inline]
fn first_step(c: &[__m256d; 4]) -> (i32, __m256d, __m256d) {
    use std::arch::x86_64::{_mm256_add_pd as add, _mm256_mul_pd as mul, _mm256_set1_pd as set};
    let (zero, one) = (_mm256_setzero_pd(), set(1.0));
    let slope = |s: __m256d| {
        add(
            mul(add(mul(mul(set(3.0), c[3]), s), mul(set(2.0), c[2])), s),
            c[1],
        )
    };
    let eval = |s: __m256d| add(mul(add(mul(add(mul(c[3], s), c[2]), s), c[1]), s), c[0]);
    // `half` is `0.5 * (1 - 0)`, `a` is 0.
    let d0 = slope(zero);
    let d1 = add(
        d0,
        mul(
            set(0.5),
            add(mul(set(2.0), c[2]), mul(mul(set(6.0), c[3]), zero)),
        ),
    );
    let d2 = slope(one);
    let margin = mul(set(1e-9), add(add(abs(d0), abs(d1)), abs(d2)));
    let below = _mm256_xor_pd(margin, set(-0.0));
    let gt = |d: __m256d| _mm256_cmp_pd::<_CMP_GT_OQ>(d, margin);
    let lt = |d: __m256d| _mm256_cmp_pd::<_CMP_LT_OQ>(d, below);
    let rising = _mm256_and_pd(_mm256_and_pd(gt(d0), gt(d1)), gt(d2));
    let falling = _mm256_and_pd(_mm256_and_pd(lt(d0), lt(d1)), lt(d2));
    let monotonic = _mm256_movemask_pd(_mm256_or_pd(rising, falling));
    (monotonic, eval(zero), eval(one))
}

/// [`super::along_segment`] lane by lane: the cubic's coefficients, constant term first.
#[target_feature(enable = "avx2")]
#[inline]
fn along_segment(c: &[f64; 8], p0: [__m256d; 3], q: [__m256d; 3]) -> [__m256d; 4] {
    use std::arch::x86_64::{_mm256_add_pd as add, _mm256_mul_pd as mul, _mm256_sub_pd as sub};
    let (ux0, ux1) = (p0[0], q[0]);
    let edge = |i: usize| {
        let d = c[i + 1] - c[i];
        let dv = _mm256_set1_pd(d);
        (add(_mm256_set1_pd(c[i]), mul(dv, ux0)), mul(dv, ux1))
    };
    let (e00, e10, e01, e11) = (edge(0), edge(2), edge(4), edge(6));
    let (t0, t1) = (p0[1], q[1]);
    let face = |a: (__m256d, __m256d), b: (__m256d, __m256d)| {
        let d = (sub(b.0, a.0), sub(b.1, a.1));
        [
            add(a.0, mul(d.0, t0)),
            add(add(a.1, mul(d.1, t0)), mul(d.0, t1)),
            mul(d.1, t1),
        ]
    };
    let (f0, f1) = (face(e00, e10), face(e01, e11));
    let (uz0, uz1) = (p0[2], q[2]);
    let d = [sub(f1[0], f0[0]), sub(f1[1], f0[1]), sub(f1[2], f0[2])];
    [
        add(f0[0], mul(d[0], uz0)),
        add(add(f0[1], mul(d[1], uz0)), mul(d[0], uz1)),
        add(add(f0[2], mul(d[2], uz0)), mul(d[1], uz1)),
        mul(d[2], uz1),
    ]
}

#[cfg(test)]
mod tests {
    use super::super::{
        intersect_voxel, intersect_voxel_packet, voxel_occluders_packet, voxel_occludes,
    };
    use super::*;
    use crate::shade::sampling::Rng;

    /// Voxel `v` of a test: random corner values (one NaN corner in every 40th), on a grid of
    /// quarter units, of edge 1/4 or 1/16; returns it with its edge.
    fn random_voxel(rng: &mut Rng, v: usize) -> (Voxel, f64) {
        let lo = [0, 1, 2].map(|_| (rng.next_f64() * 8.0).floor() * 0.25);
        let size = if v.is_multiple_of(3) { 0.25 } else { 0.0625 };
        let mut voxel = Voxel {
            lo,
            hi: lo.map(|x| x + size),
            values: [0; 8].map(|_| (rng.next_f64() * 2.0 - 1.0) as f32),
            level: 0,
        };
        if v.is_multiple_of(40) {
            voxel.values[v % 8] = f32::NAN;
        }
        (voxel, size)
    }

    #[test]
    fn four_lanes_give_each_ray_its_single_ray_hit() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = Rng::for_pixel(7, 0, 0);
        let (mut hits, mut misses) = (0, 0);
        for v in 0..400 {
            let (voxel, size) = random_voxel(&mut rng, v);
            let lo = voxel.lo;
            // Rays from around the voxel towards points in or near it; some parallel to an
            // axis, some along a face, corner or edge, some short, some starting inside.
            let rays: Vec<GridRay> = (0..64)
                .map(|k| {
                    let target = [0, 1, 2].map(|a| lo[a] + (rng.next_f64() * 1.4 - 0.2) * size);
                    let mut o =
                        [0, 1, 2].map(|a| target[a] + (rng.next_f64() * 2.0 - 1.0) * size * 3.0);
                    if k % 11 == 0 {
                        o = [0, 1, 2].map(|a| lo[a] + rng.next_f64() * size);
                    }
                    let mut d = [0, 1, 2].map(|a| target[a] - o[a]);
                    match k % 9 {
                        0 => d[k % 3] = 0.0,
                        1 => d[(k + 1) % 3] = -0.0,
                        2 => {
                            o[0] = lo[0];
                            d[0] = 0.0;
                        }
                        3 => o = voxel.hi,
                        _ => {}
                    }
                    GridRay { o, d }
                })
                .collect();
            let recips: Vec<[f64; 3]> = rays.iter().map(GridRay::recip).collect();
            let tmin: Vec<f64> = (0..64)
                .map(|k| if k % 5 == 0 { 0.3 } else { 0.0 })
                .collect();
            let tmax: Vec<f64> = (0..64)
                .map(|k| if k % 4 == 0 { 0.8 } else { f64::INFINITY })
                .collect();
            for m in [
                u64::MAX,
                0x8000_0000_0000_0001,
                0b1110,
                0x00f0_0f00_1234_5678,
            ] {
                let mut got = vec![None; 64];
                let hit =
                    intersect_voxel_packet(&voxel, 0.1, &rays, &recips, m, &tmin, &tmax, &mut got);
                assert_eq!(hit & !m, 0, "voxel {v}: a ray outside the mask");
                for k in rays_of(m) {
                    let want = intersect_voxel(&voxel, 0.1, &rays[k], tmin[k], tmax[k]);
                    let got = if hit >> k & 1 == 1 { got[k] } else { None };
                    assert_eq!(got, want, "voxel {v} ray {k}");
                    if want.is_some() {
                        hits += 1;
                    } else {
                        misses += 1;
                    }
                }
            }
        }
        assert!(
            hits > 5_000 && misses > 5_000,
            "{hits} hits, {misses} misses"
        );
    }

    #[test]
    fn four_lanes_give_each_ray_its_single_ray_occlusion() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = Rng::for_pixel(11, 0, 0);
        let (mut hit, mut clear) = (0, 0);
        for v in 0..400 {
            let (voxel, size) = random_voxel(&mut rng, v);
            let lo = voxel.lo;
            // Shadow and occlusion rays: from points in or just off the voxel (a surface
            // point's neighbourhood), in all directions, some along an axis or a face, some
            // short, some starting past the voxel's entry.
            let rays: Vec<GridRay> = (0..64)
                .map(|k| {
                    let o = [0, 1, 2].map(|a| lo[a] + (rng.next_f64() * 1.6 - 0.3) * size);
                    let mut d = [0, 1, 2].map(|_| rng.next_f64() * 2.0 - 1.0);
                    match k % 7 {
                        0 => d[k % 3] = 0.0,
                        1 => d[(k + 1) % 3] = -0.0,
                        _ => {}
                    }
                    GridRay { o, d }
                })
                .collect();
            let recips: Vec<[f64; 3]> = rays.iter().map(GridRay::recip).collect();
            let tmin: Vec<f64> = (0..64)
                .map(|k| if k % 5 == 0 { 0.01 * size } else { 1e-9 })
                .collect();
            let tmax: Vec<f64> = (0..64)
                .map(|k| {
                    if k % 4 == 0 {
                        0.5 * size
                    } else {
                        f64::INFINITY
                    }
                })
                .collect();
            for m in [
                u64::MAX,
                0x8000_0000_0000_0001,
                0b1110,
                0x00f0_0f00_1234_5678,
                1 << (v % 64),
            ] {
                let got = voxel_occluders_packet(&voxel, 0.1, &rays, &recips, m, &tmin, &tmax);
                assert_eq!(got & !m, 0, "voxel {v}: a ray outside the mask");
                for k in rays_of(m) {
                    let want = voxel_occludes(&voxel, 0.1, &rays[k], tmin[k], tmax[k]);
                    assert_eq!(got >> k & 1 == 1, want, "voxel {v} ray {k}");
                    if want {
                        hit += 1;
                    } else {
                        clear += 1;
                    }
                }
            }
        }
        assert!(
            hit > 2_000 && clear > 5_000,
            "{hit} occluded, {clear} clear"
        );
    }
}
