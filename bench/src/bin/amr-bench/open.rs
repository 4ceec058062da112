//! `amr-bench open FILES..`: median open time of each file, as a Markdown table.

use std::path::PathBuf;

use amr_bench::open::open_time;
use clap::Args;

/// Arguments of `amr-bench open`.
#[derive(Args, Debug)]
pub struct OpenArgs {
    /// The .amrk files.
    files: Vec<PathBuf>,
    /// Opens per file.
    #[arg(long, default_value_t = 21)]
    runs: usize,
}

/// Prints the table.
pub fn run(args: &OpenArgs) -> anyhow::Result<()> {
    let runs = args.runs;
    println!("| file | bytes | bricks | median open (ms) over {runs} runs |\n|---|---|---|---|");
    for f in &args.files {
        let (t, bytes, bricks) = open_time(f, runs)?;
        println!(
            "| {} | {bytes} | {bricks} | {:.3} |",
            f.display(),
            t.as_secs_f64() * 1e3
        );
    }
    Ok(())
}
