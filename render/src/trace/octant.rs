//! Exact intersection of a ray with the isosurface of one trilinear voxel.
//!
//! Along the ray the trilinear interpolant is a cubic in the ray parameter. The segment inside
//! the voxel is mapped to `s in [0, 1]` in the voxel's local coordinates (so tiny voxels far from
//! the origin behave like the unit cube), the cubic's coefficients are built by multiplying the
//! three linear factors, and [`Cubic::first_root`] isolates the first root with the derivative's
//! roots and refines it.

use crate::bvh::packet::{rays_where, Mask};
use crate::trace::cubic::Cubic;
use crate::trace::ray::{larger, smaller, GridRay};
use crate::trace::source::Voxel;

#[cfg(target_arch = "x86_64")]
mod x4;

/// Relative widening of each segment at both ends, so that a ray passing exactly through a shared
/// face, edge or corner is covered by the voxels on both sides despite round-off.
const SEGMENT_WIDEN: f64 = 1e-9;
/// Values within this fraction of the voxel's value span around the isovalue count as on the
/// surface (round-off of the `f64` evaluation is ~1e-16 of that span).
const SPAN_TOL: f64 = 1e-9;
/// Values within this many `f32` ulps of the isovalue's magnitude count as on the surface, so that
/// vertex values that two voxels computed separately and rounded to `f32` leave no crack.
const ULP_TOL: f64 = 4.0 * f32::EPSILON as f64;

/// Where a ray meets the isosurface inside a voxel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelHit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// Voxel-local coordinates of the hit (within `[0, 1]^3` up to the segment widening).
    pub local: [f64; 3],
}

/// A linear polynomial `a + b s`.
#[derive(Clone, Copy)]
struct Lin(f64, f64);

/// The first hit of `ray` with the surface `value == iso` of `voxel` with `t` in `[tmin, tmax]`.
#[inline]
pub fn intersect_voxel(
    voxel: &Voxel,
    iso: f32,
    ray: &GridRay,
    tmin: f64,
    tmax: f64,
) -> Option<VoxelHit> {
    Segment::new(voxel, iso, ray, tmin, tmax)?.first_hit()
}

