//! The sample-based baseline (section 4's ray marching): step along the ray by a fixed distance,
//! or by half a cell of the level each sample lands in, evaluate the same reconstruction, and
//! bisect the first sign change of `F - iso`.

use crate::camera::dot;
use crate::trace::ray::GridRay;
use crate::trace::source::{GridFrame, VoxelSource};
use crate::trace::tracer::{SurfaceHit, Tracer};

/// Bisection steps after a sign change is found (the bracket shrinks to `step / 2^BISECTIONS`).
const BISECTIONS: u32 = 24;

/// How far a [`SampleTracer`] steps along a ray, in ray-parameter units (world distance for
/// unit directions).
#[derive(Clone, Debug, PartialEq)]
pub enum SampleStep {
    /// The same distance everywhere: section 4's baseline.
    Fixed(f64),
    /// Per AMR level, coarsest first: the step after a sample on level `l` is entry `l` (the last
    /// entry past the end). A fixed step fine enough for the finest level crosses a deep
    /// hierarchy's coarse levels in thousands of steps per cell.
    PerLevel(Vec<f64>),
}

impl SampleStep {
    /// Half a cell of each level (its smallest side in world units) of `src`.
    pub fn half_cells<S: VoxelSource + ?Sized>(src: &S) -> SampleStep {
        let unit = src.frame().unit;
        let steps = (0..)
            .map_while(|l| src.cell_size(l))
            .map(|c| 0.5 * (0..3).map(|a| c[a] * unit[a]).fold(f64::INFINITY, f64::min))
            .collect();
        SampleStep::PerLevel(steps)
    }

    /// The step after a sample on `level`.
    fn after(&self, level: u32) -> f64 {
        match self {
            SampleStep::Fixed(s) => *s,
            SampleStep::PerLevel(steps) => steps
                .get(level as usize)
                .or(steps.last())
                .copied()
                .unwrap_or(0.0),
        }
    }
}

/// Marches rays through the reconstruction.
pub struct SampleTracer<'a, S: VoxelSource + ?Sized> {
    /// The reconstruction.
    pub src: &'a S,
    /// The reconstruction of each surface's field, by surface; empty when every surface is of
    /// `src`'s field.
    pub sources: &'a [&'a S],
    /// Isovalues, one per surface.
    pub isos: Vec<f32>,
    /// Step along the ray.
    pub step: SampleStep,
}

impl<S: VoxelSource + ?Sized> SampleTracer<'_, S> {
    /// The reconstruction surface `i` is of.
    fn source(&self, i: usize) -> &S {
        self.sources.get(i).copied().unwrap_or(self.src)
    }

    /// `F - iso` of `src` at `t` and the level sampled there.
    fn value(&self, src: &S, ray: &GridRay, t: f64, iso: f32) -> Option<(f64, u32)> {
        src.sample(ray.at(t))
            .map(|(v, level)| (f64::from(v) - f64::from(iso), level))
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
        let (iso, src) = (self.isos[i], self.source(i));
        let frame = self.src.frame();
        let (t0, t1) = ray.clip([0.0; 3], frame.extent, tmin, tmax)?;
        if !t1.is_finite() {
            return None;
        }
        let mut prev: Option<(f64, f64)> = None;
        let (mut t, mut k) = (t0, 0u64);
        // The step after a point without a value: the coarsest level's.
        let mut step = self.step.after(0);
        loop {
            if !(step > 0.0) {
                return None;
            }
            if let Some((f, level)) = self.value(src, ray, t, iso) {
                if let Some((tp, fp)) = prev {
                    if (fp < 0.0) != (f < 0.0) || f == 0.0 {
                        let t_hit = self.bisect(src, ray, iso, (tp, fp), (t, f));
                        return Some(self.hit(src, ray, t_hit, Some(fp < f)));
                    }
                } else if f == 0.0 {
                    return Some(self.hit(src, ray, t, None));
                }
                prev = Some((t, f));
                step = self.step.after(level);
            } else {
                prev = None;
            }
            if t >= t1 {
                return None;
            }
            k += 1;
            let next = match self.step {
                // Multiples of the step from `t0`: no rounding accumulates along the ray.
                SampleStep::Fixed(s) => t0 + k as f64 * s,
                SampleStep::PerLevel(_) => t + step,
            };
            if !(next > t) {
                // A step below the rounding of `t`: the march would not move.
                return None;
            }
            t = next.min(t1);
        }
    }

    fn release_pages(&self) {
        self.src.release_pages();
        self.sources.iter().for_each(|s| s.release_pages());
    }
}

impl<S: VoxelSource + ?Sized> SampleTracer<'_, S> {
    /// The root of `src`'s `F - iso` in the bracket `(a, fa)`, `(b, fb)` along `ray`.
    fn bisect(
        &self,
        src: &S,
        ray: &GridRay,
        iso: f32,
        (mut a, fa): (f64, f64),
        (mut b, fb): (f64, f64),
    ) -> f64 {
        if fb == 0.0 {
            return b;
        }
        let neg_a = fa < 0.0;
        for _ in 0..BISECTIONS {
            let m = 0.5 * (a + b);
            match self.value(src, ray, m, iso) {
                Some((0.0, _)) => return m,
                Some((f, _)) if (f < 0.0) == neg_a => a = m,
                _ => b = m,
            }
        }
        0.5 * (a + b)
    }

    /// The hit of `src`'s surface at `t` along `ray`; `rising` is whether the field grows along
    /// the ray there, when the bracket of the crossing tells (else the gradient does).
    fn hit(&self, src: &S, ray: &GridRay, t: f64, rising: Option<bool>) -> SurfaceHit {
        let pos = ray.at(t);
        let len = (ray.d[0] * ray.d[0] + ray.d[1] * ray.d[1] + ray.d[2] * ray.d[2]).sqrt();
        let level = src.sample(pos).map_or(0, |s| s.1);
        let size = (self.step.after(level) * len).max(1e-9);
        // The hybrid method's smooth normal (one cell of the level apart, blended across level
        // boundaries), so that the two methods differ only in where they find the surface.
        let grad = src
            .level_gradient(pos, level, [0.5 * size; 3])
            .unwrap_or([0.0; 3]);
        // From the crossing, not from the smooth normal, which may lean past the ray at a
        // silhouette ([`SurfaceHit::rising`]).
        let rising = rising.unwrap_or_else(|| dot(grad, ray.d) > 0.0);
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
