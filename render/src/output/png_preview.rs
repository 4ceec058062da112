//! A tone-mapped 8-bit sRGB PNG of a frame, composited over its background.

use std::io::BufWriter;
use std::path::Path;

use crate::error::{RenderError, Result};

use crate::output::background::Background;
use crate::output::frame::FrameBuffer;
use amr_format::output::temporary_for;

/// The preview's RGB8 bytes, row-major from the top-left, over `background`.
pub fn preview_rgb8(frame: &FrameBuffer, background: &Background) -> Vec<u8> {
    let behind = background.radiance();
    let mut out = Vec::with_capacity(frame.len() * 3);
    for i in 0..frame.len() {
        let a = frame.alpha[i];
        for c in 0..3 {
            out.push(display_srgb8(frame.rgb[c][i] + behind[c] * (1.0 - a)));
        }
    }
    out
}

/// The 8-bit sRGB value the preview shows for linear radiance `v` (tone-mapped).
pub fn display_srgb8(v: f32) -> u8 {
    to_srgb8(v / (1.0 + 0.25 * v))
}

fn to_srgb8(v: f32) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Writes `rgb8` (`width x height` RGB8) as a PNG, through a temporary file.
pub fn write_png(path: &Path, width: u32, height: u32, rgb8: &[u8]) -> Result<()> {
    let tmp = temporary_for(path, ".tmp").map_err(|e| RenderError::output(path, e))?;
    let result = (|| -> std::result::Result<(), String> {
        let mut enc = png::Encoder::new(BufWriter::new(tmp.as_file()), width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| e.to_string())?;
        w.write_image_data(rgb8).map_err(|e| e.to_string())?;
        w.finish().map_err(|e| e.to_string())?;
        Ok(())
    })();
    result.map_err(|e| RenderError::output(path, e))?;
    tmp.persist(path)
        .map_err(|e| RenderError::output(path, e.error))?;
    Ok(())
}

/// Writes the preview of `frame` over `background` to `path`.
pub fn write_preview(path: &Path, frame: &FrameBuffer, background: &Background) -> Result<()> {
    write_png(
        path,
        frame.width,
        frame.height,
        &preview_rgb8(frame, background),
    )
}
