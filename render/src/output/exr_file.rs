//! OpenEXR output: channels R, G, B, A, Z, N.X/Y/Z, P.X/Y/Z, `level` (and `color_value` when the
//! frame is painted by data) as 32-bit floats, with
//! the camera, isovalues, timings and the origin of `P` in the header, compressed losslessly
//! ([`ExrCompression`]). Written to a temporary file beside the target and renamed, so a reader
//! never sees half a frame.

use std::path::Path;

use exr::block::lines::LineRefMut;
use exr::image::write::samples::{SamplesWriter, WritableSamples};
use exr::math::RoundingMode;
use exr::meta::attribute::LevelMode;
use exr::meta::header::Header;
use exr::prelude::*;

use amr_format::output::temporary_for;

use crate::error::{RenderError, Result};

use crate::output::frame::FrameBuffer;

/// One of a frame's planes as the samples of an EXR channel, borrowed.
struct Plane<'a>(&'a Vec<f32>);

impl<'s, 'a: 's> WritableSamples<'s> for Plane<'a> {
    type Writer = PlaneWriter<'a>;

    fn sample_type(&self) -> SampleType {
        SampleType::F32
    }

    fn infer_level_modes(&self) -> (LevelMode, RoundingMode) {
        (LevelMode::Singular, RoundingMode::Down)
    }

    fn create_samples_writer(&'s self, header: &Header) -> PlaneWriter<'a> {
        PlaneWriter {
            width: header.layer_size.width(),
            samples: self.0,
        }
    }
}

/// Hands the writer the lines of a [`Plane`].
struct PlaneWriter<'a> {
    width: usize,
    samples: &'a [f32],
}

impl SamplesWriter for PlaneWriter<'_> {
    fn extract_line(&self, line: LineRefMut<'_>) {
        let start = line.location.position.y() * self.width + line.location.position.x();
        let samples = &self.samples[start..start + line.location.sample_count];
        // The line's bytes are a buffer of exactly this many samples, in memory.
        line.write_samples_from_slice(samples)
            .expect("a line's buffer holds its samples");
    }
}

/// The channel of the values that painted surfaces and slices, written when a frame has any: a
/// user can recolour the frame with another colormap or range.
pub const COLOR_VALUE_CHANNEL: &str = "color_value";

/// Header attribute names holding the world origin that `P.X`, `P.Y`, `P.Z` are relative to.
pub const P_ORIGIN_ATTRS: [&str; 3] = ["P_origin_x", "P_origin_y", "P_origin_z"];

/// How the channels of an EXR frame are compressed; every choice is lossless.
///
/// PIZ is the default: on this renderer's frames it writes about 2x faster than ZIP (in
/// instructions) and makes smaller files (`docs/benchmarks-render.md`, "EXR output").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ExrCompression {
    /// Wavelet and Huffman coding, in tiles of 256x256 pixels.
    #[default]
    Piz,
    /// Deflate over blocks of 16 scan lines: slowest, files about as small as PIZ's.
    Zip,
    /// Run-length coding, in tiles of 64x64 pixels: fastest, largest files.
    Rle,
    /// Uncompressed.
    None,
}

impl ExrCompression {
    /// Every choice, in the order command lines list them.
    pub const ALL: [ExrCompression; 4] = [
        ExrCompression::Piz,
        ExrCompression::Zip,
        ExrCompression::Rle,
        ExrCompression::None,
    ];

    /// The name used on command lines.
    pub fn name(self) -> &'static str {
        match self {
            ExrCompression::Piz => "piz",
            ExrCompression::Zip => "zip",
            ExrCompression::Rle => "rle",
            ExrCompression::None => "none",
        }
    }

    fn encoding(self) -> Encoding {
        match self {
            ExrCompression::Piz => Encoding::SMALL_FAST_LOSSLESS,
            ExrCompression::Zip => Encoding::SMALL_LOSSLESS,
            ExrCompression::Rle => Encoding::FAST_LOSSLESS,
            ExrCompression::None => Encoding::UNCOMPRESSED,
        }
    }
}

impl std::fmt::Display for ExrCompression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ExrCompression {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let s = s.trim().to_ascii_lowercase();
        Self::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| format!("unknown EXR compression '{s}' (piz, zip, rle, none)"))
    }
}

/// Writes `frame` to `path` with `meta` (name, text) pairs as text attributes, compressed the
/// default way.
pub fn write_exr(path: &Path, frame: &FrameBuffer, meta: &[(String, String)]) -> Result<()> {
    write_exr_with(path, frame, meta, ExrCompression::default())
}

