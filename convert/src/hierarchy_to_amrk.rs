//! The one conversion every reader shares: a reader describes its hierarchy (levels, boxes,
//! fields) and streams its boxes' values slab by slab; this module declares every brick to the
//! `.amrk` writer up front and routes each slab into its bricks.

use std::path::{Path, PathBuf};

use amr_format::{FormatError, IBox, LevelSpec};

use crate::bricking::{BrickLayout, BrickSink, ConvertOptions, ConvertStats};
use amr_format::progress::Progress;

/// Part of one field of one box, valid cells only, ready to be cut into bricks.
#[derive(Debug)]
pub struct Slab<'a> {
    /// The box's level.
    pub level: usize,
    /// The box's index in its level, as [`AmrSource::boxes`] lists them.
    pub index: usize,
    /// The box's valid cells.
    pub valid: IBox,
    /// The field's position in the selection handed to [`AmrSource::stream`].
    pub field: usize,
    /// The cells of this slab: the box's full x range, some rows and layers, aligned to the
    /// brick grid of the box (each row and layer range starts at the box's lower corner plus a
    /// multiple of the `chunk` passed to [`AmrSource::stream`]).
    pub cells: IBox,
    /// The values of `cells`, x fastest.
    pub values: &'a [f32],
}

/// What can go wrong in the conversion every reader shares; each reader's error type wraps it.
#[derive(Debug, thiserror::Error)]
pub enum ConvertError {
    /// A requested field is not in the dump.
    #[error("{}: no field named '{name}'{hint}; the file has: {available}", path.display())]
    UnknownField {
        /// The dump's main file (the one [`AmrSource::path`] names).
        path: PathBuf,
        /// The requested name.
        name: String,
        /// The dump's field names, comma-separated.
        available: String,
        /// The field that differs only in letter case, as ` (did you mean 'density'?)`, or
        /// nothing.
        hint: String,
    },
    /// The output would replace one of the dump's files or something that is not a regular
    /// file ([`amr_format::output::check_output`]; the message names both), or its file system
    /// has no room for it.
    #[error("{0}")]
    RefusedOutput(FormatError),
    /// The `.amrk` writer refused the data or failed to write.
    #[error("writing {}: {cause}", path.display())]
    Output {
        /// The output file.
        path: PathBuf,
        /// The writer's error (its message is part of this one's, so it is not also the
        /// error's `source()`: printing the chain would repeat it).
        cause: FormatError,
    },
}

/// An opened dump that can be converted: what a reader implements.
pub trait AmrSource {
    /// The reader's error type.
    type Error: From<ConvertError>;

    /// The dump's main file, named in errors about the dump as a whole.
    fn path(&self) -> &Path;

    /// Every field name, in the dump's order.
    fn fields(&self) -> &[String];

    /// The levels as the `.amrk` writer wants them, coarsest first.
    fn level_specs(&self) -> Vec<LevelSpec>;

    /// When in the simulation the dump was written, `(time, step)`, as far as the dump says.
    fn simulation(&self) -> (Option<f64>, Option<i64>) {
        (None, None)
    }

    /// Each level's valid boxes, in the order [`Slab::index`] counts them.
    fn boxes(&self) -> Vec<&[IBox]>;

    /// `(level, index)` of every box in the order [`stream`](Self::stream) hands out its slabs
    /// (for each field, when it streams field by field). The converter joins only boxes that
    /// come close together in this order, so that it holds few unfinished joined bricks
    /// ([`amr_format::box_join::join_runs`]).
    /// By default: level by level, each level's boxes in order.
    fn stream_order(&self) -> Vec<(usize, usize)> {
        self.boxes()
            .iter()
            .enumerate()
            .flat_map(|(l, boxes)| (0..boxes.len()).map(move |i| (l, i)))
            .collect()
    }

    /// Streams the fields `comps` (indices into [`fields`](Self::fields)) of every box to
    /// `sink`, in slabs of at most `chunk` rows and layers (x whole), each aligned to the box's
    /// lower corner. Returns the bytes of cell data read.
    fn stream(
        &self,
        comps: &[usize],
        chunk: i64,
        progress: &dyn Progress,
        sink: &mut dyn FnMut(Slab) -> Result<(), Self::Error>,
    ) -> Result<u64, Self::Error>;
}

