//! `amr-render info FILE [--json]`: what a file holds.

use std::io::Write;
use std::path::PathBuf;

use amr_render::info::summarize;
use amr_render::mapping::open_mapped;

/// Arguments of `amr-render info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The .amrk file.
    file: PathBuf,
    /// Print the same as one JSON object (levels, fields with their ranges and percentiles,
    /// the kd-tree, bytes by section), for scripts.
    #[arg(long)]
    json: bool,
}

/// Prints levels, bricks, cells, fields and ranges, the tree and bytes by section.
pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    let file = open_mapped(&args.file)?;
    let summary = summarize(&file);
    let mut out = std::io::stdout().lock();
    if args.json {
        // As an I/O error, so that a closed pipe (`| head`) ends the run quietly.
        serde_json::to_writer_pretty(&mut out, &summary).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else {
        out.write_all(summary.to_text().as_bytes())?;
    }
    Ok(())
}
