//! What every reader shares on its way into the writer: the conversion options and statistics,
//! and the layout that splits each input box into bricks (or joins runs of small ones into one)
//! and routes slabs of box data to them.

use std::collections::hash_map::Entry;
use std::collections::HashMap;
use std::path::Path;

use amr_format::box_join::{join_runs, max_open};
use amr_format::{
    copy_subbox, paste_subbox, AmrkWriter, BrickSpec, Compression, FormatError, HierarchySpec,
    IBox, LevelSpec,
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
    /// Join runs of small boxes that arrive close together into bricks of at most `brick`
    /// and [`MAX_JOINED_EXTENT`] cells per axis (see [`amr_format::box_join`]); off keeps every
    /// box in its own bricks.
    pub join: bool,
    /// Fields computed from the converted ones, written after them
    /// ([`crate::derive::DerivedField`]).
    pub derived: Vec<crate::derive::DerivedField>,
    /// Store the tight leaf ranges (what every file for rendering should have); off only for
    /// an intermediate file read once.
    pub tight_ranges: bool,
}

impl Default for ConvertOptions {
    /// All fields, bricks of 32 cells per axis, raw, small boxes joined, no derived field,
    /// tight ranges stored: what `amr-convert` does without options.
    fn default() -> Self {
        ConvertOptions {
            fields: Vec::new(),
            brick: 32,
            compression: Compression::None,
            join: true,
            derived: Vec::new(),
            tight_ranges: true,
        }
    }
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
    /// Boxes read, over all levels (fewer than the bricks when boxes were split, more when
    /// small ones were joined).
    pub boxes: u64,
}

/// Cells per axis of a brick joined from small boxes, at most (and at most `--brick`). Joined up
/// to 16, a level cut into boxes of 2 to 16 cells extracts as fast as the same cells in boxes of
/// `16^3`; joined up to 32, the same `16^3` boxes extract up to 1.2 times slower at isovalues
/// where few of a larger leaf's cells are near the surface (its one value range culls less):
/// `docs/benchmarks-extract.md`, `join`.
pub const MAX_JOINED_EXTENT: u32 = 16;

/// Where one input box's cells go in the brick table.
#[derive(Clone, Copy, Debug)]
enum BoxBricks {
    /// Split into bricks of at most `brick` cells per axis: consecutive from `first`, x
    /// fastest, `nx * ny` per layer (one brick when the box fits in one).
    Split { first: usize, nx: usize, ny: usize },
    /// One of a run of boxes joined into the single brick `brick`.
    Joined { brick: usize },
}

/// One field of a joined brick, gathered from its boxes' slabs until every cell has come.
#[derive(Debug)]
struct PendingBrick {
    values: Vec<f32>,
    filled: u64,
}

/// Every input box in the brick table: boxes larger than a brick split into bricks, runs of small
/// boxes that arrive close together and together fill a box of at most a brick joined into one
/// (see [`amr_format::box_join`]).
#[derive(Debug)]
pub struct BrickLayout {
    brick: i64,
    bricks: Vec<BrickSpec>,
    boxes: Vec<Vec<BoxBricks>>,
    /// Joined bricks still waiting for cells, by (brick, field): about
    /// `amr_format::box_join::PENDING_BYTES` of them at most when the boxes come in the order
    /// the layout was made for.
    pending: HashMap<(usize, usize), PendingBrick>,
    /// Bytes of `pending`'s values.
    pending_bytes: u64,
    /// Twice the bytes the join planned to keep pending at most: a reader that streams out of
    /// the order it declared fails here with a clear error instead of growing without bound.
    pending_cap: u64,
}

