//! `amr-render info FILE`: what a file holds.

use std::io::Write;
use std::path::PathBuf;

use amr_render::info::describe;
use amr_render::mapping::open_mapped;

/// Arguments of `amr-render info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The .amrk file.
    file: PathBuf,
}

/// Prints levels, bricks, cells, fields and ranges, the tree and bytes by section.
pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    let file = open_mapped(&args.file)?;
    std::io::stdout().write_all(describe(&file).as_bytes())?;
    Ok(())
}
