//! `amr-render`: renders isosurfaces of `.amrk` files; `demo`, `extract`, `info` and `verify` are
//! subcommands. Each command's arguments become a validated request for the `amr_render` library
//! in its own file; this one only dispatches.

mod animation;
mod demo;
mod extract;
mod field_scale_arg;
mod frame_warnings;
mod frame_writer;
mod frames;
mod heap;
mod info;
mod iso_value;
mod movie;
#[cfg(feature = "mpi")]
mod mpi;
mod outputs;
mod progress;
mod render;
mod render_args;
mod scene_file;
mod surface_arg;
mod verify;

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

/// Ray traces isosurfaces of block-structured AMR data stored in .amrk files.
#[derive(Parser, Debug)]
#[command(
    version,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    args_override_self = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Renders FILE.amrk to an EXR frame (the default command).
    #[command(flatten)]
    render: Option<render_args::RenderArgs>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Synthesizes a small multi-level dataset, converts it and renders it.
    Demo(demo::DemoArgs),
    /// Extracts the active octants for one or more isovalues and reports statistics.
    Extract(extract::ExtractArgs),
    /// Prints what a file holds: levels, bricks, cells, fields, tree, bytes by section.
    Info(info::InfoArgs),
    /// Reads the whole file and checks data checksums, the tree's tiling, brick lists and ranges.
    Verify(verify::VerifyArgs),
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match (cli.command, cli.render) {
        (Some(Command::Demo(args)), _) => demo::run(&args),
        (Some(Command::Extract(args)), _) => extract::run(&args),
        (Some(Command::Info(args)), _) => info::run(&args),
        (Some(Command::Verify(args)), _) => verify::run(&args),
        (None, Some(args)) => render::run(&args),
        (None, None) => anyhow::bail!("nothing to do: give FILE.amrk or a subcommand (see --help)"),
    }
}

/// The command line, a scene file in first position expanded, parsed; `--write-scene`'s file
/// composed, to be written once the command has succeeded.
fn parse() -> anyhow::Result<(Cli, Option<scene_file::PendingScene>)> {
    let cmd = Cli::command();
    let argv = scene_file::expand(std::env::args_os().collect(), &cmd)?;
    let matches = cmd
        .clone()
        .try_get_matches_from(argv)
        .unwrap_or_else(exit_on);
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(exit_on);
    let scene = match cli.render.as_ref().and_then(|r| r.write_scene.as_ref()) {
        Some(path) => Some(scene_file::prepare(path, &cmd, &matches)?),
        None => None,
    };
    Ok((cli, scene))
}

/// Prints clap's message and exits: 0 after `--help` or `--version`, 1 for a bad command line
/// (like every other bad input; clap's own code would be 2).
fn exit_on<T>(e: clap::Error) -> T {
    let _ = e.print();
    std::process::exit(if e.use_stderr() { 1 } else { 0 })
}

fn main() -> ExitCode {
    heap::keep_large_blocks_mapped();
    amr_render::sigbus::install();
    let outcome = parse().and_then(|(cli, scene)| {
        run(cli)?;
        scene.map_or(Ok(()), scene_file::PendingScene::write)
    });
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("Error: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// True when `e` is a write to a closed pipe (`amr-render info F | head`): not a failure.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn cli_is_consistent() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
