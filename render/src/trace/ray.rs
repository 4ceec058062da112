//! Rays in grid coordinates: the exact `f64` ray the intersections use, and the `f32` ray the
//! BVH is traversed with, re-based at the domain's entry point so that it stays precise.

use glam::Vec3A;
use obvhs::ray::Ray;

use crate::bvh::packet::Mask;
use crate::trace::source::GridFrame;

#[cfg(target_arch = "x86_64")]
mod x4;

/// Grid units by which the `f32` BVH ray starts before the domain.
pub const BVH_LEAD: f64 = 1.0;

/// The `f32` ray a BVH is traversed with, and the map from its parameter to the exact ray's:
/// `t = t_off + t32 / scale`.
#[derive(Clone, Copy, Debug)]
pub struct BvhRay {
    /// The `f32` ray (unit grid-space direction).
    pub ray: Ray,
    /// Exact-ray parameter at `t32 = 0`.
    pub t_off: f64,
    /// Grid length of the exact ray's direction.
    pub scale: f64,
}

/// A ray `o + t d` in grid coordinates. When `d` is a unit world direction mapped to the grid,
/// `t` is the distance in world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridRay {
    /// Origin, grid coordinates.
    pub o: [f64; 3],
    /// Direction, grid units per unit of `t`.
    pub d: [f64; 3],
}

impl GridRay {
    /// The grid-space ray for a world-space ray `origin + t dir`.
    pub fn from_world(frame: &GridFrame, origin: [f64; 3], dir: [f64; 3]) -> GridRay {
        GridRay {
            o: frame.to_grid(origin),
            d: frame.to_grid_dir(dir),
        }
    }

    /// Point at parameter `t`.
    pub fn at(&self, t: f64) -> [f64; 3] {
        [0, 1, 2].map(|a| self.o[a] + t * self.d[a])
    }

    /// The parameter interval where the ray lies in the closed box `[lo, hi]`, clipped to
    /// `[tmin, tmax]`; `None` when empty. A zero-length interval (a ray touching an edge or a
    /// corner) is kept.
    #[inline]
    pub fn clip(&self, lo: [f64; 3], hi: [f64; 3], tmin: f64, tmax: f64) -> Option<(f64, f64)> {
        self.clip_with(&self.recip(), lo, hi, tmin, tmax)
    }

    /// The reciprocals of the direction's components, for [`GridRay::clip_with`].
    #[inline]
    pub fn recip(&self) -> [f64; 3] {
        self.d.map(|x| 1.0 / x)
    }

