//! The rendered frame: one plane per output channel.

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
    /// A frame of `width x height` pixels from its rows of samples, top row first.
    pub fn from_pixels(
        width: u32,
        height: u32,
        pixels: &[PixelSample],
        p_origin: [f64; 3],
    ) -> FrameBuffer {
        let plane = |f: &dyn Fn(&PixelSample) -> f32| pixels.iter().map(f).collect::<Vec<f32>>();
        FrameBuffer {
            width,
            height,
            rgb: [
                plane(&|s| s.rgb[0]),
                plane(&|s| s.rgb[1]),
                plane(&|s| s.rgb[2]),
            ],
            alpha: plane(&|s| s.alpha),
            z: plane(&|s| s.z),
            n: [plane(&|s| s.n[0]), plane(&|s| s.n[1]), plane(&|s| s.n[2])],
            p: [plane(&|s| s.p[0]), plane(&|s| s.p[1]), plane(&|s| s.p[2])],
            level: plane(&|s| s.level),
            color_value: plane(&|s| s.color_value),
            p_origin,
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
