//! A vertex's eight sides as the vertex value reads them: each side's level and value, and the
//! kd-tree leaf it was found in.
//!
//! [`Sampler::vertex_value_in`] needs of the eight leaf cells touching a vertex only their
//! levels and values, and the full leaf cell of the first side of the coarsest level where that
//! level is coarser than the asking one (the coarse octant to interpolate). That cell is read
//! again from its side's kd-tree leaf ([`Sampler::leaf_cell`], the locate's answer), so the
//! sides are found exactly as [`Sampler::around_in`] finds them and the value is its value bit
//! for bit.

use crate::error::Result;

use super::grid::axes;
use super::interp::avg8;
use super::leaf_hints::LeafHints;
use super::mixed::{distinct_sides, sides_in};
use super::sampler::{LeafCell, Locate, Sampler, VertexMemo};

/// The eight sides of a vertex (side `n` as in [`Sampler::around`]): per side its leaf cell's
/// value, and per distinct side (not a repeat, [`Sampler::nudges`]) its level and kd-tree leaf.
/// A repeated side's level stays `u32::MAX`: it is its first side's, which comes before it, so
/// the coarsest level and its first side are read over all eight.
#[derive(Clone, Copy)]
pub(super) struct VertexSides {
    pub(super) levels: [u32; 8],
    pub(super) values: [f32; 8],
    pub(super) leaves: [u32; 8],
}

impl Default for VertexSides {
    fn default() -> Self {
        Self {
            levels: [u32::MAX; 8],
            values: [0.0; 8],
            leaves: [0; 8],
        }
    }
}

/// Where [`Sampler::sides_into`] writes the sides it finds: full leaf cells
/// ([`Sampler::around_in`]) or [`VertexSides`] (the vertex value).
pub(super) trait SideSink {
    /// Side `n`, located as leaf cell `c`.
    fn put_located(&mut self, n: usize, c: &LeafCell);
    /// Side `n`, the cell at finest cell `f` of kd-tree leaf `leaf` when that leaf's brick holds
    /// it: false (nothing written) otherwise.
    fn put_in_leaf<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        n: usize,
        leaf: u32,
        f: [i64; 3],
    ) -> bool;
    /// Side `n` repeats side `first` (the side without the axes on which the two coincide).
    fn repeat(&mut self, n: usize, first: usize);
}

impl SideSink for [LeafCell; 8] {
    #[inline(always)]
    fn put_located(&mut self, n: usize, c: &LeafCell) {
        self[n] = *c;
    }

    #[inline(always)]
    fn put_in_leaf<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        n: usize,
        leaf: u32,
        f: [i64; 3],
    ) -> bool {
        sampler
            .cell_in_leaf_numbered(leaf, f)
            .map(|x| self[n] = x)
            .is_some()
    }

    #[inline(always)]
    fn repeat(&mut self, n: usize, first: usize) {
        self[n] = self[first];
    }
}

impl SideSink for VertexSides {
    #[inline(always)]
    fn put_located(&mut self, n: usize, c: &LeafCell) {
        (self.levels[n], self.values[n], self.leaves[n]) = (c.level, c.value, c.leaf);
    }

    #[inline(always)]
    fn put_in_leaf<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        n: usize,
        leaf: u32,
        f: [i64; 3],
    ) -> bool {
        sampler
            .side_in_leaf(leaf, f)
            .map(|(level, value)| {
                (self.levels[n], self.values[n], self.leaves[n]) = (level, value, leaf);
            })
            .is_some()
    }

    /// Only the value: the repeated side's level stays `u32::MAX` (see [`VertexSides`]).
    #[inline(always)]
    fn repeat(&mut self, n: usize, first: usize) {
        self.values[n] = self.values[first];
    }
}

impl<D: AsRef<[u8]>> Sampler<'_, D> {
    /// The sides of the vertex whose nudges are `lo`, `hi` and `same` ([`Self::nudges`]),
    /// written into `out`: false (`out` then partly written) where a side is not covered.
    ///
    /// The sides are located in order ([`Self::locate_hinted`], trying the leaves of `hints`
    /// first), each located side's kd-tree leaf giving the later sides in its box, read from
    /// its brick when read in place: leaves tile the domain, so that is the locate's answer,
    /// and a side not read so is located in its turn (the first side not covered, or failing,
    /// is the same one).
    #[inline(always)]
    pub(super) fn sides_into<L: Locate, S: SideSink>(
        &self,
        loc: &L,
        (lo, hi, same): ([i64; 3], [i64; 3], usize),
        out: &mut S,
        hints: &mut LeafHints,
    ) -> Result<bool> {
        let side = |n: usize| axes(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
        let mut todo = distinct_sides(same);
        while todo != 0 {
            let n = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let Some((c, b)) = self.locate_hinted(loc, side(n), hints)? else {
                return Ok(false);
            };
            out.put_located(n, &c);
            let mut take = sides_in(&b, lo, hi) & todo;
            while take != 0 {
                let m = take.trailing_zeros() as usize;
                take &= take - 1;
                if out.put_in_leaf(self, m, c.leaf, side(m)) {
                    todo &= !(1 << m);
                }
            }
        }
        if same != 0 {
            for n in 1..8 {
                out.repeat(n, n & !same);
            }
        }
        Ok(true)
    }

    /// [`Self::vertex_value_unmemoized_in`] through [`VertexSides`]: the same sides, the same
    /// coarse cell, the same operations.
    #[inline(always)]
    pub(super) fn vertex_value_lean_in<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        level: u32,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        let (lo, hi, same) = self.nudges(v);
        let mut sides = VertexSides::default();
        if !self.sides_into(loc, (lo, hi, same), &mut sides, &mut memo.hints)? {
            return Ok(None);
        }
        let coarsest = sides.levels.iter().copied().fold(u32::MAX, u32::min);
        if coarsest >= level {
            return Ok(Some(avg8(&sides.values)));
        }
        let side = sides
            .levels
            .iter()
            .position(|&l| l == coarsest)
            .expect("the coarsest level is present");
        let f = axes(|a| if side >> a & 1 == 1 { hi[a] } else { lo[a] });
        let q = match self.leaf_cell(sides.leaves[side], f)? {
            Some(q) => q,
            None => match loc.locate_cell(f)? {
                Some(q) => q,
                None => return Ok(None),
            },
        };
        let octant = self.octant_toward(v, &q, side);
        let Some(corners) = self.leaf_octant_corners_in(loc, &q, octant, memo)? else {
            return Ok(None);
        };
        Ok(Some(self.coarse_lerp(v, &q, octant, &corners)))
    }
}
