//! The frame loop: strips of tiles of 8x8 pixels in parallel (each tile's primary rays, and the
//! continuations behind transparent hits, traced together), `spp` jittered samples per pixel,
//! ray counting and progress, pixels written straight into the frame's planes; then, band of
//! rows after band, the filter of the ambient occlusion.

use std::cell::Cell;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::bvh::packet::Mask;
use crate::camera::{Camera, Projection};
use crate::output::frame::{FrameBuffer, PixelSample, RowPlanes};
use crate::shade::ao_filter::{self, AoRow, AoRows, PixelSpan};
use crate::shade::ao_packets::TileAo;
use crate::shade::integrate::{shade_hit_alone, shade_hits, KeyShadow, Lighting, SearchHint};
use crate::shade::layers::TileLayers;
use crate::shade::packets::{TileHits, TILE_RAYS};
use crate::shade::sampling::Rng;
use crate::trace::ray::GridRay;
use crate::trace::source::GridFrame;
use crate::trace::tracer::{Behind, Paint, SurfaceHit, Tracer};

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
    fn next_hits(&self, i: usize, rays: &[GridRay], tmax: &[f64], out: &mut [Option<SurfaceHit>]) {
        self.rays.set(self.rays.get() + rays.len() as u64);
        self.inner.next_hits(i, rays, tmax, out)
    }
    fn next_hits_from(
        &self,
        i: usize,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
    ) {
        self.rays.set(self.rays.get() + rays.len() as u64);
        self.inner.next_hits_from(i, rays, tmin, tmax, out)
    }
    fn next_crossings(
        &self,
        i: usize,
        rays: &[GridRay],
        behind: &[Behind],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
    ) {
        self.rays.set(self.rays.get() + rays.len() as u64);
        self.inner.next_crossings(i, rays, behind, tmax, out)
    }
    fn occluded(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> bool {
        self.rays.set(self.rays.get() + 1);
        self.inner.occluded(i, ray, tmin, tmax)
    }
    fn occluded_many(
        &self,
        i: usize,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: f64,
        active: Mask,
    ) -> Mask {
        self.rays
            .set(self.rays.get() + u64::from(active.count_ones()));
        self.inner.occluded_many(i, rays, tmin, tmax, active)
    }
    fn occluded_in_turn(
        &self,
        order: &[usize],
        rays: &[GridRay],
        tmin: &[f64],
        tmax: f64,
        active: Mask,
        answer: &mut dyn FnMut(usize, Mask) -> Mask,
    ) {
        // Each surface asked counts the rays it is asked about, as `occluded_many` does.
        let mut asked = active;
        self.inner
            .occluded_in_turn(order, rays, tmin, tmax, active, &mut |s, hit| {
                self.rays
                    .set(self.rays.get() + u64::from(asked.count_ones()));
                asked = answer(s, hit);
                asked
            })
    }
    fn paint(&self, i: usize, hit: &SurfaceHit) -> Option<Paint> {
        self.inner.paint(i, hit)
    }

    fn unlit(&self, i: usize) -> bool {
        self.inner.unlit(i)
    }
}

/// Pixels rendered, per thread, between two [`Tracer::release_pages`] calls: the map pages a
/// frame holds resident are those about this many pixels' rays touch, not the whole frame's;
/// they grow with the rays, up to a few pages per ray on a file much larger than the frame's view
/// of it (`docs/rendering.md`, "Map pages").
const RELEASE_PIXELS_PER_THREAD: u64 = 1 << 13;

/// Columns of the pieces a frame's strips are cut into (a multiple of [`TILE`]): pieces, not
/// strips, are what the threads share and what counts towards a release.
const PIECE_COLUMNS: u32 = 16 * TILE;

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
    let frame = FrameBuffer::zeroed(settings.width, settings.height, tracer.frame().origin);
    render_in_planes(tracer, camera, light, settings, progress, frame)
}

