//! Rays in grid coordinates: the exact `f64` ray the intersections use, and the `f32` ray the
//! BVH is traversed with, re-based at the domain's entry point so that it stays precise.

use glam::Vec3A;
use obvhs::ray::Ray;

use crate::trace::source::GridFrame;

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
