//! The rendered frame: one plane per output channel.

use rayon::prelude::*;

/// What one pixel sample produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelSample {
    /// Premultiplied linear colour.
    pub rgb: [f32; 3],
    /// Coverage: 0 where no surface was hit.
    pub alpha: f32,
    /// Distance to the first hit (`+inf` on a miss).
    pub z: f32,
    /// Unit normal at the first hit (gradient direction), zero on a miss.
    pub n: [f32; 3],
    /// First hit position, world coordinates relative to [`FrameBuffer::p_origin`].
    pub p: [f32; 3],
    /// AMR level of the first hit (`-1` on a miss).
    pub level: f32,
    /// The value painted at the first hit painted by data (NaN where none is).
    pub color_value: f32,
}

impl PixelSample {
    /// A ray that hit nothing.
    pub const MISS: PixelSample = PixelSample {
        rgb: [0.0; 3],
        alpha: 0.0,
        z: f32::INFINITY,
        n: [0.0; 3],
        p: [f32::NAN; 3],
        level: -1.0,
        color_value: f32::NAN,
    };
}

/// The planes of a [`FrameBuffer`], each an `f32` per pixel: R, G, B, alpha, depth, the
/// normal's three, the position's three, the level and the painted value.
pub const FRAME_PLANES: u64 = 13;

/// A frame's channels, row-major from the top-left pixel.
#[derive(Clone, Debug, Default)]
pub struct FrameBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Premultiplied linear R, G, B.
    pub rgb: [Vec<f32>; 3],
    /// Coverage.
    pub alpha: Vec<f32>,
    /// Ray distance to the first hit, `+inf` on a miss.
    pub z: Vec<f32>,
    /// Normal of the first hit.
    pub n: [Vec<f32>; 3],
    /// World position of the first hit minus `p_origin` (NaN on a miss).
    pub p: [Vec<f32>; 3],
    /// AMR level of the first hit, `-1` on a miss.
    pub level: Vec<f32>,
    /// The value painted at the first hit painted by data, NaN where none is.
    pub color_value: Vec<f32>,
    /// World point that `p` is relative to (the domain's lower corner), kept in `f64` so that
    /// positions in a domain far from the origin keep their precision.
    pub p_origin: [f64; 3],
}

impl FrameBuffer {
    /// Bytes of the planes of a `width x height` frame.
    pub fn bytes_for(width: u32, height: u32) -> u64 {
        FRAME_PLANES * 4 * u64::from(width) * u64::from(height)
    }

    /// A frame of `width x height` pixels from its samples, row-major from the top row (rows
    /// copied in parallel).
    pub fn from_pixels(
        width: u32,
        height: u32,
        pixels: &[PixelSample],
        p_origin: [f64; 3],
    ) -> FrameBuffer {
        assert_eq!(pixels.len(), width as usize * height as usize);
        let mut frame = FrameBuffer::zeroed(width, height, p_origin);
        frame
            .rows_mut()
            .into_par_iter()
            .zip(pixels.par_chunks(width.max(1) as usize))
            .for_each(|(mut row, px)| row.set_all(px));
        frame
    }

    /// A frame of `width x height` pixels, every channel zero (the planes are allocated zeroed,
    /// so their pages are first touched by whoever writes them).
    pub fn zeroed(width: u32, height: u32, p_origin: [f64; 3]) -> FrameBuffer {
        let n = width as usize * height as usize;
        let plane = || vec![0.0f32; n];
        FrameBuffer {
            width,
            height,
            rgb: [plane(), plane(), plane()],
            alpha: plane(),
            z: plane(),
            n: [plane(), plane(), plane()],
            p: [plane(), plane(), plane()],
            level: plane(),
            color_value: plane(),
            p_origin,
        }
    }

    /// A frame of `width x height` pixels in this frame's planes, for a render that writes every
    /// pixel: a plane of that many pixels keeps its memory and, until overwritten, its values;
    /// another is made anew, zeroed.
    pub fn reshaped(mut self, width: u32, height: u32, p_origin: [f64; 3]) -> FrameBuffer {
        let n = width as usize * height as usize;
        let others = [
            &mut self.alpha,
            &mut self.z,
            &mut self.level,
            &mut self.color_value,
        ];
        let planes = self.rgb.iter_mut().chain(&mut self.n).chain(&mut self.p);
        for plane in planes.chain(others) {
            if plane.len() != n {
                *plane = vec![0.0; n];
            }
        }
        FrameBuffer {
            width,
            height,
            p_origin,
            ..self
        }
    }

