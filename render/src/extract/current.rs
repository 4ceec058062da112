//! Active voxels of the `current` reconstruction (Wald et al. 2017): inside a kd-tree leaf of level
//! `L` the field is trilinear on the level-`L` dual cells, each corner taking the leaf cell at that
//! corner; the voxels are those dual cells clipped to the leaf's box.
//!
//! A leaf's voxels are disjoint from every other leaf's, so each is emitted once. Refs are
//! `leaf << 32 | id`, where `id` is the linear index (x fastest) of the dual cell in the leaf's
//! dual range: dual cell `i` spans from the centre of level-`L` cell `i` to that of `i + 1`, and
//! the range runs from one before the leaf's first overlapping cell to its last. A clipped voxel's
//! corner values are the dual cell's trilinear interpolant at the clipped corners (the restriction
//! of a trilinear function to a sub-box is the trilinear function of those values), so the
//! exact cubic intersector sees the same field as [`Sampler::sample`] with [`Reconstruction::Current`],
//! up to `f32` rounding of the clipped corners.
//!
//! [`Reconstruction::Current`]: crate::reconstruct::Reconstruction::Current

use amr_format::IBox;

use crate::error::{RenderError, Result};

use super::{candidate_leaves, over_leaves};
use crate::reconstruct::interp::corners_straddle;
use crate::reconstruct::Sampler;
use crate::voxel::Voxel;

/// A kd-tree leaf seen at its level: level, box of finest cells, dual range.
#[derive(Clone, Copy, Debug)]
struct DualFrame {
    level: u32,
    /// The leaf's box in finest-level cells, relative to the domain.
    finest: IBox,
    /// Dual cells (lowest-cell absolute indices) that overlap the leaf.
    duals: IBox,
}

impl DualFrame {
    fn new<D: AsRef<[u8]>>(s: &Sampler<'_, D>, leaf: u32) -> Option<Self> {
        let (_, level) = s.leaf_top(leaf)?;
        let finest = s.file().tree().leaf_box(leaf);
        let cells = s.grid().level_box(level, &finest);
        let duals = IBox::new(cells.lo.map(|v| v - 1), cells.hi);
        Some(Self {
            level,
            finest,
            duals,
        })
    }
}

/// Extracts and decodes the `current` reconstruction's active voxels of one field.
pub struct CurrentVoxels<'s, 'f, D> {
    sampler: &'s Sampler<'f, D>,
}

impl<'s, 'f, D: AsRef<[u8]> + Sync> CurrentVoxels<'s, 'f, D> {
    /// The voxels of `sampler`'s field.
    pub fn new(sampler: &'s Sampler<'f, D>) -> Self {
        Self { sampler }
    }

    /// Refs of the voxels whose corner values `v` satisfy `min v < iso <= max v`, in leaf order
    /// and sorted within each leaf.
    pub fn extract(&self, iso: f32) -> Result<Vec<u64>> {
        self.extract_leaves(iso, &candidate_leaves(self.sampler, iso))
    }

    /// [`Self::extract`] over the given `leaves` only, in the order given.
    pub fn extract_leaves(&self, iso: f32, leaves: &[u32]) -> Result<Vec<u64>> {
        over_leaves(leaves, |leaf| self.extract_leaf(leaf, iso))
    }

    fn extract_leaf(&self, leaf: u32, iso: f32) -> Result<Vec<u64>> {
        let mut out = Vec::new();
        let Some(f) = DualFrame::new(self.sampler, leaf) else {
            return Ok(out);
        };
        check_ids(&f, leaf)?;
        // The leaf cells at the centres of the level-L cells the dual range touches, once each.
        let corners = IBox::new(f.duals.lo, f.duals.hi.map(|v| v + 1));
        let e = corners.extent();
        let mut table = Vec::with_capacity((e[0] * e[1] * e[2]) as usize);
        for z in corners.lo[2]..corners.hi[2] {
            for y in corners.lo[1]..corners.hi[1] {
                for x in corners.lo[0]..corners.hi[0] {
                    table.push(self.corner_value(f.level, [x, y, z])?);
                }
            }
        }
        let de = f.duals.extent();
        for z in f.duals.lo[2]..f.duals.hi[2] {
            for y in f.duals.lo[1]..f.duals.hi[1] {
                for x in f.duals.lo[0]..f.duals.hi[0] {
                    let i = [x, y, z];
                    let mut dual = [0f32; 8];
                    let mut covered = true;
                    for (n, v) in dual.iter_mut().enumerate() {
                        let c = [0, 1, 2].map(|a| i[a] + (n >> a & 1) as i64);
                        match table[corners.linear_index(c)] {
                            Some(x) => *v = x,
                            None => covered = false,
                        }
                    }
                    if !covered {
                        continue;
                    }
                    let Some((_, _, values)) = self.clip(&f, i, &dual) else {
                        continue;
                    };
                    if corners_straddle(&values, iso) {
                        let id = (i[0] - f.duals.lo[0])
                            + de[0] * ((i[1] - f.duals.lo[1]) + de[1] * (i[2] - f.duals.lo[2]));
                        out.push(u64::from(leaf) << 32 | id as u64);
                    }
                }
            }
        }
        Ok(out)
    }

