//! Smooth normals inside one level, read from the bricks: the central differences one cell
//! apart that smooth normals take of the `octant` and `current` fields, computed from the
//! 4x4x4 cell values around the point's dual cell instead of from six point samples.
//!
//! Where every cell of a level `L` block is a leaf cell of `L`, both reconstructions are the
//! trilinear interpolant of the cell values on the level's dual cells (cell centres at the
//! corners; the octant method's vertex values are then averages of these corners, which the
//! trilinear interpolant takes at the same points). For that interpolant `f` and a step `h` of
//! one cell on axis `a`, `(f(p + h) - f(p - h)) / 2h` is the trilinear interpolant, over the dual
//! cell holding `p`, of the central differences `(v[i + 1] - v[i - 1]) / 2h` at its eight corners:
//! both are linear on `a` between the corners with the same weights on the other axes. So the
//! gradient is eight corner gradients, each one subtraction of two neighbouring cells, shared
//! by every point of the dual cell, and the same function of `p` as the six samples give (up
//! to rounding: the samples round to `f32`, this evaluates in `f64`). Next to another level,
//! each component whose 16 cells are leaf cells of the level is still read from the block, and
//! only the other axes are sampled. See `docs/reconstruction.md`.

use amr_format::IBox;

use crate::error::Result;

use super::grid::{axes, Grid};
use super::sampler::{Sampler, Slab};

/// The cells of a 4x4x4 block of one level that [`Sampler::gradient_in_block`] reads: the
/// dual cell's eight corners (offsets 1 and 2) and their neighbours on each axis (at most one
/// offset of 0 or 3), x fastest.
const NEEDED: [[usize; 3]; 32] = needed_cells();

/// Per offset in the block (`x + 4 y + 16 z`): its index in [`NEEDED`] (64 for the others).
const SLOT: [usize; 64] = slots();

const fn needed_cells() -> [[usize; 3]; 32] {
    let mut out = [[0; 3]; 32];
    let (mut i, mut n) = (0, 0);
    while i < 64 {
        let c = [i & 3, i >> 2 & 3, i >> 4 & 3];
        let outer = (c[0] == 0 || c[0] == 3) as usize
            + (c[1] == 0 || c[1] == 3) as usize
            + (c[2] == 0 || c[2] == 3) as usize;
        if outer <= 1 {
            out[n] = c;
            n += 1;
        }
        i += 1;
    }
    out
}

const fn slots() -> [usize; 64] {
    let mut out = [64; 64];
    let mut n = 0;
    while n < 32 {
        let c = NEEDED[n];
        out[c[0] + 4 * c[1] + 16 * c[2]] = n;
        n += 1;
    }
    out
}

/// A row of [`NEEDED`]'s cells: offsets `x[0]` up to `x[1]` on the x axis at `y` and `z`.
#[derive(Clone, Copy)]
struct Row {
    y: usize,
    z: usize,
    x: [usize; 2],
}

/// The rows of [`NEEDED`], in its order: a row with no outer offset on y and z holds its four
/// cells, one with one outer offset its two inner ones.
static ROWS: [Row; 12] = rows();

const fn rows() -> [Row; 12] {
    let mut out = [Row {
        y: 0,
        z: 0,
        x: [0; 2],
    }; 12];
    let (mut z, mut n) = (0, 0);
    while z < 4 {
        let mut y = 0;
        while y < 4 {
            let outer = (y == 0 || y == 3) as usize + (z == 0 || z == 3) as usize;
            if outer <= 1 {
                let x = if outer == 0 { [0, 4] } else { [1, 3] };
                out[n] = Row { y, z, x };
                n += 1;
            }
            y += 1;
        }
        z += 1;
    }
    out
}

/// Per axis `a` and corner `n` of the dual cell (cell `1 + bit` of the block on each axis):
/// the [`NEEDED`] slots of its neighbours above and below on `a`.
const PAIRS: [[[usize; 2]; 8]; 3] = pairs();

const fn pairs() -> [[[usize; 2]; 8]; 3] {
    let mut out = [[[0; 2]; 8]; 3];
    let mut a = 0;
    while a < 3 {
        let mut n = 0;
        while n < 8 {
            let c = [1 + (n & 1), 1 + (n >> 1 & 1), 1 + (n >> 2 & 1)];
            let (mut up, mut down) = (c, c);
            up[a] += 1;
            down[a] -= 1;
            out[a][n] = [
                SLOT[up[0] + 4 * up[1] + 16 * up[2]],
                SLOT[down[0] + 4 * down[1] + 16 * down[2]],
            ];
            n += 1;
        }
        a += 1;
    }
    out
}

/// The values of the cells of a block that the gradient reads, in [`NEEDED`]'s order.
pub type LevelBlock = [f32; 32];