/// [`render_frame`] in the planes of `planes`, a frame handed back from an earlier render: its
/// memory is written again instead of fresh pages being touched. Every pixel of every plane is
/// written, so what the planes held does not matter; planes of another size are made anew.
#[inline(never)]
pub fn render_in_planes<T: Tracer + Sync + ?Sized>(
    tracer: &T,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
    planes: FrameBuffer,
) -> (FrameBuffer, u64) {
    let (w, h) = (settings.width, settings.height);
    let threads = rayon::current_num_threads().max(1) as u64;
    let release_pixels = RELEASE_PIXELS_PER_THREAD.saturating_mul(threads);
    // Pixels (times samples) rendered since the last release, by all threads.
    let since_release = AtomicU64::new(0);
    let mut frame = planes.reshaped(w, h, tracer.frame().origin);
    let mut planes = frame.rows_mut();
    let mut pending = PendingRows::default();
    let mut rays = 0;
    let band_rows = band_rows(w);
    let rendered = |pixels| {
        // The thread whose piece crosses the count releases; the others go on (their accesses
        // fault the same bytes back in).
        let before = since_release.fetch_add(pixels, Ordering::Relaxed);
        if before < release_pixels && before + pixels >= release_pixels {
            since_release.store(0, Ordering::Relaxed);
            tracer.release_pages();
        }
    };
    for b0 in (0..h).step_by(band_rows as usize) {
        let band = b0..(b0 + band_rows).min(h);
        let rows = render_band(
            tracer,
            camera,
            light,
            settings,
            (0..w, band.clone()),
            &mut planes[band.start as usize..band.end as usize],
            &rendered,
            progress,
        );
        rays += rows.iter().map(|r| r.rays).sum::<u64>();
        pending.push(rows);
        // The rows whose filter window is rendered are filtered; those the filter of the rows
        // still to come reads are kept.
        let ready = if band.end == h {
            h
        } else {
            band.end - ao_filter::MARGIN
        } as usize;
        let (rows, filtered) = pending.take_until(ready, ao_filter::MARGIN as usize);
        let first = ready - filtered.len();
        let out = &mut planes[first..ready];
        filter_rows(rows, filtered, out, camera, light, settings, w);
        pending.drop_before(ready.saturating_sub(ao_filter::MARGIN as usize));
    }
    drop(planes);
    tracer.release_pages();
    (frame, rays)
}

/// Pixels of a frame rendered before their rows' ambient occlusion is filtered: the rows' hits
/// to filter (44 bytes a hit, up to two a pixel) are held for about this many pixels at once,
/// not for the whole frame (a frame of up to this many pixels is one band). Small enough that a
/// 1024x768 frame is several bands, whose dropped rows' memory the next band's rows reuse
/// instead of touching fresh pages (`docs/benchmarks-render.md`, "clock1").
const BAND_PIXELS: u32 = 1 << 17;

/// Rows of a band of a frame `w` pixels wide: a multiple of [`TILE`] holding about
/// [`BAND_PIXELS`] pixels.
fn band_rows(w: u32) -> u32 {
    (BAND_PIXELS / w.max(1) / TILE).max(1) * TILE
}

