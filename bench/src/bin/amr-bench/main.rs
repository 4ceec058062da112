//! `amr-bench`: measurements of the renderer for `docs/benchmarks*.md`; `open`, `read`, `bvh`,
//! `boxes`, `sample` and `suite` are subcommands.

mod boxes;
mod bvh;
mod open;
mod read;
mod render_stats;
mod sample;
mod suite;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Measurements of the amr-iso renderer, for docs/benchmarks*.md.
#[derive(Parser, Debug)]
#[command(version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Median time to map and open (validate) each file.
    Open(open::OpenArgs),
    /// Time to read and decode every brick of one field, once per file, in the order given.
    Read(read::ReadArgs),
    /// BVH built in chunks against one BVH, side by side: build time, scratch, frame time.
    Bvh(bvh::BvhArgs),
    /// Nanoseconds per point sample of each reconstruction, near level boundaries and away.
    Sample(sample::SampleArgs),
    /// Writes a hierarchy of many small irregular boxes with mixed ratios (extraction stress).
    Boxes(boxes::BoxesArgs),
    /// Regenerates docs/benchmarks-suite.md and its plots (docs/img/*.png) end to end.
    Suite(suite::SuiteArgs),
    /// The suite's scale render of one file, statistics as JSON on stdout (run by `suite`).
    #[command(name = "render-stats", hide = true)]
    RenderStats(render_stats::RenderStatsArgs),
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Open(args) => open::run(&args),
        Command::Read(args) => read::run(&args),
        Command::Bvh(args) => bvh::run(&args),
        Command::Sample(args) => sample::run(&args),
        Command::Boxes(args) => boxes::run(&args),
        Command::Suite(args) => suite::run(args),
        Command::RenderStats(args) => render_stats::run(&args),
    }
}

fn main() -> ExitCode {
    amr_render::sigbus::install();
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

    #[test]
    fn the_child_command_is_the_one_the_suite_runs() {
        use clap::CommandFactory;
        let name = amr_bench::suite::scale_render::CHILD_COMMAND;
        assert!(super::Cli::command().find_subcommand(name).is_some());
    }
}