/// Per axis: the [`NEEDED`] slots (bit per slot) whose differences give the gradient along it,
/// which are the corners of the dual cells of the two samples one cell apart on that axis.
const AXIS_SLOTS: [u32; 3] = axis_slots();

const fn axis_slots() -> [u32; 3] {
    let mut out = [0u32; 3];
    let mut a = 0;
    while a < 3 {
        let mut n = 0;
        while n < 8 {
            out[a] |= 1 << PAIRS[a][n][0] | 1 << PAIRS[a][n][1];
            n += 1;
        }
        a += 1;
    }
    out
}

/// The [`NEEDED`] slots (bit per slot) of the dual cell's eight corner cells (offsets 1 and 2
/// on every axis): half a cell around any point of the dual cell lies in them.
const CORE_SLOTS: u32 = core_slots();

const fn core_slots() -> u32 {
    let mut out = 0;
    let mut k = 0;
    while k < 32 {
        let c = NEEDED[k];
        if matches!(c[0], 1 | 2) && matches!(c[1], 1 | 2) && matches!(c[2], 1 | 2) {
            out |= 1 << k;
        }
        k += 1;
    }
    out
}

/// Per [`NEEDED`] slot: the axes (bit per axis) whose gradient reads it ([`AXIS_SLOTS`]).
const SLOT_AXES: [u8; 32] = slot_axes();

const fn slot_axes() -> [u8; 32] {
    let mut out = [0u8; 32];
    let mut k = 0;
    while k < 32 {
        let mut a = 0;
        while a < 3 {
            if AXIS_SLOTS[a] >> k & 1 == 1 {
                out[k] |= 1 << a;
            }
            a += 1;
        }
        k += 1;
    }
    out
}

/// The cells of a block of one level as far as they are leaf cells of it: their values (in
/// [`NEEDED`]'s order) and, bit per slot, which are ([`Sampler::level_cells`]); a slot whose bit
/// is clear holds 0.
#[derive(Clone, Copy)]
pub struct LevelCells {
    /// The values, in [`NEEDED`]'s order.
    pub values: LevelBlock,
    /// Bit `k` set: slot `k` is a leaf cell of the level at every finest cell of it; clear:
    /// it is not, or it was not looked at because every axis reading it lacks another cell.
    pub valid: u32,
}

impl LevelCells {
    /// No cell known.
    const NONE: Self = Self {
        values: [0.0; 32],
        valid: 0,
    };

    /// True when every cell is a leaf cell of the level.
    #[inline(always)]
    pub fn is_whole(&self) -> bool {
        self.valid == u32::MAX
    }

    /// Per axis: true when the cells the gradient along it reads are all leaf cells of the
    /// level, so the block gives that component.
    pub fn axes(&self) -> [bool; 3] {
        axes(|a| self.valid & AXIS_SLOTS[a] == AXIS_SLOTS[a])
    }

    /// True when the dual cell's eight corner cells are leaf cells of the level, so that no
    /// other level lies within half a cell of it around any point of the dual cell
    /// ([`super::level_blend`]). False also where a corner cell was not looked at.
    pub fn core_is_whole(&self) -> bool {
        self.valid & CORE_SLOTS == CORE_SLOTS
    }
}

/// What a block of cells that is not whole gives toward a smooth normal's gradient.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PartialGradient {
    /// The components whose cells are leaf cells of the level ([`LevelCells::axes`]); the
    /// others are sampled.
    pub given: [Option<f64>; 3],
    /// The dual cell's eight corner cells are leaf cells of the level
    /// ([`LevelCells::core_is_whole`]): no other level is near enough to blend with.
    pub core_is_whole: bool,
}

/// Kd-tree leaves a block may span before [`Sampler::level_block`] gives up.
const BLOCK_LEAVES: usize = 8;

/// A level's cell width and the grid's offset as `f64`s, per axis: what locating a point's dual
/// cell and weighting its corners compute with, converted once per level.
#[derive(Clone, Copy)]
struct LevelSteps {
    /// One cell's width in finest cells ([`Grid::scale`]).
    scale: [f64; 3],
    /// The finest domain's lower corner ([`Grid::offset`]).
    offset: [f64; 3],
    /// A dual cell's width in doubled units (`2 * scale`).
    dual_width: [f64; 3],
    /// A central difference's span in doubled units (`4 * scale`: two cells), and 1 in lane 3.
    span: [f64; 4],
}

impl LevelSteps {
    /// The steps of `level`, which `grid` has.
    fn of(grid: &Grid, level: u32) -> Self {
        let (s, o) = (grid.scale(level), grid.offset());
        Self {
            scale: axes(|a| s[a] as f64),
            offset: axes(|a| o[a] as f64),
            dual_width: axes(|a| (2 * s[a]) as f64),
            span: [0, 1, 2, 3].map(|a| if a < 3 { (4 * s[a]) as f64 } else { 1.0 }),
        }
    }

