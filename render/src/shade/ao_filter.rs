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

/// How large one pixel is at a hit: what the plane tolerance scales with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PixelSpan {
    /// A perspective camera's: the angle one pixel spans (radians), its size at a hit growing
    /// with the hit's distance from the camera, which a ray faces a hit along.
    Angle(f32),
    /// An orthographic camera's: one pixel's size in world units at every depth, and the
    /// view's unit direction, which every ray faces a hit along.
    Parallel {
        /// A pixel's size, world units.
        size: f32,
        /// The view's unit direction.
        forward: [f32; 3],
    },
}

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
}

impl AoRow {
    /// An empty row, to be filled pixel by pixel from the left.
    pub fn new() -> AoRow {
        AoRow::with_capacity(0)
    }

    /// An empty row with room for `pixels` pixels. Their hits grow as they come: room for the
    /// most a row can hold ([`FILTERED_HITS`] per pixel) would be about 88 bytes a pixel of the
    /// frame held until the filter, most of it never used.
    pub fn with_capacity(pixels: usize) -> AoRow {
        let mut start = Vec::with_capacity(pixels + 1);
        start.push(0);
        AoRow {
            start,
            layers: Vec::new(),
        }
    }

    /// The hits recorded so far, to which the next pixel appends its own before
    /// [`AoRow::end_pixel`].
    pub fn layers_mut(&mut self) -> &mut Vec<AoLayer> {
        &mut self.layers
    }

    /// Ends the current pixel: the hits appended since the last call are its.
    pub fn end_pixel(&mut self) {
        self.start.push(self.layers.len() as u32);
    }

    /// Ends `n` pixels without hits.
    pub fn end_pixels(&mut self, n: usize) {
        let at = self.layers.len() as u32;
        self.start.resize(self.start.len() + n, at);
    }

    /// Appends `more`, the pixels to the right of this row's.
    pub fn append(&mut self, more: AoRow) {
        let layers = self.layers.len() as u32;
        self.start
            .extend(more.start[1..].iter().map(|&s| s + layers));
        self.layers.extend(more.layers);
    }

    /// Appends `more`, the rows of the pixels to the right of this row's, left to right, the
    /// room for all of their hits made at once.
    pub fn append_all(&mut self, more: Vec<AoRow>) {
        self.start
            .reserve(more.iter().map(|m| m.start.len() - 1).sum());
        self.layers
            .reserve(more.iter().map(|m| m.layers.len()).sum());
        for more in more {
            self.append(more);
        }
    }

    fn pixel(&self, x: u32) -> &[AoLayer] {
        let x = x as usize;
        &self.layers[self.start[x] as usize..self.start[x + 1] as usize]
    }
}

/// The filtered hits of a rectangle of pixels, one [`AoRow`] per row from the top, and what
/// the window's comparisons read of them ([`Slots`]) for a band of its rows.
#[derive(Clone, Debug)]
pub struct AoRows<'a> {
    width: u32,
    rows: &'a [AoRow],
    /// The rows whose slots are kept: those of the band and its window's margins.
    kept: Range<u32>,
    /// Per kept row, each hit's slots; `None` where no pixel of the row has that hit, read as
    /// `empty`.
    slots: Vec<[Option<Slots>; FILTERED_HITS]>,
    /// The slots of a row without the hit: what [`Slots::of`] would make for it.
    empty: Slots,
}

