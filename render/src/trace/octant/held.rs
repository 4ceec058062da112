//! Single-ray candidates of an any-hit walk, each in its own voxel, held back until four fill
//! the AVX2 lanes of one segment test.

use super::VoxelSetup;
use crate::bvh::packet::Mask;
use crate::trace::ray::GridRay;
use crate::trace::source::Voxel;

/// How many candidates are tested together: one per lane.
const LANES: usize = 4;

/// One quantity of the candidates held, lane `i` for candidate `i`, aligned for a register's
/// load.
#[derive(Clone, Copy, Default)]
#[repr(C, align(32))]
struct Lane([f64; LANES]);

/// Up to four candidates of an any-hit walk that one ray alone reached, each its ray clipped to
/// its voxel's box and its voxel's set-up done, as [`super::Segment::new`] begins; the rest of
/// the test ([`super::Segment::in_box`], the hull, the root) is done for all four at once. An
/// any-hit answer does not depend on when a candidate is tested: a ray whose test is held back
/// only walks on to more candidates until it is, and is occluded exactly when one of the
/// candidates its own walk gives it is.
#[derive(Default)]
pub struct HeldSegments {
    tmin: Lane,
    tmax: Lane,
    /// The ray's interval in the voxel's box.
    t0: Lane,
    t1: Lane,
    /// The ray's origin less the voxel's lower corner, and its direction.
    rel: [Lane; 3],
    d: [Lane; 3],
    /// The voxel's extent.
    w: [Lane; 3],
    /// The voxel's set-up.
    c: [Lane; 8],
    tol: Lane,
    /// Each candidate's ray.
    rays: [usize; LANES],
    /// The rays of the candidates held, a bit each.
    held_rays: Mask,
    len: usize,
}

impl HeldSegments {
    /// Holds the candidate of ray `k` (`ray`, with its reciprocal direction `recip`, over
    /// `[tmin, tmax]`) in `voxel`, unless its box or its values already rule it out; true when
    /// the lanes are full.
    #[inline]
    pub fn hold(
        &mut self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        recip: &[f64; 3],
        (tmin, tmax): (f64, f64),
        k: usize,
    ) -> bool {
        let Some((t0, t1)) = ray.clip_with(recip, voxel.lo, voxel.hi, tmin, tmax) else {
            return false;
        };
        let Some(setup) = VoxelSetup::new(voxel, iso) else {
            return false;
        };
        let i = self.len;
        self.tmin.0[i] = tmin;
        self.tmax.0[i] = tmax;
        self.t0.0[i] = t0;
        self.t1.0[i] = t1;
        for a in 0..3 {
            self.rel[a].0[i] = ray.o[a] - voxel.lo[a];
            self.d[a].0[i] = ray.d[a];
            self.w[a].0[i] = voxel.hi[a] - voxel.lo[a];
        }
        for j in 0..8 {
            self.c[j].0[i] = setup.c[j];
        }
        self.tol.0[i] = setup.tol;
        self.rays[i] = k;
        self.held_rays |= 1 << k;
        self.len += 1;
        self.len == LANES
    }

    /// True when a candidate of ray `k` is held.
    #[inline]
    pub fn holds(&self, k: usize) -> bool {
        self.held_rays >> k & 1 != 0
    }