    /// [`Sampler::dual_cell`] of doubled point `p`.
    #[inline(always)]
    fn dual_cell(&self, p: [f64; 3]) -> Option<[i64; 3]> {
        let first =
            axes(|a| (((p[a] - self.scale[a]) * 0.5 + self.offset[a]) / self.scale[a]).floor());
        first
            .iter()
            .all(|x| x.abs() < 1e15)
            .then(|| first.map(whole_to_i64))
    }

    /// The trilinear weight at `p` of each corner of the dual cell whose lower corner cell's
    /// centre is `base` (doubled units, [`Grid::centre`]).
    #[inline(always)]
    fn weights(&self, p: [f64; 3], base: [f64; 3]) -> [f64; 8] {
        let t = axes(|a| ((p[a] - base[a]) / self.dual_width[a]).clamp(0.0, 1.0));
        let u = [[1.0 - t[0], t[0]], [1.0 - t[1], t[1]], [1.0 - t[2], t[2]]];
        std::array::from_fn(|n| u[0][n & 1] * u[1][n >> 1 & 1] * u[2][n >> 2])
    }
}

/// Per corner `n` of a dual cell, the difference of its neighbours' values above and below it
/// on each axis (lane `a`; lane 3 is 0), from a block's values ([`PAIRS`]): what the gradient
/// weighs, the same for every point of the dual cell.
#[derive(Clone, Copy)]
struct CornerDifferences([[f64; 4]; 8]);

impl CornerDifferences {
    /// The differences in `block`.
    fn of(block: &LevelBlock) -> Self {
        Self(std::array::from_fn(|n| {
            let mut d = [0.0; 4];
            for (a, d) in d.iter_mut().take(3).enumerate() {
                let [up, down] = PAIRS[a][n];
                *d = f64::from(block[up]) - f64::from(block[down]);
            }
            d
        }))
    }

    /// The gradient ([`Sampler::gradient_in_block`]): on each axis the corners' differences
    /// weighted by `w` ([`LevelSteps::weights`]), summed corner by corner, over the span of
    /// two cells.
    #[inline(always)]
    fn gradient(&self, w: &[f64; 8], span: &[f64; 4]) -> [f64; 3] {
        let mut sum = [0.0; 4];
        for (wn, d) in w.iter().zip(&self.0) {
            for (sum, d) in sum.iter_mut().zip(d) {
                *sum += wn * d;
            }
        }
        axes(|a| sum[a] / span[a])
    }
}

/// Kd-tree leaves of another level whose boxes [`Sampler::level_cells`] remembers.
const FOREIGN_LEAVES: usize = 4;

/// Finest cells of a cell cut by kd-tree leaves that [`Sampler::level_block`] checks one by
/// one before giving up.
const CUT_CELL_FINEST: i64 = 64;

/// A kd-tree leaf a block's cells are read from: the cells of the block's level lying whole in
/// it (within its finest brick), that brick's lower cell and strides, and which of the block's
/// slabs holds its values.
#[derive(Clone, Copy)]
struct BlockLeaf {
    lo: [i64; 3],
    hi: [i64; 3],
    brick_lo: [i64; 3],
    stride: [i64; 3],
    brick: u32,
    slab: usize,
}

impl BlockLeaf {
    /// A leaf holding no cell.
    const EMPTY: Self = Self {
        lo: [0; 3],
        hi: [0; 3],
        brick_lo: [0; 3],
        stride: [0; 3],
        brick: 0,
        slab: 0,
    };

    #[inline(always)]
    fn holds(&self, c: [i64; 3]) -> bool {
        (0..3).all(|a| self.lo[a] <= c[a] && c[a] < self.hi[a])
    }

    #[inline(always)]
    fn index(&self, c: [i64; 3]) -> usize {
        (0..3)
            .map(|a| (c[a] - self.brick_lo[a]) * self.stride[a])
            .sum::<i64>() as usize
    }
}

/// Kd-tree leaves [`RecentLeaf`] remembers.
const RECENT_LEAVES: usize = 4;

/// The kd-tree leaves (with their levels) in which the last blocks' cells were found: the next
/// block's cells are often in them too. Any of them holding a cell of its level is the leaf
/// [`Sampler::block_leaf`] would find for it.
#[derive(Clone, Copy, Default)]
struct RecentLeaf {
    leaves: [Option<(u32, BlockLeaf)>; RECENT_LEAVES],
    /// The entry the next leaf found replaces.
    next: usize,
}

