//! The part of the domain an extraction keeps: an optional box and the half-spaces of a view
//! frustum, in grid coordinates. Leaves are visited, and voxels kept, only when their box may
//! overlap it; the per-leaf extraction itself is unchanged.
//!
//! The tests are conservative for the frustum (a box is left out only when it lies wholly outside
//! one of its planes, so a box near an edge of the frustum may be kept) and exact for the box (a
//! voxel is kept when its closed box meets the closed clip box). Every voxel a ray inside the
//! region can meet is kept, so a frame whose rays stay inside sees the surfaces it would see with
//! the whole extraction.

use std::time::Instant;

use crate::error::Result;
use crate::reconstruct::Sampler;

use super::{Extraction, Extractor, DUAL_BASE};

/// The closed half-space `normal · (p - point) >= 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfSpace {
    /// A point on the boundary plane.
    pub point: [f64; 3],
    /// The normal, pointing inside (any length).
    pub normal: [f64; 3],
}

impl HalfSpace {
    /// True unless the box `[lo, hi]` lies wholly outside, by more than `slack` grid units.
    pub fn may_overlap(&self, lo: [f64; 3], hi: [f64; 3], slack: f64) -> bool {
        let n = self.normal;
        let far: f64 = (0..3)
            .map(|a| n[a] * ((if n[a] >= 0.0 { hi[a] } else { lo[a] }) - self.point[a]))
            .sum();
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        far >= -slack * len
    }
}

/// What an extraction keeps, in grid coordinates; the default keeps everything.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Region {
    /// A closed box `(lo, hi)`.
    pub bounds: Option<([f64; 3], [f64; 3])>,
    /// Half-spaces (a view frustum's sides).
    pub half_spaces: Vec<HalfSpace>,
    /// Grid units by which boxes are grown before the half-space tests, against round-off.
    pub slack: f64,
}

impl Region {
    /// True when the region keeps the whole domain.
    pub fn is_everything(&self) -> bool {
        self.bounds.is_none() && self.half_spaces.is_empty()
    }

    /// True when the closed box `[lo, hi]` may meet the region: it meets the bounds and lies
    /// wholly outside none of the half-spaces.
    pub fn overlaps(&self, lo: [f64; 3], hi: [f64; 3]) -> bool {
        if let Some((blo, bhi)) = self.bounds {
            if (0..3).any(|a| hi[a] < blo[a] || lo[a] > bhi[a]) {
                return false;
            }
        }
        self.half_spaces
            .iter()
            .all(|h| h.may_overlap(lo, hi, self.slack))
    }

    /// The grid box that holds every voxel leaf `leaf` can emit, for any reconstruction: the
    /// leaf's box grown by two cells of its level (a leaf emits the voxels of the cells of its
    /// level that overlap it, which may reach most of a cell past it, and a dual cell or a face
    /// slab reaches half a cell further). `None` for a leaf no brick covers, which emits nothing.
    pub fn leaf_reach<D: AsRef<[u8]>>(
        sampler: &Sampler<'_, D>,
        leaf: u32,
    ) -> Option<([f64; 3], [f64; 3])> {
        let (_, level) = sampler.leaf_top(leaf)?;
        let b = sampler.file().tree().leaf_box(leaf);
        let s = sampler.grid().scale(level);
        Some((
            [0, 1, 2].map(|a| (2 * (b.lo[a] - 2 * s[a])) as f64),
            [0, 1, 2].map(|a| (2 * (b.hi[a] + 2 * s[a])) as f64),
        ))
    }

    /// The leaves of `leaves` whose voxels may meet the region, in the order given.
    pub fn leaves<D: AsRef<[u8]>>(&self, sampler: &Sampler<'_, D>, leaves: Vec<u32>) -> Vec<u32> {
        if self.is_everything() {
            return leaves;
        }
        leaves
            .into_iter()
            .filter(|&l| Self::leaf_reach(sampler, l).is_some_and(|(lo, hi)| self.overlaps(lo, hi)))
            .collect()
    }

    /// Keeps the refs whose voxel box (`voxel_box` of the ref) meets the region, in order; the
    /// first error of `voxel_box` is returned (the refs are then unspecified).
    pub fn retain_refs(
        &self,
        refs: &mut Vec<u64>,
        mut voxel_box: impl FnMut(u64) -> Result<([f64; 3], [f64; 3])>,
    ) -> Result<()> {
        if self.is_everything() {
            return Ok(());
        }
        let mut bad = None;
        refs.retain(|&r| match voxel_box(r) {
            Ok((lo, hi)) => self.overlaps(lo, hi),
            Err(e) => {
                bad.get_or_insert(e);
                false
            }
        });
        bad.map_or(Ok(()), Err)
    }
}

impl<'f, D: AsRef<[u8]> + Sync> Extractor<'f, D> {
    /// [`Self::extract`] limited to `region`: only candidate leaves whose voxels may meet it
    /// are visited, and only voxels whose box meets it are kept. The statistics count the leaves
    /// visited and the voxels kept; the time includes the filtering.
    pub fn extract_in(&self, iso: f32, region: &Region) -> Result<Extraction> {
        if region.is_everything() {
            return self.extract(iso);
        }
        let start = Instant::now();
        let leaves = region.leaves(&self.sampler, self.candidate_leaves(iso));
        let mut out = self.extract_leaves(iso, &leaves)?;
        region.retain_refs(&mut out.refs, |r| {
            let (lo, hi) = self.voxel_box(r)?;
            Ok((lo.map(|v| v as f64), hi.map(|v| v as f64)))
        })?;
        out.refs.shrink_to_fit();
        out.stats.active = out.refs.len() as u64;
        out.stats.active_duals = out.refs.iter().filter(|&&r| r as u32 >= DUAL_BASE).count() as u64;
        out.stats.seconds = start.elapsed().as_secs_f64();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_are_closed_and_half_spaces_conservative() {
        let r = Region {
            bounds: Some(([0.0; 3], [1.0; 3])),
            ..Region::default()
        };
        assert!(r.overlaps([1.0, 0.0, 0.0], [2.0, 1.0, 1.0]));
        assert!(!r.overlaps([1.5, 0.0, 0.0], [2.0, 1.0, 1.0]));
        let h = Region {
            half_spaces: vec![HalfSpace {
                point: [0.0; 3],
                normal: [1.0, 1.0, 0.0],
            }],
            ..Region::default()
        };
        assert!(h.overlaps([-1.0, -1.0, 0.0], [0.0, 0.0, 1.0]));
        assert!(!h.overlaps([-2.0, -2.0, 0.0], [-0.1, -0.1, 1.0]));
        assert!(h.overlaps([-2.0, 0.0, 0.0], [-1.0, 3.0, 1.0]));
        assert!(Region::default().is_everything());
    }
}
