//! The frame loop: rows in parallel, `spp` jittered samples per pixel, ray counting and progress,
//! then the filter of the ambient occlusion over the whole frame.

use std::cell::Cell;

use rayon::prelude::*;

use crate::camera::{Camera, PixelDirs};
use crate::output::frame::{FrameBuffer, PixelSample};
use crate::shade::ao_filter::{self, AoBuffer, AoLayer};
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
    let (pixels, rays) = finish(rows, camera, light, settings, (w, h));
    (
        FrameBuffer::from_pixels(w, h, &pixels, tracer.frame().origin),
        rays,
    )
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
    let (mw, mh) = (mx1 - mx0, my1 - my0);
    let (pixels, rays) = finish(rows, camera, light, settings, (mw, mh));
    let mut out = Vec::with_capacity(w as usize * h as usize);
    for y in y0 - my0..y0 - my0 + h {
        let first = (y * mw + (x0 - mx0)) as usize;
        out.extend_from_slice(&pixels[first..first + w as usize]);
    }
    (out, rays)
}

/// One rendered row: its pixels, the hits of each to filter, and its ray queries.
struct Row {
    pixels: Vec<PixelSample>,
    ao_counts: Vec<u8>,
    ao_layers: Vec<AoLayer>,
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
        ao_counts: Vec::new(),
        ao_layers: Vec::new(),
        rays: 0,
    };
    let mut hint = SearchHint::default();
    let dirs = camera.pixel_dirs(settings.width, settings.height);
    for x in xs {
        let before = row.ao_layers.len();
        let layers = record.then_some(&mut row.ao_layers);
        let px = pixel(&counting, &dirs, light, (x, y), settings, &mut hint, layers);
        row.pixels.push(px);
        if record {
            row.ao_counts.push((row.ao_layers.len() - before) as u8);
        }
    }
    row.rays = counting.rays.get();
    row
}

/// The pixels of `rows` (a `w x h` rectangle), the ambient occlusion filtered, and the ray
/// queries they took.
fn finish(
    rows: Vec<Row>,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    (w, h): (u32, u32),
) -> (Vec<PixelSample>, u64) {
    let rays = rows.iter().map(|r| r.rays).sum();
    let mut ao = filters(light, settings).then(|| AoBuffer::new(w, h));
    let mut pixels = Vec::with_capacity(w as usize * h as usize);
    for row in rows {
        if let Some(ao) = ao.as_mut() {
            let mut layers = row.ao_layers.as_slice();
            for &n in &row.ao_counts {
                let (these, rest) = layers.split_at(usize::from(n));
                ao.push_pixel(these);
                layers = rest;
            }
        }
        pixels.extend(row.pixels);
    }
    if let Some(ao) = ao {
        let pixel_angle =
            2.0 * (0.5 * camera.fov_deg).to_radians().tan() / f64::from(settings.height);
        ao.apply(&mut pixels, pixel_angle as f32);
    }
    (pixels, rays)
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