impl RecentLeaf {
    /// The remembered leaf of `level` holding `cell`, if any.
    #[inline(always)]
    fn holding(&self, level: u32, cell: [i64; 3]) -> Option<BlockLeaf> {
        self.leaves
            .iter()
            .flatten()
            .find(|(l, leaf)| *l == level && leaf.holds(cell))
            .map(|&(_, leaf)| leaf)
    }

    /// Remembers `leaf` of `level`, in place of the oldest.
    #[inline(always)]
    fn keep(&mut self, level: u32, leaf: BlockLeaf) {
        self.leaves[self.next] = Some((level, leaf));
        self.next = (self.next + 1) % RECENT_LEAVES;
    }
}

impl<'f, D: AsRef<[u8]>> Sampler<'f, D> {
    /// The central differences of the `octant` (and `current`) field at doubled point `p` one
    /// cell of `level` apart on each axis (cell sizes in doubled units: `2 * scale`), divided by
    /// twice the step, when the cells of `level` around `p`'s dual cell of that level that the
    /// differences read are leaf cells ([`Self::level_block`]); `None` otherwise (near a level
    /// boundary or the domain's edge), where the caller samples.
    pub fn level_gradient(&self, p: [f64; 3], level: u32) -> Result<Option<[f64; 3]>> {
        let Some(first) = self.dual_cell(p, level) else {
            return Ok(None);
        };
        Ok(self
            .level_block(level, first)?
            .map(|block| self.gradient_in_block(&block, p, level, first)))
    }

    /// [`Self::level_gradient`] axis by axis: the component along each axis whose cells are leaf
    /// cells of `level` ([`LevelCells::axes`]), `None` on the others, where the caller samples.
    /// Each component is the one [`Self::level_gradient`] gives when it gives all three.
    pub fn level_gradient_axes(&self, p: [f64; 3], level: u32) -> Result<[Option<f64>; 3]> {
        let Some(first) = self.dual_cell(p, level) else {
            return Ok([None; 3]);
        };
        let cells = self.level_cells(level, first)?;
        Ok(self.gradient_axes_in(&cells, p, level, first))
    }

    /// The lower corner cell of the dual cell of `level` holding doubled point `p` (the cells
    /// at its corners are `first` and one more on each axis), as `current` sampling finds it;
    /// `None` for a level the file lacks or a point not finite.
    #[inline]
    pub fn dual_cell(&self, p: [f64; 3], level: u32) -> Option<[i64; 3]> {
        let grid = self.grid();
        if level as usize >= grid.num_levels() {
            return None;
        }
        LevelSteps::of(grid, level).dual_cell(p)
    }

    /// [`Self::level_gradient`] at `p` in the dual cell `first` of `level`, from the block's
    /// values there.
    #[inline]
    pub fn gradient_in_block(
        &self,
        block: &LevelBlock,
        p: [f64; 3],
        level: u32,
        first: [i64; 3],
    ) -> [f64; 3] {
        let (steps, base) = self.steps_and_base(level, first);
        CornerDifferences::of(block).gradient(&steps.weights(p, base), &steps.span)
    }

    /// [`Self::gradient_in_block`]'s component along each axis that `cells` give
    /// ([`LevelCells::axes`]), the same bits; `None` on the others.
    #[inline]
    pub fn gradient_axes_in(
        &self,
        cells: &LevelCells,
        p: [f64; 3],
        level: u32,
        first: [i64; 3],
    ) -> [Option<f64>; 3] {
        let given = cells.axes();
        if given == [false; 3] {
            return [None; 3];
        }
        let (steps, base) = self.steps_and_base(level, first);
        let g = CornerDifferences::of(&cells.values).gradient(&steps.weights(p, base), &steps.span);
        axes(|a| given[a].then_some(g[a]))
    }

    /// The steps of `level` and the centre of the dual cell's lower corner cell `first`.
    #[inline(always)]
    fn steps_and_base(&self, level: u32, first: [i64; 3]) -> (LevelSteps, [f64; 3]) {
        let base = self.grid().centre(level, first);
        (LevelSteps::of(self.grid(), level), base.map(|x| x as f64))
    }

    /// The values of the cells of `level` that [`Self::level_gradient`] reads in the dual cell
    /// whose lower corner cell is `first` (the 4x4x4 cells from `first - 1`, but for the block's
    /// edges and corners), when each is a leaf cell everywhere (it lies whole in a kd-tree leaf
    /// whose finest brick is of `level`, or all its finest cells lie in such leaves) and they
    /// span at most [`BLOCK_LEAVES`] leaves; `None` otherwise. A pure function of `level` and
    /// `first`.
    pub fn level_block(&self, level: u32, first: [i64; 3]) -> Result<Option<LevelBlock>> {
        self.level_block_near(level, first, &mut RecentLeaf::default())
    }

