//! Stitched vertex values from only the coarse corners they depend on.
//!
//! A vertex on the fine side of a level boundary takes the trilinear interpolant of a coarse
//! octant at the vertex (`docs/reconstruction.md`). The vertex lies on that octant's boundary,
//! so on at least one axis its local coordinate `t` is exactly 0 or 1, where
//! `lerp(a, b, 0) = a * 1 + b * 0` is `a` bit for bit whenever `a` is not zero and `b` is finite
//! (and symmetrically at 1). When every value the interpolation could meet is finite (the
//! sampler checks the bricks' stored ranges once, [`Sampler::bounded`]), the interpolant is
//! therefore computed from the corners with non-zero weight alone (typically one, two or four
//! of the eight), each by the same vertex rule as the full octant; where a kept operand is zero
//! (the skipped one could flip its sign) the full octant is evaluated instead.

use amr_format::IBox;

use crate::error::Result;

use super::grid::axes;
use super::interp::{avg8, lerp};
use super::mixed::holds;
use super::sampler::{LeafCell, Locate, Octant, Sampler, VertexMemo};

/// What one octant evaluation has learnt while stitching its vertices: coarse octants
/// evaluated whole, coarse vertex values, the kd-tree leaves met (their boxes), which nearby
/// cells are read from before they are located, and the coarse leaf cells known to cover their
/// whole finest box, whose cells are answered without a read.
pub(super) struct Stitches {
    octants: [(Octant, Option<[f32; 8]>); 4],
    num_octants: usize,
    vertices: [([i64; 3], u32, Option<f32>); 16],
    num_vertices: usize,
    /// Kd-tree leaves: box and leaf.
    leaves: [(IBox, u32); 6],
    num_leaves: usize,
    /// Whole leaf cells: finest box, level and value.
    wholes: [(IBox, u32, f32); 4],
    num_wholes: usize,
    /// The coarse leaf cell (level and cell) last tested for being whole.
    last_coarse: Option<(u32, [i64; 3])>,
}

impl Stitches {
    /// Nothing learnt yet.
    pub(super) fn new() -> Self {
        let none = Octant {
            level: 0,
            cell: [0; 3],
            octant: 0,
        };
        let empty = IBox::new([0; 3], [0; 3]);
        Self {
            octants: [(none, None); 4],
            num_octants: 0,
            vertices: [([0; 3], 0, None); 16],
            num_vertices: 0,
            leaves: [(empty, 0); 6],
            num_leaves: 0,
            wholes: [(empty, 0, 0.0); 4],
            num_wholes: 0,
            last_coarse: None,
        }
    }

    fn octant(&self, o: &Octant) -> Option<Option<[f32; 8]>> {
        self.octants[..self.num_octants]
            .iter()
            .find(|(k, _)| k == o)
            .map(|(_, c)| *c)
    }

    fn add_octant(&mut self, o: Octant, corners: Option<[f32; 8]>) {
        if self.num_octants < self.octants.len() {
            self.octants[self.num_octants] = (o, corners);
            self.num_octants += 1;
        }
    }

    #[inline]
    fn vertex(&self, v: [i64; 3], level: u32) -> Option<Option<f32>> {
        self.vertices[..self.num_vertices]
            .iter()
            .find(|(w, l, _)| *w == v && *l == level)
            .map(|(_, _, x)| *x)
    }

    fn add_vertex(&mut self, v: [i64; 3], level: u32, value: Option<f32>) {
        if self.num_vertices < self.vertices.len() {
            self.vertices[self.num_vertices] = (v, level, value);
            self.num_vertices += 1;
        }
    }

    /// Remembers kd-tree leaf `leaf` (box `leaf_box`), if not yet known and there is room.
    pub(super) fn add_leaf(&mut self, leaf: u32, leaf_box: IBox) {
        let known = &self.leaves[..self.num_leaves];
        if self.num_leaves < self.leaves.len() && !known.iter().any(|(_, l)| *l == leaf) {
            self.leaves[self.num_leaves] = (leaf_box, leaf);
            self.num_leaves += 1;
        }
    }

    /// Remembers that every finest cell of box `b` lies in a leaf cell of `level` and value
    /// `value`, if not yet known and there is room.
    fn add_whole(&mut self, b: IBox, level: u32, value: f32) {
        let known = &self.wholes[..self.num_wholes];
        if self.num_wholes < self.wholes.len() && !known.iter().any(|(k, _, _)| *k == b) {
            self.wholes[self.num_wholes] = (b, level, value);
            self.num_wholes += 1;
        }
    }

