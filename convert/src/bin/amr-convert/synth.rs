//! `amr-convert synth`: writes one of the analytic datasets, refined around its isosurface.

use std::path::PathBuf;

use amr_format::Compression;
use anyhow::Context;

use crate::progress_bar::Bar;
use amr_synth::{count_cells, fit_cells, write_synth, Case, SynthParams};

/// zstd level used by `--compress`.
const ZSTD_LEVEL: i32 = 3;
/// Bytes of one cell of the one field, stored raw.
const RAW_BYTES_PER_CELL: u64 = 4;
/// Brick size when neither `--brick` nor `--cells` chooses one.
const DEFAULT_BRICK: u32 = 32;

/// Arguments of `amr-convert synth`.
#[derive(Clone, Debug, clap::Args)]
pub struct SynthArgs {
    /// Analytic case: blobs (two merging 1/r blobs), sphere (signed distance) or ripple (32 periodic blobs)
    pub case: String,
    /// Output .amrk file
    #[arg(short, long)]
    pub output: PathBuf,
    /// Number of refinement levels
    #[arg(long, default_value_t = 3)]
    pub levels: u32,
    /// Refinement ratio between levels (any integer >= 2)
    #[arg(long, default_value_t = 2)]
    pub ratio: u32,
    /// Cells per axis of level 0 (ignored with --cells)
    #[arg(long, default_value_t = 64)]
    pub base: u32,
    /// Cells per axis of a brick [default: 32; with --cells, 32, 16, 8 or 4, whichever fits the target]
    #[arg(long)]
    pub brick: Option<u32>,
    /// Target total number of cells (e.g. 1e9); chooses --base to come close
    #[arg(long, value_parser = parse_count)]
    pub cells: Option<u64>,
    /// Compress each brick with zstd (stored raw where that does not pay)
    #[arg(long)]
    pub compress: bool,
    /// Physical position of the domain's lower corner, as X,Y,Z
    #[arg(long, value_parser = parse_point, default_value = "0,0,0", allow_hyphen_values = true)]
    pub origin: [f64; 3],
    /// Physical edge length of the cubic domain
    #[arg(long, default_value_t = 1.0)]
    pub size: f64,
}

impl SynthArgs {
    /// The validated case and parameters, with `--cells` resolved; the second value is the
    /// fitted total cell count, if `--cells` was given.
    pub fn to_params(&self) -> anyhow::Result<(Case, SynthParams)> {
        let case: Case = self.case.parse().map_err(anyhow::Error::msg)?;
        let params = SynthParams {
            levels: self.levels,
            ratio: self.ratio,
            base: self.base,
            brick: self.brick.unwrap_or(DEFAULT_BRICK),
            origin: self.origin,
            size: self.size,
        };
        params.validate()?;
        // Nothing is counted, fitted or built past what the output's file system can hold:
        // a mistyped `--cells 1e15` or `--levels 20` is refused in seconds, not after hours.
        let limit = amr_format::output::free_bytes_for(&self.output)
            .map_or(u64::MAX, |free| free / RAW_BYTES_PER_CELL);
        let (params, cells) = match self.cells {
            Some(target) => fit_cells(&case, &params, target, self.brick.is_none(), limit)
                .map_err(|e| too_large(e, &self.output, target > limit))?,
            None => {
                let cells = count_cells(&case, &params, limit)?;
                (params, cells)
            }
        };
        if cells > limit {
            anyhow::bail!(
                "{}: {} levels of base {} refined by {} hold more than {limit} cells, more than \
                 its file system has room for; ask for fewer levels or a smaller --base",
                self.output.display(),
                params.levels,
                params.base,
                params.ratio
            );
        }
        Ok((case, params))
    }
}

/// Runs `amr-convert synth` and prints a one-line summary to stderr.
pub fn run_synth(args: &SynthArgs) -> anyhow::Result<()> {
    let (case, params) = args.to_params()?;
    amr_format::output::check_output(&args.output, &[])?;
    let compression = if args.compress {
        Compression::Zstd { level: ZSTD_LEVEL }
    } else {
        Compression::None
    };
    let bar = Bar::bytes(&format!("synth {case}"));
    let s = write_synth(
        &args.output,
        case,
        &params,
        amr_render::extract::writer_options(compression),
        &bar,
    )
    .with_context(|| format!("writing {}", args.output.display()))?;
    let per_level: Vec<String> = s.cells_per_level.iter().map(u64::to_string).collect();
    eprintln!(
        "{}: {case}, base {} brick {} ratio {}, cells per level [{}] = {} cells, {} bricks, {} bytes, {:.2} s",
        args.output.display(),
        params.base,
        params.brick,
        params.ratio,
        per_level.join(", "),
        s.write.cells,
        s.write.bricks,
        s.write.file_bytes,
        s.seconds
    );
    Ok(())
}

