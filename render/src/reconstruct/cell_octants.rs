//! Several octants of one leaf cell next to other levels, computed together.
//!
//! The corners of a cell's eight octants are its 27 lattice points (per axis: the cell's two
//! faces and its centre). Every one but the cell centre is the value at a vertex computed from
//! the eight finest cells the vertex is nudged into; per axis those lie at six finest
//! coordinates (each face and the centre, nudged toward `-` and toward `+`), each in the cell or
//! in its neighbour of the same level on that axis, so all of them lie in the cell's 27
//! positions (the cell and its 26 neighbours of its level). [`CellOctants`] locates each
//! position once, when a point first needs it, and computes each lattice point once, when an
//! octant first needs it, by [`Sampler::corners_mixed`]'s rules (the operations of
//! [`Sampler::vertex_value_in`] in its order, stitched corners through [`super::stitch`]): an
//! octant asked after another one of the same cell shares its positions and points, and every
//! corner has the same bits whichever octant asks.

use amr_format::IBox;

use crate::error::Result;

use super::grid::axes;
use super::interp::avg8;
use super::leaf_hints::LeafHints;
use super::mixed::{holds, SIDES_DOWN};
use super::sampler::{LeafCell, Locate, Octant, Position, Sampler, VertexMemo, NO_CELL};
use super::stitch::Stitches;

/// The centre of the lattice and of the positions (index `x + 3 y + 9 z`).
const CENTRE: usize = 13;

/// A position's index step along each axis.
const STRIDE: [usize; 3] = [1, 3, 9];

/// Per position: its place along each axis (0 below the cell, 1 in it, 2 above).
const PLACE: [[usize; 3]; 27] = {
    let mut out = [[0; 3]; 27];
    let mut p = 0;
    while p < 27 {
        out[p] = [p % 3, p / 3 % 3, p / 9];
        p += 1;
    }
    out
};

/// The octants of one leaf cell as far as computed: its positions located and its lattice
/// points evaluated so far.
pub(super) struct CellOctants {
    level: u32,
    cell: [i64; 3],
    value: f32,
    /// The cell's finest cells.
    own: IBox,
    /// Lattice point 0's doubled coordinates, and the doubled distance between points.
    lo: [i64; 3],
    s: [i64; 3],
    /// Per axis and entry `2 * point + dir` (`dir` 1: nudged toward `+`): the finest coordinate
    /// (clamped into the domain) and its position's index step (0 below the cell, 1 in it, 2
    /// above, times [`STRIDE`]).
    at: [[i64; 6]; 3],
    step: [[u8; 6]; 3],
    /// Per axis and lattice point: the positions along the axis its cells lie in, a bit each.
    along: [[u8; 3]; 3],
    /// Per axis and position along it (0 below the cell, 1 in it, 2 above): the position's
    /// finest cells in the domain, `lo` and `hi`.
    span: [[(i64, i64); 3]; 3],
    /// Per position (`x + 3 y + 9 z`): the leaf cell located there and its kd-tree leaf's box.
    /// `located` marks the positions looked up, `covered` those where a leaf cell was found,
    /// `whole` those whose every finest cell (in the domain) lies in that leaf cell.
    positions: [Position; 27],
    /// The distinct kd-tree leaves met (a position of each), tried before locating a position.
    leaves: [u8; 4],
    num_leaves: usize,
    located: u32,
    covered: u32,
    whole: u32,
    /// Per lattice point: its value (`None`: a cell involved is not covered), once `computed`.
    points: [Option<f32>; 27],
    computed: u32,
    /// A leaf cell already located and its kd-tree leaf's box ([`Sampler::position_cell`]).
    near: Option<(LeafCell, IBox)>,
    /// The stitch memory, made when the first stitched point needs it.
    stitches: Option<Stitches>,
    /// The kd-tree leaves positions were located in last (kept from cell to cell).
    hints: LeafHints,
}

