//! `amr-bench suite --out DIR`: regenerates `DIR/benchmarks-suite.md` and `DIR/img/*.png`.

use std::path::PathBuf;

use amr_bench::suite::{run_suite, SuiteConfig};
use clap::Args;

/// Arguments of `amr-bench suite`.
#[derive(Args, Debug)]
pub struct SuiteArgs {
    /// Directory for benchmarks-suite.md and img/.
    #[arg(long, default_value = "docs")]
    out: PathBuf,
    /// Small sizes and few runs (about a minute), for smoke tests.
    #[arg(long)]
    quick: bool,
    /// Leave out the scale section (which writes the largest files).
    #[arg(long, conflicts_with = "scale_only")]
    skip_scale: bool,
    /// Run only the scale section and replace it in the existing benchmarks-suite.md.
    #[arg(long)]
    scale_only: bool,
    /// Largest cell count of the scale section (e.g. 8e9 adds a file larger than 24 GiB of
    /// memory, about 4 bytes per cell of disk in the scratch directory).
    #[arg(long, value_name = "N", value_parser = parse_cells)]
    max_cells: Option<u64>,
    /// Directory for the datasets (default: the system's temporary directory).
    #[arg(long, value_name = "DIR")]
    scratch: Option<PathBuf>,
    /// Run only this section (figure8, recon, tradeoff, stress, scale; repeatable) and
    /// replace it in the existing benchmarks-suite.md.
    #[arg(long, value_name = "SECTION")]
    only: Vec<String>,
}

/// A cell count such as `8e9` or `8000000000`: at least 1000.
fn parse_cells(s: &str) -> Result<u64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a cell count"))?;
    if !(1e3..=1e13).contains(&v) {
        return Err(format!("cell count {s} must be between 1e3 and 1e13"));
    }
    Ok(v.round() as u64)
}

/// Runs the suite; the scale section renders in child processes of this executable.
pub fn run(args: SuiteArgs) -> anyhow::Result<()> {
    let cfg = SuiteConfig {
        out: args.out,
        quick: args.quick,
        skip_scale: args.skip_scale,
        scale_only: args.scale_only,
        max_cells: args.max_cells,
        scratch: args.scratch,
        render_exe: std::env::current_exe().ok(),
        only: args.only,
    };
    let path = run_suite(cfg)?;
    println!("wrote {}", path.display());
    Ok(())
}