/// Declares the public test `$name`, which runs `$test` (inlined into each compilation) compiled
/// for AVX2 where the CPU has it, else a plain compilation kept out of line, so that the choice
/// inlines into its callers without the test. The AVX2 compilation makes the same `f64`
/// operations in the same order (no fused multiply-adds: Rust never contracts), so the same
/// answers, in fewer instructions (three-operand forms spare the register copies SSE needs).
macro_rules! avx2_or_plain {
    ($(#[$doc:meta])* pub fn $name:ident($($arg:ident: $ty:ty),*) -> $ret:ty = $test:ident;) => {
        $(#[$doc])*
        #[inline]
        pub fn $name($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) -> $ret {
                    $test($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2, checked just above.
                    return unsafe { avx2($($arg),*) };
                }
            }
            #[cfg_attr(target_arch = "x86_64", inline(never))]
            fn plain($($arg: $ty),*) -> $ret {
                $test($($arg),*)
            }
            plain($($arg),*)
        }
    };
    ($(#[$doc:meta])* pub fn $name:ident($($arg:ident: $ty:ty),*) -> $ret:ty = $test:ident,
        avx2: $avx2:ident;) => {
        $(#[$doc])*
        #[inline]
        pub fn $name($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2, checked just above.
                return unsafe { $avx2($($arg),*) };
            }
            #[cfg_attr(target_arch = "x86_64", inline(never))]
            fn plain($($arg: $ty),*) -> $ret {
                $test($($arg),*)
            }
            plain($($arg),*)
        }

        #[doc = concat!("[`", stringify!($name), "`]'s AVX2 compilation, for a caller compiled for")]
        /// AVX2 itself (which has no need of the CPU's test).
        ///
        /// # Safety
        /// The CPU must have AVX2.
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        #[inline(never)]
        pub fn $avx2($($arg: $ty),*) -> $ret {
            $test($($arg),*)
        }
    };
}

avx2_or_plain! {
    /// [`intersect_voxel`] given `clip`, the interval [`GridRay::clip`] gives `ray` in the
    /// voxel's box for the interval `t` (for a caller that clipped it before the voxel's values
    /// were known): the same hit.
    pub fn intersect_voxel_clipped(
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        t: (f64, f64),
        clip: (f64, f64)
    ) -> Option<VoxelHit> = hit_clipped;
}

/// [`intersect_voxel_clipped`]'s test.
#[inline(always)]
fn hit_clipped(
    voxel: &Voxel,
    iso: f32,
    ray: &GridRay,
    t: (f64, f64),
    clip: (f64, f64),
) -> Option<VoxelHit> {
    let setup = VoxelSetup::new(voxel, iso)?;
    Segment::in_box_inlined(voxel, &setup, ray, t, clip)?.first_hit()
}

/// True exactly when [`intersect_voxel`] finds a hit: the any-hit test, which skips refining
/// where the hit is.
#[inline]
pub fn voxel_occludes(voxel: &Voxel, iso: f32, ray: &GridRay, tmin: f64, tmax: f64) -> bool {
    voxel_occludes_with(voxel, iso, ray, &ray.recip(), tmin, tmax)
}

avx2_or_plain! {
    /// [`voxel_occludes`] given `recip`, the ray's reciprocal direction ([`GridRay::recip`]),
    /// for a ray that keeps it for all its candidates: the same answer without the three
    /// divisions.
    pub fn voxel_occludes_with(
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        recip: &[f64; 3],
        tmin: f64,
        tmax: f64
    ) -> bool = occludes_with, avx2: voxel_occludes_with_avx2;
}

/// [`voxel_occludes_with`]'s test.
#[inline(always)]
fn occludes_with(
    voxel: &Voxel,
    iso: f32,
    ray: &GridRay,
    recip: &[f64; 3],
    tmin: f64,
    tmax: f64,
) -> bool {
    ray.clip_with(recip, voxel.lo, voxel.hi, tmin, tmax)
        .is_some_and(|t| occludes_clipped(voxel, iso, ray, (tmin, tmax), t))
}

avx2_or_plain! {
    /// [`voxel_occludes_with`] given `clip`, the interval [`GridRay::clip_with`] gives `ray` in
    /// the voxel's box for the interval `t` (for a caller that clipped it before the voxel's
    /// values were known): the same answer.
    pub fn voxel_occludes_clipped(
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        t: (f64, f64),
        clip: (f64, f64)
    ) -> bool = occludes_clipped, avx2: voxel_occludes_clipped_avx2;
}

/// [`voxel_occludes_clipped`]'s test.
#[inline(always)]
fn occludes_clipped(
    voxel: &Voxel,
    iso: f32,
    ray: &GridRay,
    t: (f64, f64),
    clip: (f64, f64),
) -> bool {
    VoxelSetup::new(voxel, iso)
        .and_then(|setup| Segment::in_box_inlined(voxel, &setup, ray, t, clip))
        .is_some_and(|seg| seg.cubic.has_root(0.0, 1.0, seg.tol))
}

/// [`voxel_occludes`] for the rays `m` of a packet, each with its reciprocal direction
/// ([`GridRay::recip`]) and its own `tmin` and `tmax`: the rays of `m` for which it is true (the
/// voxel's set-up is computed once, and with AVX2 the segments are built four rays at a time).
#[inline]
pub fn voxel_occluders_packet(
    voxel: &Voxel,
    iso: f32,
    rays: &[GridRay],
    recips: &[[f64; 3]],
    m: Mask,
    tmin: &[f64],
    tmax: &[f64],
) -> Mask {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { x4::occluders(voxel, iso, rays, recips, m, tmin, tmax) };
    }
    let Some(setup) = VoxelSetup::new(voxel, iso) else {
        return 0;
    };
    rays_where(m, |k| {
        let (tmin, tmax) = (tmin[k], tmax[k]);
        rays[k]
            .clip_with(&recips[k], voxel.lo, voxel.hi, tmin, tmax)
            .and_then(|t| Segment::in_box(voxel, &setup, &rays[k], (tmin, tmax), t))
            .is_some_and(|seg| seg.cubic.has_root(0.0, 1.0, seg.tol))
    })
}

/// [`voxel_occluders_packet`]'s AVX2 compilation, for a caller compiled for AVX2 itself.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub fn voxel_occluders_packet_avx2(
    voxel: &Voxel,
    iso: f32,
    rays: &[GridRay],
    recips: &[[f64; 3]],
    m: Mask,
    tmin: &[f64],
    tmax: &[f64],
) -> Mask {
    x4::occluders(voxel, iso, rays, recips, m, tmin, tmax)
}

