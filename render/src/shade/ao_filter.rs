//! An edge-aware spatial filter of the ambient-occlusion term alone: each shaded hit's
//! occlusion becomes the average of the occlusions of the hits of the same surface, on the
//! same plane and facing the same way, in the pixels around it; the rest of the colour
//! (lights, shadows, specular highlights, edges between surfaces) is left sharp.
//!
//! The colour of a hit is linear in its occlusion, so the shader keeps, for the first few
//! shaded hits along a pixel's ray, the occlusion it shaded with and how much the pixel's colour
//! changes per unit of it ([`AoLayer`]); the filter then moves the pixel's colour by that much
//! times the change of the occlusion. It runs after the whole frame (or a rectangle with a
//! margin of [`MARGIN`] pixels), in a fixed order: the frame is the same on any number of
//! threads and in tiles.
//!
//! The window is the size of the tile the rays' pattern is spread over
//! ([`crate::shade::sampling::TILE`]): on a smooth surface it averages each stratum of the
//! pattern once.

use std::ops::Range;

use rayon::prelude::*;

use crate::output::frame::PixelSample;
use crate::shade::sampling::TILE;

#[cfg(target_arch = "x86_64")]
mod x8;

/// Pixels of the filter's square window before a pixel, on each axis.
const BEFORE: u32 = TILE / 2;
/// Pixels of the window after a pixel, on each axis.
const AFTER: u32 = TILE - 1 - BEFORE;
/// Pixels around a rectangle of a frame that the filter of its pixels reads.
pub const MARGIN: u32 = BEFORE;
/// Shaded hits per pixel whose occlusion is filtered (the nearest ones along the ray).
pub const FILTERED_HITS: usize = 2;
/// Least cosine between the normals of two hits averaged together.
const MIN_NORMAL_COSINE: f32 = 0.9;
/// Least cosine between a hit's normal and its ray counted in the plane tolerance.
const MIN_FACING: f32 = 0.2;
/// Largest distance of a neighbour's hit from a hit's tangent plane, in pixel footprints at
/// the hit per pixel of offset (at least one).
const PLANE_TOLERANCE: f32 = 1.0;

/// One shaded hit's ambient occlusion and what the filter compares between hits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AoLayer {
    /// The isosurface hit.
    pub surface: u32,
    /// Hit position relative to the camera, world coordinates.
    pub p: [f32; 3],
    /// Unit normal on the camera's side.
    pub n: [f32; 3],
    /// The occlusion shaded with: the fraction of ambient light that reaches the hit.
    pub ao: f32,
    /// Change of the pixel's premultiplied colour per unit of `ao`.
    pub weight: [f32; 3],
}

/// The filtered hits of one row of pixels: pixel `x`'s are `layers[start[x]..start[x + 1]]`.
#[derive(Clone, Debug, Default)]
pub struct AoRow {
    start: Vec<u32>,
    layers: Vec<AoLayer>,
    /// Each hit's pixel, so that a window's hits in a row are read as one run.
    column: Vec<u32>,
}

impl AoRow {
    /// An empty row, to be filled pixel by pixel from the left.
    pub fn new() -> AoRow {
        AoRow::with_capacity(0)
    }

    /// An empty row with room for `pixels` pixels' hits (at most [`FILTERED_HITS`] each): a
    /// row filled or appended to up to that many pixels never grows its vectors.
    pub fn with_capacity(pixels: usize) -> AoRow {
        let mut start = Vec::with_capacity(pixels + 1);
        start.push(0);
        AoRow {
            start,
            layers: Vec::with_capacity(FILTERED_HITS * pixels),
            column: Vec::with_capacity(FILTERED_HITS * pixels),
        }
    }

    /// The hits recorded so far, to which the next pixel appends its own before
    /// [`AoRow::end_pixel`].
    pub fn layers_mut(&mut self) -> &mut Vec<AoLayer> {
        &mut self.layers
    }

    /// Ends the current pixel: the hits appended since the last call are its.
    pub fn end_pixel(&mut self) {
        let x = self.start.len() as u32 - 1;
        self.column.resize(self.layers.len(), x);
        self.start.push(self.layers.len() as u32);
    }

    /// Appends `more`, the pixels to the right of this row's.
    pub fn append(&mut self, more: AoRow) {
        let layers = self.layers.len() as u32;
        let pixels = self.start.len() as u32 - 1;
        self.start
            .extend(more.start[1..].iter().map(|&s| s + layers));
        self.layers.extend(more.layers);
        self.column.extend(more.column.iter().map(|&x| x + pixels));
    }

    fn pixel(&self, x: u32) -> &[AoLayer] {
        let x = x as usize;
        &self.layers[self.start[x] as usize..self.start[x + 1] as usize]
    }
}

