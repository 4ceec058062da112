//! One dump in, one `.amrk` file out: detects the input format and runs its converter.

use std::error::Error;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::time::Instant;

use amr_format::hierarchy::MAX_BRICK_EXTENT;
use amr_format::progress::Progress;
use amr_format::FormatError;
use amr_render::dump_hint::{first_bytes, HDF5_SIGNATURE};

use crate::amrex::{self, AmrexError};
use crate::bricking::{ConvertOptions, ConvertStats};
use crate::chombo::ChomboError;
use crate::derive::DerivedField;
use crate::enzo::EnzoError;
use crate::rewrite::{rewrite, RewriteError};

/// Why a dump was not converted. Each message names the file and the problem, with the
/// reader's own explanation (and its causes) written out in full.
#[derive(Debug, thiserror::Error)]
pub enum DumpError {
    /// The input does not exist.
    #[error("input {} does not exist", path.display())]
    Missing {
        /// The input as given.
        path: PathBuf,
    },
    /// The input is none of the formats this crate reads.
    #[error("unrecognised input {}: {reason}", path.display())]
    Unrecognised {
        /// The input as given.
        path: PathBuf,
        /// What it is, and what was expected.
        reason: String,
    },
    /// A file needed to recognise the input could not be read.
    #[error("cannot read {}: {error}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's error.
        error: std::io::Error,
    },
    /// The brick size is out of range.
    #[error("--brick {0}: the brick size must be 1 to {MAX_BRICK_EXTENT}")]
    BrickSize(u32),
    /// The output would replace an input or something that is not a regular file.
    #[error("{}", chain(.0))]
    Output(FormatError),
    /// The AMReX reader or the writer failed.
    #[error("converting AMReX plotfile {}: {}", path.display(), chain(error))]
    Amrex {
        /// The plotfile directory.
        path: PathBuf,
        /// The reader's error (boxed: it is large, and errors are rare).
        error: Box<AmrexError>,
    },
    /// The Chombo reader or the writer failed (the error names the file).
    #[error("converting HDF5 file (Chombo layout): {}", chain(.0))]
    Chombo(Box<ChomboError>),
    /// A reader failed on the dump's metadata ([`crate::describe::describe`]).
    #[error("reading {format} {}: {detail}", path.display())]
    Reading {
        /// What the dump was taken for.
        format: &'static str,
        /// The dump as given.
        path: PathBuf,
        /// The reader's error and its causes.
        detail: String,
    },
    /// An option that does not apply to an `.amrk` input.
    #[error("{}: an .amrk input keeps its bricks, so {option} does not apply", path.display())]
    NotForAmrk {
        /// The input.
        path: PathBuf,
        /// The option.
        option: &'static str,
    },
    /// Rewriting an `.amrk` file, or deriving fields, failed.
    #[error("{}", chain(.0))]
    Rewrite(Box<RewriteError>),
    /// The Enzo reader or the writer failed.
    #[error("converting Enzo dataset {}: {}", params.display(), chain(error))]
    Enzo {
        /// The dataset's parameter file.
        params: PathBuf,
        /// The reader's error (boxed: it is large, and errors are rare).
        error: Box<EnzoError>,
    },
}

/// `error` and its causes, joined by ": ".
pub(crate) fn chain(error: &dyn Error) -> String {
    let mut text = error.to_string();
    let mut cause = error.source();
    while let Some(c) = cause {
        text.push_str(": ");
        text.push_str(&c.to_string());
        cause = c.source();
    }
    text
}

/// What a conversion read and wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ConvertSummary {
    /// Bytes read from the input's data files.
    pub bytes_read: u64,
    /// Cells written per field, over all levels.
    pub cells: u64,
    /// Bricks written.
    pub bricks: u64,
    /// Boxes read, over all levels.
    pub boxes: u64,
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
        // A rewritten .amrk file has bricks, not the boxes they were made of.
        let boxes = match self.boxes {
            0 => String::new(),
            n => format!(" of {n} boxes"),
        };
        write!(
            f,
            "read {:.1} MiB, wrote {} cells{boxes} in {} bricks, {:.1} MiB, in {:.2} s ({:.0} MiB/s)",
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
    /// An `.amrk` file, rewritten (fields kept or derived, compression changed).
    Amrk,
    /// An Enzo dataset: its parameter file and hierarchy file.
    Enzo {
        /// The parameter file.
        params: PathBuf,
        /// The `.hierarchy` file.
        hierarchy: PathBuf,
    },
}