/// The error for a failure of the `.amrk` writer on `output`.
pub(crate) fn output_error<E: From<ConvertError>>(output: &Path, source: FormatError) -> E {
    match source {
        // Its message names the output already.
        FormatError::Output { .. } => E::from(ConvertError::RefusedOutput(source)),
        _ => E::from(ConvertError::Output {
            path: output.to_path_buf(),
            cause: source,
        }),
    }
}

/// The slabs of box `valid` with at most `chunk` rows and layers each, the whole x range:
/// `(y0, y1, z0, z1)`, z outermost, aligned to the box's lower corner.
pub fn slab_ranges(valid: &IBox, chunk: i64) -> impl Iterator<Item = (i64, i64, i64, i64)> + '_ {
    let chunk = chunk.max(1);
    let step = chunk as usize;
    (valid.lo[2]..valid.hi[2])
        .step_by(step)
        .flat_map(move |z0| {
            (valid.lo[1]..valid.hi[1]).step_by(step).map(move |y0| {
                (
                    y0,
                    (y0 + chunk).min(valid.hi[1]),
                    z0,
                    (z0 + chunk).min(valid.hi[2]),
                )
            })
        })
}

/// Indices of the fields named in `names`, in that order, repeats counted once; all fields
/// when `names` is empty.
pub fn select_fields<S: AmrSource + ?Sized>(
    src: &S,
    names: &[String],
) -> Result<Vec<usize>, S::Error> {
    Ok(field_positions(src.path(), src.fields(), names)?)
}

/// The positions in `fields` (those of the input `path`) of the fields named in `names`, in
/// that order, repeats counted once; all fields when `names` is empty.
pub fn field_positions(
    path: &Path,
    fields: &[String],
    names: &[String],
) -> Result<Vec<usize>, ConvertError> {
    if names.is_empty() {
        return Ok((0..fields.len()).collect());
    }
    let mut out: Vec<usize> = Vec::with_capacity(names.len());
    for name in names {
        let c =
            fields
                .iter()
                .position(|f| f == name)
                .ok_or_else(|| ConvertError::UnknownField {
                    path: path.to_path_buf(),
                    name: name.clone(),
                    available: fields.join(", "),
                    hint: amr_render::error::same_but_case(name, fields),
                })?;
        if !out.contains(&c) {
            out.push(c);
        }
    }
    Ok(out)
}

/// Valid cells over all levels and boxes.
pub fn total_cells<S: AmrSource + ?Sized>(src: &S) -> u64 {
    src.boxes()
        .iter()
        .flat_map(|l| l.iter())
        .map(|b| b.num_cells().unwrap_or(0))
        .sum()
}

/// Converts `src` into the `.amrk` file `output`: every box split into bricks of at most
/// `opts.brick` cells per axis (with `opts.join`, runs of small boxes joined into one), all
/// bricks declared before any data is read, then the data streamed slab by slab into the writer.
///
/// The output appears only when the conversion succeeds: the writer works in a temporary file
/// that an error (or a kill) leaves behind only as that temporary, never at `output`.
pub fn convert<S: AmrSource + ?Sized>(
    src: &S,
    output: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertStats, S::Error> {
    let comps = select_fields(src, &opts.fields)?;
    let boxes = src.boxes();
    let order = opts.join.then(|| src.stream_order());
    let layout = BrickLayout::new(&boxes, opts.brick, order.as_deref(), comps.len());
    let fields = comps.iter().map(|&c| src.fields()[c].clone()).collect();
    let writer_options = match opts.tight_ranges {
        true => amr_render::extract::writer_options(opts.compression),
        false => amr_format::WriterOptions {
            compression: opts.compression,
            tight: None,
        },
    };
    let mut sink = BrickSink::create(output, src.level_specs(), fields, layout, writer_options)
        .map_err(|e| output_error(output, e))?;
    let (time, step) = src.simulation();
    // A time the dump gives as NaN or infinite is not recorded rather than refused.
    sink.set_simulation(time.filter(|t| t.is_finite()), step)
        .map_err(|e| output_error(output, e))?;
    let mut write = |s: Slab| {
        sink.write_slab(s.level, s.index, &s.valid, &s.cells, s.field, s.values)
            .map_err(|e| output_error(output, e))
    };
    let bytes_read = src.stream(&comps, i64::from(opts.brick.max(1)), progress, &mut write)?;
    let bricks = sink.finish().map_err(|e| output_error(output, e))?;
    progress.finish();
    Ok(ConvertStats {
        bytes_read,
        cells: total_cells(src),
        bricks,
        boxes: boxes.iter().map(|l| l.len() as u64).sum(),
    })
}