    /// [`Self::level_block`], taking the kd-tree leaves of its cells from `recent` when it holds
    /// them ([`Self::block_leaf_near`]), and keeping the leaves found there.
    fn level_block_near(
        &self,
        level: u32,
        first: [i64; 3],
        recent: &mut RecentLeaf,
    ) -> Result<Option<LevelBlock>> {
        let lo = axes(|a| first[a] - 1);
        let Some((leaf, slab)) = self.block_leaf_near(level, first, 0, recent)? else {
            return Ok(None);
        };
        let mut out = [0f32; 32];
        if leaf.holds(lo) && leaf.holds(axes(|a| lo[a] + 3)) {
            // One leaf holds the whole block: one index and three strides.
            let start = leaf.index(lo);
            let step = leaf.stride.map(|x| x as usize);
            let Some(v) = slab.get(start..=start + 3 * (step[0] + step[1] + step[2])) else {
                return Ok(None);
            };
            // Row by row (x fastest, as in `NEEDED`).
            let mut k = 0;
            for row in &ROWS {
                let at = row.y * step[1] + row.z * step[2];
                put_run(&mut out, k, &v[at + row.x[0]..at + row.x[1]]);
                k += row.x[1] - row.x[0];
            }
            return Ok(Some(out));
        }
        // Otherwise row by row too, each row in runs of the cells one leaf holds, from the
        // leaves met so far or one found next.
        let mut slabs: [Option<Slab<'f>>; BLOCK_LEAVES] = Default::default();
        slabs[0] = Some(slab);
        let mut leaves = [leaf; BLOCK_LEAVES];
        let (mut known, mut last) = (1, 0);
        let mut k = 0;
        for row in &ROWS {
            let mut x = row.x[0];
            while x < row.x[1] {
                let cell = [lo[0] + x as i64, lo[1] + row.y as i64, lo[2] + row.z as i64];
                if !leaves[last].holds(cell) {
                    match (0..known).find(|&i| leaves[i].holds(cell)) {
                        Some(i) => last = i,
                        None if known == BLOCK_LEAVES => return Ok(None),
                        None => {
                            let found = self.block_leaf_near(level, cell, known, recent)?;
                            let Some((l, slab)) = found.filter(|(l, _)| l.holds(cell)) else {
                                return Ok(None);
                            };
                            slabs[known] = Some(slab);
                            leaves[known] = l;
                            last = known;
                            known += 1;
                        }
                    }
                }
                let l = &leaves[last];
                // The leaf holds the row's cells up to its upper face on x.
                let end = row.x[1].min((l.hi[0] - lo[0]) as usize);
                let start = l.index(cell);
                let Some(v) = slabs[l.slab]
                    .as_ref()
                    .and_then(|s| s.get(start..start + (end - x)))
                else {
                    return Ok(None);
                };
                put_run(&mut out, k, v);
                k += end - x;
                x = end;
            }
        }
        Ok(Some(out))
    }

    /// The cells of [`Self::level_block`] that are leaf cells everywhere, found in at most
    /// [`BLOCK_LEAVES`] kd-tree leaves (cells past those count as not): the whole block when
    /// [`Self::level_block`] gives it, else the cells that are, as far as an axis could still
    /// use them ([`LevelCells::valid`]). A pure function of `level` and `first`.
    pub fn level_cells(&self, level: u32, first: [i64; 3]) -> Result<LevelCells> {
        self.level_cells_near(level, first, &mut RecentLeaf::default())
    }

    /// [`Self::level_cells`], the block's leaves taken from or kept in `recent`
    /// ([`Self::level_block_near`]).
    fn level_cells_near(
        &self,
        level: u32,
        first: [i64; 3],
        recent: &mut RecentLeaf,
    ) -> Result<LevelCells> {
        Ok(match self.level_block_near(level, first, recent)? {
            Some(values) => LevelCells {
                values,
                valid: u32::MAX,
            },
            None => self.level_cells_apart(level, first)?,
        })
    }

    /// [`Self::level_cells`] where [`Self::level_block`] gives no whole block.
    #[inline(never)]
    fn level_cells_apart(&self, level: u32, first: [i64; 3]) -> Result<LevelCells> {
        let lo = axes(|a| first[a] - 1);
        let mut slabs: [Option<Slab<'f>>; BLOCK_LEAVES] = Default::default();
        let mut out = LevelCells::NONE;
        // Cell by cell, from the leaves met so far or one found next.
        let mut leaves = [BlockLeaf::EMPTY; BLOCK_LEAVES];
        let (mut known, mut last) = (0, 0);
        // Boxes of kd-tree leaves whose finest brick is of another level: a cell whose lowest
        // finest cell lies in one is not a leaf cell of `level` (as `block_leaf` finds).
        let mut foreign = [IBox::default(); FOREIGN_LEAVES];
        let mut num_foreign = 0;
        let grid = self.grid();
        // The axes whose cells are all leaf cells of `level` so far; a cell only axes already
        // lost read is not looked at.
        let mut alive = 7u8;
        for (k, c) in NEEDED.iter().enumerate() {
            if SLOT_AXES[k] & alive == 0 {
                continue;
            }
            let cell = axes(|a| lo[a] + c[a] as i64);
            if known == 0 || !leaves[last].holds(cell) {
                match (0..known).find(|&j| leaves[j].holds(cell)) {
                    Some(j) => last = j,
                    None if known == BLOCK_LEAVES => {
                        alive &= !SLOT_AXES[k];
                        continue;
                    }
                    None => {
                        let f = grid.finest_box(level, cell).lo;
                        if foreign[..num_foreign].iter().any(|b| b.contains_cell(f)) {
                            alive &= !SLOT_AXES[k];
                            continue;
                        }
                        let found = self.block_leaf(level, cell, known)?;
                        let Some((l, slab)) = found.filter(|(l, _)| l.holds(cell)) else {
                            alive &= !SLOT_AXES[k];
                            if num_foreign < FOREIGN_LEAVES {
                                if let Some(leaf) = self.find_leaf(f) {
                                    if !matches!(self.leaf_top(leaf), Some((_, top)) if top == level)
                                    {
                                        foreign[num_foreign] = self.leaf_box(leaf);
                                        num_foreign += 1;
                                    }
                                }
                            }
                            continue;
                        };
                        slabs[known] = Some(slab);
                        leaves[known] = l;
                        last = known;
                        known += 1;
                    }
                }
            }
            let l = &leaves[last];
            if let Some(v) = slabs[l.slab].as_ref().and_then(|s| s.get(l.index(cell))) {
                out.values[k] = *v;
                out.valid |= 1 << k;
            } else {
                alive &= !SLOT_AXES[k];
            }
        }
        Ok(out)
    }

    /// True when every finest cell of `finest` (the finest cells of one cell of `level`, at
    /// most [`CUT_CELL_FINEST`]) lies in a kd-tree leaf whose finest brick is of `level`.
    #[cold]
    #[inline(never)]
    fn leaf_cell_of_level(&self, finest: &IBox, level: u32) -> bool {
        let e = finest.extent();
        if e[0] * e[1] * e[2] > CUT_CELL_FINEST {
            return false;
        }
        let mut leaf_box = IBox::default();
        for z in finest.lo[2]..finest.hi[2] {
            for y in finest.lo[1]..finest.hi[1] {
                for x in finest.lo[0]..finest.hi[0] {
                    if leaf_box.contains_cell([x, y, z]) {
                        continue;
                    }
                    let Some(leaf) = self.find_leaf([x, y, z]) else {
                        return false;
                    };
                    if !matches!(self.leaf_top(leaf), Some((_, top)) if top == level) {
                        return false;
                    }
                    leaf_box = self.leaf_box(leaf);
                }
            }
        }
        true
    }

    /// [`Self::block_leaf`], from `recent` when one of its leaves holds `cell` (kept there
    /// otherwise).
    #[inline(always)]
    fn block_leaf_near(
        &self,
        level: u32,
        cell: [i64; 3],
        slab: usize,
        recent: &mut RecentLeaf,
    ) -> Result<Option<(BlockLeaf, Slab<'f>)>> {
        if let Some(leaf) = recent.holding(level, cell) {
            let values = match self.values_in_place(leaf.brick) {
                Some(v) => Slab::Borrowed(v),
                None => self.values(leaf.brick)?,
            };
            return Ok(Some((BlockLeaf { slab, ..leaf }, values)));
        }
        let found = self.block_leaf(level, cell, slab)?;
        if let Some((leaf, _)) = &found {
            recent.keep(level, *leaf);
        }
        Ok(found)
    }

    /// The kd-tree leaf holding the lowest finest cell of cell `cell` of `level`, to be kept in
    /// slab `slab` of a block, and its brick's values, when its finest brick is of `level` and
    /// the cell is a leaf cell everywhere (whole in that leaf, or in leaves all of `level`);
    /// `None` otherwise.
    fn block_leaf(
        &self,
        level: u32,
        cell: [i64; 3],
        slab: usize,
    ) -> Result<Option<(BlockLeaf, Slab<'f>)>> {
        let grid = self.grid();
        let finest = grid.finest_box(level, cell);
        let Some(leaf) = self.find_leaf(finest.lo) else {
            return Ok(None);
        };
        let Some((brick, top)) = self.leaf_top(leaf) else {
            return Ok(None);
        };
        let leaf_box = self.leaf_box(leaf);
        if top != level {
            return Ok(None);
        }
        let brick_cells = self.brick_cells(brick);
        let whole = if leaf_box.contains_box(&finest) {
            // The cells of `level` lying whole in the leaf, within the brick.
            let (s, o, shift) = (grid.scale(level), grid.offset(), grid.shift(level));
            let floor_div = |x: i64, a: usize| match shift {
                Some(sh) => x >> sh[a],
                None => x.div_euclid(s[a]),
            };
            IBox::new(
                axes(|a| floor_div(leaf_box.lo[a] + o[a] + s[a] - 1, a)),
                axes(|a| floor_div(leaf_box.hi[a] + o[a], a)),
            )
            .intersect(&brick_cells)
        } else if self.leaf_cell_of_level(&finest, level) {
            // A cell cut by a leaf's face (the kd-tree splits on finest cells, which need not
            // fall on a coarser level's cells): the cell alone, read from the same brick (one
            // brick of a level holds a cell).
            IBox::new(cell, axes(|a| cell[a] + 1)).intersect(&brick_cells)
        } else {
            return Ok(None);
        };
        let e = brick_cells.extent();
        let values = match self.values_in_place(brick) {
            Some(v) => Slab::Borrowed(v),
            None => self.values(brick)?,
        };
        let leaf = BlockLeaf {
            lo: whole.lo,
            hi: whole.hi,
            brick_lo: brick_cells.lo,
            stride: [1, e[0], e[0] * e[1]],
            brick,
            slab,
        };
        Ok(Some((leaf, values)))
    }
}

/// Slots of a [`LevelBlocks`] table (a power of two).
const BLOCK_SLOTS: usize = 4096;

/// A slot of [`LevelBlocks`]: a level and dual cell, and what the gradient reads there.
#[derive(Clone, Copy)]
struct BlockSlot {
    /// The level and the dual cell's lower corner cell.
    key: (u32, [i64; 3]),
    /// The centre of that cell in doubled units ([`Grid::centre`]).
    base: [f64; 3],
    /// The axes whose component the cells give ([`LevelCells::axes`]).
    given: [bool; 3],
    /// Every cell is a leaf cell of the level ([`LevelCells::is_whole`]).
    whole: bool,
    /// The dual cell's corner cells are leaf cells of the level ([`LevelCells::core_is_whole`]).
    core_is_whole: bool,
    /// The corner differences of the cells' values ([`CornerDifferences::of`]).
    differences: CornerDifferences,
}

impl BlockSlot {
    /// A slot holding no dual cell.
    const EMPTY: Self = Self {
        key: (u32::MAX, [0; 3]),
        base: [0.0; 3],
        given: [false; 3],
        whole: false,
        core_is_whole: false,
        differences: CornerDifferences([[0.0; 4]; 8]),
    };
}

/// A per-thread memo of [`Sampler::level_cells`]' answers, direct-mapped by level and dual
/// cell, kept as their corner differences: the hits of neighbouring rays share dual cells, so
/// most gradients weigh remembered differences. They are pure functions of their key, so the
/// memo never changes a gradient.
#[derive(Default)]
pub struct LevelBlocks {
    /// The sampler served, by [`Sampler::id`] (0: none yet).
    owner: u64,
    /// Per level of the sampler's grid: its steps.
    levels: Vec<LevelSteps>,
    slots: Vec<BlockSlot>,
    /// The kd-tree leaves of the last blocks filled ([`Sampler::level_block_near`]).
    recent: RecentLeaf,
}

impl LevelBlocks {
    /// Bytes of one table.
    pub const BYTES: usize = BLOCK_SLOTS * std::mem::size_of::<BlockSlot>();

    /// [`Sampler::level_gradient`], reading the cells from this memo when it holds them; where
    /// that is `None`, the components [`Sampler::level_gradient_axes`] gives and whether the
    /// dual cell's corner cells are leaf cells of the level are put in `partial` (left alone
    /// otherwise).
    #[inline]
    pub fn gradient<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        p: [f64; 3],
        level: u32,
        partial: &mut PartialGradient,
    ) -> Result<Option<[f64; 3]>> {
        if self.owner != sampler.id() || self.slots.is_empty() {
            self.serve(sampler);
        }
        let Some(steps) = self.levels.get(level as usize) else {
            return Ok(None);
        };
        let Some(first) = steps.dual_cell(p) else {
            return Ok(None);
        };
        let key = (level, first);
        let index = slot_of(level, first);
        let slot = &self.slots[index];
        // Most hits: a remembered whole block, weighed here; the rest below.
        if slot.key == key && slot.whole {
            let w = steps.weights(p, slot.base);
            return Ok(Some(slot.differences.gradient(&w, &steps.span)));
        }
        self.gradient_in_slot(sampler, p, key, index, partial)
    }

    /// [`Self::gradient`] at `p` in the dual cell `key` (level and lower corner cell) where
    /// slot `index` holds another dual cell (it is filled) or a block that is not whole.
    #[inline(never)]
    fn gradient_in_slot<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        p: [f64; 3],
        key: (u32, [i64; 3]),
        index: usize,
        partial: &mut PartialGradient,
    ) -> Result<Option<[f64; 3]>> {
        if self.slots[index].key != key {
            self.fill(sampler, key, index)?;
        }
        let (slot, steps) = (&self.slots[index], &self.levels[key.0 as usize]);
        partial.core_is_whole = slot.core_is_whole;
        if slot.given == [false; 3] {
            partial.given = [None; 3];
            return Ok(None);
        }
        let g = slot
            .differences
            .gradient(&steps.weights(p, slot.base), &steps.span);
        if slot.whole {
            return Ok(Some(g));
        }
        partial.given = axes(|a| slot.given[a].then_some(g[a]));
        Ok(None)
    }

