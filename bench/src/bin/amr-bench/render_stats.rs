//! `amr-bench render-stats FILE --iso V` (hidden): the suite's scale render of one file in a
//! process of its own, so that its peak RSS is the render's; statistics as JSON on stdout.

use std::path::PathBuf;

use amr_bench::suite::scale_render::render_stats;
use clap::Args;

/// Arguments of `amr-bench render-stats`.
#[derive(Args, Debug)]
pub struct RenderStatsArgs {
    /// The .amrk file.
    file: PathBuf,
    /// The isovalue.
    #[arg(long, allow_negative_numbers = true)]
    iso: f32,
}

/// Renders and prints the statistics.
pub fn run(args: &RenderStatsArgs) -> anyhow::Result<()> {
    let stats = render_stats(&args.file, args.iso)?;
    println!("{}", serde_json::to_string_pretty(&stats)?);
    Ok(())
}
