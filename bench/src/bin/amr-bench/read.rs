//! `amr-bench read FILES..`: time to decode every brick of one field, as a Markdown table.

use std::path::PathBuf;

use amr_bench::read::read_all;
use clap::Args;

/// Arguments of `amr-bench read`.
#[derive(Args, Debug)]
pub struct ReadArgs {
    /// The .amrk files.
    files: Vec<PathBuf>,
    /// Field index.
    #[arg(long, default_value_t = 0)]
    field: usize,
}

/// Prints the table.
pub fn run(args: &ReadArgs) -> anyhow::Result<()> {
    println!(
        "| file | stored bytes | cells | seconds | Mcells/s | stored MB/s |\n|---|---|---|---|---|---|"
    );
    for f in &args.files {
        let r = read_all(f, args.field)?;
        let s = r.time.as_secs_f64();
        println!(
            "| {} | {} | {} | {s:.3} | {:.1} | {:.1} |",
            f.display(),
            r.stored_bytes,
            r.cells,
            r.cells as f64 / s / 1e6,
            r.stored_bytes as f64 / s / 1e6
        );
        std::hint::black_box(r.checksum);
    }
    Ok(())
}
