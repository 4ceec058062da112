//! Leaf-cell location near one kd-tree leaf without walking the tree.
//!
//! [`LocalLocator::start`] gathers, once per leaf, every kd-tree leaf touching the leaf's box
//! grown by the reach of the reconstruction (two cells of the coarsest level met, the rule of
//! `amr-format/src/kdtree/ranges.rs`), and a table over the level-`L` cells of that region naming
//! the kd-tree leaf each lies in. A point is then located with one table read and one brick
//! read; points outside the region, or in a level-`L` cell split between kd-tree leaves, fall back
//! to the kd-tree walk. The answers are exactly [`Sampler::locate`]'s.

use crate::error::Result;
use amr_format::IBox;

use super::grid::axes;
use super::sampler::{LeafCell, Locate, Sampler, Slab};

/// No kd-tree leaf recorded yet.
const EMPTY: u32 = u32::MAX;
/// Split between kd-tree leaves: ask the tree.
const MIXED: u32 = u32::MAX - 1;

/// Largest growth of the region, in level-`L` cells.
const MAX_REACH: i64 = 8;

/// Queries a deferred leaf answers through the tree before [`LocalLocator::ensure_started`]
/// prepares its table. A table costs a walk over every kd-tree leaf touching the region, which
/// next to a much finer level is thousands of leaves (about 1.5 M instructions on issue 17's
/// `tiny.amrk`), while a tree walk costs a few hundred: a leaf with a handful of boundary
/// octants is cheaper without one.
const QUERIES_BEFORE_TABLE: u32 = 512;

/// One kd-tree leaf near the current leaf.
struct Part<'f> {
    leaf: u32,
    /// Its finest brick, that brick's level, cells and values; `None` where no brick covers it.
    top: Option<(u32, u32, IBox, Slab<'f>)>,
    /// log2 of the brick level's cell width per axis, when all are powers of two.
    shift: Option<[u32; 3]>,
}

/// Per-thread scratch: a table locating leaf cells around one kd-tree leaf.
pub struct LocalLocator<'s, 'f, D> {
    sampler: &'s Sampler<'f, D>,
    /// The region's level-`L` cells (absolute indices).
    cells: IBox,
    /// Width of a level-`L` cell in finest cells, and its log2 when every axis is a power of 2.
    scale: [i64; 3],
    shift: Option<[u32; 3]>,
    offset: [i64; 3],
    table: Vec<u32>,
    parts: Vec<Part<'f>>,
    touching: Vec<u32>,
    /// The leaf given to [`Self::defer`] and not yet prepared.
    deferred: Option<(u32, IBox)>,
    /// Queries answered through the tree since the last [`Self::defer`].
    walks: std::cell::Cell<u32>,
    /// Tables prepared so far.
    tables: u64,
}

impl<'s, 'f, D: AsRef<[u8]>> LocalLocator<'s, 'f, D> {
    /// An empty locator (every query goes to the tree until [`Self::start`]).
    pub fn new(sampler: &'s Sampler<'f, D>) -> Self {
        Self {
            sampler,
            cells: IBox::new([0; 3], [0; 3]),
            scale: [1; 3],
            shift: None,
            offset: [0; 3],
            table: Vec::new(),
            parts: Vec::new(),
            touching: Vec::new(),
            deferred: None,
            walks: std::cell::Cell::new(0),
            tables: 0,
        }
    }

