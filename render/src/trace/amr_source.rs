//! The `.amrk` file as a voxel source: active octants from the extraction (issue 4), decoded
//! from their 32:32 refs, and point samples of the chosen reconstruction.

use std::path::Path;

use crate::render_cmd::{RenderArgs, RenderConfig};

/// Renders the file named in `args`.
pub fn render_file(args: &RenderArgs, _cfg: RenderConfig) -> anyhow::Result<()> {
    anyhow::bail!(
        "{}: active-octant extraction is not available in this build yet",
        args.file.display()
    )
}

/// Synthesizes, converts and renders the demo dataset.
pub fn demo(_out: &Path) -> anyhow::Result<()> {
    anyhow::bail!("the demo needs the active-octant extraction, not available in this build yet")
}
