//! Smooth normals across a level boundary: the central differences step by one cell of the
//! hit's level, so where a surface passes from one level to another the step, and with it the
//! normal, jumps. Near a boundary the differences of both levels, each one cell of its level
//! apart, are weighed by the distance to the other level's cells, which makes the normal
//! continuous there (the field is; `docs/reconstruction.md`).
//!
//! At a point `p` whose kd-tree leaf is of level `L`, a leaf of another level `M` at distance
//! `d` weighs `1 - d / r` (zero from `d = r` on), where `r` is a quarter of a cell of the finer
//! of `L` and `M`, per axis (distances are measured in those quarter cells, so anisotropic
//! cells blend over as many cells on every axis); `L` itself weighs 1. On either side of a
//! boundary between `L` and `M` the two weights meet at 1 and 1, and each falls to zero within
//! `r`: the blend is a continuous function of `p`, and the band it covers is half a cell of the
//! finer level wide. Half a cell of `L` around `p` lies in the 2x2x2 cells of `L` at the
//! corners of `p`'s dual cell, so wherever those are leaf cells of `L` (as the blocks of
//! [`super::level_gradient`] require) nothing is blended and the normal is the one-level one.
//!
//! (A single difference by the weighted mean of the two cells was tried: one set of samples
//! instead of two, but a step that is not a whole cell of either level differences across the
//! dual cells' kinks unevenly: in the sweep of `tests/tests/render_normals.rs` the normals then
//! turned by up to 0.012 degrees between neighbouring rays within a level, against 0.008, and
//! strayed up to 1.01 degrees from the sphere's, against 0.90.)

use amr_format::IBox;

use super::grid::{axes, Grid};
use super::level_gradient::dual_cell_slot;
use super::sampler::Sampler;

/// Most levels one blend weighs; past that, the lightest are left out.
const MOST_LEVELS: usize = 4;

/// The levels whose differences smooth normals weigh at a point, with their weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelWeights {
    levels: [(u32, f64); MOST_LEVELS],
    len: usize,
}

impl LevelWeights {
    /// Level `level` alone, weight 1.
    pub fn one(level: u32) -> Self {
        let mut levels = [(0, 0.0); MOST_LEVELS];
        levels[0] = (level, 1.0);
        Self { levels, len: 1 }
    }

    /// The level when only one is weighed.
    pub fn single(&self) -> Option<u32> {
        (self.len == 1).then_some(self.levels[0].0)
    }

    /// The levels and their weights.
    pub fn iter(&self) -> impl Iterator<Item = (u32, f64)> + '_ {
        self.levels[..self.len].iter().copied()
    }

    /// Raises `level`'s weight to `w` (adding the level when it is new; when the blend is
    /// full, in place of the lightest level if that is lighter).
    fn raise(&mut self, level: u32, w: f64) {
        if let Some(e) = self.levels[..self.len].iter_mut().find(|e| e.0 == level) {
            e.1 = e.1.max(w);
        } else if self.len < MOST_LEVELS {
            self.levels[self.len] = (level, w);
            self.len += 1;
        } else if let Some(e) = self
            .levels
            .iter_mut()
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .filter(|e| e.1 < w)
        {
            *e = (level, w);
        }
    }

    /// Weighs level `other` by its leaf `b`'s distance from `p`, a point in a leaf of `own`
    /// (module comment): `1 - d / r` when within `r`.
    fn weigh_leaf(&mut self, grid: &Grid, p: [f64; 3], own: u32, other: u32, b: &IBox) {
        let d2 = gap_squared(p, b, blend_reach(grid, own.max(other)));
        if d2 < 1.0 {
            self.raise(other, 1.0 - d2.sqrt());
        }
    }

    /// The weighted sum of `gradient` over the levels, divided by the weights of the levels
    /// where it is `Some`; `None` where it is `None` for every level. With one level, that
    /// level's gradient, the same bits.
    pub fn blend(&self, mut gradient: impl FnMut(u32) -> Option<[f64; 3]>) -> Option<[f64; 3]> {
        if let Some(level) = self.single() {
            return gradient(level);
        }
        let (mut sum, mut total) = ([0.0; 3], 0.0);
        for (level, w) in self.iter() {
            if let Some(g) = gradient(level) {
                for a in 0..3 {
                    sum[a] += w * g[a];
                }
                total += w;
            }
        }
        (total > 0.0).then(|| sum.map(|x| x / total))
    }
}