/// A ray's segment inside a voxel, widened, as the cubic of the interpolant minus the isovalue
/// in `s in [0, 1]`.
struct Segment {
    /// Ray parameters of the segment's ends.
    ta: f64,
    tb: f64,
    /// Voxel-local coordinates of the segment's start, and its extent.
    p0: [f64; 3],
    q: [f64; 3],
    /// The interpolant minus the isovalue along the segment.
    cubic: Cubic,
    /// Values within `tol` of zero count as on the surface.
    tol: f64,
}

/// What the intersection with a voxel needs of the voxel and the isovalue alone, whatever the
/// ray: computed once for all the rays of a packet that reach the voxel.
pub struct VoxelSetup {
    /// The corner values less the isovalue.
    c: [f64; 8],
    /// Values within `tol` of zero count as on the surface.
    tol: f64,
}

impl VoxelSetup {
    /// The set-up of `voxel` for `iso`; `None` when the voxel's values exclude `iso`.
    #[inline(always)]
    pub fn new(voxel: &Voxel, iso: f32) -> Option<VoxelSetup> {
        let (vmin, vmax) = voxel.range();
        if vmin > iso || vmax < iso {
            return None;
        }
        let iso = f64::from(iso);
        let c = voxel.values.map(|v| f64::from(v) - iso);
        // `v - iso` and `|v|` are largest in magnitude at the smallest or largest value (both
        // are monotonic in `v`, rounding included), so these are the maxima over all corners.
        let (lo, hi) = (f64::from(vmin), f64::from(vmax));
        let span = larger((hi - iso).abs(), (lo - iso).abs());
        let magnitude = larger(larger(iso.abs(), hi.abs()), lo.abs());
        let tol = smaller(larger(SPAN_TOL * span, ULP_TOL * magnitude), 0.5 * span);
        Some(VoxelSetup { c, tol })
    }
}

/// [`intersect_voxel`] for the rays `m` of a packet, each with its reciprocal direction
/// ([`GridRay::recip`]) and its own `tmin` and `tmax`: the rays of `m` that [`intersect_voxel`]
/// gives a hit, each that hit in `hits[k]` (the voxel's set-up is computed once; the entries of
/// the other rays are left unspecified).
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn intersect_voxel_packet(
    voxel: &Voxel,
    iso: f32,
    rays: &[GridRay],
    recips: &[[f64; 3]],
    m: Mask,
    tmin: &[f64],
    tmax: &[f64],
    hits: &mut [Option<VoxelHit>],
) -> Mask {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { x4::hits(voxel, iso, rays, recips, m, tmin, tmax, hits) };
    }
    let Some(setup) = VoxelSetup::new(voxel, iso) else {
        return 0;
    };
    rays_where(m, |k| {
        let (tmin, tmax) = (tmin[k], tmax[k]);
        hits[k] = rays[k]
            .clip_with(&recips[k], voxel.lo, voxel.hi, tmin, tmax)
            .and_then(|t| Segment::in_box(voxel, &setup, &rays[k], (tmin, tmax), t))
            .and_then(|seg| seg.first_hit());
        hits[k].is_some()
    })
}

