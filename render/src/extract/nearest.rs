//! Active voxels of the `nearest` reconstruction: the field is each leaf cell's value, so the
//! isosurface is the set of cell faces separating a cell below the isovalue from one at or above
//! it. A voxel is one such face.
//!
//! A face between two leaf cells is emitted by the finer one (whose face it is entirely: the
//! region refined beyond a level is a union of whole cells of that level), and between two cells
//! of the same level by the lower one, as its upper face. A cell belongs to the kd-tree leaf
//! holding its lowest finest-level cell, so every face is emitted once. Refs are
//! `leaf << 32 | cell * 8 + face`, `cell` numbering the level-`L` cells overlapping the leaf (x
//! fastest) and `face = 2 axis + side` (side 1: the upper face). Faces on the domain boundary
//! separate nothing and are never voxels.
//!
//! A face decodes to a *face slab*: the box reaching half a cell of the finer side to either side
//! of the face, whose corners take the lower cell's value on the lower side and the upper cell's
//! on the upper side. Its corner range straddles the isovalue exactly when the face does; the
//! nearest source intersects it at the face plane (`trace/nearest_source.rs`).

use amr_format::IBox;

use crate::error::{RenderError, Result};

use super::{candidate_leaves, over_leaves};
use crate::reconstruct::interp::straddles;
use crate::reconstruct::{LeafCell, Sampler};
use crate::voxel::Voxel;

/// Extracts and decodes the `nearest` reconstruction's active faces of one field.
pub struct NearestFaces<'s, 'f, D> {
    sampler: &'s Sampler<'f, D>,
}

/// A kd-tree leaf at its level: the level, its box of finest cells and the level cells overlapping it.
#[derive(Clone, Copy, Debug)]
struct CellFrame {
    level: u32,
    finest: IBox,
    cells: IBox,
}

impl CellFrame {
    fn new<D: AsRef<[u8]>>(s: &Sampler<'_, D>, leaf: u32) -> Option<Self> {
        let (_, level) = s.leaf_top(leaf)?;
        let finest = s.file().tree().leaf_box(leaf);
        let cells = s.grid().level_box(level, &finest);
        Some(Self {
            level,
            finest,
            cells,
        })
    }
}

/// Whether cell `c` of level `level` emits the face on `side` of axis `a`, given the leaf cell
/// across it.
fn owns_face(level: u32, side: usize, across: &LeafCell) -> bool {
    across.level < level || (across.level == level && side == 1)
}

impl<'s, 'f, D: AsRef<[u8]> + Sync> NearestFaces<'s, 'f, D> {
    /// The faces of `sampler`'s field.
    pub fn new(sampler: &'s Sampler<'f, D>) -> Self {
        Self { sampler }
    }

    /// Refs of the faces between a cell below `iso` and one at or above it (`min < iso <= max`
    /// of the two values), in leaf order and sorted within each leaf.
    pub fn extract(&self, iso: f32) -> Result<Vec<u64>> {
        self.extract_leaves(iso, &candidate_leaves(self.sampler, iso))
    }

    /// [`Self::extract`] over the given `leaves` only, in the order given.
    pub fn extract_leaves(&self, iso: f32, leaves: &[u32]) -> Result<Vec<u64>> {
        over_leaves(leaves, |leaf| self.extract_leaf(leaf, iso))
    }

    /// The leaf cell holding level-`level` cell `cell`'s lowest finest cell; `None` outside the
    /// domain or where no brick covers it. By proper nesting every finest cell of `cell` has the
    /// same leaf level, and the same leaf cell when that level is `level` or coarser.
    fn cell_at(&self, level: u32, cell: [i64; 3]) -> Result<Option<LeafCell>> {
        let g = self.sampler.grid();
        let f = g.finest_box(level, cell).lo;
        let ext = g.extent();
        if (0..3).any(|a| f[a] < 0 || f[a] >= ext[a]) {
            return Ok(None);
        }
        self.sampler.locate(f)
    }