/// Renders the columns `xs` of the rows `ys` of `settings`' frame into `planes` (one per row,
/// holding those columns), piece after piece in parallel; returns the rows' hits to filter and
/// ray queries. Calls `rendered(pixels)` after each piece and `progress(rows)` after each
/// strip's last piece.
#[allow(clippy::too_many_arguments)]
fn render_band<T: Tracer + Sync + ?Sized>(
    tracer: &T,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    (xs, ys): (Range<u32>, Range<u32>),
    planes: &mut [RowPlanes<'_>],
    rendered: &(dyn Fn(u64) + Sync),
    progress: &(dyn Fn(u64) + Sync),
) -> Vec<Row> {
    assert_eq!(planes.len(), ys.len());
    let spp = u64::from(settings.spp.max(1));
    let per_strip = xs.len().div_ceil(PIECE_COLUMNS as usize).max(1);
    // Each piece's rows: views of its columns of the frame's rows, written by the piece alone.
    let mut pieces: Vec<(u32, u32, Vec<RowPlanes<'_>>)> = Vec::new();
    for (y, strip) in ys
        .clone()
        .step_by(TILE as usize)
        .zip(planes.chunks_mut(TILE as usize))
    {
        let mut views: Vec<Vec<RowPlanes<'_>>> = (0..per_strip)
            .map(|_| Vec::with_capacity(strip.len()))
            .collect();
        for row in strip.iter_mut() {
            let columns = row.split_columns(PIECE_COLUMNS as usize);
            for (view, piece) in columns.into_iter().zip(views.iter_mut()) {
                piece.push(view);
            }
        }
        pieces.extend(
            (xs.start..)
                .step_by(PIECE_COLUMNS as usize)
                .zip(views)
                .map(|(x, rows)| (x, y, rows)),
        );
    }
    let part: Vec<Vec<Row>> = pieces
        .into_par_iter()
        .map(|(x, y, mut out)| {
            let px = x..(x + PIECE_COLUMNS).min(xs.end);
            let py = y..(y + TILE).min(ys.end);
            let (last, pixels) = (px.end == xs.end, (px.len() * py.len()) as u64 * spp);
            // The first piece of a strip holds the rows the others are appended to.
            let width = if x == xs.start { xs.len() } else { 0 };
            let strip = render_strip(tracer, camera, light, settings, (px, py), width, &mut out);
            if last {
                progress(strip.len() as u64);
            }
            rendered(pixels);
            strip
        })
        .collect();
    // The pieces of a strip are consecutive, left to right: their rows joined are the strip's.
    // Strips are joined in parallel: the joins first touch the rows' pages.
    let strips: Vec<Vec<Row>> = part.into_par_iter().chunks(per_strip).map(joined).collect();
    strips.into_iter().flatten().collect()
}

/// The rows of a strip from its pieces, left to right.
fn joined(pieces: Vec<Vec<Row>>) -> Vec<Row> {
    let mut pieces = pieces.into_iter();
    let mut strip = pieces.next().unwrap_or_default();
    let mut rest: Vec<_> = pieces.map(Vec::into_iter).collect();
    for row in &mut strip {
        let more = rest.iter_mut().filter_map(Iterator::next).collect();
        row.append_all(more);
    }
    strip
}

/// The rows of a frame rendered and not yet dropped: those not yet written and, before them,
/// the rows their filter reads.
#[derive(Default)]
struct PendingRows {
    /// Frame row of `rows[0]`.
    top: usize,
    /// Rows from `top` on.
    rows: Vec<Row>,
    /// Frame rows written so far.
    written: usize,
}

impl PendingRows {
    /// Appends the next rendered rows.
    fn push(&mut self, rows: Vec<Row>) {
        self.rows.extend(rows);
    }

    /// The rows from up to `margin` written rows before the first unwritten one to the last
    /// rendered, and which of them to write: those up to frame row `ready` (exclusive), counted
    /// as written.
    fn take_until(&mut self, ready: usize, margin: usize) -> (&mut [Row], Range<usize>) {
        let from = self.written.saturating_sub(margin).max(self.top);
        let written = self.written - from..ready - from;
        self.written = ready;
        (&mut self.rows[from - self.top..], written)
    }

    /// Drops the rows before frame row `row`.
    fn drop_before(&mut self, row: usize) {
        let row = row.max(self.top);
        self.rows.drain(..row - self.top);
        self.top = row;
    }
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
    let (mw, mh) = (mx1 - mx0, my1 - my0);
    let mut region = FrameBuffer::zeroed(mw, mh, tracer.frame().origin);
    let mut planes = region.rows_mut();
    let (xs, ys) = (mx0..mx1, my0..my1);
    let mut rows = render_band(
        tracer,
        camera,
        light,
        settings,
        (xs, ys),
        &mut planes,
        &|_| {},
        &|_| {},
    );
    let rays = rows.iter().map(|r| r.rays).sum();
    let all = 0..rows.len();
    filter_rows(&mut rows, all, &mut planes, camera, light, settings, mw);
    drop(planes);
    let (cut_x, cut_y) = ((x0 - mx0) as usize, (y0 - my0) as usize);
    let mut out = Vec::with_capacity(w as usize * h as usize);
    for y in cut_y..cut_y + h as usize {
        let row = y * mw as usize;
        out.extend((cut_x..cut_x + w as usize).map(|x| region.sample(row + x)));
    }
    (out, rays)
}

/// One rendered row's hits to filter (its pixels are in the frame) and its ray queries.
struct Row {
    ao: AoRow,
    rays: u64,
}

impl Row {
    /// Appends `more`, the rows of the pixels to the right of this row's, left to right.
    fn append_all(&mut self, more: Vec<Row>) {
        self.rays += more.iter().map(|m| m.rays).sum::<u64>();
        self.ao.append_all(more.into_iter().map(|m| m.ao).collect());
    }
}

/// True when `light`'s ambient occlusion is filtered across pixels in frames of `settings`:
/// with one sample per pixel (more samples average the occlusion within each pixel).
fn filters(light: &Lighting, settings: RenderSettings) -> bool {
    light.ao_filter && light.ao_rays > 0 && settings.spp <= 1
}

/// Pixels per side of a tile, whose primary rays are traced together.
const TILE: u32 = 8;

/// Renders the pixels `xs` of the rows `ys` (at most [`TILE`]) into `out` (one per row, from
/// column `xs.start`), tile after tile of [`TILE`] columns; returns the rows' hits to filter
/// (with room for `width` pixels) and counts the strip's ray queries in its first row.
fn render_strip<T: Tracer + ?Sized>(
    tracer: &T,
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    (xs, ys): (std::ops::Range<u32>, std::ops::Range<u32>),
    width: usize,
    out: &mut [RowPlanes<'_>],
) -> Vec<Row> {
    assert_eq!(out.len(), ys.len());
    let counting = Counting {
        inner: tracer,
        rays: Cell::new(0),
    };
    let record = filters(light, settings);
    let mut rows: Vec<Row> = ys
        .clone()
        .map(|_| Row {
            ao: AoRow::with_capacity(if record { width.max(xs.len()) } else { 0 }),
            rays: 0,
        })
        .collect();
    let mut hint = SearchHint::default();
    let dirs = camera.pixel_dirs(settings.width, settings.height);
    let frame = tracer.frame();
    // The point the AO filter's positions are taken from. A perspective camera's rays all
    // start there: their grid origin is the same.
    let eye = camera.pos;
    let grid_eye = frame.to_grid(eye);
    let pinhole = dirs.from_one_point();
    let spp = settings.spp.max(1);
    // The generators place the samples in their pixels and the shading's ambient-occlusion
    // rays; a frame that does neither leaves them out.
    let sampled = spp > 1 || light.ao_rays > 0;
    let mut unused_rng = Rng::for_pixel(0, 0, 0);
    let alone = hits_alone(tracer, light, spp);
    // With one sample per pixel, each ray passes through its pixel's centre: its direction's
    // offsets are its column's and its row's.
    let down: Vec<f64> = ys.clone().map(|y| dirs.down(f64::from(y) + 0.5)).collect();
    let mut across = [0.0f64; TILE as usize];
    let mut tile = TileHits::new(tracer.num_surfaces());
    let mut shadows = Box::<KeyShadow>::default();
    // This thread's layers of the strip before: their rays' vectors keep their room.
    let mut layers = STRIP_LAYERS.take().unwrap_or_default();
    let mut ao = TileAo::default();
    // One tile's samples, generators, world directions and grid rays, reused tile after tile.
    let mut acc: Vec<PixelAcc> = Vec::with_capacity(TILE_RAYS);
    let mut rngs = Vec::with_capacity(TILE_RAYS);
    let mut dirs_k = Vec::with_capacity(TILE_RAYS);
    let mut rays = Vec::with_capacity(TILE_RAYS);
    let miss = PixelAcc::only(PixelSample::MISS);
    for x0 in xs.clone().step_by(TILE as usize) {
        let x1 = (x0 + TILE).min(xs.end);
        let tw = (x1 - x0) as usize;
        // The tile's first column in `out`.
        let col = (x0 - xs.start) as usize;
        for (a, x) in across.iter_mut().zip(x0..x1) {
            *a = dirs.across(f64::from(x) + 0.5);
        }
        if spp > 1 {
            acc.clear();
            acc.resize(tw * ys.len(), PixelAcc::default());
        }
        for s in 0..spp {
            rngs.clear();
            dirs_k.clear();
            rays.clear();
            for (y, &sy) in ys.clone().zip(&down) {
                for (x, &sx) in (x0..x1).zip(&across) {
                    let (start, dir) = if spp > 1 {
                        let mut rng = Rng::for_pixel(x, y, s);
                        let (jx, jy) = rng.subpixel(spp);
                        rngs.push(rng);
                        dirs.ray(f64::from(x) + jx, f64::from(y) + jy)
                    } else {
                        (dirs.start(sx, sy), dirs.through(sx, sy))
                    };
                    dirs_k.push(dir);
                    rays.push(GridRay {
                        o: if pinhole {
                            grid_eye
                        } else {
                            frame.to_grid(start)
                        },
                        d: frame.to_grid_dir(dir),
                    });
                }
            }
            // A tile whose rays hit nothing has no layers: every sample is a miss.
            let any_hit = tile.trace(&counting, light, &rays, &mut hint);
            if spp == 1 && !any_hit {
                // Every pixel a miss: no generator, no shading.
                for (row, out) in rows.iter_mut().zip(out.iter_mut()) {
                    out.set_run(col, &[miss; TILE as usize][..tw]);
                    if record {
                        row.ao.end_pixels(tw);
                    }
                }
                continue;
            }
            if alone {
                shade_alone(
                    &counting,
                    &frame,
                    light,
                    eye,
                    (&dirs_k, &tile),
                    (col, tw),
                    out,
                );
                continue;
            }
            if spp == 1 && sampled {
                // With one sample, the generators only place the shading's rays: made for the
                // tiles that have any (the centre sample leaves them as they are).
                for y in ys.clone() {
                    rngs.extend((x0..x1).map(|x| Rng::for_pixel(x, y, s)));
                }
            }
            if any_hit {
                layers.trace(&counting, light, &rays, &mut tile);
                shadows.trace(&counting, light, &dirs_k, &mut layers);
                if light.ao_rays > 0 {
                    ao.trace(&counting, light, &dirs_k, &mut rngs, &mut layers);
                }
            }
            // A row of the tile's pixels, written into the planes at once.
            let mut run = [PixelSample::MISS; TILE as usize];
            let last = s + 1 == spp;
            for (r, row) in rows.iter_mut().enumerate() {
                for k in r * tw..(r + 1) * tw {
                    let sample = if any_hit {
                        let ao_layers = record.then_some(row.ao.layers_mut());
                        let rng = if sampled {
                            &mut rngs[k]
                        } else {
                            &mut unused_rng
                        };
                        let (dir, of) = (dirs_k[k], layers.of(k));
                        shade_hits(&counting, &frame, light, (eye, dir), of, rng, ao_layers)
                    } else {
                        PixelSample::MISS
                    };
                    let pixel = if spp == 1 {
                        PixelAcc::only(sample)
                    } else {
                        acc[k].add(sample);
                        if s + 1 < spp {
                            continue;
                        }
                        acc[k].finish(spp)
                    };
                    run[k - r * tw] = pixel;
                    if record {
                        row.ao.end_pixel();
                    }
                }
                if last {
                    out[r].set_run(col, &run[..tw]);
                }
            }
        }
    }
    if let Some(first) = rows.first_mut() {
        first.rays = counting.rays.get();
    }
    STRIP_LAYERS.set(Some(layers));
    rows
}

/// True when each pixel of a frame is its one primary ray's hit shaded alone: one sample per
/// pixel, one opaque surface (a ray's one layer is its hit) and no shadow or AO rays to trace
/// for it. Such a tile's pixels are shaded straight from its hits ([`shade_alone`]), without
/// the layers, shadow and AO stages that give each hit nothing more.
fn hits_alone<T: Tracer + ?Sized>(tracer: &T, light: &Lighting, spp: u32) -> bool {
    spp == 1
        && tracer.num_surfaces() == 1
        && light.opacity[0] >= 1.0
        && !light.shadows
        && light.ao_rays == 0
}

/// Writes the pixels of a tile `tw` rays wide from column `col` of `out` (one per row of the
/// tile) when [`hits_alone`]: each ray `k`'s hit in `tile`, seen along `dirs[k]` by a camera at
/// `eye`, shaded as [`shade_hit_alone`] (a miss where it has none).
#[inline(always)]
fn shade_alone<T: Tracer + ?Sized>(
    tracer: &T,
    frame: &GridFrame,
    light: &Lighting,
    eye: [f64; 3],
    (dirs, tile): (&[[f64; 3]], &TileHits),
    (col, tw): (usize, usize),
    out: &mut [RowPlanes<'_>],
) {
    let mut unused_rng = Rng::for_pixel(0, 0, 0);
    let mut run = [PixelSample::MISS; TILE as usize];
    for (r, out) in out.iter_mut().enumerate() {
        for (k, px) in (r * tw..(r + 1) * tw).zip(&mut run) {
            let sample = match tile.hit(k, 0) {
                Some(hit) => {
                    let (ray, hit) = ((eye, dirs[k]), (0, hit));
                    shade_hit_alone(tracer, frame, light, ray, hit, &mut unused_rng)
                }
                None => PixelSample::MISS,
            };
            *px = PixelAcc::only(sample);
        }
        out.set_run(col, &run[..tw]);
    }
}

thread_local! {
    /// The [`TileLayers`] of this thread's last strip, reused by its next one: a strip that
    /// allocated its own grew each of its rays' vectors of layers anew.
    static STRIP_LAYERS: Cell<Option<Box<TileLayers>>> = const { Cell::new(None) };
}

/// Filters the ambient occlusion of the rows `filtered` of `rows` (a rectangle `w` pixels wide,
/// top row first) in their pixels' colours, `out` (one per filtered row); rows in parallel. The
/// filter reads the rows of `rows` around them too. Nothing to do for frames without the filter.
#[allow(clippy::too_many_arguments)]
fn filter_rows(
    rows: &mut [Row],
    filtered: Range<usize>,
    out: &mut [RowPlanes<'_>],
    camera: &Camera,
    light: &Lighting,
    settings: RenderSettings,
    w: u32,
) {
    assert_eq!(filtered.len(), out.len());
    if !filters(light, settings) {
        return;
    }
    // The filter reads the rows' hits as one slice; they are handed back at the end.
    let ao: Vec<AoRow> = rows.iter_mut().map(|r| std::mem::take(&mut r.ao)).collect();
    // A pixel's size at a unit's distance: the angle it spans, or its size at every depth.
    let size = camera.pixel_size(1.0, settings.height) as f32;
    let span = match camera.projection {
        Projection::Perspective => PixelSpan::Angle(size),
        Projection::Orthographic { .. } => PixelSpan::Parallel {
            size,
            forward: camera.forward().map(|v| v as f32),
        },
    };
    // Band after band of rows, each band's rows in parallel: the filter's slots are held for
    // one band (and its margins) at a time, not for all the rows.
    for (y0, out) in filtered
        .clone()
        .step_by(FILTER_BAND)
        .zip(out.chunks_mut(FILTER_BAND))
    {
        let band = y0 as u32..(y0 + out.len()) as u32;
        let filter = AoRows::band(w, &ao, band);
        out.par_iter_mut().enumerate().for_each(|(i, row)| {
            filter.apply_row((y0 + i) as u32, row.rgb_mut(), span);
        });
    }
    for (row, ao) in rows.iter_mut().zip(ao) {
        row.ao = ao;
    }
}

/// Rows filtered together by [`filter_rows`]: the slots of about this many rows are held at once.
const FILTER_BAND: usize = 64;

/// A pixel's samples added up: the average of their colours and coverage, the rest of the first
/// sample that hit anything.
#[derive(Clone, Copy)]
struct PixelAcc {
    first: PixelSample,
    have_first: bool,
    rgba: [f32; 4],
}

impl Default for PixelAcc {
    fn default() -> Self {
        Self {
            first: PixelSample::MISS,
            have_first: false,
            rgba: [0.0; 4],
        }
    }
}

impl PixelAcc {
    fn add(&mut self, sample: PixelSample) {
        for c in 0..3 {
            self.rgba[c] += sample.rgb[c];
        }
        self.rgba[3] += sample.alpha;
        if !self.have_first && sample.alpha > 0.0 {
            self.first = sample;
            self.have_first = true;
        }
    }

    /// The pixel of one sample: what [`PixelAcc::add`] and [`PixelAcc::finish`] give it.
    #[inline]
    fn only(sample: PixelSample) -> PixelSample {
        let mut px = if sample.alpha > 0.0 {
            sample
        } else {
            PixelSample::MISS
        };
        px.rgb = sample.rgb.map(|c| 0.0 + c);
        px.alpha = 0.0 + sample.alpha;
        px
    }

    /// The pixel of `spp` samples.
    fn finish(&self, spp: u32) -> PixelSample {
        let inv = 1.0 / spp as f32;
        let mut px = self.first;
        px.rgb = [self.rgba[0] * inv, self.rgba[1] * inv, self.rgba[2] * inv];
        px.alpha = self.rgba[3] * inv;
        px
    }
}
