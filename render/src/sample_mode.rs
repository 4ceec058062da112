//! The sample-based baseline (section 4's ray marching): step along the ray by a fixed distance,
//! evaluate the same reconstruction, and bisect the first sign change of `F - iso`.

use crate::camera::dot;
use crate::trace::ray::GridRay;
use crate::trace::source::{GridFrame, VoxelSource};
use crate::trace::tracer::{SurfaceHit, Tracer};

/// Bisection steps after a sign change is found (the bracket shrinks to `step / 2^BISECTIONS`).
const BISECTIONS: u32 = 24;

/// Marches rays through the reconstruction with a fixed step.
pub struct SampleTracer<'a, S: VoxelSource + ?Sized> {
    /// The reconstruction.
    pub src: &'a S,
    /// Isovalues, one per surface.
    pub isos: Vec<f32>,
    /// Step along the ray, in ray-parameter units (world distance for unit directions).
    pub step: f64,
}

impl<S: VoxelSource + ?Sized> SampleTracer<'_, S> {
    fn value(&self, ray: &GridRay, t: f64, iso: f32) -> Option<f64> {
        self.src
            .sample(ray.at(t))
            .map(|(v, _)| f64::from(v) - f64::from(iso))
    }
}

impl<S: VoxelSource + ?Sized> Tracer for SampleTracer<'_, S> {
    fn frame(&self) -> GridFrame {
        self.src.frame()
    }

    fn num_surfaces(&self) -> usize {
        self.isos.len()
    }

    fn next_hit(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> Option<SurfaceHit> {
        let iso = self.isos[i];
        let frame = self.src.frame();
        let (t0, t1) = ray.clip([0.0; 3], frame.extent, tmin, tmax)?;
        if !(self.step > 0.0) || !t1.is_finite() {
            return None;
        }
        let mut prev: Option<(f64, f64)> = None;
        let n = ((t1 - t0) / self.step).ceil() as u64;
        for k in 0..=n {
            let t = (t0 + k as f64 * self.step).min(t1);
            let Some(f) = self.value(ray, t, iso) else {
                prev = None;
                continue;
            };
            if let Some((tp, fp)) = prev {
                if (fp < 0.0) != (f < 0.0) || f == 0.0 {
                    let t_hit = self.bisect(ray, iso, tp, fp, t, f);
                    return Some(self.hit(ray, t_hit));
                }
            } else if f == 0.0 {
                return Some(self.hit(ray, t));
            }
            prev = Some((t, f));
        }
        None
    }

    fn release_pages(&self) {
        self.src.release_pages();
    }
}

impl<S: VoxelSource + ?Sized> SampleTracer<'_, S> {
    fn bisect(&self, ray: &GridRay, iso: f32, mut a: f64, fa: f64, mut b: f64, fb: f64) -> f64 {
        if fb == 0.0 {
            return b;
        }
        let neg_a = fa < 0.0;
        for _ in 0..BISECTIONS {
            let m = 0.5 * (a + b);
            match self.value(ray, m, iso) {
                Some(0.0) => return m,
                Some(f) if (f < 0.0) == neg_a => a = m,
                _ => b = m,
            }
        }
        0.5 * (a + b)
    }

    fn hit(&self, ray: &GridRay, t: f64) -> SurfaceHit {
        let pos = ray.at(t);
        let len = (ray.d[0] * ray.d[0] + ray.d[1] * ray.d[1] + ray.d[2] * ray.d[2]).sqrt();
        let size = (self.step * len).max(1e-9);
        let grad = self.src.gradient(pos, [0.5 * size; 3]).unwrap_or([0.0; 3]);
        let level = self.src.sample(pos).map_or(0, |s| s.1);
        let rising = dot(grad, ray.d) > 0.0;
        SurfaceHit {
            t,
            pos,
            grad,
            rising,
            level,
            size,
            r: u64::MAX,
        }
    }
}
