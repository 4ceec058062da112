//! Painting by data: a [`Tracer`] wrapper that gives surfaces the colour of a field (or of the AMR
//! level) at each hit through a [`ColorScale`], and adds [`Slice`]s as unlit planes after the
//! surfaces, so that the shader composites everything in depth order. The default colour range
//! comes from a pre-pass over the values the frame shows.

use std::sync::atomic::{AtomicU32, Ordering};

use rayon::prelude::*;

use crate::bvh::packet::Mask;
use crate::camera::Camera;
use crate::coloring::ColorScale;
use crate::colormap::level_linear;
use crate::slice::Slice;
use crate::trace::ray::GridRay;
use crate::trace::source::{GridFrame, VoxelSource};
use crate::trace::tracer::{
    next_crossings_by_queries, next_hits_one_by_one, Behind, Paint, SurfaceHit, Tracer,
};

/// Pixels between the primary rays of the colour-range pre-pass, on each axis.
const RANGE_STRIDE: u32 = 4;

/// What paints one surface or slice.
#[derive(Clone, Copy)]
pub enum Painter<'a> {
    /// The AMR level, with the categorical palette.
    Level,
    /// A field, sampled with its source's reconstruction, and the index of its range in
    /// [`PaintedTracer::ranges`] (one per field that paints).
    Field(&'a (dyn VoxelSource + 'a), usize),
    /// The length of the vector of several fields, each sampled with its source's
    /// reconstruction, and the index of its range.
    Magnitude(&'a [&'a (dyn VoxelSource + 'a)], usize),
}

impl Painter<'_> {
    /// The index of its range in [`PaintedTracer::ranges`]; `None` for the level.
    fn range_index(&self) -> Option<usize> {
        match self {
            Painter::Level => None,
            Painter::Field(_, k) | Painter::Magnitude(_, k) => Some(*k),
        }
    }
}

/// The colour range of one field's painted values, from the values a frame shows
/// ([`PaintedTracer::visible_ranges`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisibleRange {
    /// The values at the colormap's ends.
    pub range: (f64, f64),
    /// Whether some of the values seen lie below the low end and above the high end.
    pub beyond: (bool, bool),
}

/// A slice in grid coordinates, and what paints it.
#[derive(Clone, Copy)]
pub struct GridSlice<'a> {
    point: [f64; 3],
    normal: [f64; 3],
    painter: Painter<'a>,
}

impl<'a> GridSlice<'a> {
    /// `slice` in the grid of `frame`, painted by `painter`.
    pub fn new(slice: &Slice, frame: &GridFrame, painter: Painter<'a>) -> Self {
        GridSlice {
            point: frame.to_grid(slice.point),
            normal: [0, 1, 2].map(|a| slice.normal[a] * frame.unit[a]),
            painter,
        }
    }
}

/// A tracer whose surfaces are painted by data, followed by slices.
pub struct PaintedTracer<'a, T: ?Sized> {
    /// The surfaces.
    pub inner: &'a T,
    /// What paints each surface of `inner` (`None`: the surface's own colour).
    pub surfaces: Vec<Option<Painter<'a>>>,
    /// Slices, numbered after the surfaces.
    pub slices: Vec<GridSlice<'a>>,
    /// The source whose levels [`Painter::Level`] paints slices with.
    pub levels: &'a (dyn VoxelSource + 'a),
    /// Values to colours, per field that paints: its colormap, log scale and given range.
    pub scales: Vec<ColorScale>,
    /// The values at the colormap's ends, per field that paints.
    pub ranges: Vec<(f64, f64)>,
    /// Bit `l` set once [`Painter::Level`] has painted level `l` into a pixel.
    pub painted_levels: AtomicU32,
}

impl<'a, T: Tracer + Sync + ?Sized> PaintedTracer<'a, T> {
    /// The levels [`Painter::Level`] has painted into pixels so far, ascending.
    pub fn levels_painted(&self) -> Vec<u32> {
        let bits = self.painted_levels.load(Ordering::Relaxed);
        (0..u32::BITS).filter(|l| bits & (1 << l) != 0).collect()
    }

