//! `amr-render`: renders isosurfaces of `.amrk` files; `info` and `verify` inspect them.

use std::path::PathBuf;
use std::process::ExitCode;

use amr_render::info::describe;
use amr_render::mapping::open_mapped;
use anyhow::Context;
use clap::{Parser, Subcommand};

/// Ray traces isosurfaces of block-structured AMR data stored in .amrk files.
#[derive(Parser, Debug)]
#[command(version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Prints what a file holds: levels, bricks, cells, fields, tree, bytes by section.
    Info {
        /// The .amrk file.
        file: PathBuf,
    },
    /// Reads the whole file and checks data checksums, the tree's tiling, brick lists and ranges.
    Verify {
        /// The .amrk file.
        file: PathBuf,
    },
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Info { file } => {
            let f = open_mapped(&file)?;
            print!("{}", describe(&f));
        }
        Command::Verify { file } => {
            let f = open_mapped(&file)?;
            let report = f.verify().map_err(|e| e.in_file(&file)).context("verification failed")?;
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
