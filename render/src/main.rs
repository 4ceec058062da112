//! `amr-render`: renders isosurfaces of `.amrk` files; `demo`, `extract`, `info`, `verify` and
//! `bench` are subcommands.

use std::path::PathBuf;
use std::process::ExitCode;

use amr_render::extract_cmd::{run_extract, ExtractArgs};
use amr_render::info::describe;
use amr_render::mapping::open_mapped;
use amr_render::render_cmd::{parse_size, run_demo, run_render, RenderArgs};
use anyhow::Context;
use clap::{Parser, Subcommand};

/// Ray traces isosurfaces of block-structured AMR data stored in .amrk files.
#[derive(Parser, Debug)]
#[command(
    version,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Renders FILE.amrk to an EXR frame (the default command).
    #[command(flatten)]
    render: Option<RenderArgs>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Synthesizes a small multi-level dataset, converts it and renders it.
    Demo {
        /// The EXR frame to write (a PNG preview is written beside it).
        #[arg(short, long, default_value = "demo.exr")]
        output: PathBuf,
    },
    /// Extracts the active octants for one or more isovalues and reports statistics.
    Extract(ExtractArgs),
    /// Prints what a file holds: levels, bricks, cells, fields, tree, bytes by section.
    Info {
        /// The .amrk file.
        file: PathBuf,
    },
    /// Measurements for docs/benchmarks.md.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Reads the whole file and checks data checksums, the tree's tiling, brick lists and ranges.
    Verify {
        /// The .amrk file.
        file: PathBuf,
    },
}

#[derive(Subcommand, Debug)]
enum BenchCommand {
    /// Median time to map and open (validate) each file.
    Open {
        /// The .amrk files.
        files: Vec<PathBuf>,
        /// Opens per file.
        #[arg(long, default_value_t = 21)]
        runs: usize,
    },
    /// Time to read and decode every brick of one field, once per file, in the order given.
    Read {
        /// The .amrk files.
        files: Vec<PathBuf>,
        /// Field index.
        #[arg(long, default_value_t = 0)]
        field: usize,
    },
    /// BVH built in chunks against one BVH, side by side: build time, scratch, frame time.
    Bvh {
        /// The .amrk file (its first field is used).
        file: PathBuf,
        /// The isovalue.
        #[arg(long, allow_negative_numbers = true)]
        iso: f32,
        /// Refs per chunk of each variant, comma-separated; 0 is one BVH over all refs.
        #[arg(long, value_delimiter = ',', default_value = "0,65536")]
        chunks: Vec<usize>,
        /// Frames per variant (the variants take turns).
        #[arg(long, default_value_t = 5)]
        runs: usize,
        /// Image size.
        #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
        size: (u32, u32),
        /// Cast shadow rays.
        #[arg(long)]
        shadows: bool,
        /// Ambient-occlusion rays per hit.
        #[arg(long, default_value_t = 0)]
        ao: u32,
    },
    /// Regenerates docs/benchmarks-suite.md and its plots (docs/img/*.png) end to end.
    Suite {
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
    },
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

fn run_bench(cmd: BenchCommand) -> anyhow::Result<()> {
    match cmd {
        BenchCommand::Open { files, runs } => {
            println!(
                "| file | bytes | bricks | median open (ms) over {runs} runs |\n|---|---|---|---|"
            );
            for f in files {
                let (t, bytes, bricks) = amr_render::bench::open::open_time(&f, runs)?;
                println!(
                    "| {} | {bytes} | {bricks} | {:.3} |",
                    f.display(),
                    t.as_secs_f64() * 1e3
                );
            }
        }
        BenchCommand::Read { files, field } => {
            println!("| file | stored bytes | cells | seconds | Mcells/s | stored MB/s |\n|---|---|---|---|---|---|");
            for f in files {
                let r = amr_render::bench::read::read_all(&f, field)?;
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
        }
        BenchCommand::Bvh {
            file,
            iso,
            chunks,
            runs,
            size,
            shadows,
            ao,
        } => {
            if !iso.is_finite() {
                anyhow::bail!("isovalue {iso} is not a finite number");
            }
            let cfg = amr_render::bench::bvh::BvhBenchConfig {
                chunks: chunks
                    .iter()
                    .map(|&c| if c == 0 { usize::MAX } else { c })
                    .collect(),
                runs,
                size,
                shadows,
                ao,
            };
            let (active, variants) = amr_render::bench::bvh::compare(&file, iso, &cfg)?;
            print!("{}", amr_render::bench::bvh::table(active, &variants));
        }
        BenchCommand::Suite {
            out,
            quick,
            skip_scale,
            scale_only,
            max_cells,
            scratch,
            only,
        } => {
            let render_exe = std::env::current_exe().ok();
            let cfg = amr_render::bench::suite::SuiteConfig {
                out,
                quick,
                skip_scale,
                scale_only,
                max_cells,
                scratch,
                render_exe,
                only,
            };
            let path = amr_render::bench::suite::run_suite(cfg)?;
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let Some(command) = cli.command else {
        let args = cli
            .render
            .expect("clap requires the render arguments without a subcommand");
        return run_render(&args);
    };
    match command {
        Command::Demo { output } => run_demo(&output)?,
        Command::Extract(args) => run_extract(&args)?,
        Command::Info { file } => {
            let f = open_mapped(&file)?;
            print!("{}", describe(&f));
        }
        Command::Bench(cmd) => run_bench(cmd)?,
        Command::Verify { file } => {
            let f = open_mapped(&file)?;
            let report = f
                .verify()
                .map_err(|e| e.in_file(&file))
                .context("verification failed")?;
            println!("{}: OK: {report}", file.display());
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("Error: {e:#}");
            ExitCode::from(1)
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn cli_is_consistent() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
