//! The description of an AMR hierarchy that a reader hands to the writer: levels, fields, bricks.

use crate::error::{FormatError, Result};
use crate::geometry::IBox;

/// Largest number of cells along one axis of a brick.
pub const MAX_BRICK_EXTENT: i64 = 1024;
/// Largest number of cells in one brick (so that 8 octants per cell fit a 32-bit octant id).
pub const MAX_BRICK_CELLS: u64 = 1 << 28;
/// Largest number of levels.
pub const MAX_LEVELS: usize = 32;
/// Largest extent of the domain along one axis, in finest-level cells (kd split planes are u32).
pub const MAX_FINEST_EXTENT: i64 = u32::MAX as i64;

/// One refinement level.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelSpec {
    /// Physical size of one cell of this level on each axis.
    pub cell_size: [f64; 3],
    /// Physical position of the lower corner of cell index (0, 0, 0) of this level.
    pub origin: [f64; 3],
    /// Refinement ratio to the next finer level on each axis (ignored on the finest level).
    pub ratio_to_next: [u32; 3],
    /// The level's index domain: the cells that would cover the whole problem domain.
    pub domain: IBox,
}

/// One brick: a box of cells of one level whose values are stored together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BrickSpec {
    /// Refinement level, 0 = coarsest.
    pub level: u32,
    /// The brick's cells in its level's index space.
    pub cells: IBox,
}

/// Everything the writer must know before the first brick arrives.
#[derive(Clone, Debug, PartialEq)]
pub struct HierarchySpec {
    /// Levels, coarsest first.
    pub levels: Vec<LevelSpec>,
    /// Field names, in the order their data is written.
    pub fields: Vec<String>,
    /// All bricks of all levels, in any order.
    pub bricks: Vec<BrickSpec>,
}

impl HierarchySpec {
    /// Factor from level `level`'s index space to the finest level's, per axis.
    pub fn finest_scale(&self, level: usize) -> [i64; 3] {
        finest_scale(self.levels.iter().map(|l| l.ratio_to_next), level)
    }

    /// Total number of cells over all bricks.
    pub fn total_cells(&self) -> u64 {
        self.bricks
            .iter()
            .map(|b| b.cells.num_cells().unwrap_or(0))
            .sum()
    }

    /// Checks what the writer relies on; same-level overlap is found later, while the tree is built.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(FormatError::InvalidHierarchy(m));
        if self.levels.is_empty() {
            return bad("no levels".into());
        }
        if self.levels.len() > MAX_LEVELS {
            return bad(format!(
                "{} levels (at most {MAX_LEVELS})",
                self.levels.len()
            ));
        }
        if self.fields.is_empty() {
            return bad("no fields".into());
        }
        for (i, name) in self.fields.iter().enumerate() {
            if name.is_empty() || name.len() > 1024 {
                return bad(format!("field {i} has an empty or over-long name"));
            }
            if self.fields[..i].contains(name) {
                return bad(format!("field name '{name}' appears twice"));
            }
        }
        let nl = self.levels.len();
        for (l, lev) in self.levels.iter().enumerate() {
            if lev.cell_size.iter().any(|&d| !(d.is_finite() && d > 0.0)) {
                return bad(format!(
                    "level {l}: cell size {:?} is not positive and finite",
                    lev.cell_size
                ));
            }
            if lev.origin.iter().any(|o| !o.is_finite()) {
                return bad(format!("level {l}: origin {:?} is not finite", lev.origin));
            }
            if lev.domain.is_empty() {
                return bad(format!("level {l}: empty index domain {:?}", lev.domain));
            }
            if l + 1 < nl {
                if lev.ratio_to_next.iter().any(|&r| r < 2) {
                    return bad(format!(
                        "level {l}: refinement ratio {:?} (must be >= 2)",
                        lev.ratio_to_next
                    ));
                }
                let r = lev.ratio_to_next.map(i64::from);
                let next = &self.levels[l + 1].domain;
                if lev.domain.refine(r) != Some(*next) {
                    return bad(format!(
                        "level {} domain {:?} is not level {l} domain {:?} refined by {:?}",
                        l + 1,
                        next,
                        lev.domain,
                        r
                    ));
                }
            }
        }
        let finest = self.levels[nl - 1].domain;
        for a in 0..3 {
            let e = finest.hi[a].checked_sub(finest.lo[a]);
            if e.is_none_or(|e| e > MAX_FINEST_EXTENT) {
                return bad(format!(
                    "the finest level spans more than {MAX_FINEST_EXTENT} cells on axis {a}"
                ));
            }
        }
        if self.bricks.len() >= u32::MAX as usize {
            return bad(format!(
                "{} bricks (at most {})",
                self.bricks.len(),
                u32::MAX - 1
            ));
        }
        for (i, b) in self.bricks.iter().enumerate() {
            let l = b.level as usize;
            if l >= nl {
                return bad(format!(
                    "brick {i} is on level {l}, but there are {nl} levels"
                ));
            }
            if b.cells.is_empty() {
                return bad(format!("brick {i} (level {l}) is empty: {:?}", b.cells));
            }
            if !self.levels[l].domain.contains_box(&b.cells) {
                return bad(format!(
                    "brick {i} (level {l}) {:?} lies outside the level's domain {:?}",
                    b.cells, self.levels[l].domain
                ));
            }
            let e = b.cells.extent();
            if e.iter().any(|&x| x > MAX_BRICK_EXTENT)
                || b.cells.num_cells().unwrap_or(u64::MAX) > MAX_BRICK_CELLS
            {
                return bad(format!(
                    "brick {i} (level {l}) has extent {e:?}: at most {MAX_BRICK_EXTENT} per axis and {MAX_BRICK_CELLS} cells; split it with --brick"
                ));
            }
        }
        Ok(())
    }
}

/// Product of the ratios from `level` to the last level, given each level's ratio to the next.
pub(crate) fn finest_scale(ratios: impl Iterator<Item = [u32; 3]>, level: usize) -> [i64; 3] {
    let ratios: Vec<[u32; 3]> = ratios.collect();
    let mut s = [1i64; 3];
    for r in ratios
        .iter()
        .take(ratios.len().saturating_sub(1))
        .skip(level)
    {
        for a in 0..3 {
            s[a] = s[a].saturating_mul(r[a] as i64);
        }
    }
    s
}
