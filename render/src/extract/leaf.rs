//! Extraction inside one leaf: the merged dual cells and the boundary octants it owns.
//!
//! A leaf owns a voxel when it holds the voxel's lowest finest-level cell (the finest cell
//! whose half-open box holds the voxel's lower corner), so every voxel belongs to exactly one
//! leaf. A dual cell of level `L` is merged (one voxel for its eight octants) when its eight
//! cells are all leaf cells of level `L`; every other octant of the leaf's cells is a voxel of
//! its own, with corners from [`Sampler::corners`].

use amr_format::{IBox, Result};

use super::local::{Neighbourhood, LEAF};
use super::refs::{make_ref, LocalVoxel};
use crate::reconstruct::interp::{min_max, straddles};
use crate::reconstruct::Sampler;

/// Counts one leaf contributes to the statistics.
#[derive(Clone, Copy, Debug, Default)]
pub struct LeafCounts {
    /// Voxels whose corners were evaluated.
    pub evaluated: u64,
}

/// The level-`L` frame of a leaf: its level, finest brick, box of finest-level cells and box of
/// level-`L` cells overlapping it.
#[derive(Clone, Copy, Debug)]
pub struct LeafFrame {
    /// The leaf.
    pub leaf: u32,
    /// The level of its finest brick.
    pub level: u32,
    /// Its finest brick.
    pub brick: u32,
    /// Its box in finest-level cells, relative to the domain.
    pub finest: IBox,
    /// The level-`level` cells (absolute indices) overlapping it: local cell indices count these.
    pub cells: IBox,
}

impl LeafFrame {
    /// The frame of `leaf`, `None` when no brick covers it.
    pub fn new<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, leaf: u32) -> Option<Self> {
        let (brick, level) = sampler.leaf_top(leaf)?;
        let finest = sampler.file().tree().leaf_box(leaf);
        let cells = sampler.grid().level_box(level, &finest);
        Some(Self {
            leaf,
            level,
            brick,
            finest,
            cells,
        })
    }

    /// True when the leaf owns the voxel whose lower corner is doubled point `lo`.
    #[inline]
    pub fn owns(&self, lo: [i64; 3]) -> bool {
        (0..3).all(|a| {
            let f = lo[a].div_euclid(2);
            self.finest.lo[a] <= f && f < self.finest.hi[a]
        })
    }
}

/// Appends the active voxels of `frame` for `iso` to `out`, sorted by id.
pub fn extract_leaf<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    frame: &LeafFrame,
    iso: f32,
    hood: &mut Neighbourhood,
    out: &mut Vec<u64>,
) -> Result<LeafCounts> {
    let mut counts = LeafCounts::default();
    let start = out.len();
    let level = frame.level;
    hood.fill(sampler, level, &frame.cells)?;
    let grid = sampler.grid();
    let s = grid.scale(level);
    let o = grid.offset();

    // Merged dual cells: the lowest cell c0 is owned when its centre's finest cell is ours.
    let first = [0, 1, 2].map(|a| -(-(frame.finest.lo[a] + o[a] - s[a] / 2)).div_euclid(s[a]));
    let last = [0, 1, 2].map(|a| (frame.finest.hi[a] - 1 + o[a] - s[a] / 2).div_euclid(s[a]));
    let e = hood.cells.extent();
    let step = [1usize, e[0] as usize, (e[0] * e[1]) as usize];
    let offsets: [usize; 8] = std::array::from_fn(|n| (0..3).map(|a| (n >> a & 1) * step[a]).sum());
    for z in first[2]..=last[2] {
        for y in first[1]..=last[1] {
            let row = hood.index([first[0], y, z]);
            for (k, x) in (first[0]..=last[0]).enumerate() {
                let i = row + k;
                if !hood.all_leaf && offsets.iter().any(|&d| hood.kind(i + d) != LEAF) {
                    continue;
                }
                let v: [f32; 8] = std::array::from_fn(|n| hood.value(i + offsets[n]));
                counts.evaluated += 1;
                let (lo, hi) = min_max(&v);
                if straddles(lo, hi, iso) {
                    let cell = frame.cells.linear_index([x, y, z]) as u32;
                    out.push(make_ref(frame.leaf, LocalVoxel::Dual { cell }));
                }
            }
        }
    }

    // Octants that touch a level boundary, the domain boundary or an uncovered region.
    if !hood.all_leaf {
        let c = &frame.cells;
        for z in c.lo[2]..c.hi[2] {
            for y in c.lo[1]..c.hi[1] {
                for x in c.lo[0]..c.hi[0] {
                    let cell = [x, y, z];
                    let i = hood.index(cell);
                    if !hood.near_boundary[i] {
                        continue;
                    }
                    let centre = grid.centre(level, cell);
                    for octant in 0..8u8 {
                        let lo = [0, 1, 2].map(|a| {
                            if octant >> a & 1 == 1 {
                                centre[a]
                            } else {
                                centre[a] - s[a]
                            }
                        });
                        if !frame.owns(lo) {
                            continue;
                        }
                        let low = i
                            - (0..3)
                                .map(|a| (1 - (octant as usize >> a & 1)) * step[a])
                                .sum::<usize>();
                        if offsets.iter().all(|&d| hood.kind(low + d) == LEAF) {
                            continue;
                        }
                        counts.evaluated += 1;
                        let Some(v) =
                            sampler.corners(level, cell, hood.value(i), octant, &mut hood.memo)?
                        else {
                            continue;
                        };
                        let (vlo, vhi) = min_max(&v);
                        if straddles(vlo, vhi, iso) {
                            let local = frame.cells.linear_index(cell) as u32;
                            out.push(make_ref(
                                frame.leaf,
                                LocalVoxel::Octant {
                                    cell: local,
                                    octant,
                                },
                            ));
                        }
                    }
                }
            }
        }
    }
    out[start..].sort_unstable();
    Ok(counts)
}