    /// Every row's slice of every channel, top row first: rows can be written in parallel.
    pub fn rows_mut(&mut self) -> Vec<RowPlanes<'_>> {
        let w = self.width.max(1) as usize;
        let h = self.height as usize;
        let [r, g, b] = &mut self.rgb;
        let [nx, ny, nz] = &mut self.n;
        let [px, py, pz] = &mut self.p;
        let mut planes = [
            r,
            g,
            b,
            &mut self.alpha,
            &mut self.z,
            nx,
            ny,
            nz,
            px,
            py,
            pz,
            &mut self.level,
            &mut self.color_value,
        ]
        .map(|p| p.chunks_mut(w));
        (0..h)
            .map(|_| RowPlanes {
                planes: std::array::from_fn(|i| planes[i].next().unwrap_or_default()),
            })
            .collect()
    }

    /// Pixel `i` (row-major from the top-left pixel) as a sample.
    pub fn sample(&self, i: usize) -> PixelSample {
        PixelSample {
            rgb: [self.rgb[0][i], self.rgb[1][i], self.rgb[2][i]],
            alpha: self.alpha[i],
            z: self.z[i],
            n: [self.n[0][i], self.n[1][i], self.n[2][i]],
            p: [self.p[0][i], self.p[1][i], self.p[2][i]],
            level: self.level[i],
            color_value: self.color_value[i],
        }
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// True for a frame without pixels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of pixels with coverage.
    pub fn covered(&self) -> usize {
        self.alpha.iter().filter(|&&a| a > 0.0).count()
    }
}

/// One row of every channel of a [`FrameBuffer`], in the order R, G, B, A, Z, N.X/Y/Z,
/// P.X/Y/Z, level, painted value.
#[derive(Debug)]
pub struct RowPlanes<'a> {
    planes: [&'a mut [f32]; 13],
}

impl<'a> RowPlanes<'a> {
    /// Writes the row's pixels from `pixels`, its samples from the left.
    pub fn set_all(&mut self, pixels: &[PixelSample]) {
        self.set_run(0, pixels);
    }

    /// Writes the row's pixels from `x` on from `pixels`: plane after plane, each range
    /// checked once.
    #[inline(always)]
    pub fn set_run(&mut self, x: usize, pixels: &[PixelSample]) {
        #[inline(always)]
        fn put(
            plane: &mut [f32],
            x: usize,
            pixels: &[PixelSample],
            f: impl Fn(&PixelSample) -> f32,
        ) {
            for (d, s) in plane[x..x + pixels.len()].iter_mut().zip(pixels) {
                *d = f(s);
            }
        }
        let [r, g, b, a, z, nx, ny, nz, px, py, pz, level, value] = &mut self.planes;
        put(r, x, pixels, |s| s.rgb[0]);
        put(g, x, pixels, |s| s.rgb[1]);
        put(b, x, pixels, |s| s.rgb[2]);
        put(a, x, pixels, |s| s.alpha);
        put(z, x, pixels, |s| s.z);
        put(nx, x, pixels, |s| s.n[0]);
        put(ny, x, pixels, |s| s.n[1]);
        put(nz, x, pixels, |s| s.n[2]);
        put(px, x, pixels, |s| s.p[0]);
        put(py, x, pixels, |s| s.p[1]);
        put(pz, x, pixels, |s| s.p[2]);
        put(level, x, pixels, |s| s.level);
        put(value, x, pixels, |s| s.color_value);
    }

    /// The row's R, G and B.
    pub fn rgb_mut(&mut self) -> [&mut [f32]; 3] {
        let [r, g, b, ..] = &mut self.planes;
        [&mut **r, &mut **g, &mut **b]
    }

    /// The row cut into pieces of `n` columns (the last one shorter), left to right.
    pub fn split_columns(&mut self, n: usize) -> Vec<RowPlanes<'_>> {
        let pieces = self.planes[0].len().div_ceil(n.max(1));
        let mut columns = self.planes.each_mut().map(|p| p.chunks_mut(n.max(1)));
        (0..pieces)
            .map(|_| RowPlanes {
                planes: std::array::from_fn(|i| columns[i].next().unwrap_or_default()),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_for_counts_every_plane() {
        let f = FrameBuffer::zeroed(3, 2, [0.0; 3]);
        let planes = f.rgb.iter().chain(&f.n).chain(&f.p);
        let others = [&f.alpha, &f.z, &f.level, &f.color_value];
        let floats: usize = planes.chain(others).map(Vec::len).sum();
        assert_eq!(FrameBuffer::bytes_for(3, 2), 4 * floats as u64);
    }

    #[test]
    fn a_reshaped_frame_keeps_planes_of_its_size_and_remakes_others() {
        let mut frame = FrameBuffer::zeroed(4, 3, [0.0; 3]);
        frame.z[5] = 7.0;
        let z = frame.z.as_ptr();
        let same = frame.reshaped(3, 4, [1.0; 3]);
        assert_eq!((same.width, same.height, same.p_origin), (3, 4, [1.0; 3]));
        assert_eq!((same.z.as_ptr(), same.z[5]), (z, 7.0));
        let other = same.reshaped(2, 2, [0.0; 3]);
        let planes = other.rgb.iter().chain(&other.n).chain(&other.p);
        let others = [&other.alpha, &other.z, &other.level, &other.color_value];
        assert!(planes.chain(others).all(|p| p == &vec![0.0; 4]));
    }
}