    /// The value of the leaf cell at the centre of level-`level` cell `cell` (nudged toward `+`,
    /// clamped into the domain): a corner of the `current` dual cells.
    fn corner_value(&self, level: u32, cell: [i64; 3]) -> Result<Option<f32>> {
        let g = self.sampler.grid();
        let at = g.finest_cell(g.centre(level, cell), 7);
        Ok(self.sampler.locate(at)?.map(|c| c.value))
    }

    /// Dual cell `i` of the frame's level clipped to the leaf: doubled box and corner values;
    /// `None` when the intersection has no volume.
    fn clip(
        &self,
        f: &DualFrame,
        i: [i64; 3],
        dual: &[f32; 8],
    ) -> Option<([i64; 3], [i64; 3], [f32; 8])> {
        let g = self.sampler.grid();
        let s = g.scale(f.level);
        let base = g.centre(f.level, i);
        let lo = [0, 1, 2].map(|a| base[a].max(2 * f.finest.lo[a]));
        let hi = [0, 1, 2].map(|a| (base[a] + 2 * s[a]).min(2 * f.finest.hi[a]));
        if (0..3).any(|a| hi[a] <= lo[a]) {
            return None;
        }
        let t = |p: [i64; 3]| [0, 1, 2].map(|a| (p[a] - base[a]) as f64 / (2 * s[a]) as f64);
        let (t0, t1) = (t(lo), t(hi));
        let mut values = [0f32; 8];
        for (n, v) in values.iter_mut().enumerate() {
            let u = [0, 1, 2].map(|a| if n >> a & 1 == 1 { t1[a] } else { t0[a] });
            *v = trilinear64(dual, u) as f32;
        }
        Some((lo, hi, values))
    }

    /// The voxel `r` names: its clipped box and corner values, recomputed from the file. An error
    /// when `r` names no voxel of this file. `dual` is true when the box is a whole dual cell.
    pub fn decode(&self, r: u64) -> Result<Voxel> {
        let (leaf, id) = ((r >> 32) as u32, r as u32);
        let bad = |m: &str| RenderError::BadVoxelRef {
            r,
            what: format!("current voxel: {m}"),
        };
        if leaf as usize >= self.sampler.file().num_leaves() {
            return Err(bad("no such leaf"));
        }
        let f = DualFrame::new(self.sampler, leaf).ok_or_else(|| bad("no brick there"))?;
        let e = f.duals.extent();
        let id = i64::from(id);
        if id >= e[0] * e[1] * e[2] {
            return Err(bad("index past the leaf"));
        }
        let d = [id % e[0], id / e[0] % e[1], id / (e[0] * e[1])];
        let i = [0, 1, 2].map(|a| f.duals.lo[a] + d[a]);
        let mut dual = [0f32; 8];
        for (n, v) in dual.iter_mut().enumerate() {
            let c = [0, 1, 2].map(|a| i[a] + (n >> a & 1) as i64);
            *v = self
                .corner_value(f.level, c)?
                .ok_or_else(|| bad("a corner is not covered"))?;
        }
        let (lo, hi, values) = self
            .clip(&f, i, &dual)
            .ok_or_else(|| bad("outside the leaf"))?;
        Ok(Voxel {
            lo: lo.map(|v| v as f64),
            hi: hi.map(|v| v as f64),
            values,
            level: f.level,
        })
    }
}

/// Fails when a leaf's dual range has more cells than a 32-bit id can name.
fn check_ids(f: &DualFrame, leaf: u32) -> Result<()> {
    let e = f.duals.extent();
    if (e[0] as u128) * (e[1] as u128) * (e[2] as u128) > u128::from(u32::MAX) {
        return Err(RenderError::Unsupported(format!(
            "leaf {leaf}: {e:?} dual cells do not fit 32-bit voxel ids"
        )));
    }
    Ok(())
}

/// Trilinear interpolation in `f64`, `a (1 - t) + b t` per axis (exact at `t = 0` and `t = 1`).
fn trilinear64(v: &[f32; 8], t: [f64; 3]) -> f64 {
    let lerp = |a: f64, b: f64, t: f64| a * (1.0 - t) + b * t;
    let c = v.map(f64::from);
    let x = [
        lerp(c[0], c[1], t[0]),
        lerp(c[2], c[3], t[0]),
        lerp(c[4], c[5], t[0]),
        lerp(c[6], c[7], t[0]),
    ];
    lerp(lerp(x[0], x[1], t[1]), lerp(x[2], x[3], t[1]), t[2])
}
