//! An `.amrk` file written anew from another: some of its fields kept, derived fields computed
//! cell by cell ([`DerivedField`]), its bricks compressed or not; the levels, bricks and tree
//! as they were. Memory holds a few megabytes of cells at a time, whatever the file's size.

use std::path::Path;

use amr_format::progress::Progress;
use amr_format::{AmrkWriter, BrickSpec, Compression, FormatError, HierarchySpec, LevelSpec};
use amr_render::mapping::{open_mapped, MappedFile, PageRelease};
use rayon::prelude::*;

use crate::bricking::ConvertStats;
use crate::derive::{DeriveError, DerivedField};
use crate::differential::Gradients;
use crate::finite::ToFiniteF32;
use crate::hierarchy_to_amrk::{field_positions, ConvertError};

/// Cells of the bricks computed together before they are written, at most (one brick may
/// exceed it): enough for both cores, a few megabytes per field.
const CHUNK_CELLS: u64 = 1 << 20;

/// Why an `.amrk` file was not rewritten.
#[derive(Debug, thiserror::Error)]
pub enum RewriteError {
    /// The input does not open as an `.amrk` file (the error names it).
    #[error("{0}")]
    Open(FormatError),
    /// A brick of the input does not decode (the error names the file and the brick).
    #[error("{0}")]
    Read(FormatError),
    /// A derived field cannot be made from the input.
    #[error("{}: {error}", path.display())]
    Derive {
        /// The input file.
        path: std::path::PathBuf,
        /// What is wrong with the derived field (part of this error's message, so not its
        /// `source()`: printing the chain would repeat it).
        error: DeriveError,
    },
    /// A derived field's formula gives no finite `f32` at some cell (boxed: errors are rare,
    /// and this one is large).
    #[error("{0}")]
    NotFinite(Box<NotFinite>),
    /// A neighbour of a cell could not be read for a derived field's gradients.
    #[error("{}: reading the neighbours of a cell: {error}", path.display())]
    Neighbours {
        /// The input file.
        path: std::path::PathBuf,
        /// The renderer's error (part of the message, not its `source()`).
        error: amr_render::RenderError,
    },
    /// The renderer's sampler could not be made for a derived field's gradients.
    #[error("{0}")]
    Sample(amr_render::RenderError),
    /// A field is unknown, or the output is refused or failed.
    #[error(transparent)]
    Convert(#[from] ConvertError),
}

/// A derived field's value at a cell that is no finite `f32`, and where.
#[derive(Debug, thiserror::Error)]
#[error(
    "{}: the derived field {name} = {formula} is {what} at level {level}, cell {cell:?}, where \
     {inputs}; an .amrk file holds finite values only: change the formula (as max(density, \
     1e-30) inside a log)",
    path.display()
)]
pub struct NotFinite {
    /// The input file.
    pub path: std::path::PathBuf,
    /// The derived field's name.
    pub name: String,
    /// Its formula.
    pub formula: String,
    /// "NaN", "infinite" or "outside the f32 range (VALUE)".
    pub what: String,
    /// The cell's level.
    pub level: u32,
    /// The cell, in its level's index space.
    pub cell: [i64; 3],
    /// The input values there, `name = value, ...`.
    pub inputs: String,
}