/// Works out what `input` is, or says why it is not recognised.
pub fn detect(input: &Path) -> Result<InputFormat, DumpError> {
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
            return Err(unrecognised(
                input,
                format!(
                    "its Header starts with '{}', not an AMReX plotfile version string",
                    first.trim()
                ),
            ));
        }
        return Err(unrecognised(
            input,
            "a directory without a Header file (not an AMReX plotfile) and without exactly one \
             .hierarchy file (not an Enzo dataset)"
                .into(),
        ));
    }
    if input.exists() && !input.is_file() {
        // Never opened: opening a FIFO would wait for a writer.
        return Err(unrecognised(
            input,
            "not a regular file (a device, pipe or socket)".into(),
        ));
    }
    let ext = input
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("h5" | "hdf5")) {
        return Ok(InputFormat::ChomboHdf5);
    }
    if !input.exists() {
        return Err(DumpError::Missing {
            path: input.to_path_buf(),
        });
    }
    let head = first_bytes::<8>(input);
    if head == Some(HDF5_SIGNATURE) {
        // Chombo's own names end in .hdf5 or .h5, but a renamed file is still one.
        return Ok(InputFormat::ChomboHdf5);
    }
    if head == Some(amr_format::raw::MAGIC) {
        return Ok(InputFormat::Amrk);
    }
    let reason = match input.parent() {
        Some(dir) if input.file_name().is_some_and(|n| n == "Header") && detect(dir).is_ok() => {
            format!(
                "the Header of an AMReX plotfile: give the plotfile's directory, {}",
                dir.display()
            )
        }
        _ => "expected an AMReX plotfile directory, a Chombo .h5/.hdf5 file, or an Enzo \
              parameter file with its .hierarchy beside it"
            .to_string(),
    };
    Err(unrecognised(input, reason))
}

fn unrecognised(input: &Path, reason: String) -> DumpError {
    DumpError::Unrecognised {
        path: input.to_path_buf(),
        reason,
    }
}