impl BrickLayout {
    /// Lays out the valid boxes of each level (`levels[l]` holds level `l`'s boxes) in bricks of
    /// at most `brick` cells per axis. With `join_order`, the `(level, index)` of every box in
    /// the order their data will arrive, runs of small boxes are joined into bricks of at most
    /// `brick` and [`MAX_JOINED_EXTENT`] cells per axis, few enough unfinished at any point of
    /// that order that `fields` fields of them stay within
    /// [`amr_format::box_join::PENDING_BYTES`]; an order that does not list every box exactly
    /// once joins nothing.
    pub fn new(
        levels: &[&[IBox]],
        brick: u32,
        join_order: Option<&[(usize, usize)]>,
        fields: usize,
    ) -> Self {
        let b = i64::from(brick.max(1));
        let extent = b.min(i64::from(MAX_JOINED_EXTENT));
        let open = max_open(extent, fields);
        let planned = (open as u64)
            .saturating_mul((extent as u64).pow(3) * 4)
            .saturating_mul(fields.max(1) as u64);
        let joined = join_order
            .filter(|order| lists_every_box_once(levels, order))
            .map(|order| joined_boxes(levels, order, extent, open))
            .unwrap_or_default();
        let mut bricks = Vec::new();
        let mut boxes = Vec::with_capacity(levels.len());
        let mut joined_brick: HashMap<usize, usize> = HashMap::new();
        for (l, level) in levels.iter().enumerate() {
            let mut per_box = Vec::with_capacity(level.len());
            for (i, valid) in level.iter().enumerate() {
                if let Some(&(run, cells)) = joined.get(&(l, i)) {
                    let brick = *joined_brick.entry(run).or_insert_with(|| {
                        bricks.push(BrickSpec {
                            level: l as u32,
                            cells,
                        });
                        bricks.len() - 1
                    });
                    per_box.push(BoxBricks::Joined { brick });
                    continue;
                }
                let e = valid.extent();
                per_box.push(BoxBricks::Split {
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
            pending: HashMap::new(),
            pending_bytes: 0,
            pending_cap: planned.saturating_mul(2),
        }
    }

    /// The brick table, for the writer's hierarchy.
    pub fn bricks(&self) -> &[BrickSpec] {
        &self.bricks
    }

    /// Writes every brick lying inside `cells`, a part of box `index` of `level` (whose valid box
    /// is `valid`) aligned to the brick grid, holding `values` of field `field` (x fastest). A
    /// joined brick is written once the last of its boxes' cells has come. `scratch` is reused
    /// between calls.
    #[allow(clippy::too_many_arguments)]
    pub fn write_slab(
        &mut self,
        writer: &mut AmrkWriter,
        level: usize,
        index: usize,
        valid: &IBox,
        cells: &IBox,
        field: usize,
        values: &[f32],
        scratch: &mut Vec<f32>,
    ) -> Result<(), FormatError> {
        let b = self.brick;
        match self.boxes[level][index] {
            BoxBricks::Split { first, nx, ny } => {
                let brick_range = |a: usize| {
                    let lo = (cells.lo[a] - valid.lo[a]) / b;
                    let hi = (cells.hi[a] - valid.lo[a] + b - 1) / b;
                    lo as usize..hi as usize
                };
                for iz in brick_range(2) {
                    for iy in brick_range(1) {
                        for ix in brick_range(0) {
                            let id = first + ix + nx * (iy + ny * iz);
                            let brick = &self.bricks[id];
                            debug_assert!(cells.contains_box(&brick.cells));
                            copy_subbox(values, cells, &brick.cells, scratch);
                            writer.write_brick(id, field, scratch)?;
                        }
                    }
                }
                Ok(())
            }
            BoxBricks::Joined { brick } => self.gather(writer, brick, cells, field, values),
        }
    }

    /// Adds a slab to joined brick `brick`'s values of `field`, and writes them once complete.
    fn gather(
        &mut self,
        writer: &mut AmrkWriter,
        brick: usize,
        cells: &IBox,
        field: usize,
        values: &[f32],
    ) -> Result<(), FormatError> {
        let whole = self.bricks[brick].cells;
        let count = cells.num_cells().unwrap_or(u64::MAX);
        let total = whole.num_cells().unwrap_or(u64::MAX);
        if !whole.contains_box(cells) || values.len() as u64 != count {
            return Err(FormatError::Usage(format!(
                "a slab of cells {:?}..{:?} ({} values) does not fit joined brick {brick} ({:?}..{:?})",
                cells.lo, cells.hi, values.len(), whole.lo, whole.hi
            )));
        }
        let pending = match self.pending.entry((brick, field)) {
            Entry::Occupied(e) => e.into_mut(),
            Entry::Vacant(e) => {
                self.pending_bytes += total * 4;
                if self.pending_bytes > self.pending_cap {
                    return Err(FormatError::Usage(format!(
                        "the input's boxes arrive in another order than the reader declared: \
                         {} bytes of joined bricks would wait for cells, more than the {} \
                         planned; convert with --keep-boxes",
                        self.pending_bytes, self.pending_cap
                    )));
                }
                e.insert(PendingBrick {
                    values: vec![0.0; total as usize],
                    filled: 0,
                })
            }
        };
        paste_subbox(values, cells, &mut pending.values, &whole);
        pending.filled += count;
        if pending.filled < total {
            return Ok(());
        }
        let done = self.pending.remove(&(brick, field)).expect("just filled");
        self.pending_bytes -= total * 4;
        if done.filled != total {
            return Err(FormatError::Usage(format!(
                "joined brick {brick} was given {} cells of field {field} for its {total}",
                done.filled
            )));
        }
        writer.write_brick(brick, field, &done.values)
    }

    /// Fails when a joined brick is still missing cells.
    fn check_complete(&self) -> Result<(), FormatError> {
        match self.pending.iter().next() {
            None => Ok(()),
            Some((&(brick, field), p)) => Err(FormatError::Usage(format!(
                "joined brick {brick} got {} of its {} cells of field {field}",
                p.filled,
                p.values.len()
            ))),
        }
    }
}

/// True when `order` names every box of `levels` exactly once.
fn lists_every_box_once(levels: &[&[IBox]], order: &[(usize, usize)]) -> bool {
    let mut seen: Vec<Vec<bool>> = levels.iter().map(|l| vec![false; l.len()]).collect();
    let total: usize = levels.iter().map(|l| l.len()).sum();
    order.len() == total
        && order.iter().all(
            |&(l, i)| match seen.get_mut(l).and_then(|level| level.get_mut(i)) {
                Some(slot) if !*slot => {
                    *slot = true;
                    true
                }
                _ => false,
            },
        )
}

/// The boxes that belong to runs of more than one, by `(level, index)`: the run's number and
/// cells.
fn joined_boxes(
    levels: &[&[IBox]],
    order: &[(usize, usize)],
    extent: i64,
    max_open: usize,
) -> HashMap<(usize, usize), (usize, IBox)> {
    let sequence: Vec<(u32, IBox)> = order
        .iter()
        .map(|&(l, i)| (l as u32, levels[l][i]))
        .collect();
    let mut joined = HashMap::new();
    for (run, j) in join_runs(&sequence, extent, max_open)
        .into_iter()
        .enumerate()
    {
        if j.members.len() > 1 {
            for &position in &j.members {
                joined.insert(order[position], (run, j.cells));
            }
        }
    }
    joined
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
        options: amr_format::WriterOptions,
    ) -> Result<Self, FormatError> {
        let spec = HierarchySpec {
            levels,
            fields,
            bricks: layout.bricks().to_vec(),
        };
        let writer = AmrkWriter::create(output, spec, options)?;
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

    /// Records when in the simulation the data was written (see `AmrkWriter::set_simulation`).
    pub fn set_simulation(
        &mut self,
        time: Option<f64>,
        step: Option<i64>,
    ) -> Result<(), FormatError> {
        self.writer.set_simulation(time, step)
    }

    /// Finishes the file; returns the number of bricks written.
    pub fn finish(self) -> Result<u64, FormatError> {
        self.layout.check_complete()?;
        let bricks = self.layout.bricks().len() as u64;
        self.writer.finish()?;
        Ok(bricks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One level of `n` pairs of `8 x 16 x 16` boxes, each pair filling a `16^3` block.
    fn pairs(n: i64) -> Vec<IBox> {
        (0..n)
            .flat_map(|k| {
                let x = 16 * k;
                [
                    IBox::new([x, 0, 0], [x + 8, 16, 16]),
                    IBox::new([x + 8, 0, 0], [x + 16, 16, 16]),
                ]
            })
            .collect()
    }

    fn sink(dir: &Path, boxes: &[IBox], order: &[(usize, usize)]) -> BrickSink {
        let layout = BrickLayout::new(&[boxes], 32, Some(order), 1);
        let n = boxes.len() as i64 / 2;
        let level = LevelSpec {
            cell_size: [1.0; 3],
            origin: [0.0; 3],
            ratio_to_next: [2; 3],
            domain: IBox::new([0, 0, 0], [16 * n, 16, 16]),
        };
        let out = dir.join("out.amrk");
        BrickSink::create(
            &out,
            vec![level],
            vec!["f".into()],
            layout,
            amr_format::WriterOptions::default(),
        )
        .unwrap()
    }

    /// A reader that streams out of the order it declared gets a clear error once the joined
    /// bricks waiting for cells pass the cap, instead of holding ever more of them.
    #[test]
    fn boxes_out_of_the_declared_order_fail_at_the_cap_instead_of_growing() {
        let dir = tempfile::tempdir().unwrap();
        let boxes = pairs(8);
        let declared: Vec<(usize, usize)> = (0..boxes.len()).map(|i| (0, i)).collect();
        let in_order = |sink: &mut BrickSink, order: &[usize]| {
            order.iter().try_for_each(|&i| {
                let values = vec![1.0; 8 * 16 * 16];
                sink.write_slab(0, i, &boxes[i], &boxes[i], 0, &values)
            })
        };
        let mut good = sink(dir.path(), &boxes, &declared);
        assert_eq!(
            good.layout.bricks().len(),
            8,
            "each pair joined into one brick"
        );
        good.layout.pending_cap = 2 * 16 * 16 * 16 * 4;
        in_order(&mut good, &(0..16).collect::<Vec<_>>()).unwrap();
        assert_eq!(good.finish().unwrap(), 8);

        let mut bad = sink(dir.path(), &boxes, &declared);
        bad.layout.pending_cap = 2 * 16 * 16 * 16 * 4;
        let halves_first: Vec<usize> = (0..16).step_by(2).chain((1..16).step_by(2)).collect();
        let e = in_order(&mut bad, &halves_first).unwrap_err().to_string();
        assert!(
            e.contains("another order than the reader declared") && e.contains("--keep-boxes"),
            "{e}"
        );
        assert_eq!(
            bad.layout.pending.len(),
            2,
            "no brick past the cap was started"
        );
    }
}