/// Writes `output` from the `.amrk` file `input` (named `label` in messages: the dump it was
/// converted from, for an intermediate file): its fields `fields` (all when empty, in the order
/// given), then the fields `derived`, with `compression`. The output appears only when complete.
pub fn rewrite(
    input: &Path,
    label: &Path,
    output: &Path,
    fields: &[String],
    derived: &[DerivedField],
    compression: Compression,
    progress: &dyn Progress,
) -> Result<ConvertStats, RewriteError> {
    let file = open_mapped(input).map_err(RewriteError::Open)?;
    let names: Vec<String> = file.fields().iter().map(|f| f.name.clone()).collect();
    let kept = field_positions(label, &names, fields)?;
    let out_fields: Vec<String> = kept.iter().map(|&f| names[f].clone()).collect();
    let (bound, out_fields) = bind_all(label, &names, out_fields, derived)?;
    let gradients = derived
        .iter()
        .zip(&bound)
        .map(|(d, inputs)| {
            d.operator()
                .map(|_| Gradients::new(&file, inputs).map_err(RewriteError::Sample))
                .transpose()
        })
        .collect::<Result<Vec<_>, _>>()?;
    let read = read_fields(names.len(), &kept, &bound);
    let plan = Plan {
        file: &file,
        path: label,
        kept: &kept,
        read: &read,
        derived,
        bound: &bound,
        gradients: &gradients,
    };
    let spec = HierarchySpec {
        levels: file
            .levels()
            .iter()
            .map(|l| LevelSpec {
                cell_size: l.cell_size,
                origin: l.origin,
                ratio_to_next: l.ratio_to_next,
                domain: l.domain,
            })
            .collect(),
        fields: out_fields,
        bricks: file
            .bricks()
            .map(|b| BrickSpec {
                level: b.level,
                cells: b.cells,
            })
            .collect(),
    };
    let refused = |e| crate::hierarchy_to_amrk::output_error::<ConvertError>(output, e);
    let mut writer = AmrkWriter::create(
        output,
        spec,
        amr_render::extract::writer_options(compression),
    )
    .map_err(refused)?;
    writer
        .set_simulation(file.simulation_time(), file.simulation_step())
        .map_err(refused)?;
    let bytes_of = |b: usize| -> u64 { read.iter().map(|&f| file.brick_data(f, b).len).sum() };
    progress.set_total((0..file.num_bricks()).map(bytes_of).sum());
    let release = PageRelease::new(&file);
    let mut stats = ConvertStats::default();
    for chunk in chunks(&file) {
        let computed: Vec<Result<Vec<Vec<f32>>, RewriteError>> = chunk
            .clone()
            .into_par_iter()
            .map(|b| plan.brick(b))
            .collect();
        for (b, values) in chunk.zip(computed) {
            for (f, values) in values?.iter().enumerate() {
                writer.write_brick(b, f, values).map_err(refused)?;
            }
            let bytes = bytes_of(b);
            stats.bytes_read += bytes;
            stats.cells += file.brick(b).cells.num_cells().unwrap_or(0);
            progress.advance(bytes);
        }
        release.release();
    }
    writer.finish().map_err(refused)?;
    progress.finish();
    stats.bricks = file.num_bricks() as u64;
    Ok(stats)
}

/// Binds each derived field's formula to the fields it reads: positions in `names` (the input's
/// fields) or, numbered after them, in the fields derived before it. Refuses a name `names` or
/// the output's fields `out` already hold, and an operator on gradients that reads a derived
/// field. Returns the bindings and the output's fields with the derived ones after `out`.
pub fn bind_all(
    path: &Path,
    names: &[String],
    mut out: Vec<String>,
    derived: &[DerivedField],
) -> Result<(Vec<Vec<usize>>, Vec<String>), RewriteError> {
    let error = |error| RewriteError::Derive {
        path: path.to_path_buf(),
        error,
    };
    let mut readable = names.to_vec();
    let mut bound = Vec::with_capacity(derived.len());
    for d in derived {
        d.check_name(&out).map_err(error)?;
        d.check_name(names).map_err(error)?;
        let inputs = d.bind(&readable).map_err(error)?;
        if d.operator().is_some() {
            if let Some(&k) = inputs.iter().find(|&&k| k >= names.len()) {
                return Err(error(DeriveError::NotStored {
                    name: d.name().to_string(),
                    field: readable[k].clone(),
                }));
            }
        }
        bound.push(inputs);
        out.push(d.name().to_string());
        readable.push(d.name().to_string());
    }
    Ok((bound, out))
}

/// The input fields read, each once: those `kept` and those the derived fields' bindings
/// `bound` name (a binding at or past `stored` is a field derived before, not read).
fn read_fields(stored: usize, kept: &[usize], bound: &[Vec<usize>]) -> Vec<usize> {
    let mut read: Vec<usize> = Vec::new();
    for &f in kept.iter().chain(bound.iter().flatten()) {
        if f < stored && !read.contains(&f) {
            read.push(f);
        }
    }
    read
}

/// Consecutive runs of bricks of about [`CHUNK_CELLS`] cells.
fn chunks(file: &MappedFile) -> Vec<std::ops::Range<usize>> {
    let mut runs = Vec::new();
    let (mut start, mut cells) = (0, 0u64);
    for b in 0..file.num_bricks() {
        cells += file.brick(b).cells.num_cells().unwrap_or(0);
        if cells >= CHUNK_CELLS {
            runs.push(start..b + 1);
            (start, cells) = (b + 1, 0);
        }
    }
    if start < file.num_bricks() {
        runs.push(start..file.num_bricks());
    }
    runs
}