impl Segment {
    /// The segment of `ray` in `voxel` within `[tmin, tmax]`; `None` when there is none, when
    /// the voxel's values exclude `iso`, or when the cubic provably stays clear of zero.
    #[inline]
    fn new(voxel: &Voxel, iso: f32, ray: &GridRay, tmin: f64, tmax: f64) -> Option<Segment> {
        // The box first: most candidates it rejects (their leaf's box met the ray, or they lie
        // behind a hit found already), while the BVH holds only voxels whose range has `iso`.
        let (t_in, t_out) = ray.clip(voxel.lo, voxel.hi, tmin, tmax)?;
        let setup = VoxelSetup::new(voxel, iso)?;
        Self::in_box(voxel, &setup, ray, (tmin, tmax), (t_in, t_out))
    }

    /// The segment of `ray` in `voxel` within `[tmin, tmax]`, given the ray's interval
    /// `[t_in, t_out]` in the voxel's box.
    #[inline]
    fn in_box(
        voxel: &Voxel,
        setup: &VoxelSetup,
        ray: &GridRay,
        t: (f64, f64),
        clip: (f64, f64),
    ) -> Option<Segment> {
        Self::in_box_inlined(voxel, setup, ray, t, clip)
    }

    /// [`Self::in_box`], inlined into its caller.
    #[inline(always)]
    fn in_box_inlined(
        voxel: &Voxel,
        setup: &VoxelSetup,
        ray: &GridRay,
        (tmin, tmax): (f64, f64),
        (t_in, t_out): (f64, f64),
    ) -> Option<Segment> {
        let widen =
            SEGMENT_WIDEN * (t_out - t_in) + 8.0 * f64::EPSILON * larger(t_in.abs(), t_out.abs());
        let ta = larger(tmin, t_in - widen);
        let tb = smaller(tmax, t_out + widen);
        let w = [0, 1, 2].map(|a| voxel.hi[a] - voxel.lo[a]);
        let local = |t: f64| [0, 1, 2].map(|a| ((ray.o[a] - voxel.lo[a]) + t * ray.d[a]) / w[a]);
        let p0 = local(ta);
        let p1 = local(tb);
        let q = [0, 1, 2].map(|a| p1[a] - p0[a]);
        let tol = setup.tol;
        let cubic = along_segment(&setup.c, p0, q);
        if cubic.clear_of_zero_on_unit(tol) {
            return None;
        }
        Some(Segment {
            ta,
            tb,
            p0,
            q,
            cubic,
            tol,
        })
    }

    /// The segment's first hit with the surface.
    #[inline]
    fn first_hit(&self) -> Option<VoxelHit> {
        let s = self.cubic.first_root(0.0, 1.0, self.tol)?;
        Some(Self::hit_at(s, (self.ta, self.tb), self.p0, self.q))
    }

    /// The point at `s` of the segment from ray parameter `ta` to `tb`, which starts at
    /// voxel-local `p0` and extends `q`.
    #[inline(always)]
    fn hit_at(s: f64, (ta, tb): (f64, f64), p0: [f64; 3], q: [f64; 3]) -> VoxelHit {
        VoxelHit {
            t: ta + s * (tb - ta),
            local: [0, 1, 2].map(|a| p0[a] + s * q[a]),
        }
    }
}