impl<'a> AoRows<'a> {
    /// The rows `rows` of a rectangle `width` pixels wide (each row holding `width` pixels),
    /// for filtering any of them.
    pub fn new(width: u32, rows: &'a [AoRow]) -> AoRows<'a> {
        AoRows::band(width, rows, 0..rows.len() as u32)
    }

    /// The rows `rows` of a rectangle `width` pixels wide, for filtering the rows `band`:
    /// the slots, about 64 bytes a pixel, are made for those and their window's margins only.
    pub fn band(width: u32, rows: &'a [AoRow], band: Range<u32>) -> AoRows<'a> {
        assert!(rows.iter().all(|r| r.start.len() == width as usize + 1));
        let kept = band.start.saturating_sub(BEFORE)..(band.end + AFTER).min(rows.len() as u32);
        let slots = rows[kept.start as usize..kept.end as usize]
            .par_iter()
            .map(|row| std::array::from_fn(|h| Slots::of(row, h)))
            .collect();
        AoRows {
            width,
            rows,
            kept,
            slots,
            empty: Slots::empty(width as usize),
        }
    }

    /// Row `y`'s slots (a row of the band or its margins).
    fn slots_of(&self, y: u32) -> [&Slots; FILTERED_HITS] {
        assert!(self.kept.contains(&y));
        let slots = &self.slots[(y - self.kept.start) as usize];
        std::array::from_fn(|h| slots[h].as_ref().unwrap_or(&self.empty))
    }

    /// Replaces the occlusion of every hit of row `y` (of the band) by the filtered one in the
    /// colour of `pixels` (that row), a pixel spanning `span`. Each row reads the others only,
    /// so rows can be filtered in any order and in parallel.
    pub fn apply_row(&self, y: u32, rgb: [&mut [f32]; 3], span: PixelSpan) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            return unsafe { self.apply_row_avx2(y, rgb, span) };
        }
        self.apply_row_with(y, rgb, |x0, h, out| {
            for (x, out) in (x0..(x0 + GROUP).min(self.width as usize)).zip(out) {
                if let Some(layer) = self.rows[y as usize].pixel(x as u32).get(h) {
                    *out = self.filtered(layer, x as u32, y, span);
                }
            }
        });
    }

    /// [`AoRows::apply_row`] with the hits of [`GROUP`] pixels filtered at once.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn apply_row_avx2(&self, y: u32, rgb: [&mut [f32]; 3], span: PixelSpan) {
        self.apply_row_with(y, rgb, |x0, h, out| {
            x8::filter_group(self, y, x0, h, span, out)
        });
    }

    /// [`AoRows::apply_row`], `filter(x0, h, out)` writing the filtered occlusion of hit `h` of
    /// each of the [`GROUP`] pixels from `x0` that have one (`out[x - x0]`).
    #[inline(always)]
    fn apply_row_with(
        &self,
        y: u32,
        mut rgb: [&mut [f32]; 3],
        mut filter: impl FnMut(usize, usize, &mut [f32; GROUP]),
    ) {
        let width = self.width as usize;
        assert!(rgb.iter().all(|c| c.len() == width));
        let row = &self.rows[y as usize];
        let slots = self.slots_of(y);
        let mut out = [[0.0f32; GROUP]; FILTERED_HITS];
        for x0 in (0..width).step_by(GROUP) {
            let mut any = false;
            for (h, out) in out.iter_mut().enumerate() {
                if slots[h].any_hit(x0) {
                    filter(x0, h, out);
                    any = true;
                }
            }
            if !any {
                continue;
            }
            for (i, x) in (x0..(x0 + GROUP).min(width)).enumerate() {
                for (h, layer) in row.pixel(x as u32).iter().enumerate() {
                    let ao = out[h][i];
                    for (c, colour) in rgb.iter_mut().enumerate() {
                        colour[x] += layer.weight[c] * (ao - layer.ao);
                    }
                }
            }
        }
    }

    /// The filtered occlusion of `layer`, a hit of pixel `(x, y)`: the mean over the window
    /// around it of the occlusions of the hits of its surface that face its way and lie on its
    /// tangent plane, added up row after row, pixel after pixel, hit after hit.
    fn filtered(&self, layer: &AoLayer, x: u32, y: u32, span: PixelSpan) -> f32 {
        let footprint = footprint(layer.p, layer.n, span);
        let (mut sum, mut count) = (0.0f32, 0u32);
        let last_row = self.rows.len() as u32 - 1;
        for qy in y.saturating_sub(BEFORE)..=(y + AFTER).min(last_row) {
            let dy = qy.abs_diff(y);
            let row = self.slots_of(qy);
            for (dx, steps) in window_columns(dy) {
                let tolerance = footprint * steps;
                // Slot `x + BEFORE` is pixel `x`'s: the window's columns are all inside.
                let i = (x + BEFORE) as usize;
                let i = i.wrapping_add_signed(dx);
                for q in row {
                    let n = [q.n[0][i], q.n[1][i], q.n[2][i]];
                    let p = [q.p[0][i], q.p[1][i], q.p[2][i]];
                    if q.surface[i] == layer.surface
                        && dot(n, layer.n) >= MIN_NORMAL_COSINE
                        && dot(layer.n, sub(p, layer.p)).abs() <= tolerance
                    {
                        sum += q.ao[i];
                        count += 1;
                    }
                }
            }
        }
        if count > 0 {
            sum / count as f32
        } else {
            layer.ao
        }
    }
}

/// Pixels whose hits are filtered together (one per lane).
const GROUP: usize = 8;

