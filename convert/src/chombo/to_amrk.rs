//! Plotfile to `.amrk`: every box is split into bricks, all bricks are declared before any data
//! is read, then the data is streamed slab by slab (one row of bricks at a time) into the
//! writer.

use std::path::Path;

use amr_format::{copy_subbox, AmrkWriter, BrickSpec, Compression, HierarchySpec, WriterOptions};

use super::error::{ChomboError, Result};
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
    /// Bytes of cell data read from the HDF5 file.
    pub bytes_read: u64,
    /// Cells written per field, over all levels.
    pub cells: u64,
    /// Bricks written.
    pub bricks: u64,
}

/// Where one box's bricks sit in the brick table: consecutive, x fastest, `nx * ny` per layer.
#[derive(Clone, Copy, Debug)]
struct BoxBricks {
    first: usize,
    nx: usize,
    ny: usize,
}

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
    let b = i64::from(opts.brick.max(1));
    let mut bricks = Vec::new();
    let mut box_bricks: Vec<Vec<BoxBricks>> = Vec::with_capacity(pf.levels.len());
    for (l, level) in pf.levels.iter().enumerate() {
        let mut per_box = Vec::with_capacity(level.boxes.len());
        for valid in &level.boxes {
            let e = valid.extent();
            per_box.push(BoxBricks {
                first: bricks.len(),
                nx: ceil_div(e[0], b) as usize,
                ny: ceil_div(e[1], b) as usize,
            });
            bricks.extend(valid.split([b; 3]).into_iter().map(|cells| BrickSpec {
                level: l as u32,
                cells,
            }));
        }
        box_bricks.push(per_box);
    }
    let nbricks = bricks.len() as u64;
    let spec = HierarchySpec {
        levels: pf.level_specs(),
        fields: comps.iter().map(|&c| pf.fields[c].clone()).collect(),
        bricks: bricks.clone(),
    };
    let out_err = |source| ChomboError::Output {
        path: output.to_path_buf(),
        source,
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
        let iy = ((s.cells.lo[1] - s.valid.lo[1]) / b) as usize;
        let iz = ((s.cells.lo[2] - s.valid.lo[2]) / b) as usize;
        let first = bb.first + bb.nx * (iy + bb.ny * iz);
        for (k, brick) in bricks[first..first + bb.nx].iter().enumerate() {
            debug_assert!(s.cells.contains_box(&brick.cells));
            copy_subbox(s.values, &s.cells, &brick.cells, &mut buf);
            writer
                .write_brick(first + k, s.field, &buf)
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