    /// [`GridRay::clip`] with the reciprocals of the direction's components given (`recip`):
    /// the same interval, without the three divisions, for a ray clipped to many boxes.
    #[inline]
    pub fn clip_with(
        &self,
        recip: &[f64; 3],
        lo: [f64; 3],
        hi: [f64; 3],
        tmin: f64,
        tmax: f64,
    ) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (tmin, tmax);
        for a in 0..3 {
            if self.d[a] == 0.0 {
                if self.o[a] < lo[a] || self.o[a] > hi[a] {
                    return None;
                }
            } else {
                let inv = recip[a];
                let (mut ta, mut tb) = ((lo[a] - self.o[a]) * inv, (hi[a] - self.o[a]) * inv);
                if ta > tb {
                    std::mem::swap(&mut ta, &mut tb);
                }
                t0 = larger(t0, ta);
                t1 = smaller(t1, tb);
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// The `f32` ray for BVH traversal over `[tmin, tmax]`, and the map back to this ray's `t`.
    ///
    /// The `f32` ray has a unit grid-space direction and starts [`BVH_LEAD`] grid units before
    /// the point where this ray enters the domain grown by `pad`: its parameter is then in grid
    /// units and at least `BVH_LEAD` inside the domain, far above the absolute epsilon obvhs
    /// clips near-hits with, whatever the world scale. `t = t_off + t32 / scale`.
    /// `None` if the ray misses the domain.
    pub fn bvh_ray(&self, frame: &GridFrame, pad: f64, tmin: f64, tmax: f64) -> Option<BvhRay> {
        self.bvh_ray_with(&self.recip(), frame, pad, tmin, tmax)
    }

    /// [`GridRay::bvh_ray`] with the reciprocals of the direction's components given (`recip`,
    /// [`GridRay::recip`]), for a ray that keeps them for its candidates' clips.
    pub fn bvh_ray_with(
        &self,
        recip: &[f64; 3],
        frame: &GridFrame,
        pad: f64,
        tmin: f64,
        tmax: f64,
    ) -> Option<BvhRay> {
        self.bvh_ray_led(recip, frame, pad, tmin, tmax, BVH_LEAD)
    }

    /// [`GridRay::bvh_ray_with`] for a query that needs no voxel lying wholly before `tmin`:
    /// the `f32` ray starts only [`any_hit_lead`] grid units before its first point, so the
    /// walk, which enters no box the `f32` ray leaves before the node test's entry bound
    /// [`crate::bvh::T_MIN`], skips the voxels behind the start (those a shadow ray leaves
    /// behind on its own surface). It still reaches every voxel the exact ray meets from `tmin`
    /// on: where the exact ray meets a voxel the `f32` ray is within far less than `pad` of it,
    /// so it leaves the padded box at least about `pad` later, past the entry bound.
    pub fn bvh_ray_ahead(
        &self,
        frame: &GridFrame,
        pad: f64,
        tmin: f64,
        tmax: f64,
    ) -> Option<BvhRay> {
        self.bvh_ray_ahead_with(&self.recip(), frame, pad, tmin, tmax)
    }

    /// [`GridRay::bvh_ray_ahead`] with the reciprocals of the direction's components given
    /// (`recip`, [`GridRay::recip`]), for a ray that keeps them for its candidates' clips.
    pub fn bvh_ray_ahead_with(
        &self,
        recip: &[f64; 3],
        frame: &GridFrame,
        pad: f64,
        tmin: f64,
        tmax: f64,
    ) -> Option<BvhRay> {
        self.bvh_ray_led(recip, frame, pad, tmin, tmax, any_hit_lead(pad))
    }

    /// [`GridRay::bvh_ray_with`] with the `f32` ray starting `lead` grid units before the
    /// exact ray's first point in the padded domain.
    fn bvh_ray_led(
        &self,
        recip: &[f64; 3],
        frame: &GridFrame,
        pad: f64,
        tmin: f64,
        tmax: f64,
        lead: f64,
    ) -> Option<BvhRay> {
        let lo = [-pad; 3];
        let hi = frame.extent.map(|e| e + pad);
        let (t0, t1) = self.clip_with(recip, lo, hi, tmin, tmax)?;
        let scale = (self.d[0] * self.d[0] + self.d[1] * self.d[1] + self.d[2] * self.d[2]).sqrt();
        if !(scale > 0.0 && scale.is_finite()) {
            return None;
        }
        let t_off = t0 - lead / scale;
        let p = self.at(t0);
        let o = [0, 1, 2].map(|a| p[a] - self.d[a] / scale * lead);
        let v = |x: [f64; 3]| Vec3A::new(x[0] as f32, x[1] as f32, x[2] as f32);
        let span = ((t1 - t_off) * scale * (1.0 + 1e-6)) as f32;
        let dir = self.d.map(|x| x / scale);
        let ray = Ray::new(
            v(o),
            v(dir),
            0.0,
            if span.is_finite() { span } else { f32::MAX },
        );
        Some(BvhRay { ray, t_off, scale })
    }
}

/// The `f32` BVH rays of a packet's `rays` (at most [`Mask::BITS`]), each for its query over
/// `[tmin[k], tmax[k]]`: `recips[k]` is ray `k`'s [`GridRay::recip`], and for each ray that
/// meets the domain grown by `pad` (bit `k` of the mask returned), `ray32[k]` and `back[k]`
/// (`(t_off, scale)`) are the [`BvhRay`] of [`GridRay::bvh_ray_with`] for a query from the
/// origin (`tmin[k] <= 0`) or of [`GridRay::bvh_ray_ahead`] for one behind a hit (`tmin[k] >
/// 0`), bit for bit. The other rays' `ray32` and `back` are left alone. With AVX2, four rays
/// at a time.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn bvh_rays(
    rays: &[GridRay],
    frame: &GridFrame,
    pad: f64,
    tmin: &[f64],
    tmax: &[f64],
    recips: &mut [[f64; 3]],
    ray32: &mut [Ray],
    back: &mut [(f64, f64)],
) -> Mask {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { x4::bvh_rays(rays, frame, pad, tmin, tmax, recips, ray32, back) };
    }
    bvh_rays_scalar(rays, frame, pad, tmin, tmax, recips, ray32, back)
}

/// [`bvh_rays`] one ray at a time: the fallback, and what the AVX2 path is tested against.
#[allow(clippy::too_many_arguments)]
pub fn bvh_rays_scalar(
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
    assert!(n <= Mask::BITS as usize && tmin.len() == n && tmax.len() == n);
    let mut active: Mask = 0;
    for k in 0..n {
        recips[k] = rays[k].recip();
        let b = if tmin[k] > 0.0 {
            rays[k].bvh_ray_ahead_with(&recips[k], frame, pad, tmin[k], tmax[k])
        } else {
            rays[k].bvh_ray_with(&recips[k], frame, pad, tmin[k], tmax[k])
        };
        if let Some(b) = b {
            ray32[k] = b.ray;
            back[k] = (b.t_off, b.scale);
            active |= 1 << k;
        }
    }
    active
}

