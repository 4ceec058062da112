//! Cutting surfaces open at a clip box: a [`Tracer`] wrapper that gives each ray's query only the
//! part of its parameter interval inside the box. A hit outside the box is never reported, so a
//! primary ray passes through the cut to the surfaces behind it, and shadow and ambient-occlusion
//! rays, which query through the same tracer, see the same cut geometry.

use crate::trace::ray::GridRay;
use crate::trace::source::GridFrame;
use crate::trace::tracer::{Paint, SurfaceHit, Tracer};

/// `inner`, its surfaces cut to the closed grid box `[lo, hi]`.
pub struct ClippedTracer<'a, T: ?Sized> {
    /// The surfaces.
    pub inner: &'a T,
    /// Lower corner of the box, grid coordinates.
    pub lo: [f64; 3],
    /// Upper corner of the box, grid coordinates.
    pub hi: [f64; 3],
}

impl<T: Tracer + ?Sized> Tracer for ClippedTracer<'_, T> {
    fn frame(&self) -> GridFrame {
        self.inner.frame()
    }

    fn num_surfaces(&self) -> usize {
        self.inner.num_surfaces()
    }

    fn next_hit(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> Option<SurfaceHit> {
        let (t0, t1) = ray.clip(self.lo, self.hi, tmin, tmax)?;
        self.inner.next_hit(i, ray, t0, t1)
    }

    fn occluded(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> bool {
        ray.clip(self.lo, self.hi, tmin, tmax)
            .is_some_and(|(t0, t1)| self.inner.occluded(i, ray, t0, t1))
    }

    fn release_pages(&self) {
        self.inner.release_pages();
    }

    fn paint(&self, i: usize, hit: &SurfaceHit) -> Option<Paint> {
        self.inner.paint(i, hit)
    }

    fn unlit(&self, i: usize) -> bool {
        self.inner.unlit(i)
    }
}