    /// The level and value of the leaf cell at finest cell `f` when it lies in a whole leaf
    /// cell met so far, or in a kd-tree leaf met so far whose brick is read in place
    /// ([`Sampler::value_in_leaf`]).
    #[inline(always)]
    fn level_value<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        f: [i64; 3],
    ) -> Option<(u32, f32)> {
        for (b, level, value) in &self.wholes[..self.num_wholes] {
            if holds(b, f) {
                return Some((*level, *value));
            }
        }
        for (b, leaf) in &self.leaves[..self.num_leaves] {
            if holds(b, f) {
                return sampler.level_value_in_leaf(*leaf, f);
            }
        }
        None
    }
}

/// `lerp(a, b, t)`, skipping the operand of weight 0 when `t` is 0 or 1; `None` when the
/// operand kept is zero (the skipped one could change the sign of that zero). A NaN operand
/// stands for a value not computed and passes through.
#[inline]
fn lerp_skipping(a: f32, b: f32, t: f32) -> Option<f32> {
    let kept = if t == 0.0 {
        a
    } else if t == 1.0 {
        b
    } else {
        return Some(lerp(a, b, t));
    };
    (kept != 0.0).then_some(kept)
}

/// [`super::interp::trilinear`] of corners `v` at `t` through [`lerp_skipping`]: the same bits
/// when the corners of weight 0 (NaN in `v`) are finite, `None` when a zero was kept.
#[inline]
fn trilinear_skipping(v: &[f32; 8], t: [f32; 3]) -> Option<f32> {
    let x = [
        lerp_skipping(v[0], v[1], t[0])?,
        lerp_skipping(v[2], v[3], t[0])?,
        lerp_skipping(v[4], v[5], t[0])?,
        lerp_skipping(v[6], v[7], t[0])?,
    ];
    let y = [
        lerp_skipping(x[0], x[1], t[1])?,
        lerp_skipping(x[2], x[3], t[1])?,
    ];
    lerp_skipping(y[0], y[1], t[2])
}

