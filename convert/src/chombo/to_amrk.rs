//! Plotfile to `.amrk`: every box is split into bricks, all bricks are declared before any data
//! is read, then the data is streamed slab by slab (one row of bricks at a time) into the
//! writer.

use std::path::Path;

use super::error::{ChomboError, Result};
use super::plotfile::Plotfile;
use super::reader::{stream, Slab};
use crate::bricking::{BrickLayout, BrickSink, ConvertOptions, ConvertStats};
use crate::progress::Progress;

/// Converts the Chombo plotfile `input` into the `.amrk` file `output`.
///
/// The output appears only when the conversion succeeds: the writer works in a temporary file
/// beside `output` and renames it into place at the end; on any error nothing is left at
/// `output`.
pub fn convert(
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertStats> {
    let pf = Plotfile::open(input)?;
    let comps = pf.select_fields(&opts.fields)?;
    let layout = BrickLayout::new(
        pf.levels.iter().map(|level| level.boxes.as_slice()),
        opts.brick,
    );
    let out_err = |source| ChomboError::Output {
        path: output.to_path_buf(),
        source,
    };
    let fields = comps.iter().map(|&c| pf.fields[c].clone()).collect();
    let mut sink = BrickSink::create(output, pf.level_specs(), fields, layout, opts.compression)
        .map_err(out_err)?;
    let write = |s: Slab| -> Result<()> {
        sink.write_slab(s.level, s.index, &s.valid, &s.cells, s.field, s.values)
            .map_err(out_err)
    };
    let stats = stream(&pf, &comps, i64::from(opts.brick.max(1)), progress, write)?;
    let nbricks = sink.finish().map_err(out_err)?;
    progress.finish();
    Ok(ConvertStats {
        bytes_read: stats.bytes_read,
        cells: pf.total_cells(),
        bricks: nbricks,
    })
}
