//! Plotfile to `.amrk`: every box is split into bricks, all bricks are declared before any data
//! is read, then the data is streamed slab by slab into the writer.

use std::path::Path;

use amr_format::{copy_subbox, AmrkWriter, BrickSpec, Compression, HierarchySpec, WriterOptions};

use super::error::{AmrexError, Result};
use super::plotfile::Plotfile;
use super::reader::{stream, Slab};
use crate::progress::Progress;

/// What to convert and how.
#[derive(Clone, Debug)]
pub struct ConvertOptions {
    /// Field names to keep, in output order; empty keeps all.
    pub fields: Vec<String>,
    /// Largest brick extent along each axis, in cells (at least 1).
    pub brick: u32,
    /// Compression of the brick data.
    pub compression: Compression,
}

/// What a conversion did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ConvertStats {
    /// Bytes read from the data files.
    pub bytes_read: u64,
    /// Cells written per field, over all levels.
    pub cells: u64,
    /// Bricks written.
    pub bricks: u64,
}

/// The bricks of one box: they are consecutive in the brick table, x fastest, one z layer of
/// `per_layer` bricks after the other.
#[derive(Clone, Copy, Debug)]
struct BoxBricks {
    first: usize,
    per_layer: usize,
}

/// Converts the plotfile directory `input` into the `.amrk` file `output`.
///
/// The output appears only when the conversion succeeds: the writer works in a temporary file
/// that an error (or a kill) leaves behind only as that temporary, never at `output`.
pub fn convert(
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertStats> {
    let pf = Plotfile::open(input)?;
    let comps = pf.select_fields(&opts.fields)?;
    let b = i64::from(opts.brick.max(1));
    let mut bricks = Vec::new();
    let mut box_bricks: Vec<Vec<BoxBricks>> = Vec::with_capacity(pf.levels.len());
    for (l, pl) in pf.levels.iter().enumerate() {
        let mut per_box = Vec::with_capacity(pl.cells.boxes.len());
        for valid in &pl.cells.boxes {
            let pieces = valid.split([b; 3]);
            let e = valid.extent();
            let per_layer = (ceil_div(e[0], b) * ceil_div(e[1], b)) as usize;
            per_box.push(BoxBricks {
                first: bricks.len(),
                per_layer,
            });
            bricks.extend(pieces.into_iter().map(|cells| BrickSpec {
                level: l as u32,
                cells,
            }));
        }
        box_bricks.push(per_box);
    }
    let nbricks = bricks.len() as u64;
    let spec = HierarchySpec {
        levels: pf.level_specs(),
        fields: comps.iter().map(|&c| pf.header.fields[c].clone()).collect(),
        bricks: bricks.clone(),
    };
    let out_err = |source| AmrexError::Output {
        path: output.to_path_buf(),
        source: Box::new(source),
    };
    let mut writer = AmrkWriter::create(
        output,
        spec,
        WriterOptions {
            compression: opts.compression,
        },
    )
    .map_err(out_err)?;
    let mut buf = Vec::new();
    let sink = |s: Slab| -> Result<()> {
        let bb = box_bricks[s.level][s.index];
        let layer = ((s.cells.lo[2] - s.valid.lo[2]) / b) as usize;
        let first = bb.first + layer * bb.per_layer;
        for (id, brick) in bricks[first..first + bb.per_layer].iter().enumerate() {
            debug_assert!(s.cells.contains_box(&brick.cells));
            copy_subbox(s.values, &s.cells, &brick.cells, &mut buf);
            writer
                .write_brick(first + id, s.field, &buf)
                .map_err(out_err)?;
        }
        Ok(())
    };
    let stats = stream(&pf, &comps, b, progress, sink)?;
    writer.finish().map_err(out_err)?;
    progress.finish();
    Ok(ConvertStats {
        bytes_read: stats.bytes_read,
        cells: pf.total_cells(),
        bricks: nbricks,
    })
}

fn ceil_div(a: i64, b: i64) -> i64 {
    (a + b - 1) / b
}