/// [`write_exr`] with the channels compressed by `compression`.
pub fn write_exr_with(
    path: &Path,
    frame: &FrameBuffer,
    meta: &[(String, String)],
    compression: ExrCompression,
) -> Result<()> {
    let size = (frame.width as usize, frame.height as usize);
    let pixels = size.0.checked_mul(size.1);
    let planes = frame.rgb.iter().chain(&frame.n).chain(&frame.p);
    let others = [&frame.alpha, &frame.z, &frame.level, &frame.color_value];
    if planes.chain(others).any(|p| Some(p.len()) != pixels) {
        let message = format!(
            "a channel of the {}x{} frame is not that size",
            size.0, size.1
        );
        return Err(RenderError::output(path, message));
    }
    // The planes are read where they are: a copy of them all would double the frame's memory.
    let ch = |name: &str, data| AnyChannel::new(name, Plane(data));
    let channels = vec![
        ch("R", &frame.rgb[0]),
        ch("G", &frame.rgb[1]),
        ch("B", &frame.rgb[2]),
        ch("A", &frame.alpha),
        ch("Z", &frame.z),
        ch("N.X", &frame.n[0]),
        ch("N.Y", &frame.n[1]),
        ch("N.Z", &frame.n[2]),
        ch("P.X", &frame.p[0]),
        ch("P.Y", &frame.p[1]),
        ch("P.Z", &frame.p[2]),
        ch("level", &frame.level),
    ];
    let mut channels = channels;
    if frame.color_value.iter().any(|v| !v.is_nan()) {
        channels.push(ch(COLOR_VALUE_CHANNEL, &frame.color_value));
    }
    let mut attrs = LayerAttributes::named("");
    attrs.layer_name = None;
    attrs.software_name = Some(text("amr-render"));
    for (k, v) in meta {
        attrs.other.insert(text(k), AttributeValue::Text(text(v)));
    }
    for (a, name) in P_ORIGIN_ATTRS.iter().enumerate() {
        attrs
            .other
            .insert(text(name), AttributeValue::F64(frame.p_origin[a]));
    }
    let layer = Layer::new(
        size,
        attrs,
        compression.encoding(),
        AnyChannels::sort(channels.into()),
    );
    let image = Image::from_layer(layer);
    // A temporary named after the target and this process (removed on any error, and by a
    // later writer of the same target if this process dies), renamed into place when complete.
    let tmp = temporary_for(path, ".tmp").map_err(|e| RenderError::output(path, e))?;
    image
        .write()
        .to_file(tmp.path())
        .map_err(|e| RenderError::output(path, e))?;
    tmp.persist(path)
        .map_err(|e| RenderError::output(path, e.error))?;
    Ok(())
}

fn text(s: &str) -> Text {
    Text::new_or_none(s).unwrap_or_else(|| {
        let ascii: String = s
            .chars()
            .map(|c| if (c as u32) < 256 { c } else { '?' })
            .collect();
        Text::new_or_panic(ascii)
    })
}

/// One channel of an EXR file read back: width, height, values (for tests and tools).
pub fn read_channel(path: &Path, name: &str) -> Result<(u32, u32, Vec<f32>)> {
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| RenderError::Invalid(format!("cannot read {}: {e}", path.display())))?;
    let layer = &image.layer_data;
    let ch = layer
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == name)
        .ok_or_else(|| RenderError::Invalid(format!("{}: no channel {name}", path.display())))?;
    let v: Vec<f32> = ch.sample_data.values_as_f32().collect();
    Ok((layer.size.0 as u32, layer.size.1 as u32, v))
}

/// The text attributes of an EXR file's first layer, as `write_exr` wrote them (for tests and
/// tools).
pub fn read_text_attributes(path: &Path) -> Result<Vec<(String, String)>> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| RenderError::Invalid(format!("cannot read {}: {e}", path.display())))?;
    let Some(header) = meta.headers.first() else {
        return Ok(Vec::new());
    };
    Ok(header
        .own_attributes
        .other
        .iter()
        .filter_map(|(k, v)| match v {
            AttributeValue::Text(t) => Some((k.to_string(), t.to_string())),
            _ => None,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_whose_channel_is_not_its_size_is_refused_not_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("short.exr");
        let mut frame = FrameBuffer::zeroed(4, 3, [0.0; 3]);
        frame.n[1].pop();
        let err = write_exr(&path, &frame, &[]).unwrap_err().to_string();
        assert!(err.contains("short.exr") && err.contains("4x3"), "{err}");
        assert!(!path.exists());
        frame.n[1].push(0.0);
        write_exr(&path, &frame, &[]).unwrap();
        assert_eq!(read_channel(&path, "N.Y").unwrap(), (4, 3, vec![0.0; 12]));
    }
}