    /// The rays of the candidates held that [`super::voxel_occludes`] finds occluded; none is
    /// held after.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub unsafe fn occluded(&mut self) -> Mask {
        use super::x4::{along_segment, clear_of_zero, widened, Segments};
        use std::arch::x86_64::*;
        let n = std::mem::take(&mut self.len);
        if n == 0 {
            return 0;
        }
        self.held_rays = 0;
        // SAFETY: a `Lane` is four `f64`s aligned to 32 bytes.
        let load = |x: &Lane| unsafe { _mm256_load_pd(x.0.as_ptr()) };
        // `Segment::in_box` lane by lane; the lanes past `n` hold stale values, and no lane's
        // answer depends on another's.
        let (ta, tb) = widened(
            load(&self.tmin),
            load(&self.tmax),
            load(&self.t0),
            load(&self.t1),
        );
        let (mut p0, mut q) = ([_mm256_setzero_pd(); 3], [_mm256_setzero_pd(); 3]);
        for a in 0..3 {
            let (rel, d, w) = (load(&self.rel[a]), load(&self.d[a]), load(&self.w[a]));
            let local = |t: __m256d| _mm256_div_pd(_mm256_add_pd(rel, _mm256_mul_pd(t, d)), w);
            p0[a] = local(ta);
            q[a] = _mm256_sub_pd(local(tb), p0[a]);
        }
        let mut corners = [_mm256_setzero_pd(); 8];
        for (v, x) in corners.iter_mut().zip(&self.c) {
            *v = load(x);
        }
        let c = along_segment(&corners, p0, q);
        let tol = load(&self.tol);
        let pass = ((1 << n) - 1) & !clear_of_zero(&c, tol);
        if pass == 0 {
            return 0;
        }
        let segs = Segments::new(pass, (ta, tb), (p0, q), c, tol);
        (0..n)
            .filter(|&i| segs.has_root(i))
            .fold(0, |out, i| out | 1 << self.rays[i])
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::super::voxel_occludes;
    use super::*;
    use crate::shade::sampling::Rng;

    /// A voxel of edge 1/4, 1/16 or 3/16 (not a power of two) on a grid of quarter units, with
    /// random corner values (one NaN corner in every 40th), and a shadow or occlusion ray from in
    /// or near it (some along an axis, some short, some from past the voxel's entry) with its
    /// interval.
    fn candidate(rng: &mut Rng, v: usize) -> (Voxel, GridRay, (f64, f64)) {
        let lo = [0, 1, 2].map(|_| (rng.next_f64() * 8.0).floor() * 0.25);
        let size = [0.25, 0.0625, 0.1875][v % 3];
        let mut voxel = Voxel {
            lo,
            hi: lo.map(|x| x + size),
            values: [0; 8].map(|_| (rng.next_f64() * 2.0 - 1.0) as f32),
            level: 0,
        };
        if v % 40 == 0 {
            voxel.values[v % 8] = f32::NAN;
        }
        let o = [0, 1, 2].map(|a| lo[a] + (rng.next_f64() * 1.6 - 0.3) * size);
        let mut d = [0, 1, 2].map(|_| rng.next_f64() * 2.0 - 1.0);
        match v % 7 {
            0 => d[v % 3] = 0.0,
            1 => d[(v + 1) % 3] = -0.0,
            _ => {}
        }
        let tmin = if v % 5 == 0 { 0.01 * size } else { 1e-9 };
        let tmax = if v % 4 == 0 {
            0.5 * size
        } else {
            f64::INFINITY
        };
        (voxel, GridRay { o, d }, (tmin, tmax))
    }

    #[test]
    fn held_candidates_are_occluded_as_each_alone() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = Rng::for_pixel(5, 0, 0);
        let (mut occluded, mut clear) = (0, 0);
        let mut held = HeldSegments::default();
        for group in 0..2_000 {
            // One to six candidates, each of its own ray `i`; the lanes are tested when full and
            // at the group's end.
            let (mut want, mut got): (Mask, Mask) = (0, 0);
            for i in 0..1 + group % 6 {
                let (voxel, ray, (tmin, tmax)) = candidate(&mut rng, 6 * group + i);
                if voxel_occludes(&voxel, 0.1, &ray, tmin, tmax) {
                    want |= 1 << i;
                    occluded += 1;
                } else {
                    clear += 1;
                }
                if held.hold(&voxel, 0.1, &ray, &ray.recip(), (tmin, tmax), i) {
                    // SAFETY: the CPU has AVX2, checked above.
                    got |= unsafe { held.occluded() };
                }
            }
            // SAFETY: as above.
            got |= unsafe { held.occluded() };
            assert_eq!(got, want, "group {group}");
        }
        assert!(
            occluded > 300 && clear > 1_000,
            "{occluded} occluded, {clear} clear"
        );
    }
}