    /// Empties the memo for `sampler`'s dual cells and takes its levels' steps.
    #[cold]
    #[inline(never)]
    fn serve<D: AsRef<[u8]>>(&mut self, sampler: &Sampler<'_, D>) {
        let grid = sampler.grid();
        self.owner = sampler.id();
        self.levels = (0..grid.num_levels() as u32)
            .map(|level| LevelSteps::of(grid, level))
            .collect();
        self.slots.clear();
        self.slots.resize(BLOCK_SLOTS, BlockSlot::EMPTY);
        self.recent = RecentLeaf::default();
    }

    /// Puts the cells of the dual cell `key` (level and lower corner cell) in slot `index`.
    #[inline(never)]
    fn fill<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        key: (u32, [i64; 3]),
        index: usize,
    ) -> Result<()> {
        let (level, first) = key;
        let cells = sampler.level_cells_near(level, first, &mut self.recent)?;
        let base = sampler.grid().centre(level, first);
        self.slots[index] = BlockSlot {
            key,
            base: base.map(|x| x as f64),
            given: cells.axes(),
            whole: cells.is_whole(),
            core_is_whole: cells.core_is_whole(),
            differences: CornerDifferences::of(&cells.values),
        };
        Ok(())
    }
}

/// Copies `run` (one row's cells, 1 to 4 values) into `out` from slot `k`: copies of a fixed
/// length, which compile to moves instead of a call to `memcpy`.
#[inline(always)]
fn put_run(out: &mut LevelBlock, k: usize, run: &[f32]) {
    match *run {
        [a, b, c, d] => out[k..k + 4].copy_from_slice(&[a, b, c, d]),
        [a, b, c] => out[k..k + 3].copy_from_slice(&[a, b, c]),
        [a, b] => out[k..k + 2].copy_from_slice(&[a, b]),
        [a] => out[k] = a,
        _ => out[k..k + run.len()].copy_from_slice(run),
    }
}