/// The reciprocals of the extents `w` when each is a power of two: then `x * r` is `x / w` bit
/// for bit (both round the same real number, as the reciprocal is exact), and a multiplication
/// is several times cheaper than a division. AMR voxels inside one level have such extents. For
/// the packet test, which computes them once per voxel for all its rays; a single ray's test
/// divides.
#[inline]
fn exact_recips(w: [f64; 3]) -> Option<[f64; 3]> {
    const MANTISSA: u64 = (1 << 52) - 1;
    // `2^e` has biased exponent `E = e + 1023` and `2^-e` has `2046 - E`: no division needed.
    const FLIP: u64 = 2046 << 52;
    let bits = w.map(f64::to_bits);
    // No mantissa bits, sign clear, `E` in 1..=2045: a positive normal power of two whose
    // reciprocal is normal (zero, the subnormals, the largest power, infinity and NaN fail).
    let power_of_two = |b: u64| (b & MANTISSA == 0) & (1 << 52..=2045 << 52).contains(&b);
    (power_of_two(bits[0]) & power_of_two(bits[1]) & power_of_two(bits[2]))
        .then(|| bits.map(|b| f64::from_bits(FLIP - b)))
}

/// The trilinear interpolant of corner values `c` along `u(s) = p0 + s q`, as a cubic in `s`.
pub fn along_segment(c: &[f64; 8], p0: [f64; 3], q: [f64; 3]) -> Cubic {
    let ux = Lin(p0[0], q[0]);
    let edge = |i: usize| {
        let d = c[i + 1] - c[i];
        Lin(c[i] + d * ux.0, d * ux.1)
    };
    let (e00, e10, e01, e11) = (edge(0), edge(2), edge(4), edge(6));
    let face = |a: Lin, b: Lin| lerp_lin(a, b, Lin(p0[1], q[1]));
    let (f0, f1) = (face(e00, e10), face(e01, e11));
    let uz = [p0[2], q[2]];
    let d = [f1[0] - f0[0], f1[1] - f0[1], f1[2] - f0[2]];
    Cubic {
        c: [
            f0[0] + d[0] * uz[0],
            f0[1] + d[1] * uz[0] + d[0] * uz[1],
            f0[2] + d[2] * uz[0] + d[1] * uz[1],
            d[2] * uz[1],
        ],
    }
}

