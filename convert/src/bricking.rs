//! What every reader shares on its way into the writer: the conversion options and statistics,
//! and the layout that splits each input box into bricks and routes slabs of box data to them.

use std::path::Path;

use amr_format::{
    copy_subbox, AmrkWriter, BrickSpec, Compression, FormatError, HierarchySpec, IBox, LevelSpec,
};

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
    /// Bytes of cell data read from the input.
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

/// Every input box split into bricks of at most `brick` cells per axis, in one brick table.
#[derive(Clone, Debug)]
pub struct BrickLayout {
    brick: i64,
    bricks: Vec<BrickSpec>,
    boxes: Vec<Vec<BoxBricks>>,
}

impl BrickLayout {
    /// Splits the valid boxes of each level (`levels[l]` holds level `l`'s boxes) into bricks.
    pub fn new<'a>(levels: impl IntoIterator<Item = &'a [IBox]>, brick: u32) -> Self {
        let b = i64::from(brick.max(1));
        let mut bricks = Vec::new();
        let mut boxes = Vec::new();
        for (l, level) in levels.into_iter().enumerate() {
            let mut per_box = Vec::with_capacity(level.len());
            for valid in level {
                let e = valid.extent();
                per_box.push(BoxBricks {
                    first: bricks.len(),
                    nx: ((e[0] + b - 1) / b) as usize,
                    ny: ((e[1] + b - 1) / b) as usize,
                });
                bricks.extend(valid.split([b; 3]).into_iter().map(|cells| BrickSpec {
                    level: l as u32,
                    cells,
                }));
            }
            boxes.push(per_box);
        }
        Self {
            brick: b,
            bricks,
            boxes,
        }
    }

    /// The brick table, for the writer's hierarchy.
    pub fn bricks(&self) -> &[BrickSpec] {
        &self.bricks
    }

    /// Writes every brick lying inside `cells`, a part of box `index` of `level` (whose valid box
    /// is `valid`) aligned to the brick grid, holding `values` of field `field` (x fastest).
    /// `scratch` is reused between calls.
    #[allow(clippy::too_many_arguments)]
    pub fn write_slab(
        &self,
        writer: &mut AmrkWriter,
        level: usize,
        index: usize,
        valid: &IBox,
        cells: &IBox,
        field: usize,
        values: &[f32],
        scratch: &mut Vec<f32>,
    ) -> Result<(), FormatError> {
        let bb = self.boxes[level][index];
        let b = self.brick;
        let brick_range = |a: usize| {
            let lo = (cells.lo[a] - valid.lo[a]) / b;
            let hi = (cells.hi[a] - valid.lo[a] + b - 1) / b;
            lo as usize..hi as usize
        };
        for iz in brick_range(2) {
            for iy in brick_range(1) {
                for ix in brick_range(0) {
                    let id = bb.first + ix + bb.nx * (iy + bb.ny * iz);
                    let brick = &self.bricks[id];
                    debug_assert!(cells.contains_box(&brick.cells));
                    copy_subbox(values, cells, &brick.cells, scratch);
                    writer.write_brick(id, field, scratch)?;
                }
            }
        }
        Ok(())
    }
}

/// A writer fed slab by slab: the brick layout, the `.amrk` writer and the copy buffer together.
pub struct BrickSink {
    layout: BrickLayout,
    writer: AmrkWriter,
    scratch: Vec<f32>,
}

impl BrickSink {
    /// Starts `output` with `levels`, `fields` and the bricks of `layout` (nothing appears at
    /// `output` before [`finish`](Self::finish)).
    pub fn create(
        output: &Path,
        levels: Vec<LevelSpec>,
        fields: Vec<String>,
        layout: BrickLayout,
        compression: Compression,
    ) -> Result<Self, FormatError> {
        let spec = HierarchySpec {
            levels,
            fields,
            bricks: layout.bricks().to_vec(),
        };
        let writer = AmrkWriter::create(
            output,
            spec,
            amr_render::extract::writer_options(compression),
        )?;
        Ok(Self {
            layout,
            writer,
            scratch: Vec::new(),
        })
    }

    /// Writes the bricks inside `cells` of box `index` of `level`; see [`BrickLayout::write_slab`].
    pub fn write_slab(
        &mut self,
        level: usize,
        index: usize,
        valid: &IBox,
        cells: &IBox,
        field: usize,
        values: &[f32],
    ) -> Result<(), FormatError> {
        self.layout.write_slab(
            &mut self.writer,
            level,
            index,
            valid,
            cells,
            field,
            values,
            &mut self.scratch,
        )
    }

    /// Finishes the file; returns the number of bricks written.
    /// Records when in the simulation the data was written (see `AmrkWriter::set_simulation`).
    pub fn set_simulation(
        &mut self,
        time: Option<f64>,
        step: Option<i64>,
    ) -> Result<(), FormatError> {
        self.writer.set_simulation(time, step)
    }

    pub fn finish(self) -> Result<u64, FormatError> {
        let bricks = self.layout.bricks().len() as u64;
        self.writer.finish()?;
        Ok(bricks)
    }
}
