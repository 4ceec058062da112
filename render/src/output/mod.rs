//! Writing frames: OpenEXR with every channel and the render's metadata, and a PNG preview.

pub mod exr_file;
pub mod frame;
pub mod png_preview;

pub use frame::{FrameBuffer, PixelSample};

use std::path::Path;

/// Refuses, before any work, outputs that would replace the input `input` or something that is
/// not a regular file ([`amr_format::output::check_output`]); `None` entries are skipped.
pub fn check_outputs(input: &Path, outputs: &[Option<&Path>]) -> amr_format::Result<()> {
    for out in outputs.iter().flatten() {
        amr_format::output::check_output(out, &[input])?;
    }
    Ok(())
}