    fn extract_leaf(&self, leaf: u32, iso: f32) -> Result<Vec<u64>> {
        let mut out = Vec::new();
        let Some(f) = CellFrame::new(self.sampler, leaf) else {
            return Ok(out);
        };
        let ce = f.cells.extent();
        if (ce[0] as u128) * (ce[1] as u128) * (ce[2] as u128) * 8 > u128::from(u32::MAX) {
            return Err(RenderError::Unsupported(format!(
                "leaf {leaf}: {ce:?} cells do not fit 32-bit face ids"
            )));
        }
        let grown = f.cells.grow([1; 3]);
        let mut table = Vec::with_capacity(grown.num_cells().unwrap_or(0) as usize);
        for z in grown.lo[2]..grown.hi[2] {
            for y in grown.lo[1]..grown.hi[1] {
                for x in grown.lo[0]..grown.hi[0] {
                    table.push(self.cell_at(f.level, [x, y, z])?);
                }
            }
        }
        let g = self.sampler.grid();
        for z in f.cells.lo[2]..f.cells.hi[2] {
            for y in f.cells.lo[1]..f.cells.hi[1] {
                for x in f.cells.lo[0]..f.cells.hi[0] {
                    let c = [x, y, z];
                    if !f.finest.contains_cell(g.finest_box(f.level, c).lo) {
                        continue;
                    }
                    let Some(own) = table[grown.linear_index(c)] else {
                        continue;
                    };
                    if own.level != f.level {
                        continue;
                    }
                    for face in 0..6u32 {
                        let (a, side) = ((face / 2) as usize, (face % 2) as usize);
                        let mut n = c;
                        n[a] += if side == 1 { 1 } else { -1 };
                        let Some(across) = table[grown.linear_index(n)] else {
                            continue;
                        };
                        if !owns_face(f.level, side, &across) {
                            continue;
                        }
                        let (lo, hi) = (own.value.min(across.value), own.value.max(across.value));
                        // A NaN (a damaged file) keeps the face, for the tracer to report.
                        let nan = own.value.is_nan() || across.value.is_nan();
                        if straddles(lo, hi, iso) || nan {
                            let id = f.cells.linear_index(c) as u64 * 8 + u64::from(face);
                            out.push(u64::from(leaf) << 32 | id);
                        }
                    }
                }
            }
        }
        Ok(out)
    }

    /// The face slab `r` names, recomputed from the file: its box (half a cell of the finer side
    /// on either side of the face) and corner values (lower cell's below the face, upper cell's
    /// above). An error when `r` names no face of this file.
    pub fn decode(&self, r: u64) -> Result<Voxel> {
        let (leaf, id) = ((r >> 32) as u32, r as u32);
        let bad = |m: &str| RenderError::BadVoxelRef {
            r,
            what: format!("nearest face: {m}"),
        };
        if leaf as usize >= self.sampler.file().num_leaves() {
            return Err(bad("no such leaf"));
        }
        let f = CellFrame::new(self.sampler, leaf).ok_or_else(|| bad("no brick there"))?;
        let (cell, face) = (i64::from(id / 8), id % 8);
        let e = f.cells.extent();
        if cell >= e[0] * e[1] * e[2] || face >= 6 {
            return Err(bad("index past the leaf"));
        }
        let c = [0, 1, 2]
            .map(|a| f.cells.lo[a] + [cell % e[0], cell / e[0] % e[1], cell / (e[0] * e[1])][a]);
        let (a, side) = ((face / 2) as usize, (face % 2) as usize);
        let mut n = c;
        n[a] += if side == 1 { 1 } else { -1 };
        let own = self
            .cell_at(f.level, c)?
            .filter(|o| o.level == f.level)
            .ok_or_else(|| bad("not a leaf cell of the leaf's level"))?;
        let across = self
            .cell_at(f.level, n)?
            .filter(|x| owns_face(f.level, side, x))
            .ok_or_else(|| bad("no face there"))?;
        let g = self.sampler.grid();
        let s = g.scale(f.level);
        let centre = g.centre(f.level, c);
        let mut lo = [0, 1, 2].map(|b| centre[b] - s[b]);
        let mut hi = [0, 1, 2].map(|b| centre[b] + s[b]);
        let plane = if side == 1 { hi[a] } else { lo[a] };
        lo[a] = plane - s[a];
        hi[a] = plane + s[a];
        let (below, above) = if side == 1 {
            (own.value, across.value)
        } else {
            (across.value, own.value)
        };
        let values = std::array::from_fn(|k| if k >> a & 1 == 1 { above } else { below });
        Ok(Voxel {
            lo: lo.map(|v| v as f64),
            hi: hi.map(|v| v as f64),
            values,
            level: f.level,
        })
    }
}