    /// Prepares the table for kd-tree leaf box `finest` (finest cells, relative) of level `level`.
    pub fn start(&mut self, level: u32, finest: &IBox) -> Result<()> {
        let sampler = self.sampler;
        let grid = sampler.grid();
        let tree = sampler.file().tree();
        self.parts.clear();
        self.tables += 1;
        // The coarsest level within two level-L cells, then the region two of its cells wide.
        let mut coarsest = level;
        self.touching.clear();
        tree.for_each_leaf_touching(&finest.grow(grid.scale(level).map(|s| 2 * s)), |l| {
            self.touching.push(l)
        });
        for &l in &self.touching {
            if let Some((_, lv)) = sampler.leaf_top(l) {
                coarsest = coarsest.min(lv);
            }
        }
        // Capped at eight level-L cells (a steep level jump would make the table huge; points
        // beyond it go to the tree) and clamped to the domain.
        let (sc, sl) = (grid.scale(coarsest), grid.scale(level));
        let reach = axes(|a| (2 * sc[a]).min(MAX_REACH * sl[a]));
        let ext = grid.extent();
        let region = finest.grow(reach).intersect(&IBox::new([0; 3], ext));
        let cells = grid.level_box(level, &region);
        let n = cells.num_cells().unwrap_or(0) as usize;
        self.cells = cells;
        self.scale = grid.scale(level);
        self.offset = grid.offset();
        self.shift = pow2_shift(self.scale);
        self.table.clear();
        self.table.resize(n, EMPTY);
        self.touching.clear();
        tree.for_each_leaf_touching(&region, |l| self.touching.push(l));
        for k in 0..self.touching.len() {
            let l = self.touching[k];
            let lb = tree.leaf_box(l);
            let block = grid.level_box(level, &lb).intersect(&cells);
            if block.is_empty() {
                continue;
            }
            let idx = self.parts.len() as u32;
            let top = match sampler.leaf_top(l) {
                Some((brick, lv)) => Some((
                    brick,
                    lv,
                    sampler.brick_cells(brick),
                    sampler.values(brick)?,
                )),
                None => None,
            };
            let shift = top.as_ref().and_then(|t| pow2_shift(grid.scale(t.1)));
            self.parts.push(Part {
                leaf: l,
                top,
                shift,
            });
            let w = (block.hi[0] - block.lo[0]) as usize;
            for z in block.lo[2]..block.hi[2] {
                for y in block.lo[1]..block.hi[1] {
                    let dst = cells.linear_index([block.lo[0], y, z]);
                    for t in &mut self.table[dst..dst + w] {
                        *t = if *t == EMPTY { idx } else { MIXED };
                    }
                }
            }
        }
        Ok(())
    }

    /// Drops the references to bricks held since the last [`Self::start`]; until the next
    /// start every query goes to the tree.
    pub fn finish(&mut self) {
        self.parts.clear();
        self.cells = IBox::new([0; 3], [0; 3]);
        self.deferred = None;
    }

    /// Remembers the leaf [`Self::start`] would prepare, without preparing it: queries go to the
    /// tree (the same answers, slower) until [`Self::ensure_started`].
    pub fn defer(&mut self, level: u32, finest: &IBox) {
        self.finish();
        self.deferred = Some((level, *finest));
        self.walks.set(0);
    }

    /// Prepares the table for the leaf given to [`Self::defer`], if not yet done, once more than
    /// [`QUERIES_BEFORE_TABLE`] queries have gone to the tree since: call it before each run of
    /// queries that would use the table.
    pub fn ensure_started(&mut self) -> Result<()> {
        if self.deferred.is_none() || self.walks.get() < QUERIES_BEFORE_TABLE {
            return Ok(());
        }
        match self.deferred.take() {
            Some((level, finest)) => self.start(level, &finest),
            None => Ok(()),
        }
    }

    /// Tables prepared by [`Self::start`] since the locator was made.
    pub fn tables_built(&self) -> u64 {
        self.tables
    }

    /// [`Sampler::locate`], counted.
    #[inline]
    fn walk(&self, finest: [i64; 3]) -> Result<Option<LeafCell>> {
        self.walks.set(self.walks.get().saturating_add(1));
        self.sampler.locate(finest)
    }
}

impl<D: AsRef<[u8]>> Locate for LocalLocator<'_, '_, D> {
    #[inline]
    fn locate_cell(&self, finest: [i64; 3]) -> Result<Option<LeafCell>> {
        let abs = axes(|a| finest[a] + self.offset[a]);
        let c = match self.shift {
            Some(sh) => axes(|a| abs[a] >> sh[a]),
            None => axes(|a| abs[a].div_euclid(self.scale[a])),
        };
        if !self.cells.contains_cell(c) {
            return self.walk(finest);
        }
        let idx = self.table[self.cells.linear_index(c)];
        if idx >= MIXED {
            return self.walk(finest);
        }
        let part = &self.parts[idx as usize];
        let Some((brick, level, cells, values)) = &part.top else {
            return Ok(None);
        };
        let cell = match part.shift {
            Some(sh) => axes(|a| abs[a] >> sh[a]),
            None => self.sampler.grid().cell_of(*level, finest),
        };
        Ok(Some(LeafCell {
            leaf: part.leaf,
            brick: *brick,
            level: *level,
            cell,
            value: values[cells.linear_index(cell)],
        }))
    }
}

/// log2 of a cell width per axis, when every axis is a power of two.
pub(super) fn pow2_shift(scale: [i64; 3]) -> Option<[u32; 3]> {
    scale
        .iter()
        .all(|s| *s > 0 && (*s as u64).is_power_of_two())
        .then(|| scale.map(|s| s.trailing_zeros()))
}