/// Converts `input` (format detected) to the `.amrk` file `output` as `opts` asks, reporting
/// the bytes read to `progress`. The output appears only when the conversion succeeds, and is
/// refused when it would replace an input.
pub fn convert_dump(
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertSummary, DumpError> {
    if opts.brick == 0 || i64::from(opts.brick) > MAX_BRICK_EXTENT {
        return Err(DumpError::BrickSize(opts.brick));
    }
    let format = detect(input)?;
    let mut inputs = vec![input];
    if let InputFormat::Enzo { params, hierarchy } = &format {
        inputs.extend([params.as_path(), hierarchy.as_path()]);
    }
    amr_format::output::check_output(output, &inputs).map_err(DumpError::Output)?;
    let start = Instant::now();
    let stats = if format == InputFormat::Amrk || opts.derived.is_empty() {
        convert_format(input, format, output, opts, progress)?
    } else {
        // The dump is converted to an intermediate file beside the output (with the fields the
        // formulas read), then rewritten with the derived fields: a dump's reader hands out
        // one field of a box at a time, and holding a box's other fields until the last
        // arrives would cost a box's worth of memory per field.
        //
        // The formulas are checked against the dump's fields before the long first pass.
        let fields = crate::describe::describe(input)?.fields;
        let out = match opts.fields.is_empty() {
            true => fields.clone(),
            false => opts.fields.clone(),
        };
        crate::rewrite::bind_all(input, &fields, out, &opts.derived)
            .map_err(|e| DumpError::Rewrite(Box::new(e)))?;
        let intermediate = amr_format::output::temporary_for(output, ".tmp")
            .map_err(DumpError::Output)?
            .into_temp_path();
        let mut read = opts.fields.clone();
        if !read.is_empty() {
            let derived: Vec<&str> = opts.derived.iter().map(DerivedField::name).collect();
            for d in &opts.derived {
                read.extend(
                    d.inputs()
                        .iter()
                        .filter(|f| !read.contains(f) && !derived.contains(&f.as_str()))
                        .cloned()
                        .collect::<Vec<_>>(),
                );
            }
        }
        let first = ConvertOptions {
            fields: read,
            compression: amr_format::Compression::None,
            derived: Vec::new(),
            tight_ranges: false,
            ..opts.clone()
        };
        let phase = Phase::new(progress);
        let read = convert_format(input, format, &intermediate, &first, &phase)?;
        let derived = rewrite(
            &intermediate,
            input,
            output,
            &opts.fields,
            &opts.derived,
            opts.compression,
            &phase.then(),
        )
        .map_err(|e| DumpError::Rewrite(Box::new(e)))?;
        progress.finish();
        ConvertStats {
            bytes_read: read.bytes_read,
            boxes: read.boxes,
            ..derived
        }
    };
    let output_bytes = std::fs::metadata(output).map(|m| m.len()).unwrap_or(0);
    Ok(ConvertSummary {
        bytes_read: stats.bytes_read,
        cells: stats.cells,
        bricks: stats.bricks,
        boxes: stats.boxes,
        output_bytes,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Converts the dump `input` of format `format` to `output` (an `.amrk` input is written
/// anew, its fields derived in the same pass).
fn convert_format(
    input: &Path,
    format: InputFormat,
    output: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertStats, DumpError> {
    Ok(match format {
        InputFormat::Amrex => amrex::Plotfile::open(input)
            .and_then(|pf| crate::hierarchy_to_amrk::convert(&pf, output, opts, progress))
            .map_err(|error| DumpError::Amrex {
                path: input.to_path_buf(),
                error: Box::new(error),
            })?,
        InputFormat::ChomboHdf5 => crate::chombo::convert(input, output, opts, progress)
            .map_err(|e| DumpError::Chombo(Box::new(e)))?,
        InputFormat::Enzo { params, hierarchy } => {
            crate::enzo::convert(&params, &hierarchy, output, opts, progress).map_err(|error| {
                DumpError::Enzo {
                    params,
                    error: Box::new(error),
                }
            })?
        }
        InputFormat::Amrk => rewrite(
            input,
            input,
            output,
            &opts.fields,
            &opts.derived,
            opts.compression,
            progress,
        )
        .map_err(|e| DumpError::Rewrite(Box::new(e)))?,
    })
}

/// One of the two passes of a conversion with derived fields, reported on one bar: the first
/// pass's finish is not passed on, and the second pass's total is added to what was done.
struct Phase<'a> {
    outer: &'a dyn Progress,
    done: std::sync::atomic::AtomicU64,
    base: u64,
}

impl<'a> Phase<'a> {
    fn new(outer: &'a dyn Progress) -> Self {
        Phase {
            outer,
            done: 0.into(),
            base: 0,
        }
    }

    /// The next pass, counting on from where this one ended.
    fn then(&self) -> Phase<'a> {
        Phase {
            outer: self.outer,
            done: 0.into(),
            base: self.base + self.done.load(std::sync::atomic::Ordering::Relaxed),
        }
    }
}

impl Progress for Phase<'_> {
    fn set_total(&self, n: u64) {
        self.outer.set_total(self.base + n);
    }
    fn advance(&self, n: u64) {
        self.done.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        self.outer.advance(n);
    }
    fn finish(&self) {}
}

/// The first line of `path`, at most 256 bytes of it.
fn first_line(path: &Path) -> Result<String, DumpError> {
    let read = |error| DumpError::Read {
        path: path.to_path_buf(),
        error,
    };
    let file = File::open(path).map_err(read)?;
    let mut bytes = Vec::new();
    BufReader::new(file)
        .take(256)
        .read_until(b'\n', &mut bytes)
        .map_err(read)?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_that_are_not_dumps_say_what_to_give_instead() {
        let dir = tempfile::tempdir().unwrap();
        let plt = dir.path().join("plt00010");
        std::fs::create_dir(&plt).unwrap();
        std::fs::write(plt.join("Header"), "HyperCLaw-V1.1\n").unwrap();
        assert!(matches!(detect(&plt), Ok(InputFormat::Amrex)));
        let e = detect(&plt.join("Header")).unwrap_err().to_string();
        assert!(
            e.contains(&format!("give the plotfile's directory, {}", plt.display())),
            "{e}"
        );
        let amrk = dir.path().join("out.amrk");
        std::fs::write(
            &amrk,
            [amr_format::raw::MAGIC.as_slice(), &[0; 64]].concat(),
        )
        .unwrap();
        assert!(matches!(detect(&amrk), Ok(InputFormat::Amrk)));
        let renamed = dir.path().join("plt0010.chombo");
        std::fs::write(&renamed, [HDF5_SIGNATURE.as_slice(), &[0; 64]].concat()).unwrap();
        assert!(matches!(detect(&renamed), Ok(InputFormat::ChomboHdf5)));
        let text = dir.path().join("notes.txt");
        std::fs::write(&text, "x").unwrap();
        let e = detect(&text).unwrap_err().to_string();
        assert!(e.contains("expected an AMReX plotfile directory"), "{e}");
        // A FIFO is not read (opening it would wait for a writer), whatever its name.
        for name in ["fifo", "fifo.h5"] {
            let fifo = dir.path().join(name);
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                let e = detect(&fifo).unwrap_err().to_string();
                assert!(e.contains("not a regular file"), "{e}");
            }
        }
    }
}