/// The slot of [`LevelBlocks`] for the dual cell `first` of `level`.
#[inline(always)]
fn slot_of(level: u32, first: [i64; 3]) -> usize {
    dual_cell_slot(level, first, BLOCK_SLOTS)
}

/// The slot of a direct-mapped per-thread memo of `slots` slots (a power of two) keyed by the
/// dual cell `first` of `level`.
#[inline(always)]
pub(super) fn dual_cell_slot(level: u32, first: [i64; 3], slots: usize) -> usize {
    let h = (first[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (first[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (first[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
        ^ u64::from(level).wrapping_mul(0x27D4_EB2F_1656_67C5);
    (h >> (64 - slots.trailing_zeros())) as usize
}

/// `x as i64` for a whole number `x` below `2^51` in magnitude, without the cast's saturation
/// checks: added to `1.5 * 2^52`, `x` gives a sum in `[2^52, 2^53)`, where the ulp is 1, so
/// the sum is exact and its bits are those of `1.5 * 2^52` plus `x`.
#[inline(always)]
fn whole_to_i64(x: f64) -> i64 {
    const SHIFT: f64 = (3u64 << 51) as f64;
    (x + SHIFT).to_bits() as i64 - SHIFT.to_bits() as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_numbers_below_2_to_51_convert_as_the_cast_does() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for i in 0..100_000u64 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let scale = [1.0, 1e3, 1e8, 1e15][(i % 4) as usize];
            let x = (((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0) * scale;
            let x = x.floor();
            assert_eq!(whole_to_i64(x), x as i64, "{x}");
        }
        for x in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            999_999_999_999_999.0,
            -999_999_999_999_999.0,
        ] {
            assert_eq!(whole_to_i64(x), x as i64, "{x}");
        }
    }
}
