//! Drawing on an 8-bit RGB picture: blended rectangles, lines, pointed caps, the dark panels
//! behind light text, and text in DejaVu Sans (embedded from the `dejavu` crate, rasterized by
//! `ab_glyph`).

use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};

use super::background::Ink;

/// Colour and opacity of the panels behind light text.
const PANEL_ALPHA: f32 = 0.55;

/// An RGB8 image being drawn on.
pub(crate) struct Canvas<'a> {
    /// The pixels, row-major RGB8.
    pub rgb: &'a mut [u8],
    /// Width in pixels.
    pub w: u32,
    /// Height in pixels.
    pub h: u32,
}

impl Canvas<'_> {
    /// Blends colour `c` with opacity `a` into the pixel `(x, y)`, if it is inside.
    fn blend(&mut self, x: i64, y: i64, c: [u8; 3], a: f32) {
        if x < 0 || y < 0 || x >= i64::from(self.w) || y >= i64::from(self.h) || a <= 0.0 {
            return;
        }
        let i = 3 * (y as usize * self.w as usize + x as usize);
        for k in 0..3 {
            let old = f32::from(self.rgb[i + k]);
            self.rgb[i + k] = (old + (f32::from(c[k]) - old) * a.min(1.0)).round() as u8;
        }
    }

    /// Blends colour `c` with opacity `a` into the rectangle `w x h` at `(x0, y0)`.
    pub(crate) fn rect(&mut self, x0: i64, y0: i64, w: i64, h: i64, c: [u8; 3], a: f32) {
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                self.blend(x, y, c, a);
            }
        }
    }

    /// A triangle `width` wide at row `base`, narrowing row by row in direction `step` (-1: up)
    /// to a point: black, `color` inside.
    pub(crate) fn cap(&mut self, (x0, base): (i64, i64), width: i64, step: i64, color: [u8; 3]) {
        let rows = (width + 1) / 2 + 1;
        for r in 0..rows {
            let (inset, y) = (r, base + step * r);
            self.rect(x0 + inset, y, width - 2 * inset, 1, [0, 0, 0], 1.0);
            self.rect(x0 + inset + 1, y, width - 2 * inset - 2, 1, color, 1.0);
        }
    }

    /// Shades the box `(x0, y0)`-`(x1, y1)` with a margin of `pad` in `ink`'s panel colour
    /// (dark under light text, light under dark text), so that the text drawn on it reads over
    /// box lines and surfaces alike.
    pub(crate) fn panel(&mut self, (x0, y0): (f32, f32), (x1, y1): (f32, f32), pad: f32, ink: Ink) {
        let (x0, y0) = ((x0 - pad) as i64, (y0 - pad) as i64);
        let (x1, y1) = ((x1 + pad).ceil() as i64, (y1 + pad).ceil() as i64);
        self.rect(x0, y0, x1 - x0, y1 - y0, ink.panel, PANEL_ALPHA);
    }

    /// A line from `a` to `b` in colour `c`, `width` pixels thick.
    pub(crate) fn line(&mut self, a: (f64, f64), b: (f64, f64), c: [u8; 3], width: i64) {
        let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
        for k in 0..=n {
            let u = k as f64 / n as f64;
            let (x, y) = (a.0 + u * (b.0 - a.0), a.1 + u * (b.1 - a.1));
            self.rect(
                x as i64 - width / 2,
                y as i64 - width / 2,
                width,
                width,
                c,
                1.0,
            );
        }
    }
}

/// Draws text with DejaVu Sans.
pub(crate) struct Text {
    font: FontRef<'static>,
    /// The text's size in pixels.
    pub px: f32,
}

impl Text {
    /// Text of `px` pixels (`None` if the embedded font does not parse).
    pub(crate) fn new(px: f32) -> Option<Text> {
        let font = FontRef::try_from_slice(dejavu::sans::regular()).ok()?;
        Some(Text { font, px })
    }

    /// The width of `s` in pixels.
    pub(crate) fn width(&self, s: &str) -> f32 {
        let f = self.font.as_scaled(PxScale::from(self.px));
        s.chars().map(|c| f.h_advance(f.glyph_id(c))).sum()
    }

    /// Draws `s` with its top left at `(x, y)` in `ink`, its edge as a shadow under it, so
    /// that it reads on the picture's background, its panels and the surfaces alike.
    pub(crate) fn draw(&self, canvas: &mut Canvas<'_>, s: &str, x: f32, y: f32, ink: Ink) {
        self.draw_in(canvas, s, x + 1.0, y + 1.0, ink.edge);
        self.draw_in(canvas, s, x, y, ink.fill);
    }

    fn draw_in(&self, canvas: &mut Canvas<'_>, s: &str, x: f32, y: f32, c: [u8; 3]) {
        let f = self.font.as_scaled(PxScale::from(self.px));
        let mut pen = x;
        for ch in s.chars() {
            let id = f.glyph_id(ch);
            let glyph = id.with_scale_and_position(self.px, point(pen, y + f.ascent()));
            pen += f.h_advance(id);
            if let Some(o) = self.font.outline_glyph(glyph) {
                let b = o.px_bounds();
                o.draw(|gx, gy, cov| {
                    canvas.blend(
                        b.min.x as i64 + i64::from(gx),
                        b.min.y as i64 + i64::from(gy),
                        c,
                        cov,
                    )
                });
            }
        }
    }
}
