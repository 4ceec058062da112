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

use rayon::prelude::*;

use crate::output::frame::PixelSample;
use crate::shade::sampling::TILE;

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

/// The filtered hits of a rectangle of pixels, row-major: pixel `i`'s are
/// `layers[start[i]..start[i + 1]]`.
#[derive(Clone, Debug, Default)]
pub struct AoBuffer {
    width: u32,
    height: u32,
    start: Vec<u32>,
    layers: Vec<AoLayer>,
}

impl AoBuffer {
    /// A buffer for `width x height` pixels, to be filled pixel by pixel in row-major order.
    pub fn new(width: u32, height: u32) -> AoBuffer {
        let mut start = Vec::with_capacity(width as usize * height as usize + 1);
        start.push(0);
        AoBuffer {
            width,
            height,
            start,
            layers: Vec::new(),
        }
    }

    /// Appends the next pixel's hits.
    pub fn push_pixel(&mut self, layers: &[AoLayer]) {
        self.layers.extend_from_slice(layers);
        self.start.push(self.layers.len() as u32);
    }

    fn pixel(&self, x: u32, y: u32) -> &[AoLayer] {
        let i = (y * self.width + x) as usize;
        &self.layers[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// Replaces the occlusion of every hit by the filtered one in the colour of `pixels` (the
    /// same rectangle, row-major). `pixel_angle` is the angle one pixel spans (radians).
    pub fn apply(&self, pixels: &mut [PixelSample], pixel_angle: f32) {
        assert_eq!(pixels.len() + 1, self.start.len());
        let w = self.width as usize;
        pixels
            .par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(y, row)| {
                for (x, px) in row.iter_mut().enumerate() {
                    let (x, y) = (x as u32, y as u32);
                    for layer in self.pixel(x, y) {
                        let ao = self.filtered(layer, x, y, pixel_angle);
                        for c in 0..3 {
                            px.rgb[c] += layer.weight[c] * (ao - layer.ao);
                        }
                    }
                }
            });
    }

    /// The filtered occlusion of `layer`, a hit in pixel `(x, y)`.
    fn filtered(&self, layer: &AoLayer, x: u32, y: u32, pixel_angle: f32) -> f32 {
        let distance = norm(layer.p);
        let facing = (dot(layer.n, layer.p).abs() / distance).max(MIN_FACING);
        let footprint = PLANE_TOLERANCE * distance * pixel_angle / (facing * facing);
        let (mut sum, mut count) = (0.0f32, 0u32);
        let (x0, x1) = (x.saturating_sub(BEFORE), (x + AFTER).min(self.width - 1));
        for qy in y.saturating_sub(BEFORE)..=(y + AFTER).min(self.height - 1) {
            let row = (qy * self.width) as usize;
            let dy = qy.abs_diff(y);
            for qx in x0..=x1 {
                let offset = qx.abs_diff(x).max(dy).max(1) as f32;
                let (first, last) = (
                    self.start[row + qx as usize],
                    self.start[row + qx as usize + 1],
                );
                for q in &self.layers[first as usize..last as usize] {
                    if q.surface == layer.surface
                        && dot(q.n, layer.n) >= MIN_NORMAL_COSINE
                        && dot(layer.n, sub(q.p, layer.p)).abs() <= footprint * offset
                    {
                        sum += q.ao;
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
    fn averages_a_plane_and_keeps_other_surfaces_and_planes_apart() {
        let (w, h) = (5, 1);
        let mut buf = AoBuffer::new(w, h);
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
            buf.push_pixel(r);
        }
        let mut pixels = vec![PixelSample::MISS; 5];
        buf.apply(&mut pixels, 0.01);
        assert_eq!(pixels[0].rgb[0], 0.5 - 1.0);
        assert_eq!(pixels[1].rgb[0], 0.5);
        assert_eq!(pixels[2].rgb[0], 0.0);
        assert_eq!(pixels[3].rgb[0], 0.0);
        assert_eq!(pixels[4].rgb[0], 0.0);
    }
}