/// `e`, a fit refused at the limit the output's file system sets, said as that when `over`
/// (the target itself is past it).
fn too_large(e: amr_format::FormatError, output: &std::path::Path, over: bool) -> anyhow::Error {
    if over {
        anyhow::anyhow!(
            "{}: {e}: the file would not fit on its file system",
            output.display()
        )
    } else {
        anyhow::anyhow!("{}: {e}", output.display())
    }
}

/// Parses a cell count written as an integer or in float notation (`1e9`, `2.2e9`).
fn parse_count(s: &str) -> Result<u64, String> {
    if let Ok(n) = s.parse::<u64>() {
        return match n {
            0 => Err(format!("'{s}' is not a positive cell count")),
            n => Ok(n),
        };
    }
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 1.0 && x < u64::MAX as f64 => Ok(x.round() as u64),
        _ => Err(format!("'{s}' is not a positive cell count")),
    }
}

/// Parses `X,Y,Z` into a point.
fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let coords: Vec<f64> = parts.iter().filter_map(|p| p.parse().ok()).collect();
    match coords[..] {
        [x, y, z] if parts.len() == 3 && coords.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(format!(
            "'{s}' is not a point X,Y,Z of three finite numbers"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{CommandFactory, Parser};

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        synth: SynthArgs,
    }

    #[test]
    fn arguments_parse() {
        Cli::command().debug_assert();
        let cli = Cli::parse_from([
            "x",
            "sphere",
            "-o",
            "a.amrk",
            "--cells",
            "2.2e9",
            "--origin",
            "-1e6,2,3.5",
            "--ratio",
            "4",
        ]);
        assert_eq!(cli.synth.cells, Some(2_200_000_000));
        assert_eq!(cli.synth.origin, [-1e6, 2.0, 3.5]);
        assert_eq!(cli.synth.brick, None);
        assert!(Cli::try_parse_from(["x", "sphere", "-o", "a", "--origin", "1,2"]).is_err());
        assert!(Cli::try_parse_from(["x", "sphere", "-o", "a", "--cells", "-5"]).is_err());
    }

    #[test]
    fn writes_a_file_close_to_the_requested_cell_count() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("s.amrk");
        let args = "x ripple -o OUT --cells 2e5 --ratio 3 --compress".split(' ');
        let args = args.map(|a| if a == "OUT" { out.to_str().unwrap() } else { a });
        run_synth(&Cli::parse_from(args).synth).unwrap();
        let file = amr_format::AmrkFile::open(std::fs::read(&out).unwrap()).unwrap();
        file.verify().unwrap();
        let cells: u64 = (0..file.num_bricks())
            .map(|b| file.brick(b).cells.num_cells().unwrap())
            .sum();
        assert!((100_000..400_000).contains(&cells), "{cells} cells");
    }

    #[test]
    fn bad_case_and_parameters_are_reported() {
        let cli = Cli::parse_from(["x", "cube", "-o", "a.amrk"]);
        assert!(cli
            .synth
            .to_params()
            .unwrap_err()
            .to_string()
            .contains("blobs"));
        let cli = Cli::parse_from(["x", "blobs", "-o", "a.amrk", "--ratio", "1"]);
        assert!(cli
            .synth
            .to_params()
            .unwrap_err()
            .to_string()
            .contains("--ratio"));
        // Past what the output's file system holds (no file system holds 1e18 cells), and
        // too many levels: refused before anything is built.
        let cli = Cli::parse_from(["x", "blobs", "-o", "a.amrk", "--cells", "1e18"]);
        let err = cli.synth.to_params().unwrap_err().to_string();
        assert!(err.contains("would not fit"), "{err}");
        let cli = Cli::parse_from([
            "x", "blobs", "-o", "a.amrk", "--levels", "24", "--cells", "1000",
        ]);
        let err = cli.synth.to_params().unwrap_err().to_string();
        assert!(err.contains("fewer levels"), "{err}");
        assert!(Cli::try_parse_from(["x", "blobs", "-o", "a.amrk", "--cells", "0"]).is_err());
    }
}
