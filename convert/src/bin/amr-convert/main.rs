//! `amr-convert`: turns simulation dumps, or synthetic cases, into `.amrk` files.

mod isolate;
mod progress_bar;
mod series;
mod synth;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use amr_convert::bricking::ConvertOptions;
use amr_convert::derive::{check_distinct, DerivedField};
use amr_convert::describe::describe;
use amr_convert::dump::{convert_dump, detect, DumpError, InputFormat};
use amr_format::Compression;
use clap::{Parser, Subcommand};

use progress_bar::Bar;
use synth::{run_synth, SynthArgs};

/// Streams AMR simulation dumps (AMReX plotfiles, as directories or HDF5, Chombo HDF5 plotfiles and checkpoints, Enzo datasets) into one memory-mappable .amrk file.
#[derive(Parser, Debug)]
#[command(
    version,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// The dump to convert: an AMReX plotfile directory or HDF5 plotfile, a Chombo HDF5 plotfile
    /// or checkpoint (.h5, .hdf5), or an Enzo dataset (its parameter file, its .hierarchy, or
    /// its directory). An .amrk file is written anew with the --field, --derive and --compress
    /// asked for, its bricks as they are.
    /// Several dumps (a time series) go to one directory, one NAME.amrk each.
    #[arg(required = true, num_args = 1.., value_name = "INPUT")]
    inputs: Vec<PathBuf>,
    /// The .amrk file to write (written to a temporary file, renamed when complete); for several
    /// inputs, or a path ending in '/', the directory to write them to (created if needed).
    #[arg(short, long, required = true)]
    output: Option<PathBuf>,
    /// A field to convert (repeat for several; all fields by default).
    #[arg(long = "field", value_name = "NAME")]
    fields: Vec<String>,
    /// A field computed cell by cell from the others and stored with them, NAME=FORMULA (repeat
    /// for several; a formula may read the fields derived before it): a vector's length,
    /// speed='|x-velocity,y-velocity,z-velocity|'; an expression of fields, numbers, the
    /// operators + - * / ^ and sqrt, abs, ln, log10, exp, min, max, ...,
    /// temperature='pressure/density'; or an operator on gradients, grad(density), curl(u,v,w)
    /// (the vorticity's length), div(u,v,w) or qcriterion(u,v,w). A field name with characters
    /// other than letters, digits and _ goes in braces, {x-velocity}. Then --iso and --color-by
    /// take it like any field.
    #[arg(long = "derive", value_name = "NAME=FORMULA")]
    derived: Vec<DerivedField>,
    /// Largest brick size in cells per axis; larger input boxes are split [default: 32].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    brick: Option<u32>,
    /// Compress each brick with zstd (byte-shuffled; stored raw where that does not pay).
    #[arg(long)]
    compress: bool,
    /// Keep every input box in bricks of its own (by default, small boxes of a level that share
    /// whole faces and together fill a box of at most 16 cells per axis, and --brick, are joined
    /// into one brick, which extracts faster; --outline boxes then draws the joined bricks).
    #[arg(long)]
    keep_boxes: bool,
    /// Convert only the dumps whose .amrk is missing, older than a file of the dump, not a
    /// valid .amrk, or without the --field fields (as make would): for a series a running
    /// simulation adds to. Other options are not compared: after changing --brick,
    /// --compress or --keep-boxes, leave this out.
    #[arg(long)]
    update: bool,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Writes an analytic AMR dataset (refined near its isosurface) straight into an .amrk file.
    Synth(SynthArgs),
    /// Prints what a dump holds from its metadata alone (format, fields, levels, boxes, cells,
    /// time and step, the .amrk size), reading no cell data: before a long conversion.
    Info(InfoArgs),
}

/// `amr-convert info`.
#[derive(clap::Args, Debug)]
struct InfoArgs {
    /// The dump: as `amr-convert` takes it.
    #[arg(value_name = "INPUT")]
    input: PathBuf,
    /// Print the same as one JSON object, for scripts.
    #[arg(long)]
    json: bool,
}