    /// The value `painter` gives at grid point `pos` of a hit on level `level`.
    fn value(&self, painter: Painter<'_>, pos: [f64; 3], level: u32) -> Option<f32> {
        match painter {
            Painter::Level => Some(level as f32),
            Painter::Field(src, _) => src.sample(pos).map(|s| s.0),
            Painter::Magnitude(srcs, _) => {
                let mut squares = 0.0f64;
                for src in srcs {
                    squares += f64::from(src.sample(pos)?.0).powi(2);
                }
                Some(squares.sqrt() as f32)
            }
        }
    }

    /// The colour of `value` painted by `painter`.
    fn color(&self, painter: Painter<'_>, value: f32) -> [f32; 3] {
        match painter {
            Painter::Level => level_linear(value.max(0.0) as u32),
            Painter::Field(_, k) | Painter::Magnitude(_, k) => {
                self.scales[k].linear(f64::from(value), self.ranges[k])
            }
        }
    }

    /// The hit of slice `s` with `ray` with `t` in `[tmin, tmax]`, inside the data.
    fn slice_hit(
        &self,
        s: &GridSlice<'_>,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
    ) -> Option<SurfaceHit> {
        let den: f64 = (0..3).map(|a| s.normal[a] * ray.d[a]).sum();
        if den == 0.0 || !den.is_finite() {
            return None;
        }
        let num: f64 = (0..3).map(|a| s.normal[a] * (s.point[a] - ray.o[a])).sum();
        let t = num / den;
        if !(t >= tmin && t <= tmax) {
            return None;
        }
        let pos = [0, 1, 2].map(|a| ray.o[a] + t * ray.d[a]);
        let ext = self.inner.frame().extent;
        if (0..3).any(|a| !(pos[a] >= 0.0 && pos[a] <= ext[a])) {
            return None;
        }
        let (_, level) = self.levels.sample(pos)?;
        Some(SurfaceHit {
            t,
            pos,
            grad: s.normal,
            rising: den > 0.0,
            level,
            size: 1.0,
            r: u64::MAX,
        })
    }

    /// Per field that paints (one per entry of [`Self::scales`], in the order of
    /// [`Painter::Field`]'s index), its scale's range, else the robust range of its values that
    /// the primary rays of `camera` (every [`RANGE_STRIDE`]-th pixel of a `w x h` frame) meet
    /// before an opaque layer, with `opacity` per surface and slice; and whether some of those
    /// values lie below and above it. `None` for a field none of whose values is seen.
    pub fn visible_ranges(
        &self,
        camera: &Camera,
        (w, h): (u32, u32),
        opacity: &[f32],
    ) -> Vec<Option<VisibleRange>> {
        let frame = self.inner.frame();
        let rows: Vec<u32> = (0..h).step_by(RANGE_STRIDE as usize).collect();
        let seen: Vec<(usize, f32)> = rows
            .par_iter()
            .flat_map_iter(|&y| {
                let mut out = Vec::new();
                for x in (0..w).step_by(RANGE_STRIDE as usize) {
                    let (start, dir) = camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5, w, h);
                    let ray = GridRay::from_world(&frame, start, dir);
                    self.visible_values(&ray, opacity, &mut out);
                }
                out
            })
            .collect();
        (0..self.scales.len())
            .map(|k| {
                let mut values: Vec<f32> = seen
                    .iter()
                    .filter(|(f, _)| *f == k)
                    .map(|(_, v)| *v)
                    .collect();
                let range = self.scales[k].resolve(&mut values)?;
                let past = |below: bool| {
                    values.iter().any(|&v| match below {
                        true => f64::from(v) < range.0,
                        false => f64::from(v) > range.1,
                    })
                };
                Some(VisibleRange {
                    range,
                    beyond: (past(true), past(false)),
                })
            })
            .collect()
    }

    /// Appends to `out` the field values painted along `ray` in front of its first opaque layer,
    /// each with the index of its field's range.
    fn visible_values(&self, ray: &GridRay, opacity: &[f32], out: &mut Vec<(usize, f32)>) {
        let mut layers: Vec<(f64, usize, SurfaceHit)> = (0..self.num_surfaces())
            .filter_map(|i| {
                self.next_hit(i, ray, 0.0, f64::INFINITY)
                    .map(|h| (h.t, i, h))
            })
            .collect();
        layers.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (_, i, hit) in layers {
            if let Some((painter, Some(k))) = self.painter(i).map(|p| (p, p.range_index())) {
                // The value alone: the colours wait for the ranges this pass finds.
                if let Some(v) = self.value(painter, hit.pos, hit.level) {
                    out.push((k, v));
                }
            }
            if opacity.get(i).is_some_and(|&o| o >= 1.0) {
                break;
            }
        }
    }

    /// What paints surface or slice `i`.
    fn painter(&self, i: usize) -> Option<Painter<'a>> {
        let n = self.surfaces.len();
        match i < n {
            true => self.surfaces[i],
            false => self.slices.get(i - n).map(|s| s.painter),
        }
    }
}