/// Grid units by which the `f32` ray of [`GridRay::bvh_ray_ahead`] starts before the exact
/// ray's first point: the node test's entry bound plus the boxes' padding `pad`, so that the
/// `f32` ray meets a voxel the exact ray meets at `tmin` with a margin of about twice `pad`.
pub fn any_hit_lead(pad: f64) -> f64 {
    f64::from(crate::bvh::T_MIN) + pad
}

/// The larger of `a` and `b`, `a` when `b` is NaN: [`f64::max`] for the operands the tracer
/// meets, as one `maxsd` instead of `f64::max`'s NaN handling (three more instructions).
#[inline(always)]
pub fn larger(a: f64, b: f64) -> f64 {
    if b > a {
        b
    } else {
        a
    }
}

/// The smaller of `a` and `b`, `a` when `b` is NaN (see [`larger`]).
#[inline(always)]
pub fn smaller(a: f64, b: f64) -> f64 {
    if b < a {
        b
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator of test values.
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        /// A coordinate: mostly spread values, sometimes a special one.
        fn value(&mut self, spread: f64) -> f64 {
            let pick = self.next();
            if pick < 0.08 {
                0.0
            } else if pick < 0.1 {
                -0.0
            } else if pick < 0.11 {
                1e-9 * (self.next() - 0.5)
            } else if pick < 0.115 {
                1e-30
            } else {
                spread * (2.0 * self.next() - 1.0)
            }
        }
    }

    fn bits(r: &Ray) -> [u32; 14] {
        let mut out = [0; 14];
        let v = [r.origin, r.direction, r.inv_direction];
        for (i, v) in v.iter().enumerate() {
            for j in 0..4 {
                out[4 * i + j] = v.to_array4()[j].to_bits();
            }
        }
        out[12] = r.tmin.to_bits();
        out[13] = r.tmax.to_bits();
        out
    }

    trait Array4 {
        fn to_array4(&self) -> [f32; 4];
    }

    impl Array4 for Vec3A {
        fn to_array4(&self) -> [f32; 4] {
            // SAFETY: a `Vec3A` is 16 bytes, four `f32`.
            unsafe { std::mem::transmute::<Vec3A, [f32; 4]>(*self) }
        }
    }

    /// [`bvh_rays`] or [`bvh_rays_scalar`].
    type BvhRaysFn = fn(
        &[GridRay],
        &GridFrame,
        f64,
        &[f64],
        &[f64],
        &mut [[f64; 3]],
        &mut [Ray],
        &mut [(f64, f64)],
    ) -> Mask;

    #[test]
    fn packet_bvh_rays_match_the_single_ray_ones_bit_for_bit() {
        let frame = GridFrame {
            origin: [0.0; 3],
            unit: [1.0; 3],
            extent: [64.0, 32.0, 128.0],
        };
        let pad = 1e-5 * 128.0;
        let mut g = Lcg(7);
        let unused = Ray::new(Vec3A::ZERO, Vec3A::X, 0.0, 0.0);
        for n in [64, 61, 7, 4, 1, 0] {
            for _ in 0..200 {
                let rays: Vec<GridRay> = (0..n)
                    .map(|_| GridRay {
                        o: [0, 1, 2].map(|_| 64.0 + g.value(150.0)),
                        d: [0, 1, 2].map(|_| g.value(2.0)),
                    })
                    .collect();
                let tmin: Vec<f64> = (0..n)
                    .map(|_| if g.next() < 0.5 { 0.0 } else { g.value(50.0) })
                    .collect();
                let tmax: Vec<f64> = (0..n)
                    .map(|_| {
                        if g.next() < 0.3 {
                            f64::INFINITY
                        } else {
                            g.value(400.0)
                        }
                    })
                    .collect();
                let run = |f: BvhRaysFn| {
                    let mut recips = [[0.0; 3]; 64];
                    let mut ray32 = [unused; 64];
                    let mut back = [(0.0, 0.0); 64];
                    let m = f(
                        &rays,
                        &frame,
                        pad,
                        &tmin,
                        &tmax,
                        &mut recips,
                        &mut ray32,
                        &mut back,
                    );
                    (m, recips, ray32, back)
                };
                let (m0, recips0, ray0, back0) = run(bvh_rays_scalar);
                let (m1, recips1, ray1, back1) = run(bvh_rays);
                assert_eq!(m0, m1);
                for k in 0..n {
                    let f = |x: [f64; 3]| x.map(f64::to_bits);
                    assert_eq!(f(recips0[k]), f(recips1[k]), "{k}");
                    assert_eq!(bits(&ray0[k]), bits(&ray1[k]), "{k} {:?}", rays[k]);
                    let f = |(a, b): (f64, f64)| (a.to_bits(), b.to_bits());
                    assert_eq!(f(back0[k]), f(back1[k]), "{k}");
                }
            }
        }
    }
}