impl Default for CellOctants {
    fn default() -> Self {
        let empty = Position {
            cell: NO_CELL,
            whole: false,
            leaf_box: IBox::default(),
        };
        Self {
            level: 0,
            cell: [0; 3],
            value: 0.0,
            own: IBox::default(),
            lo: [0; 3],
            s: [0; 3],
            at: [[0; 6]; 3],
            step: [[0; 6]; 3],
            along: [[0; 3]; 3],
            span: [[(0, 0); 3]; 3],
            positions: [empty; 27],
            leaves: [0; 4],
            num_leaves: 0,
            located: 0,
            covered: 0,
            whole: 0,
            points: [None; 27],
            computed: 0,
            near: None,
            stitches: None,
            hints: LeafHints::default(),
        }
    }
}

impl CellOctants {
    /// Starts again, with nothing computed, for the octants of leaf cell `cell` of `level`, of
    /// value `value`; `near` is a leaf cell already located and its kd-tree leaf's box.
    pub(super) fn reset<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        (level, cell, value): (u32, [i64; 3], f32),
        near: Option<(LeafCell, IBox)>,
    ) {
        let grid = sampler.grid();
        let s = grid.scale(level);
        let ext = grid.extent();
        let own = grid.finest_box(level, cell);
        let c = grid.centre(level, cell);
        let lo = axes(|a| c[a] - s[a]);
        self.along = [[0; 3]; 3];
        for a in 0..3 {
            for e in 0..6 {
                let x = lo[a] + (e >> 1) as i64 * s[a];
                let f = if e & 1 == 0 { x - 1 } else { x }.div_euclid(2);
                let f = f.clamp(0, ext[a] - 1);
                let d = usize::from(f >= own.lo[a]) + usize::from(f >= own.hi[a]);
                self.at[a][e] = f;
                self.step[a][e] = (d * STRIDE[a]) as u8;
                self.along[a][e >> 1] |= 1 << d;
            }
            let w = own.hi[a] - own.lo[a];
            for d in 0..3 {
                let shift = (d as i64 - 1) * w;
                self.span[a][d] = ((own.lo[a] + shift).max(0), (own.hi[a] + shift).min(ext[a]));
            }
        }
        (self.level, self.cell, self.value) = (level, cell, value);
        (self.own, self.lo, self.s) = (own, lo, s);
        (self.located, self.covered, self.whole) = (0, 0, 0);
        self.num_leaves = 0;
        self.computed = 1 << CENTRE;
        self.near = near;
        self.stitches = None;
    }

    /// Takes the leaf cell `found` and its kd-tree leaf's box (`None`: not covered), located at
    /// a finest cell of position `p`; `fresh`: its kd-tree leaf is not one met before.
    #[inline(always)]
    fn put_position(&mut self, p: usize, found: Option<(LeafCell, IBox)>, fresh: bool) {
        self.located |= 1 << p;
        let Some((c, leaf_box)) = found else {
            return;
        };
        let d = PLACE[p];
        let inside = (0..3).fold(true, |all, a| {
            let (lo, hi) = self.span[a][d[a]];
            all & (leaf_box.lo[a] <= lo) & (hi <= leaf_box.hi[a])
        });
        let whole = (c.level <= self.level) & inside;
        self.positions[p] = Position {
            cell: c,
            whole,
            leaf_box,
        };
        self.covered |= 1 << p;
        self.whole |= u32::from(whole) << p;
        if fresh && self.num_leaves < self.leaves.len() {
            self.leaves[self.num_leaves] = p as u8;
            self.num_leaves += 1;
        }
    }

    /// Locates position `p` at one of its finest cells: read from the brick of a kd-tree leaf
    /// already met whose box holds that cell, else located (trying the leaves positions were
    /// located in last, kept apart from the memo's hints for the vertices' sides: sharing
    /// those, each evicts the other's).
    #[inline(never)]
    fn locate_position<D: AsRef<[u8]>, L: Locate>(
        &mut self,
        sampler: &Sampler<'_, D>,
        loc: &L,
        p: usize,
    ) -> Result<()> {
        let d = PLACE[p];
        let f = axes(|a| match d[a] {
            0 => self.own.lo[a] - 1,
            1 => self.own.lo[a],
            _ => self.own.hi[a],
        });
        // Leaf cells read from a leaf met keep its box.
        let mut found = self
            .near
            .and_then(|(c, b)| {
                holds(&b, f).then(|| sampler.cell_in_own_leaf(&c, f).map(|x| (x, b)))
            })
            .flatten();
        for &k in &self.leaves[..self.num_leaves] {
            if found.is_some() {
                break;
            }
            let q = &self.positions[usize::from(k)];
            if holds(&q.leaf_box, f) {
                found = sampler
                    .cell_in_own_leaf(&q.cell, f)
                    .map(|x| (x, q.leaf_box));
            }
        }
        let fresh = found.is_none();
        if fresh {
            found = sampler
                .locate_hinted(loc, f, &mut self.hints)?
                .map(|(c, _)| (c, sampler.read_box(c.leaf)));
        }
        self.put_position(p, found, fresh);
        Ok(())
    }

    /// The positions lattice point `l`'s cells lie in, a bit each.
    #[inline(always)]
    fn point_positions(&self, l: [usize; 3]) -> u32 {
        let x = u32::from(self.along[0][l[0]]);
        let mut m = 0;
        for dz in 0..3 {
            if self.along[2][l[2]] >> dz & 1 == 1 {
                for dy in 0..3 {
                    if self.along[1][l[1]] >> dy & 1 == 1 {
                        m |= x << (3 * dy + 9 * dz);
                    }
                }
            }
        }
        m
    }

    /// The corners of octant `octant` of the cell (`None` where a cell involved is not covered).
    pub(super) fn octant<D: AsRef<[u8]>, L: Locate>(
        &mut self,
        sampler: &Sampler<'_, D>,
        loc: &L,
        octant: u8,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let mut out = [0f32; 8];
        for (n, slot) in out.iter_mut().enumerate() {
            let l: [usize; 3] = axes(|a| (usize::from(octant) >> a & 1) + (n >> a & 1));
            let i = l[0] + 3 * l[1] + 9 * l[2];
            if i == CENTRE {
                // The corner at the cell centre carries the cell's value.
                *slot = self.value;
                continue;
            }
            if self.computed >> i & 1 == 0 {
                self.points[i] = self.point(sampler, loc, l, memo)?;
                self.computed |= 1 << i;
            }
            match self.points[i] {
                Some(x) => *slot = x,
                None => return Ok(None),
            }
        }
        Ok(Some(out))
    }

    /// The octants other than `octant` that the neighbours met so far suggest will be asked
    /// for: those next to a position located and not whole (another level, or not covered).
    pub(super) fn likely_octants(&self, octant: u8) -> u8 {
        let mut partial = self.located & !self.whole & !(1 << CENTRE);
        let mut likely = 0u8;
        while partial != 0 {
            let p = partial.trailing_zeros() as usize;
            partial &= partial - 1;
            let d = PLACE[p];
            // The octants next to position `p`: on the position's side of every axis it is
            // beside the cell on.
            likely |= (0..3).fold(0xFFu8, |m, a| match d[a] {
                0 => m & SIDES_DOWN[a],
                2 => m & !SIDES_DOWN[a],
                _ => m,
            });
        }
        likely & !(1 << octant)
    }

    /// The value at lattice point `l`: [`Sampler::corners_mixed`]'s corner value.
    fn point<D: AsRef<[u8]>, L: Locate>(
        &mut self,
        sampler: &Sampler<'_, D>,
        loc: &L,
        l: [usize; 3],
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        let level = self.level;
        let need = self.point_positions(l);
        let mut missing = need & !self.located;
        while missing != 0 {
            let p = missing.trailing_zeros() as usize;
            missing &= missing - 1;
            self.locate_position(sampler, loc, p)?;
        }
        let mut levels = [0u32; 8];
        let mut values = [0f32; 8];
        // Side `n`'s finest cell and position.
        let step: [[usize; 2]; 3] = axes(|a| {
            [
                usize::from(self.step[a][2 * l[a]]),
                usize::from(self.step[a][2 * l[a] + 1]),
            ]
        });
        let at: [[i64; 2]; 3] = axes(|a| [self.at[a][2 * l[a]], self.at[a][2 * l[a] + 1]]);
        let entry = |n: usize| -> ([i64; 3], usize) {
            let f = axes(|a| at[a][n >> a & 1]);
            (
                f,
                step[0][n & 1] + step[1][n >> 1 & 1] + step[2][n >> 2 & 1],
            )
        };
        if need & !self.whole == 0 {
            // Every cell is its whole position's.
            for n in 0..8 {
                let p = step[0][n & 1] + step[1][n >> 1 & 1] + step[2][n >> 2 & 1];
                let c = &self.positions[p].cell;
                (levels[n], values[n]) = (c.level, c.value);
            }
        } else {
            for n in 0..8 {
                let (f, p) = entry(n);
                let q = &self.positions[p];
                let covered = self.covered >> p & 1 == 1;
                let read = if !covered {
                    None
                } else if q.whole {
                    Some((q.cell.level, q.cell.value))
                } else if q.cell.level >= level && holds(&q.leaf_box, f) {
                    // A leaf not coarser than the cell: its level, the value from its brick.
                    sampler
                        .value_in_leaf(q.cell.leaf, f)
                        .map(|v| (q.cell.level, v))
                } else {
                    None
                };
                (levels[n], values[n]) = match read {
                    Some(x) => x,
                    None => {
                        let q = covered.then_some(*q);
                        match sampler.position_cell(
                            loc,
                            q.as_ref(),
                            self.near.as_ref(),
                            f,
                            &mut memo.hints,
                        )? {
                            Some(c) => (c.level, c.value),
                            None => return Ok(None),
                        }
                    }
                };
            }
        }
        let coarse = levels.iter().fold(false, |c, &x| c | (x < level));
        if !coarse {
            return Ok(Some(avg8(&values)));
        }
        // Stitched: the first side of the coarsest level decides the coarse octant.
        let v = axes(|a| self.lo[a] + l[a] as i64 * self.s[a]);
        let coarsest = levels.iter().copied().fold(u32::MAX, u32::min);
        let side = levels.iter().position(|&x| x == coarsest).unwrap_or(0);
        let (f, p) = entry(side);
        let position = (self.covered >> p & 1 == 1).then_some(self.positions[p]);
        let q = match position {
            Some(q) if q.whole => Some(q.cell),
            _ => sampler.position_cell(
                loc,
                position.as_ref(),
                self.near.as_ref(),
                f,
                &mut memo.hints,
            )?,
        };
        let Some(q) = q else {
            return Ok(None);
        };
        sampler.stitched_corner(
            loc,
            v,
            (&q, side),
            || values,
            &mut self.stitches,
            self.near,
            memo,
        )
    }

    /// The octant `octant` of this cell as a key of the octant table.
    pub(super) fn key(&self, octant: u8) -> Octant {
        Octant {
            level: self.level,
            cell: self.cell,
            octant,
        }
    }
}