/// Prints what `args.input` holds; HDF5 is read in a child, as for a conversion.
fn run_info(args: &InfoArgs) -> anyhow::Result<()> {
    let input = &args.input;
    if isolate::needs_child(input) {
        let mut child_args: Vec<std::ffi::OsString> = vec!["info".into(), input.into()];
        if args.json {
            child_args.push("--json".into());
        }
        return isolate::in_child(input, &child_args, None);
    }
    isolate::crash_if_asked();
    let description = describe(input)?;
    let text = match args.json {
        true => serde_json::to_string_pretty(&description)?,
        false => description.to_string(),
    };
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|()| out.flush()) {
        // A closed pipe (`| head`) ends the run quietly.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        done => Ok(done?),
    }
}

/// Converts one dump as `cli` asks.
fn convert_one(cli: &Cli, input: &Path, output: &Path) -> anyhow::Result<()> {
    if isolate::needs_child(input) {
        // HDF5 is read in a child, whose crash on a corrupt file becomes an error.
        let mut options: Vec<String> = Vec::new();
        if let Some(brick) = cli.brick {
            options.extend(["--brick".into(), brick.to_string()]);
        }
        for f in &cli.fields {
            options.extend(["--field".into(), f.clone()]);
        }
        for d in &cli.derived {
            options.extend(["--derive".into(), d.to_string()]);
        }
        if cli.compress {
            options.push("--compress".into());
        }
        if cli.keep_boxes {
            options.push("--keep-boxes".into());
        }
        return isolate::convert_in_child(input, output, &options);
    }
    isolate::crash_if_asked();
    let compression = if cli.compress {
        Compression::Zstd { level: 3 }
    } else {
        Compression::None
    };
    if detect(input).is_ok_and(|f| f == InputFormat::Amrk) {
        for (given, option) in [
            (cli.brick.is_some(), "--brick"),
            (cli.keep_boxes, "--keep-boxes"),
        ] {
            if given {
                let path = input.to_path_buf();
                return Err(DumpError::NotForAmrk { path, option }.into());
            }
        }
    }
    let opts = ConvertOptions {
        fields: cli.fields.clone(),
        brick: cli.brick.unwrap_or(ConvertOptions::default().brick),
        compression,
        join: !cli.keep_boxes,
        derived: cli.derived.clone(),
        ..ConvertOptions::default()
    };
    let summary = convert_dump(input, output, &opts, &Bar::bytes("converting"))?;
    eprintln!("{}: {summary}", output.display());
    Ok(())
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version go to stdout and succeed; a bad command line is an error (exit
            // 1, like every other bad input, rather than clap's 2).
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 1 } else { 0 });
        }
    };
    let result = match &cli.command {
        Some(Command::Synth(args)) => run_synth(args),
        Some(Command::Info(args)) => run_info(args),
        None => {
            let Some(output) = &cli.output else {
                unreachable!("clap requires --output without a subcommand")
            };
            check_distinct(&cli.derived)
                .map_err(anyhow::Error::from)
                .and_then(|()| {
                    series::outputs(&cli.inputs, output).and_then(|jobs| {
                        let done = jobs.pairs.iter().try_for_each(|(input, output)| {
                            if cli.update
                                && series::up_to_date(input, output, &cli.fields, &cli.derived)
                            {
                                eprintln!("{}: up to date, kept", output.display());
                                return Ok(());
                            }
                            convert_one(&cli, input, output)
                        });
                        if let (Err(_), Some(dir)) = (&done, &jobs.created) {
                            // Removes the directory this run made only if nothing was written into it.
                            let _ = std::fs::remove_dir(dir);
                        }
                        done
                    })
                })
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The child printed its own error.
        Err(e) if e.downcast_ref::<isolate::ChildFailed>().is_some() => ExitCode::from(1),
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