impl<D: AsRef<[u8]>> Sampler<'_, D> {
    /// The value at vertex `v` of octant `octant` of leaf cell `q`, which holds `v` and is the
    /// coarse cell the vertex is stitched to: [`Self::coarse_value_in`]'s value, computed from
    /// the octant's corners of non-zero weight when the file allows it, else from the whole
    /// octant (remembered in `known`). `None` where a cell involved is not covered.
    pub(super) fn stitched_value<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        q: &LeafCell,
        octant: u8,
        known: &mut Stitches,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        let key = Octant {
            level: q.level,
            cell: q.cell,
            octant,
        };
        if let Some(corners) = known.octant(&key).or_else(|| memo.octant_get(&key)) {
            return Ok(corners.map(|c| self.coarse_lerp(v, q, octant, &c)));
        }
        if self.bounded() {
            if let Some(x) = self.stitched_from_needed(loc, v, q, &key, known, memo)? {
                return Ok(Some(x));
            }
        }
        let corners = self.leaf_octant_corners_in(loc, q, octant, memo)?;
        known.add_octant(key, corners);
        Ok(corners.map(|c| self.coarse_lerp(v, q, octant, &c)))
    }

    /// [`Self::stitched_value`] from the corners of non-zero weight alone; `None` when that
    /// does not decide the bits (a kept zero) or a cell involved is not covered.
    fn stitched_from_needed<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        q: &LeafCell,
        key: &Octant,
        known: &mut Stitches,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        let (lo, _) = self.octant_box(key);
        let s = self.grid().scale(q.level);
        // As `coarse_lerp` computes them.
        let t = axes(|a| ((v[a] - lo[a]) as f64 / s[a] as f64) as f32);
        // The corners of non-zero weight: per axis, bit `a` of the corner clear where `t` is 0,
        // set where it is 1.
        const UPPER: [u8; 3] = [0xAA, 0xCC, 0xF0];
        let mut needed = 0xFFu8;
        for a in 0..3 {
            if t[a] == 0.0 {
                needed &= !UPPER[a];
            } else if t[a] == 1.0 {
                needed &= UPPER[a];
            }
        }
        let centre = usize::from(!key.octant & 7);
        if needed & !(1 << centre) != 0 && known.last_coarse != Some((q.level, q.cell)) {
            // The coarse cell's other corners read its cells without locating them when it
            // covers its whole finest box.
            known.last_coarse = Some((q.level, q.cell));
            let own = self.grid().finest_box(q.level, q.cell);
            let domain = IBox::new([0; 3], self.grid().extent());
            if self.leaf_box(q.leaf).contains_box(&own.intersect(&domain)) {
                known.add_whole(own, q.level, q.value);
            }
        }
        let mut corners = [f32::NAN; 8];
        while needed != 0 {
            let n = needed.trailing_zeros() as usize;
            needed &= needed - 1;
            corners[n] = if n == centre {
                q.value
            } else {
                let w = axes(|a| lo[a] + (n >> a & 1) as i64 * s[a]);
                match self.coarse_vertex(loc, w, q.level, known, memo)? {
                    Some(x) => x,
                    None => return Ok(None),
                }
            };
        }
        Ok(trilinear_skipping(&corners, t))
    }

    /// The value at vertex `w` seen from an octant of level `level` ([`Self::vertex_value_in`]'s
    /// value), its cells read from the whole cells and kd-tree leaves `known` has met where they
    /// lie there.
    fn coarse_vertex<L: Locate>(
        &self,
        loc: &L,
        w: [i64; 3],
        level: u32,
        known: &mut Stitches,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        if let Some(x) = known.vertex(w, level) {
            return Ok(x);
        }
        let value = match self.around_known(loc, w, known)? {
            None => None,
            Some((levels, values)) => {
                let coarsest = levels.iter().copied().fold(u32::MAX, u32::min);
                if coarsest < level {
                    // The first side of the coarsest level, located again for its cell: the
                    // same leaf cell as read.
                    let side = levels.iter().position(|&l| l == coarsest).unwrap_or(0);
                    let (lo, hi, _) = self.nudges(w);
                    let f = axes(|a| if side >> a & 1 == 1 { hi[a] } else { lo[a] });
                    match loc.locate_cell(f)? {
                        Some(q) => {
                            let octant = self.octant_toward(w, &q, side);
                            self.stitched_value(loc, w, &q, octant, known, memo)?
                        }
                        None => None,
                    }
                } else {
                    Some(avg8(&values))
                }
            }
        };
        known.add_vertex(w, level, value);
        Ok(value)
    }

    /// The levels and values of [`Self::around_in`]'s cells, read from the whole cells and
    /// kd-tree leaves `known` has met before locating them, and remembering the leaves located.
    fn around_known<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        known: &mut Stitches,
    ) -> Result<Option<([u32; 8], [f32; 8])>> {
        let (lo, hi, same) = self.nudges(v);
        let mut levels = [0u32; 8];
        let mut values = [0f32; 8];
        for n in 0..8 {
            let m = n & !same;
            if m != n {
                (levels[n], values[n]) = (levels[m], values[m]);
                continue;
            }
            let f = axes(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
            (levels[n], values[n]) = match known.level_value(self, f) {
                Some(x) => x,
                None => match loc.locate_cell(f)? {
                    Some(c) => {
                        known.add_leaf(c.leaf, self.leaf_box(c.leaf));
                        (c.level, c.value)
                    }
                    None => return Ok(None),
                },
            };
        }
        Ok(Some((levels, values)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::interp::trilinear;

    /// Wherever the skipping interpolation answers, it has the full interpolation's bits, for
    /// any finite values of the corners it skipped; zeros of both signs included.
    #[test]
    fn skipping_interpolation_has_the_full_bits() {
        let pool = [0.0f32, -0.0, 1.5, -2.25, 3.0e-39, -7.0e12, 0.1, -0.1];
        let ts = [0.0f32, 1.0, 0.5, 0.25, 0.75];
        let mut seed = 0x9E37_79B9_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        let (mut answered, mut declined) = (0, 0);
        for _ in 0..20_000 {
            let v: [f32; 8] = std::array::from_fn(|_| pool[next() as usize % pool.len()]);
            let t: [f32; 3] = std::array::from_fn(|_| ts[next() as usize % ts.len()]);
            let mut kept = v;
            for (n, x) in kept.iter_mut().enumerate() {
                let weight = (0..3).all(|a| {
                    if n >> a & 1 == 1 {
                        t[a] != 0.0
                    } else {
                        t[a] != 1.0
                    }
                });
                if !weight {
                    *x = f32::NAN;
                }
            }
            match trilinear_skipping(&kept, t) {
                Some(x) => {
                    answered += 1;
                    assert_eq!(x.to_bits(), trilinear(&v, t).to_bits(), "{v:?} at {t:?}");
                }
                None => declined += 1,
            }
        }
        assert!(answered > 10_000 && declined > 100, "{answered} {declined}");
    }
}
