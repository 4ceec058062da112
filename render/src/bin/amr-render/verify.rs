//! `amr-render verify FILE`: reads the whole file and checks everything `open` does not.

use std::path::PathBuf;

use amr_render::mapping::open_mapped;

/// Arguments of `amr-render verify`.
#[derive(clap::Args, Debug)]
pub struct VerifyArgs {
    /// The .amrk file.
    file: PathBuf,
}

/// Checks data checksums, the tree's tiling, brick lists and conservative ranges.
pub fn run(args: &VerifyArgs) -> anyhow::Result<()> {
    let file = open_mapped(&args.file)?;
    let report = file
        .verify()
        .map_err(|e| e.in_file(&args.file))
        .map_err(|e| anyhow::anyhow!("verification failed: {e}"))?;
    println!("{}: OK: {report}", args.file.display());
    Ok(())
}