/// `a + (b - a) t` for linear `a`, `b`, `t`: a quadratic, constant term first.
fn lerp_lin(a: Lin, b: Lin, t: Lin) -> [f64; 3] {
    let d = Lin(b.0 - a.0, b.1 - a.1);
    [a.0 + d.0 * t.0, a.1 + d.1 * t.0 + d.0 * t.1, d.1 * t.1]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn voxel(values: [f32; 8]) -> Voxel {
        Voxel {
            lo: [0.0; 3],
            hi: [1.0; 3],
            values,
            level: 0,
        }
    }

    #[test]
    fn cubic_matches_the_trilinear_along_the_segment() {
        let v = voxel([0.1, -0.7, 0.3, 0.9, -0.2, 0.4, 0.8, -0.5]);
        let c = v.values.map(f64::from);
        let (p0, q) = ([0.1, 0.9, 0.3], [0.7, -0.8, 0.5]);
        let cubic = along_segment(&c, p0, q);
        for i in 0..=10 {
            let s = i as f64 / 10.0;
            let u = [0, 1, 2].map(|a| p0[a] + s * q[a]);
            assert!((cubic.eval(s) - v.eval_local(u)).abs() < 1e-14);
        }
    }

    #[test]
    fn the_clipped_test_gives_the_hit_of_the_whole_test() {
        let mut state = 0x5851_f42d_4c95_7f2du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut hits, mut misses, mut outside) = (0, 0, 0);
        for i in 0..20_000 {
            let lo = [0, 1, 2].map(|_| (next() * 8.0).floor() * 0.25);
            let size = if i % 3 == 0 { 0.25 } else { 0.0625 };
            let v = Voxel {
                lo,
                hi: lo.map(|x| x + size),
                values: [0; 8].map(|_| (next() * 2.0 - 1.0) as f32),
                level: 0,
            };
            let target = [0, 1, 2].map(|a| lo[a] + (next() * 1.4 - 0.2) * size);
            let o = [0, 1, 2].map(|a| target[a] + (next() * 2.0 - 1.0) * size * 3.0);
            let mut d = [0, 1, 2].map(|a| target[a] - o[a]);
            if i % 7 == 0 {
                d[i % 3] = 0.0;
            }
            let ray = GridRay { o, d };
            let (tmin, tmax) = if i % 5 == 0 {
                (0.3, 0.8)
            } else {
                (0.0, f64::INFINITY)
            };
            let want = intersect_voxel(&v, 0.1, &ray, tmin, tmax);
            match ray.clip_with(&ray.recip(), v.lo, v.hi, tmin, tmax) {
                Some(clip) => {
                    let got = intersect_voxel_clipped(&v, 0.1, &ray, (tmin, tmax), clip);
                    assert_eq!(got, want, "{i}");
                    if want.is_some() {
                        hits += 1;
                    } else {
                        misses += 1;
                    }
                }
                None => {
                    assert_eq!(want, None, "{i}: a hit outside the box");
                    outside += 1;
                }
            }
        }
        assert!(
            hits > 1_000 && misses > 1_000 && outside > 1_000,
            "{hits} {misses} {outside}"
        );
    }

    #[test]
    fn exact_reciprocals_only_of_powers_of_two() {
        for e in -1022..=1022 {
            let x = 2f64.powi(e);
            assert_eq!(
                exact_recips([x, 1.0, 0.5]),
                Some([1.0 / x, 1.0, 2.0]),
                "{e}"
            );
        }
        for x in [
            0.0,
            -0.0,
            -1.0,
            3.0,
            0.75,
            f64::MAX,
            2f64.powi(1023),
            f64::MIN_POSITIVE / 2.0,
            f64::INFINITY,
            f64::NAN,
        ] {
            assert_eq!(exact_recips([1.0, x, 1.0]), None, "{x}");
        }
    }

    #[test]
    fn a_nan_corner_gives_no_hit() {
        let ray = GridRay {
            o: [-1.0, 0.3, 0.6],
            d: [1.0, 0.1, -0.05],
        };
        for i in 0..8 {
            let mut values = [0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0];
            values[i] = f32::NAN;
            let v = voxel(values);
            assert!(
                intersect_voxel(&v, 0.5, &ray, 0.0, f64::INFINITY).is_none(),
                "{i}"
            );
            assert!(!voxel_occludes(&v, 0.5, &ray, 0.0, f64::INFINITY), "{i}");
        }
    }

    #[test]
    fn axis_parallel_and_degenerate_rays() {
        let v = voxel([0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0]);
        let ray = GridRay {
            o: [-1.0, 0.5, 0.5],
            d: [1.0, 0.0, 0.0],
        };
        let h = intersect_voxel(&v, 0.25, &ray, 0.0, f64::INFINITY).unwrap();
        assert!((h.t - 1.25).abs() < 1e-12);
        // Parallel to the surface x = 0.25: never crosses.
        let ray = GridRay {
            o: [0.5, -1.0, 0.5],
            d: [0.0, 1.0, 0.0],
        };
        assert!(intersect_voxel(&v, 0.25, &ray, 0.0, f64::INFINITY).is_none());
        // Lying in the surface: hits where it enters.
        let ray = GridRay {
            o: [0.25, -1.0, 0.5],
            d: [0.0, 1.0, 0.0],
        };
        let h = intersect_voxel(&v, 0.25, &ray, 0.0, f64::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        // Origin inside the voxel.
        let ray = GridRay {
            o: [0.9, 0.5, 0.5],
            d: [-1.0, 0.0, 0.0],
        };
        let h = intersect_voxel(&v, 0.25, &ray, 0.0, f64::INFINITY).unwrap();
        assert!((h.t - 0.65).abs() < 1e-12);
        // Touching only the corner (1, 1, 1), where the value equals the isovalue.
        let ray = GridRay {
            o: [2.0, 2.0, 0.0],
            d: [-1.0, -1.0, 1.0],
        };
        let h = intersect_voxel(&v, 1.0, &ray, 0.0, f64::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
    }
}
