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
use super::mixed::{distinct_sides, sides_in, SIDES_DOWN};
use super::sampler::{LeafCell, Locate, Octant, Sampler, VertexMemo};

/// What one octant evaluation has learnt while stitching its vertices: coarse octants
/// evaluated whole, coarse vertex values, and kd-tree leaves met (with their boxes), which
/// nearby cells are read from before they are located.
pub(super) struct Stitches {
    octants: [(Octant, Option<[f32; 8]>); 4],
    num_octants: usize,
    vertices: [([i64; 3], u32, Option<f32>); 16],
    num_vertices: usize,
    leaves: [(u32, IBox); 6],
    num_leaves: usize,
}

impl Stitches {
    /// Nothing learnt yet.
    pub(super) fn new() -> Self {
        let none = Octant {
            level: 0,
            cell: [0; 3],
            octant: 0,
        };
        Self {
            octants: [(none, None); 4],
            num_octants: 0,
            vertices: [([0; 3], 0, None); 16],
            num_vertices: 0,
            leaves: [(0, IBox::new([0; 3], [0; 3])); 6],
            num_leaves: 0,
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

    /// Remembers the value at vertex `v` seen from an octant of level `level`, if there is room.
    pub(super) fn add_vertex(&mut self, v: [i64; 3], level: u32, value: Option<f32>) {
        if self.num_vertices < self.vertices.len() {
            self.vertices[self.num_vertices] = (v, level, value);
            self.num_vertices += 1;
        }
    }

    /// Remembers kd-tree leaf `leaf` (box `leaf_box`), if not yet known and there is room.
    pub(super) fn add_leaf(&mut self, leaf: u32, leaf_box: IBox) {
        let known = &self.leaves[..self.num_leaves];
        if self.num_leaves < self.leaves.len() && !known.iter().any(|(k, _)| *k == leaf) {
            self.leaves[self.num_leaves] = (leaf, leaf_box);
            self.num_leaves += 1;
        }
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
    /// The value at vertex `v` whose coarsest side, side `side`, lies in leaf cell `q` (a
    /// coarser level than some other side's), given its eight sides' values `sides` (asked only
    /// where needed). At a corner of `q`'s octant toward `v` in a bounded file that is the mean
    /// of the sides when not zero (`lerp` at 0 and 1 keeps an operand exactly when it is not
    /// zero): the value at `v` seen from `q`'s level, the coarsest around `v`. Otherwise
    /// [`Self::stitched_value`]. `stitches` is the stitch memory of the octant being computed,
    /// made on first need knowing `near`'s kd-tree leaf. `None` where a cell involved is not
    /// covered.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn stitched_corner<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        (q, side): (&LeafCell, usize),
        sides: impl FnOnce() -> [f32; 8],
        stitches: &mut Option<Stitches>,
        near: Option<(LeafCell, IBox)>,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        let octant = self.octant_toward(v, q, side);
        let new_stitches = || {
            let mut known = Stitches::new();
            if let Some((c, b)) = near {
                known.add_leaf(c.leaf, b);
            }
            known
        };
        if self.bounded() {
            let (olo, ohi) = self.octant_box(&Octant {
                level: q.level,
                cell: q.cell,
                octant,
            });
            if (0..3).all(|a| (v[a] == olo[a]) | (v[a] == ohi[a])) {
                let x = avg8(&sides());
                if x != 0.0 {
                    stitches
                        .get_or_insert_with(new_stitches)
                        .add_vertex(v, q.level, Some(x));
                    return Ok(Some(x));
                }
            }
        }
        let known = stitches.get_or_insert_with(new_stitches);
        self.stitched_value(loc, v, q, octant, known, memo)
    }

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
        let centre = usize::from(!key.octant & 7);
        // The coarse cell's own finest cells: the sides of its corners there are the cell.
        let own = (q, self.grid().finest_box(q.level, q.cell));
        let mut corners = [f32::NAN; 8];
        // The corners of non-zero weight: on no axis on the upper side where `t` is 0, nor on
        // the lower side where it is 1.
        let mut needed = (0..3).fold(0xFFu8, |m, a| {
            let zero = 0u8.wrapping_sub(u8::from(t[a] == 0.0));
            let one = 0u8.wrapping_sub(u8::from(t[a] == 1.0));
            m & !((!SIDES_DOWN[a] & zero) | (SIDES_DOWN[a] & one))
        });
        while needed != 0 {
            let n = needed.trailing_zeros() as usize;
            needed &= needed - 1;
            corners[n] = if n == centre {
                q.value
            } else {
                let w = axes(|a| lo[a] + (n >> a & 1) as i64 * s[a]);
                match self.coarse_vertex(loc, w, own, known, memo)? {
                    Some(x) => x,
                    None => return Ok(None),
                }
            };
        }
        Ok(trilinear_skipping(&corners, t))
    }

    /// The value at vertex `w` of an octant of leaf cell `own.0` (finest box `own.1`), seen from
    /// the cell's level ([`Self::vertex_value_in`]'s value): the sides in the cell are the
    /// cell, the others are read from the kd-tree leaves `known` has met where they lie there.
    fn coarse_vertex<L: Locate>(
        &self,
        loc: &L,
        w: [i64; 3],
        own: (&LeafCell, IBox),
        known: &mut Stitches,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        let level = own.0.level;
        if let Some(x) = known.vertex(w, level) {
            return Ok(x);
        }
        let value = match self.around_values(loc, w, own, known)? {
            None => None,
            Some((levels, values)) => {
                let coarsest = levels.iter().copied().min().unwrap_or(level);
                if coarsest < level {
                    // Stitched again: the cells themselves decide the coarse octant.
                    match self.around_known(loc, w, known)? {
                        Some(cells) => {
                            let (q, octant) = self.coarse_octant(w, &cells, coarsest);
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

    /// The `j`th kd-tree leaf of a vertex's search: the `j`th one `known` has met, or else the
    /// leaf holding the side `side()` (none met so far holds it), located and remembered so the
    /// rest of its cells are read from it; `None` where that side is outside every leaf.
    #[inline(always)]
    fn leaf_or_locate<L: Locate>(
        &self,
        loc: &L,
        known: &mut Stitches,
        j: usize,
        side: impl FnOnce() -> [i64; 3],
    ) -> Result<Option<(u32, IBox)>> {
        if j < known.num_leaves {
            return Ok(Some(known.leaves[j]));
        }
        Ok(loc.locate_cell(side())?.map(|c| {
            let b = self.read_box(c.leaf);
            known.add_leaf(c.leaf, b);
            (c.leaf, b)
        }))
    }

    /// The levels and values of the leaf cells [`Self::around_known`] finds around `v`, read
    /// the same way: the sides in leaf cell `own.0` (finest box `own.1`) are that cell; per
    /// kd-tree leaf, the sides in its box from its brick by one index part per axis and side
    /// of the axis; the others located.
    fn around_values<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        own: (&LeafCell, IBox),
        known: &mut Stitches,
    ) -> Result<Option<([u32; 8], [f32; 8])>> {
        let (lo, hi, same) = self.nudges(v);
        let side = |n: usize| axes(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
        let mut levels = [0u32; 8];
        let mut values = [0f32; 8];
        let mut todo = distinct_sides(same);
        let mut inside = sides_in(&own.1, lo, hi) & todo;
        todo &= !inside;
        while inside != 0 {
            let n = inside.trailing_zeros() as usize;
            inside &= inside - 1;
            (levels[n], values[n]) = (own.0.level, own.0.value);
        }
        let mut j = 0;
        while todo != 0 {
            let Some((leaf, b)) =
                self.leaf_or_locate(loc, known, j, || side(todo.trailing_zeros() as usize))?
            else {
                return Ok(None);
            };
            j += 1;
            let mut take = sides_in(&b, lo, hi) & todo;
            if take == 0 {
                continue;
            }
            todo &= !take;
            let brick = self.leaf_side_parts(leaf, lo, hi);
            while take != 0 {
                let n = take.trailing_zeros() as usize;
                take &= take - 1;
                let read = brick.and_then(|b| {
                    let i = b.parts[0][n & 1] + b.parts[1][n >> 1 & 1] + b.parts[2][n >> 2 & 1];
                    b.values.get(i as usize).map(|&x| (b.level, x))
                });
                (levels[n], values[n]) = match read {
                    Some(x) => x,
                    None => match loc.locate_cell(side(n))? {
                        Some(c) => (c.level, c.value),
                        None => return Ok(None),
                    },
                };
            }
        }
        if same != 0 {
            for n in 1..8 {
                levels[n] = levels[n & !same];
                values[n] = values[n & !same];
            }
        }
        Ok(Some((levels, values)))
    }

    /// [`Self::around_in`], reading cells from the kd-tree leaves `known` has met before
    /// locating them, and remembering the leaves located. Leaf by leaf: the sides in a leaf's
    /// box are found at once ([`sides_in`]) and read from its brick.
    fn around_known<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        known: &mut Stitches,
    ) -> Result<Option<[LeafCell; 8]>> {
        let (lo, hi, same) = self.nudges(v);
        let side = |n: usize| axes(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
        let placeholder = LeafCell {
            leaf: 0,
            brick: 0,
            level: 0,
            cell: [0; 3],
            value: 0.0,
        };
        let mut out = [placeholder; 8];
        let mut todo = distinct_sides(same);
        let mut j = 0;
        while todo != 0 {
            let Some((c, b)) =
                self.leaf_or_locate(loc, known, j, || side(todo.trailing_zeros() as usize))?
            else {
                return Ok(None);
            };
            j += 1;
            let mut take = sides_in(&b, lo, hi) & todo;
            todo &= !take;
            while take != 0 {
                let n = take.trailing_zeros() as usize;
                take &= take - 1;
                let f = side(n);
                out[n] = match self.cell_in_leaf_numbered(c, f) {
                    Some(x) => x,
                    None => match loc.locate_cell(f)? {
                        Some(x) => x,
                        None => return Ok(None),
                    },
                };
            }
        }
        if same != 0 {
            for n in 1..8 {
                out[n] = out[n & !same];
            }
        }
        Ok(Some(out))
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