impl<T: Tracer + Sync + ?Sized> Tracer for PaintedTracer<'_, T> {
    fn frame(&self) -> GridFrame {
        self.inner.frame()
    }

    fn num_surfaces(&self) -> usize {
        self.surfaces.len() + self.slices.len()
    }

    fn next_hit(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> Option<SurfaceHit> {
        match self.slices.get(i.wrapping_sub(self.surfaces.len())) {
            Some(s) if i >= self.surfaces.len() => self.slice_hit(s, ray, tmin, tmax),
            _ => self.inner.next_hit(i, ray, tmin, tmax),
        }
    }

    fn next_hits(&self, i: usize, rays: &[GridRay], tmax: &[f64], out: &mut [Option<SurfaceHit>]) {
        if i < self.surfaces.len() {
            return self.inner.next_hits(i, rays, tmax, out);
        }
        for ((ray, &tmax), out) in rays.iter().zip(tmax).zip(out) {
            *out = self.next_hit(i, ray, 0.0, tmax);
        }
    }

    fn next_hits_from(
        &self,
        i: usize,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
    ) {
        if i < self.surfaces.len() {
            return self.inner.next_hits_from(i, rays, tmin, tmax, out);
        }
        next_hits_one_by_one(self, i, rays, tmin, tmax, out)
    }

    fn next_crossings(
        &self,
        i: usize,
        rays: &[GridRay],
        behind: &[Behind],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
    ) {
        if i < self.surfaces.len() {
            return self.inner.next_crossings(i, rays, behind, tmax, out);
        }
        next_crossings_by_queries(self, i, rays, behind, tmax, out)
    }

    fn occluded(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> bool {
        // Slices cast no shadows: they show the data, not an object in the light.
        i < self.surfaces.len() && self.inner.occluded(i, ray, tmin, tmax)
    }

    fn occluded_many(
        &self,
        i: usize,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: f64,
        active: Mask,
    ) -> Mask {
        if i < self.surfaces.len() {
            self.inner.occluded_many(i, rays, tmin, tmax, active)
        } else {
            0
        }
    }

    fn release_pages(&self) {
        self.inner.release_pages();
    }

    fn paint(&self, i: usize, hit: &SurfaceHit) -> Option<Paint> {
        let painter = self.painter(i)?;
        if let (Painter::Level, Some(bit)) = (painter, 1u32.checked_shl(hit.level)) {
            // Read first: the bit is set once, not written by every pixel of the level.
            if self.painted_levels.load(Ordering::Relaxed) & bit == 0 {
                self.painted_levels.fetch_or(bit, Ordering::Relaxed);
            }
        }
        let value = self.value(painter, hit.pos, hit.level)?;
        Some(Paint {
            rgb: self.color(painter, value),
            value,
        })
    }

    fn unlit(&self, i: usize) -> bool {
        i >= self.surfaces.len()
    }
}