impl<D: AsRef<[u8]>> Sampler<'_, D> {
    /// The corners of octant `o` of a leaf cell of value `value` next to other levels (the
    /// rest of [`Self::corners_gathered`] when `memo` computes octants together), computed
    /// through the memo's [`CellOctants`]; the cell's other octants next to a position that is
    /// not whole ([`CellOctants::likely_octants`]) are computed with it and put in `memo`'s
    /// octant table. `near` is a leaf cell already located and its kd-tree leaf's box.
    pub(super) fn corners_together<L: Locate>(
        &self,
        loc: &L,
        o: &Octant,
        value: f32,
        near: Option<(LeafCell, IBox)>,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        // The memo's scratch, or a fresh one where a stitched corner asks for another cell's
        // octants while this one is in use.
        let mut cell = memo.cell_octants.take().unwrap_or_default();
        cell.reset(self, (o.level, o.cell, value), near);
        let out = cell.octant(self, loc, o.octant, memo);
        if out.is_ok() {
            let mut likely = cell.likely_octants(o.octant);
            while likely != 0 {
                let x = likely.trailing_zeros() as u8;
                likely &= likely - 1;
                let key = cell.key(x);
                if memo.octant_get(&key).is_none() {
                    // An error there is left to the octant's own ask.
                    if let Ok(c) = cell.octant(self, loc, x, memo) {
                        memo.octant_put(&key, c);
                    }
                }
            }
        }
        memo.cell_octants = Some(cell);
        out
    }
}
