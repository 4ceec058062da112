//! The frame loop: rows in parallel, `spp` jittered samples per pixel, ray counting and progress,
//! then the filter of the ambient occlusion over the whole frame.

use std::cell::Cell;

use rayon::prelude::*;

use crate::camera::{Camera, PixelDirs};
use crate::output::frame::{FrameBuffer, PixelSample};
use crate::shade::ao_filter::{self, AoLayer, AoRow, AoRows};
use crate::shade::integrate::{shade_ray, Lighting, SearchHint};
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
#[inline(never)]
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
    let mut rows: Vec<Row> = Vec::with_capacity(h as usize);
    for y0 in (0..h).step_by(band.max(1) as usize) {
        let part: Vec<Row> = (y0..(y0 + band).min(h))
            .into_par_iter()
            .map(|y| {
                let row = render_row(tracer, camera, light, settings, (0..w, y));
                progress(1);
                row
            })
            .collect();
        rows.extend(part);
        tracer.release_pages();
    }
    let rays = rows.iter().map(|r| r.rays).sum();
    let mut frame = FrameBuffer::zeroed(w, h, tracer.frame().origin);
    let out = frame.rows_mut();
    finish(rows, camera, light, settings, w, out, |mut out, pixels| {
        out.set_all(pixels)
    });
    (frame, rays)
}

/// Renders the rectangle of `settings`' frame with lower corner `(x0, y0)` and size `w x h` (rows
/// in parallel); returns its pixels row-major, each equal to the same pixel of [`render_frame`],
/// and the number of ray queries (those of the filter's margin around it included).
pub fn render_rect<T: Tracer + Sync + ?Sized>(
    tracer: &T,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    (x0, y0, w, h): (u32, u32, u32, u32),
) -> (Vec<PixelSample>, u64) {
    let (fw, fh) = (settings.width, settings.height);
    // The filter reads pixels up to `MARGIN` away: the rectangle is rendered with that margin
    // (inside the frame) and cut out after the filter.
    let margin = if filters(light, settings) {
        ao_filter::MARGIN
    } else {
        0
    };
    let (mx0, my0) = (x0.saturating_sub(margin), y0.saturating_sub(margin));
    let mx1 = (x0 + w).saturating_add(margin).min(fw).max(x0 + w);
    let my1 = (y0 + h).saturating_add(margin).min(fh).max(y0 + h);
    let rows: Vec<Row> = (my0..my1)
        .into_par_iter()
        .map(|y| render_row(tracer, camera, light, settings, (mx0..mx1, y)))
        .collect();
    let rays = rows.iter().map(|r| r.rays).sum();
    let mw = mx1 - mx0;
    let (cut_x, cut_y) = ((x0 - mx0) as usize, (y0 - my0) as usize);
    let mut out = vec![PixelSample::MISS; w as usize * h as usize];
    // One slot per rendered row: the rows of the margin write nowhere.
    let mut slots: Vec<Option<&mut [PixelSample]>> = (0..my1 - my0).map(|_| None).collect();
    for (slot, dst) in slots[cut_y..]
        .iter_mut()
        .zip(out.chunks_mut(w.max(1) as usize))
    {
        *slot = Some(dst);
    }
    finish(rows, camera, light, settings, mw, slots, |slot, pixels| {
        if let Some(dst) = slot {
            dst.copy_from_slice(&pixels[cut_x..cut_x + dst.len()]);
        }
    });
    (out, rays)
}

/// One rendered row: its pixels, the hits of each to filter, and its ray queries.
struct Row {
    pixels: Vec<PixelSample>,
    ao: AoRow,
    rays: u64,
}

/// True when `light`'s ambient occlusion is filtered across pixels in frames of `settings`:
/// with one sample per pixel (more samples average the occlusion within each pixel).
fn filters(light: &Lighting, settings: RenderSettings) -> bool {
    light.ao_filter && light.ao_rays > 0 && settings.spp <= 1
}

/// The pixels `xs` of row `y`.
fn render_row<T: Tracer + ?Sized>(
    tracer: &T,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    (xs, y): (std::ops::Range<u32>, u32),
) -> Row {
    let counting = Counting {
        inner: tracer,
        rays: Cell::new(0),
    };
    let record = filters(light, settings);
    let mut row = Row {
        pixels: Vec::with_capacity(xs.len()),
        ao: AoRow::new(),
        rays: 0,
    };
    let mut hint = SearchHint::default();
    let dirs = camera.pixel_dirs(settings.width, settings.height);
    for x in xs {
        let layers = record.then_some(row.ao.layers_mut());
        let px = pixel(&counting, &dirs, light, (x, y), settings, &mut hint, layers);
        row.pixels.push(px);
        if record {
            row.ao.end_pixel();
        }
    }
    row.rays = counting.rays.get();
    row
}

/// Hands each of `rows` (a rectangle `w` pixels wide, top row first) to `write` with its
/// destination in `out` (one per row), its ambient occlusion filtered first; rows in parallel.
fn finish<O: Send>(
    rows: Vec<Row>,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    w: u32,
    out: Vec<O>,
    write: impl Fn(O, &[PixelSample]) + Sync,
) {
    assert_eq!(rows.len(), out.len());
    let (pixels, ao): (Vec<Vec<PixelSample>>, Vec<AoRow>) =
        rows.into_iter().map(|r| (r.pixels, r.ao)).unzip();
    let filter = filters(light, settings).then(|| AoRows::new(w, &ao));
    let pixel_angle =
        (2.0 * (0.5 * camera.fov_deg).to_radians().tan() / f64::from(settings.height)) as f32;
    pixels
        .into_par_iter()
        .zip(out)
        .enumerate()
        .for_each(|(y, (mut px, out))| {
            if let Some(f) = &filter {
                f.apply_row(y as u32, &mut px, pixel_angle);
            }
            write(out, &px);
        });
}

/// Pixel `(x, y)`: the average of its samples; with `ao_layers`, its hits to filter are appended.
fn pixel<T: Tracer + ?Sized>(
    tracer: &T,
    dirs: &PixelDirs,
    light: &Lighting,
    (x, y): (u32, u32),
    settings: RenderSettings,
    hint: &mut SearchHint,
    mut ao_layers: Option<&mut Vec<AoLayer>>,
) -> PixelSample {
    let spp = settings.spp.max(1);
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
        let dir = dirs.dir(f64::from(x) + jx, f64::from(y) + jy);
        let layers = ao_layers.as_deref_mut();
        let sample = shade_ray(tracer, light, (dirs.origin(), dir), &mut rng, hint, layers);
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