/// The level a [`NearSlot`] gives a kd-tree leaf that no brick covers.
const NO_LEVEL: u32 = u32::MAX;

/// Other-level kd-tree leaves a [`NearLevels`] slot holds at most.
const NEAR_LEAVES: usize = 16;

/// Slots of a [`NearLevels`] memo.
const NEAR_SLOTS: usize = 256;

/// The kd-tree leaves of other levels touching the 2x2x2 cells of one level at the corners of
/// one dual cell, with their levels; `count` past [`NEAR_LEAVES`] when there are more.
#[derive(Clone, Copy)]
struct NearSlot {
    /// The level and the dual cell's lower corner cell (level `u32::MAX`: empty).
    key: (u32, [i64; 3]),
    count: usize,
    leaves: [(IBox, u32); NEAR_LEAVES],
}

/// A per-thread memo of the other-level leaves around dual cells ([`NearSlot`]), direct-mapped
/// by level and dual cell: neighbouring hits share dual cells, so [`Sampler::level_weights_near`]
/// walks the kd-tree once per dual cell instead of once per hit. A slot is a pure function of
/// its key, so the memo never changes a weight.
#[derive(Default)]
pub struct NearLevels {
    /// The sampler served, by [`Sampler::id`] (0: none yet).
    owner: u64,
    slots: Vec<NearSlot>,
}

impl NearLevels {
    /// Bytes of one memo.
    pub const BYTES: usize = NEAR_SLOTS * std::mem::size_of::<NearSlot>();
}

impl<D: AsRef<[u8]>> Sampler<'_, D> {
    /// [`Self::level_weights`], the other-level leaves around `p`'s dual cell of `level` taken
    /// from `memo` when it holds them: the same weights.
    pub fn level_weights_near(
        &self,
        p: [f64; 3],
        level: u32,
        memo: &mut NearLevels,
    ) -> LevelWeights {
        let grid = self.grid();
        let Some(first) = self.dual_cell(p, level) else {
            return self.level_weights(p, level);
        };
        if memo.owner != self.id() || memo.slots.is_empty() {
            memo.owner = self.id();
            memo.slots.clear();
            memo.slots.resize(
                NEAR_SLOTS,
                NearSlot {
                    key: (u32::MAX, [0; 3]),
                    count: 0,
                    leaves: [(IBox::default(), 0); NEAR_LEAVES],
                },
            );
        }
        let key = (level, first);
        let slot = &mut memo.slots[dual_cell_slot(level, first, NEAR_SLOTS)];
        if slot.key != key {
            // The finest cells of the dual cell's corner cells: a point of the dual cell in a
            // leaf of `level` weighs leaves at most a quarter of a cell of `level` away, and
            // half a cell around it lies in these cells (module comment).
            let extent = grid.extent();
            let cells = IBox::new(first, axes(|a| first[a] + 2));
            let f = grid.level_finest_box(level, &cells);
            let region = IBox::new(
                axes(|a| f.lo[a].clamp(0, extent[a])),
                axes(|a| f.hi[a].clamp(0, extent[a])),
            );
            slot.key = key;
            slot.count = 0;
            self.for_each_leaf_touching(&region, |leaf| {
                // A leaf no brick covers is kept as level `NO_LEVEL`.
                let other = self.leaf_top(leaf).map_or(NO_LEVEL, |(_, l)| l);
                if other != level {
                    if let Some(e) = slot.leaves.get_mut(slot.count) {
                        *e = (self.leaf_box(leaf), other);
                    }
                    slot.count += 1;
                }
            });
        }
        if slot.count > NEAR_LEAVES {
            return self.level_weights(p, level);
        }
        let leaves = &slot.leaves[..slot.count];
        if leaves
            .iter()
            .any(|(b, _)| gap_squared(p, b, [1.0; 3]) == 0.0)
        {
            // `p` may lie in a leaf of another level (or of none): the weights start there.
            return self.level_weights(p, level);
        }
        let mut out = LevelWeights::one(level);
        for (b, other) in leaves.iter().filter(|e| e.1 != NO_LEVEL) {
            out.weigh_leaf(grid, p, level, *other, b);
        }
        out
    }

    /// The levels whose differences smooth normals weigh at doubled point `p`, on a hit of
    /// level `level`: `level` alone unless a leaf of another level lies within a quarter of a
    /// cell of the finer of the two from `p` (module comment); a pure function of `p` there.
    pub fn level_weights(&self, p: [f64; 3], level: u32) -> LevelWeights {
        let grid = self.grid();
        let extent = grid.extent();
        if !p.iter().all(|x| x.is_finite()) {
            return LevelWeights::one(level);
        }
        let cell = axes(|a| ((0.5 * p[a]).floor() as i64).clamp(0, extent[a] - 1));
        let Some(own) = self
            .find_leaf(cell)
            .and_then(|leaf| self.leaf_top(leaf))
            .map(|(_, level)| level)
        else {
            return LevelWeights::one(level);
        };
        // The farthest any other level's leaf can weigh from.
        let reach = blend_reach(grid, own);
        let region = IBox {
            lo: axes(|a| ((0.5 * (p[a] - reach[a])).floor() as i64).clamp(0, extent[a])),
            hi: axes(|a| ((0.5 * (p[a] + reach[a])).ceil() as i64).clamp(0, extent[a])),
        };
        let mut out = LevelWeights::one(own);
        self.for_each_leaf_touching(&region, |leaf| {
            let Some((_, other)) = self.leaf_top(leaf) else {
                return;
            };
            if other == own {
                return;
            }
            out.weigh_leaf(grid, p, own, other, &self.leaf_box(leaf));
        });
        if out.single().is_some() {
            LevelWeights::one(level)
        } else {
            out
        }
    }
}

