//! `amr-bench sample FILE`: nanoseconds per point sample of each reconstruction, near level
//! boundaries and away from them, as a Markdown table.

use std::path::PathBuf;

use amr_bench::sample::{draw_points, sample_costs};
use amr_render::mapping::open_mapped;
use amr_render::reconstruct::{Reconstruction, Sampler};
use anyhow::Context;
use clap::Args;

/// Arguments of `amr-bench sample`.
#[derive(Args, Debug)]
pub struct SampleArgs {
    /// The .amrk file.
    file: PathBuf,
    /// Field index.
    #[arg(long, default_value_t = 0)]
    field: usize,
    /// Points of each kind (near level boundaries, away from them).
    #[arg(long, default_value_t = 20_000)]
    points: usize,
    /// Passes over the points; the median is reported.
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// Only these reconstructions (default: all four).
    #[arg(long, value_delimiter = ',')]
    methods: Vec<Reconstruction>,
    /// Seed of the random points.
    #[arg(long, default_value_t = 1)]
    seed: u32,
}

/// Prints the table.
pub fn run(args: &SampleArgs) -> anyhow::Result<()> {
    let file = open_mapped(&args.file).with_context(|| format!("{}", args.file.display()))?;
    let points = {
        let sampler = Sampler::new(&file, args.field, 256 << 20)
            .with_context(|| format!("{}", args.file.display()))?;
        draw_points(&sampler, args.points, args.seed)?
    };
    println!(
        "{}: {} points near level boundaries, {} away from them; one thread, median of {} passes\n",
        args.file.display(),
        points.near.len(),
        points.away.len(),
        args.runs
    );
    let methods = if args.methods.is_empty() {
        Reconstruction::ALL.to_vec()
    } else {
        args.methods.clone()
    };
    println!("| method | points | ns per sample, fresh call | ns per sample, with scratch |");
    println!("|---|---|---|---|");
    for row in sample_costs(&file, args.field, &points, &methods, args.runs)? {
        println!(
            "| {} | {} | {:.0} | {:.0} |",
            row.method,
            row.points,
            row.fresh.as_secs_f64() * 1e9,
            row.scratch.as_secs_f64() * 1e9
        );
    }
    Ok(())
}