/// The filtered hits of a rectangle of pixels, one [`AoRow`] per row from the top, and what
/// the window's comparisons read of them, as columns.
#[derive(Clone, Debug)]
pub struct AoRows<'a> {
    width: u32,
    rows: &'a [AoRow],
    columns: Vec<HitColumns>,
}

impl<'a> AoRows<'a> {
    /// The rows `rows` of a rectangle `width` pixels wide (each row holding `width` pixels).
    pub fn new(width: u32, rows: &'a [AoRow]) -> AoRows<'a> {
        assert!(rows.iter().all(|r| r.start.len() == width as usize + 1));
        let columns = rows.par_iter().map(HitColumns::of).collect();
        AoRows {
            width,
            rows,
            columns,
        }
    }

    /// Replaces the occlusion of every hit of row `y` by the filtered one in the colour of
    /// `pixels` (that row). `pixel_angle` is the angle one pixel spans (radians). Each row
    /// reads the others only, so rows can be filtered in any order and in parallel.
    pub fn apply_row(&self, y: u32, pixels: &mut [PixelSample], pixel_angle: f32) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            return unsafe { self.apply_row_avx2(y, pixels, pixel_angle) };
        }
        self.apply_row_with(y, pixels, pixel_angle, HitColumns::add_run);
    }

    /// [`AoRows::apply_row`] with the window's runs tested eight hits at a time.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn apply_row_avx2(&self, y: u32, pixels: &mut [PixelSample], pixel_angle: f32) {
        self.apply_row_with(y, pixels, pixel_angle, |cols, run, centre, mean| {
            x8::add_run(cols, run, centre, mean)
        });
    }

    /// [`AoRows::apply_row`], each run of a window's hits in a row added by `add_run`.
    #[inline(always)]
    fn apply_row_with(
        &self,
        y: u32,
        pixels: &mut [PixelSample],
        pixel_angle: f32,
        add_run: impl Fn(&HitColumns, Range<usize>, &Centre, &mut Mean),
    ) {
        assert_eq!(pixels.len(), self.width as usize);
        for (x, px) in pixels.iter_mut().enumerate() {
            let x = x as u32;
            for layer in self.rows[y as usize].pixel(x) {
                let ao = self.filtered(layer, x, y, pixel_angle, &add_run);
                for c in 0..3 {
                    px.rgb[c] += layer.weight[c] * (ao - layer.ao);
                }
            }
        }
    }

    /// The filtered occlusion of `layer`, a hit in pixel `(x, y)`.
    #[inline(always)]
    fn filtered(
        &self,
        layer: &AoLayer,
        x: u32,
        y: u32,
        pixel_angle: f32,
        add_run: &impl Fn(&HitColumns, Range<usize>, &Centre, &mut Mean),
    ) -> f32 {
        let distance = norm(layer.p);
        let facing = (dot(layer.n, layer.p).abs() / distance).max(MIN_FACING);
        let mut centre = Centre {
            surface: layer.surface,
            p: layer.p,
            n: layer.n,
            footprint: PLANE_TOLERANCE * distance * pixel_angle / (facing * facing),
            x,
            least_steps: 1,
        };
        let mut mean = Mean::default();
        let (x0, x1) = (x.saturating_sub(BEFORE), (x + AFTER).min(self.width - 1));
        let last_row = self.rows.len() as u32 - 1;
        for qy in y.saturating_sub(BEFORE)..=(y + AFTER).min(last_row) {
            let row = &self.rows[qy as usize];
            centre.least_steps = qy.abs_diff(y).max(1);
            // The window's hits in this row, pixel after pixel from `x0`: one run.
            let run = row.start[x0 as usize] as usize..row.start[x1 as usize + 1] as usize;
            add_run(&self.columns[qy as usize], run, &centre, &mut mean);
        }
        if mean.count > 0 {
            mean.sum / mean.count as f32
        } else {
            layer.ao
        }
    }
}

/// The hit whose occlusion is filtered, as the window's comparisons see it, in one row of the
/// window.
#[derive(Clone, Copy, Debug)]
struct Centre {
    surface: u32,
    p: [f32; 3],
    n: [f32; 3],
    /// The plane tolerance per pixel of offset.
    footprint: f32,
    /// Its pixel's column.
    x: u32,
    /// The offset counted for a neighbour in its own column: the row's distance, at least one.
    least_steps: u32,
}

/// The occlusions of the neighbours kept so far: their sum, in the window's order, and number.
#[derive(Clone, Copy, Debug, Default)]
struct Mean {
    sum: f32,
    count: u32,
}

/// One row's hits as columns, what the window's comparisons read, followed by
/// [`HitColumns::PAD`] entries that no comparison keeps.
#[derive(Clone, Debug, Default)]
struct HitColumns {
    surface: Vec<u32>,
    p: [Vec<f32>; 3],
    n: [Vec<f32>; 3],
    ao: Vec<f32>,
    /// Each hit's pixel.
    column: Vec<u32>,
}