/// What is read from the input and how each output field is made.
struct Plan<'a> {
    file: &'a MappedFile,
    path: &'a Path,
    /// Input fields copied, in output order.
    kept: &'a [usize],
    /// Input fields read ([`read_fields`]).
    read: &'a [usize],
    derived: &'a [DerivedField],
    /// Per derived field: the field of each of its formula's variables, an input field or,
    /// numbered after them, a field derived before it.
    bound: &'a [Vec<usize>],
    /// Per derived field: its inputs' gradients, for an operator on them.
    gradients: &'a [Option<Gradients<'a>>],
}

impl Plan<'_> {
    /// Brick `b`'s values of every output field, in output order.
    fn brick(&self, b: usize) -> Result<Vec<Vec<f32>>, RewriteError> {
        let read = self.read;
        let mut decoded: Vec<Vec<f32>> = Vec::with_capacity(read.len());
        for &f in read {
            let mut values = Vec::new();
            self.file
                .brick_values_into(f, b, &mut values)
                .map_err(RewriteError::Read)?;
            decoded.push(values);
        }
        let of = |f: usize| &decoded[read.iter().position(|&r| r == f).unwrap_or(0)];
        let mut out: Vec<Vec<f32>> = self.kept.iter().map(|&f| of(f).clone()).collect();
        let stored = self.file.fields().len();
        for ((d, inputs), gradients) in self.derived.iter().zip(self.bound).zip(self.gradients) {
            let columns: Vec<&[f32]> = inputs
                .iter()
                .map(|&f| match f < stored {
                    true => of(f).as_slice(),
                    false => out[self.kept.len() + f - stored].as_slice(),
                })
                .collect();
            let cells = columns.first().map_or(0, |c| c.len());
            let mut at = vec![0.0f64; columns.len()];
            let differential =
                match (d.operator(), gradients) {
                    (Some(op), Some(g)) => Some(g.brick(b, op, &columns).map_err(|error| {
                        RewriteError::Neighbours {
                            path: self.path.to_path_buf(),
                            error,
                        }
                    })?),
                    _ => None,
                };
            let mut values = Vec::with_capacity(cells);
            let fill = |at: &mut [f64], cell: usize| {
                for (a, c) in at.iter_mut().zip(&columns) {
                    *a = f64::from(c[cell]);
                }
            };
            for cell in 0..cells {
                let value = match &differential {
                    Some(computed) => computed[cell],
                    None => {
                        fill(&mut at, cell);
                        d.evaluate(&at)
                    }
                };
                match value.to_finite_f32() {
                    Ok(v) => values.push(v),
                    Err((what, value)) => {
                        fill(&mut at, cell);
                        return Err(self.not_finite(d, b, cell, what, value, &at));
                    }
                }
            }
            out.push(values);
        }
        Ok(out)
    }

    fn not_finite(
        &self,
        d: &DerivedField,
        b: usize,
        cell: usize,
        what: &'static str,
        value: f64,
        at: &[f64],
    ) -> RewriteError {
        let brick = self.file.brick(b);
        let [nx, ny, _] = brick.cells.extent();
        let (nx, ny) = (nx.max(1) as usize, ny.max(1) as usize);
        let offset = [cell % nx, (cell / nx) % ny, cell / (nx * ny)];
        let inputs = d
            .inputs()
            .iter()
            .zip(at)
            // The inputs are stored as f32: their shortest f32 digits.
            .map(|(n, v)| format!("{n} = {}", *v as f32))
            .collect::<Vec<_>>()
            .join(", ");
        RewriteError::NotFinite(Box::new(NotFinite {
            path: self.path.to_path_buf(),
            name: d.name().to_string(),
            formula: d.formula().to_string(),
            what: match value.is_finite() {
                true => format!("{what} ({value:e})"),
                false => what.to_string(),
            },
            level: brick.level,
            cell: [0, 1, 2].map(|a| brick.cells.lo[a] + offset[a] as i64),
            inputs,
        }))
    }
}