/// The distance `r` over which a leaf of another level weighs, where `level` is the finer of
/// the two: a quarter of a cell of `level` per axis, in doubled units (a cell is `2 * scale`).
#[inline]
fn blend_reach(grid: &Grid, level: u32) -> [f64; 3] {
    grid.scale(level).map(|s| 0.5 * s as f64)
}

/// The squared distance from doubled point `p` to the box `b` of finest cells, in units of
/// `unit` doubled units per axis.
#[inline]
fn gap_squared(p: [f64; 3], b: &IBox, unit: [f64; 3]) -> f64 {
    (0..3)
        .map(|a| {
            let gap = (2.0 * b.lo[a] as f64 - p[a]).max(p[a] - 2.0 * b.hi[a] as f64);
            let x = gap.max(0.0) / unit[a];
            x * x
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_level_blends_to_its_own_gradient_bit_for_bit() {
        let g = [0.1, -0.3, 1e-17];
        assert_eq!(LevelWeights::one(3).blend(|_| Some(g)), Some(g));
        assert_eq!(LevelWeights::one(3).blend(|_| None), None);
    }

    #[test]
    fn weights_divide_by_the_levels_that_give_a_gradient() {
        let mut w = LevelWeights::one(1);
        w.raise(2, 0.5);
        w.raise(2, 0.25);
        assert_eq!(w.iter().collect::<Vec<_>>(), vec![(1, 1.0), (2, 0.5)]);
        let g = w.blend(|l| Some([l as f64; 3])).unwrap();
        assert!((g[0] - (1.0 + 0.5 * 2.0) / 1.5).abs() < 1e-15);
        assert_eq!(w.blend(|l| (l == 2).then_some([2.0; 3])), Some([2.0; 3]));
    }

    #[test]
    fn a_full_blend_drops_its_lightest_level() {
        let mut w = LevelWeights::one(0);
        for (l, x) in [(1, 0.5), (2, 0.1), (3, 0.7), (4, 0.3), (5, 0.05)] {
            w.raise(l, x);
        }
        let mut levels: Vec<u32> = w.iter().map(|e| e.0).collect();
        levels.sort();
        assert_eq!(levels, vec![0, 1, 3, 4]);
    }
}