/// The plane tolerance per pixel of offset of a hit at `p` (from the camera) with normal `n`.
#[inline(always)]
fn footprint(p: [f32; 3], n: [f32; 3], span: PixelSpan) -> f32 {
    match span {
        PixelSpan::Angle(angle) => {
            let distance = norm(p);
            let facing = (dot(n, p).abs() / distance).max(MIN_FACING);
            PLANE_TOLERANCE * distance * angle / (facing * facing)
        }
        PixelSpan::Parallel { size, forward } => {
            let facing = dot(n, forward).abs().max(MIN_FACING);
            PLANE_TOLERANCE * size / (facing * facing)
        }
    }
}

/// The window's columns in a row `dy` rows away, from the left: each one's offset and the
/// pixels of offset its plane tolerance counts (the larger on either axis, at least one).
#[inline(always)]
fn window_columns(dy: u32) -> impl Iterator<Item = (isize, f32)> {
    (-(BEFORE as isize)..=AFTER as isize)
        .map(move |dx| (dx, dx.unsigned_abs().max(dy as usize).max(1) as f32))
}

/// Hit `h` of each pixel of a row, as columns, what the window's comparisons read: pixel
/// `x`'s at `x + BEFORE`, with [`BEFORE`] entries before the row's first pixel and [`AFTER`]
/// plus [`GROUP`] after its last that no comparison keeps (of no surface), as none where a
/// pixel has fewer hits. The window's neighbour of every pixel of a group is then one
/// column's entry at a fixed offset, and its neighbours' tests are a group's lanes.
#[derive(Clone, Debug, Default)]
struct Slots {
    surface: Vec<u32>,
    p: [Vec<f32>; 3],
    n: [Vec<f32>; 3],
    ao: Vec<f32>,
}

impl Slots {
    /// The surface of an entry without a hit.
    const NONE: u32 = u32::MAX;

    /// Hit `h` of each pixel of `row`; `None` when no pixel has one (the row's slots are then
    /// [`Slots::empty`]'s).
    fn of(row: &AoRow, h: usize) -> Option<Slots> {
        let pixels = row.start.len() - 1;
        // Pixel `x`'s hits start at `start[x]` and end at `start[x + 1]`.
        let has_hit = |w: &[u32]| (w[1] - w[0]) as usize > h;
        let first = row.start.windows(2).position(has_hit)?;
        let mut s = Slots::empty(pixels);
        for (x, w) in row.start.windows(2).enumerate().skip(first) {
            if !has_hit(w) {
                continue;
            }
            let l = &row.layers[w[0] as usize + h];
            let i = x + BEFORE as usize;
            s.surface[i] = l.surface;
            for a in 0..3 {
                s.p[a][i] = l.p[a];
                s.n[a][i] = l.n[a];
            }
            s.ao[i] = l.ao;
        }
        Some(s)
    }

    /// The slots of a row of `pixels` pixels none of which has the hit.
    fn empty(pixels: usize) -> Slots {
        let len = BEFORE as usize + pixels + AFTER as usize + GROUP;
        Slots {
            surface: vec![Self::NONE; len],
            p: std::array::from_fn(|_| vec![0.0; len]),
            n: std::array::from_fn(|_| vec![0.0; len]),
            ao: vec![0.0; len],
        }
    }

    /// True when a pixel of the group from `x0` has a hit here.
    fn any_hit(&self, x0: usize) -> bool {
        let i = x0 + BEFORE as usize;
        self.surface[i..i + GROUP].iter().any(|&s| s != Self::NONE)
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
        }
    }

    #[test]
    fn pixels_ended_at_once_equal_pixels_ended_one_by_one() {
        let facing = [0.0, 0.0, -1.0];
        let (mut a, mut b) = (AoRow::new(), AoRow::new());
        for row in [&mut a, &mut b] {
            row.layers_mut().push(layer(0, 1.0, facing, 0.5));
            row.end_pixel();
        }
        a.end_pixels(3);
        for _ in 0..3 {
            b.end_pixel();
        }
        assert_eq!((a.start, a.layers), (b.start, b.layers));
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
        let [mut r, mut g, mut b] = [(); 3].map(|_| vec![0.0f32; 5]);
        AoRows::new(5, &rows).apply_row(0, [&mut r, &mut g, &mut b], PixelSpan::Angle(0.01));
        assert_eq!(r, [0.5 - 1.0, 0.5, 0.0, 0.0, 0.0]);
    }
}
