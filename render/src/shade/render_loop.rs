//! The frame loop: rows in parallel, `spp` jittered samples per pixel, ray counting and progress.

use std::cell::Cell;

use rayon::prelude::*;

use crate::camera::Camera;
use crate::output::frame::{FrameBuffer, PixelSample};
use crate::shade::integrate::{shade_ray, Lighting};
use crate::shade::sampling::Rng;
use crate::trace::ray::GridRay;
use crate::trace::source::GridFrame;
use crate::trace::tracer::{Paint, SurfaceHit, Tracer};

/// Image size and sampling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples per pixel (1 = one ray through each pixel centre).
    pub spp: u32,
}

/// Counts the queries a shaded ray makes (primary, continuation, shadow and AO rays).
struct Counting<'a, T: ?Sized> {
    inner: &'a T,
    rays: Cell<u64>,
}

impl<T: Tracer + ?Sized> Tracer for Counting<'_, T> {
    fn frame(&self) -> GridFrame {
        self.inner.frame()
    }
    fn num_surfaces(&self) -> usize {
        self.inner.num_surfaces()
    }
    fn next_hit(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> Option<SurfaceHit> {
        self.rays.set(self.rays.get() + 1);
        self.inner.next_hit(i, ray, tmin, tmax)
    }
    fn occluded(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> bool {
        self.rays.set(self.rays.get() + 1);
        self.inner.occluded(i, ray, tmin, tmax)
    }
    fn paint(&self, i: usize, hit: &SurfaceHit) -> Option<Paint> {
        self.inner.paint(i, hit)
    }
}

/// Pixels of a band of rows rendered between two [`Tracer::release_pages`] calls: the map pages a
/// frame holds resident are those one band touches, not the whole frame's.
const BAND_PIXELS: u64 = 1 << 16;

/// Renders a frame; calls `progress(rows_done)` after each row. Returns the frame and the number
/// of ray queries (one per ray and isosurface).
pub fn render_frame<T: Tracer + Sync + ?Sized>(
    tracer: &T,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> (FrameBuffer, u64) {
    let (w, h) = (settings.width, settings.height);
    let spp = settings.spp.max(1);
    let band = (BAND_PIXELS / (u64::from(w) * u64::from(spp)).max(1)).clamp(1, u64::from(h)) as u32;
    let mut rows: Vec<(Vec<PixelSample>, u64)> = Vec::with_capacity(h as usize);
    for y0 in (0..h).step_by(band.max(1) as usize) {
        let part: Vec<(Vec<PixelSample>, u64)> = (y0..(y0 + band).min(h))
            .into_par_iter()
            .map(|y| {
                let counting = Counting {
                    inner: tracer,
                    rays: Cell::new(0),
                };
                let row = (0..w)
                    .map(|x| pixel(&counting, camera, light, x, y, w, h, spp))
                    .collect();
                progress(1);
                (row, counting.rays.get())
            })
            .collect();
        rows.extend(part);
        tracer.release_pages();
    }
    let rays = rows.iter().map(|r| r.1).sum();
    let pixels: Vec<PixelSample> = rows.into_iter().flat_map(|r| r.0).collect();
    (
        FrameBuffer::from_pixels(w, h, &pixels, tracer.frame().origin),
        rays,
    )
}

/// Renders the rectangle of `settings`' frame with lower corner `(x0, y0)` and size `w x h` (rows
/// in parallel); returns its pixels row-major, each equal to the same pixel of [`render_frame`],
/// and the number of ray queries.
pub fn render_rect<T: Tracer + Sync + ?Sized>(
    tracer: &T,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    (x0, y0, w, h): (u32, u32, u32, u32),
) -> (Vec<PixelSample>, u64) {
    let (fw, fh) = (settings.width, settings.height);
    let spp = settings.spp.max(1);
    let rows: Vec<(Vec<PixelSample>, u64)> = (y0..y0 + h)
        .into_par_iter()
        .map(|y| {
            let counting = Counting {
                inner: tracer,
                rays: Cell::new(0),
            };
            let row = (x0..x0 + w)
                .map(|x| pixel(&counting, camera, light, x, y, fw, fh, spp))
                .collect();
            (row, counting.rays.get())
        })
        .collect();
    let rays = rows.iter().map(|r| r.1).sum();
    (rows.into_iter().flat_map(|r| r.0).collect(), rays)
}

#[allow(clippy::too_many_arguments)]
fn pixel<T: Tracer + ?Sized>(
    tracer: &T,
    camera: &Camera,
    light: &Lighting,
    x: u32,
    y: u32,
    w: u32,
    h: u32,
    spp: u32,
) -> PixelSample {
    let mut acc = PixelSample::MISS;
    let mut rgba = [0.0f32; 4];
    let mut have_first = false;
    for s in 0..spp {
        let mut rng = Rng::for_pixel(x, y, s);
        let (jx, jy) = if spp == 1 {
            (0.5, 0.5)
        } else {
            (rng.next_f64(), rng.next_f64())
        };
        let dir = camera.ray_dir(f64::from(x) + jx, f64::from(y) + jy, w, h);
        let sample = shade_ray(tracer, light, camera.pos, dir, &mut rng);
        for c in 0..3 {
            rgba[c] += sample.rgb[c];
        }
        rgba[3] += sample.alpha;
        if !have_first && sample.alpha > 0.0 {
            acc = sample;
            have_first = true;
        }
    }
    let inv = 1.0 / spp as f32;
    acc.rgb = [rgba[0] * inv, rgba[1] * inv, rgba[2] * inv];
    acc.alpha = rgba[3] * inv;
    acc
}
