//! `amr-convert INPUT -o OUT`: detects the input format and runs its converter.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::time::Instant;

use amr_format::hierarchy::MAX_BRICK_EXTENT;
use amr_format::Compression;
use anyhow::{bail, Context};

use crate::amrex;
use crate::bricking::ConvertOptions;
use crate::progress::Bar;

/// What a conversion read and wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ConvertSummary {
    /// Bytes read from the input's data files.
    pub bytes_read: u64,
    /// Cells written per field, over all levels.
    pub cells: u64,
    /// Bricks written.
    pub bricks: u64,
    /// Size of the output file.
    pub output_bytes: u64,
    /// Wall-clock time of the conversion.
    pub seconds: f64,
}

impl std::fmt::Display for ConvertSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mib = |b: u64| b as f64 / (1024.0 * 1024.0);
        let rate = if self.seconds > 0.0 {
            mib(self.bytes_read) / self.seconds
        } else {
            0.0
        };
        write!(
            f,
            "read {:.1} MiB, wrote {} cells in {} bricks, {:.1} MiB, in {:.2} s ({:.0} MiB/s)",
            mib(self.bytes_read),
            self.cells,
            self.bricks,
            mib(self.output_bytes),
            self.seconds,
            rate
        )
    }
}

/// An input format `amr-convert` recognises.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InputFormat {
    /// An AMReX plotfile directory.
    Amrex,
    /// A Chombo HDF5 file (plotfile or checkpoint).
    ChomboHdf5,
    /// An Enzo dataset: its parameter file and hierarchy file.
    Enzo {
        /// The parameter file.
        params: PathBuf,
        /// The `.hierarchy` file.
        hierarchy: PathBuf,
    },
}

/// Works out what `input` is, or says why it is not recognised.
pub fn detect(input: &Path) -> anyhow::Result<InputFormat> {
    if let Some((params, hierarchy)) = crate::enzo::locate(input) {
        return Ok(InputFormat::Enzo { params, hierarchy });
    }
    if input.is_dir() {
        let header = input.join("Header");
        if header.is_file() {
            let first = first_line(&header)?;
            if amrex::looks_like_version(&first) {
                return Ok(InputFormat::Amrex);
            }
            bail!(
                "unrecognised input {}: its Header starts with '{}', not an AMReX plotfile version string",
                input.display(),
                first.trim()
            );
        }
        bail!(
            "unrecognised input {}: a directory without a Header file (not an AMReX plotfile) \
             and without exactly one .hierarchy file (not an Enzo dataset)",
            input.display()
        );
    }
    let ext = input
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("h5" | "hdf5")) {
        return Ok(InputFormat::ChomboHdf5);
    }
    if !input.exists() {
        bail!("input {} does not exist", input.display());
    }
    bail!(
        "unrecognised input {}: expected an AMReX plotfile directory, a Chombo .h5/.hdf5 file, \
         or an Enzo parameter file with its .hierarchy beside it",
        input.display()
    )
}

/// Converts `input` (format detected) to the `.amrk` file `output`, keeping `fields` (all when
/// empty), splitting boxes into bricks of at most `brick` cells per axis. Shows a progress bar
/// when stderr is a terminal.
pub fn run_convert(
    input: &Path,
    output: &Path,
    fields: &[String],
    brick: u32,
    compression: Compression,
) -> anyhow::Result<ConvertSummary> {
    if brick == 0 || i64::from(brick) > MAX_BRICK_EXTENT {
        bail!("--brick {brick}: the brick size must be 1 to {MAX_BRICK_EXTENT}");
    }
    let format = detect(input)?;
    let mut inputs = vec![input];
    if let InputFormat::Enzo { params, hierarchy } = &format {
        inputs.extend([params.as_path(), hierarchy.as_path()]);
    }
    amr_format::output::check_output(output, &inputs)?;
    let start = Instant::now();
    let opts = ConvertOptions {
        fields: fields.to_vec(),
        brick,
        compression,
    };
    let bar = Bar::bytes("converting");
    let stats = match format {
        InputFormat::Amrex => amrex::Plotfile::open(input)
            .and_then(|pf| crate::hierarchy_to_amrk::convert(&pf, output, &opts, &bar))
            .with_context(|| format!("converting AMReX plotfile {}", input.display()))?,
        InputFormat::ChomboHdf5 => {
            crate::chombo::convert(input, output, &opts, &bar).context("converting Chombo file")?
        }
        InputFormat::Enzo { params, hierarchy } => {
            crate::enzo::convert(&params, &hierarchy, output, &opts, &bar)
                .with_context(|| format!("converting Enzo dataset {}", params.display()))?
        }
    };
    let output_bytes = std::fs::metadata(output).map(|m| m.len()).unwrap_or(0);
    Ok(ConvertSummary {
        bytes_read: stats.bytes_read,
        cells: stats.cells,
        bricks: stats.bricks,
        output_bytes,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The first line of `path`, at most 256 bytes of it.
fn first_line(path: &Path) -> anyhow::Result<String> {
    let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut bytes = Vec::new();
    BufReader::new(file)
        .take(256)
        .read_until(b'\n', &mut bytes)
        .with_context(|| format!("cannot read {}", path.display()))?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}