impl HitColumns {
    /// Entries after the last hit: a group of that many read from any hit stays inside.
    const PAD: usize = 8;

    fn of(row: &AoRow) -> HitColumns {
        let len = row.layers.len() + Self::PAD;
        let mut c = HitColumns {
            surface: Vec::with_capacity(len),
            p: std::array::from_fn(|_| Vec::with_capacity(len)),
            n: std::array::from_fn(|_| Vec::with_capacity(len)),
            ao: Vec::with_capacity(len),
            column: Vec::with_capacity(len),
        };
        for l in &row.layers {
            c.surface.push(l.surface);
            for a in 0..3 {
                c.p[a].push(l.p[a]);
                c.n[a].push(l.n[a]);
            }
            c.ao.push(l.ao);
        }
        c.column.extend_from_slice(&row.column);
        // A surface no hit has: the padding is never the centre's.
        c.surface.resize(len, u32::MAX);
        for a in 0..3 {
            c.p[a].resize(len, 0.0);
            c.n[a].resize(len, 0.0);
        }
        c.ao.resize(len, 0.0);
        c.column.resize(len, 0);
        c
    }

    /// Number of hits (the padding left out).
    fn hits(&self) -> usize {
        self.ao.len() - Self::PAD
    }

    /// Adds to `mean` the occlusions of the hits `run` that are of `centre`'s surface, face its
    /// way and lie on its tangent plane, in their order.
    fn add_run(&self, run: Range<usize>, centre: &Centre, mean: &mut Mean) {
        for i in run {
            let n = [self.n[0][i], self.n[1][i], self.n[2][i]];
            let p = [self.p[0][i], self.p[1][i], self.p[2][i]];
            let steps = self.column[i].abs_diff(centre.x).max(centre.least_steps);
            if self.surface[i] == centre.surface
                && dot(n, centre.n) >= MIN_NORMAL_COSINE
                && dot(centre.n, sub(p, centre.p)).abs() <= centre.footprint * steps as f32
            {
                mean.sum += self.ao[i];
                mean.count += 1;
            }
        }
    }
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f32; 3]) -> f32 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(surface: u32, z: f32, n: [f32; 3], ao: f32) -> AoLayer {
        AoLayer {
            surface,
            p: [0.0, 0.0, z],
            n,
            ao,
            weight: [1.0; 3],
        }
    }

    #[test]
    fn a_row_appended_in_pieces_equals_the_row_filled_at_once() {
        let facing = [0.0, 0.0, -1.0];
        let pixels = [
            vec![layer(0, 1.0, facing, 0.5)],
            vec![],
            vec![layer(0, 1.0, facing, 0.25), layer(1, 2.0, facing, 0.75)],
            vec![layer(1, 2.0, facing, 1.0)],
            vec![],
        ];
        let fill = |range: std::ops::Range<usize>| {
            let mut row = AoRow::new();
            for p in &pixels[range] {
                row.layers_mut().extend_from_slice(p);
                row.end_pixel();
            }
            row
        };
        let whole = fill(0..5);
        for cut in 0..=5 {
            let mut joined = fill(0..cut);
            joined.append(fill(cut..5));
            assert_eq!(joined.start, whole.start, "cut at {cut}");
            assert_eq!(joined.layers, whole.layers, "cut at {cut}");
            assert_eq!(joined.column, whole.column, "cut at {cut}");
        }
    }

    #[test]
    fn averages_a_plane_and_keeps_other_surfaces_and_planes_apart() {
        let mut row = AoRow::new();
        let facing = [0.0, 0.0, -1.0];
        // A plane at z = 1 seen head on, with one pixel of another surface and one far behind.
        let rows = [
            vec![layer(0, 1.0, facing, 1.0)],
            vec![layer(0, 1.0, facing, 0.0)],
            vec![layer(1, 1.0, facing, 0.2)],
            vec![layer(0, 3.0, facing, 0.9)],
            vec![],
        ];
        for r in &rows {
            row.layers_mut().extend_from_slice(r);
            row.end_pixel();
        }
        let rows = [row];
        let mut pixels = vec![PixelSample::MISS; 5];
        AoRows::new(5, &rows).apply_row(0, &mut pixels, 0.01);
        assert_eq!(pixels[0].rgb[0], 0.5 - 1.0);
        assert_eq!(pixels[1].rgb[0], 0.5);
        assert_eq!(pixels[2].rgb[0], 0.0);
        assert_eq!(pixels[3].rgb[0], 0.0);
        assert_eq!(pixels[4].rgb[0], 0.0);
    }
}
