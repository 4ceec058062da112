//! The level-`L` neighbourhood of one leaf: each cell of the leaf's box grown by one cell,
//! classified as a leaf cell of level `L` (with its value), coarser, refined, outside the
//! domain or uncovered.
//!
//! It is filled from the leaves overlapping that box, one block per leaf, so no per-cell tree walk
//! is needed; it decides which dual cells can be merged and which octants touch a boundary, and
//! holds each cell's value bound for [`super::cull`].

use crate::error::Result;
use amr_format::IBox;

use super::band::fold_cell_bounds;
use super::leaf_tree::{LeafTree, Met};
use crate::reconstruct::grid::axes;

use crate::reconstruct::Sampler;

/// Finest cells per axis of a cell, at most, for which a fill takes no node of the leaf tree
/// whole (a node of up to 8 leaves rarely fits in such a cell; the test would cost more).
const GROUP_SCALE: i64 = 2;

/// A leaf cell of the leaf's own level.
pub const LEAF: u8 = 0;
/// Inside a coarser leaf cell.
pub const COARSER: u8 = 1;
/// Refined: covered by finer leaf cells.
pub const FINER: u8 = 2;
/// Outside the domain.
pub const OUTSIDE: u8 = 3;
/// Inside the domain, but no brick covers it.
pub const UNCOVERED: u8 = 4;

/// Code bit: the cell may hold a value `>= iso`.
pub const ABOVE: u8 = 1;
/// Code bit: the cell may hold a value `< iso`.
pub const BELOW: u8 = 2;
/// Code bit: the cell is not a [`LEAF`] cell.
pub const NOT_LEAF: u8 = 4;
/// Code bit: the cell lies in a coarser leaf cell whose octants are not yet in its bound.
pub const PENDING: u8 = 8;

/// [`ABOVE`] and [`BELOW`] bits of a bound `lo..=hi` for `iso`: a union of bounds straddles
/// `iso` (`min lo < iso <= max hi`) exactly when the union of their codes has both bits.
///
/// A NaN (which no converter writes: only a file damaged after it was written holds one) may
/// stand for any value, so it gives both bits: the voxels around it are extracted, and the
/// tracer, decoding one, stops the render with an error naming the file instead of leaving a
/// hole in the surface. The empty bound (`+inf..=-inf`) gives neither.
#[inline]
pub(super) fn code(lo: f32, hi: f32, iso: f32) -> u8 {
    u8::from(!(hi < iso)) | u8::from(!(lo >= iso)) << 1
}

/// `floor(v / d)` for `d > 0`, a shift when `d` is a power of two.
#[inline(always)]
pub(super) fn div_floor(v: i64, d: i64) -> i64 {
    if d & (d - 1) == 0 {
        v >> d.trailing_zeros()
    } else {
        v.div_euclid(d)
    }
}

/// The cells of a level whose cells are `scale` finest cells wide (index offset `offset`)
/// overlapping finest-level boxes: [`super::blocks::level_box`], with the shifts found once.
#[derive(Clone, Copy)]
struct LevelCells {
    scale: [i64; 3],
    offset: [i64; 3],
    shift: Option<[u32; 3]>,
}

impl LevelCells {
    fn new(scale: [i64; 3], offset: [i64; 3]) -> Self {
        let pow2 = scale.iter().all(|&d| d > 0 && d & (d - 1) == 0);
        Self {
            scale,
            offset,
            shift: pow2.then(|| scale.map(|d| d.trailing_zeros())),
        }
    }

    /// The cells overlapping finest-level box `f`.
    #[inline(always)]
    fn of(&self, f: &IBox) -> IBox {
        let (o, s) = (self.offset, self.scale);
        match self.shift {
            Some(sh) => IBox::new(
                [
                    (f.lo[0] + o[0]) >> sh[0],
                    (f.lo[1] + o[1]) >> sh[1],
                    (f.lo[2] + o[2]) >> sh[2],
                ],
                [
                    (f.hi[0] + o[0] + s[0] - 1) >> sh[0],
                    (f.hi[1] + o[1] + s[1] - 1) >> sh[1],
                    (f.hi[2] + o[2] + s[2] - 1) >> sh[2],
                ],
            ),
            None => IBox::new(
                [0, 1, 2].map(|a| (f.lo[a] + o[a]).div_euclid(s[a])),
                [0, 1, 2].map(|a| (f.hi[a] + o[a] + s[a] - 1).div_euclid(s[a])),
            ),
        }
    }
}

/// The rows of a box inside two boxes of cells, x fastest: where the first row starts in each
/// and how far apart rows (along y) and planes (along z) of rows lie.
struct Rows {
    dst: usize,
    src: usize,
    dst_y: usize,
    src_y: usize,
    dst_z: usize,
    src_z: usize,
    /// Rows per plane.
    ny: usize,
    /// Planes.
    nz: usize,
}

impl Rows {
    /// The rows of box `b`, inside both boxes of cells `dst` and `src`.
    fn of(b: &IBox, dst: &IBox, src: &IBox) -> Self {
        let (de, se, be) = (dst.extent(), src.extent(), b.extent());
        Self {
            dst: dst.linear_index(b.lo),
            src: src.linear_index(b.lo),
            dst_y: de[0] as usize,
            src_y: se[0] as usize,
            dst_z: (de[0] * de[1]) as usize,
            src_z: (se[0] * se[1]) as usize,
            ny: be[1] as usize,
            nz: be[2] as usize,
        }
    }

    /// [`Self::of`] for a box `b` known to hold cells and to lie inside both `dst` and `src`.
    #[inline(always)]
    fn inside(b: &IBox, dst: &IBox, src: &IBox) -> Self {
        let index = |c: &IBox| {
            let (x, y, z) = (b.lo[0] - c.lo[0], b.lo[1] - c.lo[1], b.lo[2] - c.lo[2]);
            let (ex, ey) = (c.hi[0] - c.lo[0], c.hi[1] - c.lo[1]);
            (
                (x + ex * (y + ey * z)) as usize,
                ex as usize,
                (ex * ey) as usize,
            )
        };
        let ((dst, dst_y, dst_z), (src, src_y, src_z)) = (index(dst), index(src));
        Self {
            dst,
            src,
            dst_y,
            src_y,
            dst_z,
            src_z,
            ny: (b.hi[1] - b.lo[1]) as usize,
            nz: (b.hi[2] - b.lo[2]) as usize,
        }
    }

    /// The index one past the last cell of the rows of `w` cells starting at `first`, rows
    /// `y` and planes `z` apart; `None` on overflow. `first` when there are no rows.
    fn end(&self, first: usize, (y, z): (usize, usize), w: usize) -> Option<usize> {
        if self.ny == 0 || self.nz == 0 || w == 0 {
            return Some(first);
        }
        first
            .checked_add((self.nz - 1).checked_mul(z)?)?
            .checked_add((self.ny - 1).checked_mul(y)?)?
            .checked_add(w)
    }

    /// True when the rows of `w` cells lie inside `dst` cells and `src` cells.
    fn fit(&self, dst: usize, src: usize, w: usize) -> bool {
        let fits = |end: Option<usize>, len: usize| end.is_some_and(|e| e <= len);
        fits(self.end(self.dst, (self.dst_y, self.dst_z), w), dst)
            && fits(self.end(self.src, (self.src_y, self.src_z), w), src)
    }
}

/// A finer level's cells and its number of cells per neighbourhood cell along each axis.
type FinerCells = (LevelCells, [i64; 3]);

/// ORs `src` into `dst`, element by element.
#[inline]
fn or_into(dst: &mut [bool], src: &[bool]) {
    for (d, &s) in dst.iter_mut().zip(src) {
        *d |= s;
    }
}

/// Per-thread scratch: the classified neighbourhood of the leaf being processed.
#[derive(Default)]
pub struct Neighbourhood {
    /// The cells held: the leaf's level-`L` box grown by one cell.
    pub cells: IBox,
    /// The level `L`.
    pub level: u32,
    kind: Vec<u8>,
    /// Cells of `cells` within one cell of a cell that is not [`LEAF`].
    pub near_boundary: Vec<bool>,
    /// True when every cell is [`LEAF`].
    pub all_leaf: bool,
    /// Per cell: the smallest and largest value of the leaf cells of level `L` or finer inside it
    /// (`+inf` and `-inf` when it holds none); a [`LEAF`] cell's value is its `lo` (its `hi` is
    /// not kept).
    lo: Vec<f32>,
    hi: Vec<f32>,
    /// Cells whose code has the [`PENDING`] bit.
    pending_left: usize,
    /// A bit per row of cells (along x; row `y + z * rows per plane`, relative to
    /// [`Self::cells`]): set when the fill flagged a cell of the row pending (the cell may have
    /// been settled since), clear when no cell of the row is pending.
    pending_rows: Vec<u64>,
    /// Per cell: the [`PENDING`] bit (set by a fill when the cell lies in a coarser leaf cell
    /// whose octants' corners are not yet in its bound, cleared by settling) and, for the
    /// isovalue of the last [`Self::classify`], the [`ABOVE`], [`BELOW`] and [`NOT_LEAF`] bits.
    codes: Vec<u8>,
    touching: Vec<Met>,
    /// Per cell inside a coarser leaf cell: true when the fill gave it a bound of its own (leaf
    /// cells of this level or finer met there), merged into the coarse one when settled. Empty
    /// while no cell is (the common case), else one flag per cell.
    mixed: Vec<bool>,
    /// Per cell: its bound from the coarse octants alone ([`super::cull::coarse_cell_bound`])
    /// once computed, NaN before; empty until the first is.
    exact: Vec<(f32, f32)>,
    /// Scratch of [`Self::mark_near_boundary`].
    dilated: Vec<bool>,
    /// The level and box of the last fill, while the cells hold it.
    filled: Option<(u32, IBox)>,
    /// The blocks of cells the last fill made [`COARSER`] and pending, each with the kd leaf
    /// covering it and that leaf's level ([`Self::settle_coarser_blocks`]).
    coarser_blocks: Vec<(IBox, u32, u32)>,
}

impl Neighbourhood {
    /// Fills the neighbourhood of `leaf` (level `level`, level-`level` box `own`), finding the
    /// leaves around it in `leaves`. Nothing is done when the last fill was of the same box: the
    /// cells, and the coarser cells' bounds settled since, do not depend on the isovalue.
    pub fn fill<D: AsRef<[u8]>>(
        &mut self,
        (sampler, leaves): (&Sampler<'_, D>, &LeafTree),
        level: u32,
        own: &IBox,
    ) -> Result<()> {
        let g = own.grow([1; 3]);
        if !self.holds(level, &g) {
            self.fill_region((sampler, leaves), level, g)?;
        }
        if !self.all_leaf && self.near_boundary.is_empty() {
            self.mark_near_boundary();
        }
        Ok(())
    }

    /// True when the cells hold level-`level` box `g` (a fill of a box holding it is kept).
    #[inline]
    pub fn holds(&self, level: u32, g: &IBox) -> bool {
        self.filled
            .is_some_and(|(lv, held)| lv == level && held.contains_box(g))
    }

    /// Fills the level-`level` cells of box `g`: [`Self::fill`] of the box inside `g` by one
    /// cell, or of several leaves at once when `g` holds their grown boxes (each cell's kind and
    /// bound depend on the cell alone, not on the box filled), without
    /// [`Self::near_boundary`], which `fill` adds when a leaf is extracted from it.
    pub fn fill_region<D: AsRef<[u8]>>(
        &mut self,
        sources: (&Sampler<'_, D>, &LeafTree),
        level: u32,
        g: IBox,
    ) -> Result<()> {
        let mut touching = std::mem::take(&mut self.touching);
        let filled = self.fill_region_using(sources, level, g, &mut touching);
        self.touching = touching;
        filled
    }

    /// [`Self::fill_region`], gathering the leaves met in `touching` (whatever it held): a
    /// list the caller keeps, so that the many tiles a thread fills share one
    /// ([`super::cell_tiles::CellTiles`]) instead of each growing its own.
    pub fn fill_region_using<D: AsRef<[u8]>>(
        &mut self,
        (sampler, leaves): (&Sampler<'_, D>, &LeafTree),
        level: u32,
        g: IBox,
        touching: &mut Vec<Met>,
    ) -> Result<()> {
        self.filled = None;
        let grid = sampler.grid();
        let n = g.num_cells().unwrap_or(0) as usize;
        self.cells = g;
        self.level = level;
        self.kind.clear();
        self.kind.resize(n, UNCOVERED);
        self.lo.clear();
        self.lo.resize(n, f32::INFINITY);
        self.hi.clear();
        self.hi.resize(n, f32::NEG_INFINITY);
        self.codes.clear();
        self.codes.resize(n, 0);
        self.mixed.clear();
        self.exact.clear();
        self.coarser_blocks.clear();
        self.pending_left = 0;
        self.pending_rows.clear();
        let e = g.extent();
        let rows = (e[1].max(0) * e[2].max(0)) as usize;
        self.pending_rows.resize(rows.div_ceil(64), 0);
        let domain = grid.domain(level);
        let s = grid.scale(level);
        let o = grid.offset();
        let region = IBox::new(
            axes(|a| g.lo[a] * s[a] - o[a]),
            axes(|a| g.hi[a] * s[a] - o[a]),
        );
        let at_level = LevelCells::new(s, o);
        // The cells and ratio of each finer level met, found once per fill.
        let mut finer: [Option<(u32, FinerCells)>; 8] = [None; 8];
        touching.clear();
        // A node of finer leaves (all with data) inside one cell comes whole: its kept exact
        // range is that of its leaves' cells, each of which would add its own to that cell.
        // Cells of at most `GROUP_SCALE` finest cells per axis rarely hold a node whole.
        let group = s.iter().any(|&v| v > GROUP_SCALE);
        let whole = |b: &IBox, coarsest: u32, complete: bool| {
            complete
                && coarsest > level
                && (0..3).all(|a| b.hi[a] - b.lo[a] <= s[a])
                && at_level.of(b).num_cells() == Some(1)
        };
        if group {
            leaves.for_each_overlapping_grouped(&region, whole, |m| touching.push(m));
        } else {
            leaves.for_each_leaf_overlapping(&region, |l| touching.push(Met::Leaf(l)));
        }
        for &met in touching.iter() {
            let l = match met {
                Met::Leaf(l) => l,
                Met::Node(n) => {
                    let block = at_level.of(&leaves.node_box(n));
                    self.set_block(&block, FINER);
                    let (a, b) = leaves.exact_node_range(sampler, n)?;
                    self.widen_with_range(g.linear_index(block.lo), a, b);
                    continue;
                }
            };
            let lb = leaves.leaf_box(l);
            // `region` is whole level cells, so this is the leaf's level box clipped to `g`.
            let part = lb.intersect(&region);
            let block = at_level.of(&part);
            match sampler.leaf_top(l) {
                None => self.set_block(&block, UNCOVERED),
                Some((_, lv)) if lv < level => {
                    self.set_coarser_block(&block);
                    self.coarser_blocks.push((block, l, lv));
                }
                Some((brick, lv)) if lv > level => {
                    self.set_block(&block, FINER);
                    if block.num_cells() == Some(1) && region.contains_box(&lb) {
                        // The whole leaf lies in one cell: its kept exact range is that of
                        // its cells folded one by one.
                        let (a, b) = leaves.exact_range(sampler, l)?;
                        self.widen_with_range(g.linear_index(block.lo), a, b);
                        continue;
                    }
                    let k = lv as usize % finer.len();
                    let map = match finer[k] {
                        Some((l, map)) if l == lv => map,
                        _ => {
                            let sf = grid.scale(lv);
                            let ratio = [s[0] / sf[0], s[1] / sf[1], s[2] / sf[2]];
                            let map = (LevelCells::new(sf, o), ratio);
                            finer[k] = Some((lv, map));
                            map
                        }
                    };
                    self.bound_finer(sampler, map, &part, brick)?;
                }
                Some((brick, _)) => {
                    let slab = sampler.values(brick)?;
                    let values: &[f32] = &slab;
                    let bc = sampler.brick_cells(brick);
                    let block = block.intersect(&bc);
                    if block.is_empty() {
                        continue;
                    }
                    self.set_leaf_rows(&Rows::of(&block, &g, &bc), values, block.extent()[0]);
                }
            }
        }
        if !domain.contains_box(&g) {
            self.mark_outside(&g.intersect(&domain));
        }
        self.finish_fill();
        Ok(())
    }

    /// Starts a fill of the level-`level` cells of box `g` by copies of tiles
    /// ([`Self::copy_tile`]) that together hold every cell of `g`; [`Self::end_copies`] ends it.
    pub fn begin_copies(&mut self, level: u32, g: IBox) {
        self.filled = None;
        let n = g.num_cells().unwrap_or(0) as usize;
        self.cells = g;
        self.level = level;
        // The copies write every cell's kind and bound: only the lengths are set here.
        for v in [&mut self.lo, &mut self.hi] {
            v.resize(n, 0.0);
        }
        self.kind.resize(n, UNCOVERED);
        self.mixed.clear();
        self.exact.clear();
        self.coarser_blocks.clear();
        self.codes.clear();
        self.codes.resize(n, 0);
        self.pending_left = 0;
        self.pending_rows.clear();
    }

    /// Copies the cells of `tile` (a neighbourhood of the level being filled) that lie in the
    /// box being filled: their kinds and bounds ([`Self::copy_mixed`] copies their flags of mixed
    /// bounds). Those cells must be settled (none pending,
    /// [`super::cull::settle_in`]), as [`super::cell_tiles::CellTiles::fill`] leaves them, so
    /// no pending flag is copied: the filled cells have none.
    pub fn copy_tile(&mut self, tile: &Neighbourhood) {
        let (g, t) = (self.cells, tile.cells);
        let b = g.intersect(&t);
        if b.is_empty() {
            return;
        }
        // Each array holds exactly the cells of its box, and `b` lies inside both boxes: then
        // every row of `b` lies inside every array, with no row checked on its own.
        let (n, m) = (self.kind.len(), tile.kind.len());
        let whole = self.lo.len() == n
            && self.hi.len() == n
            && tile.lo.len() == m
            && tile.hi.len() == m
            && g.num_cells() == Some(n as u64)
            && t.num_cells() == Some(m as u64);
        debug_assert!(whole, "cells not sized to their box");
        if !whole {
            return;
        }
        let rows = Rows::inside(&b, &g, &t);
        // One copy loop per row length, so that each row is moved by fixed-length moves.
        // SAFETY: `rows` are those of `b`, inside both boxes, whose arrays were checked above.
        unsafe {
            match b.hi[0] - b.lo[0] {
                1 => self.copy_rows::<1>(tile, &rows),
                2 => self.copy_rows::<2>(tile, &rows),
                3 => self.copy_rows::<3>(tile, &rows),
                4 => self.copy_rows::<4>(tile, &rows),
                5 => self.copy_rows::<5>(tile, &rows),
                6 => self.copy_rows::<6>(tile, &rows),
                7 => self.copy_rows::<7>(tile, &rows),
                8 => self.copy_rows::<8>(tile, &rows),
                w => self.copy_rows_of(tile, &rows, w as usize),
            }
        }
    }

    /// Copies the [`Self::mixed`] flags of the cells of `tile` that [`Self::copy_tile`] copied,
    /// when it has some (rare).
    #[inline]
    pub fn copy_mixed(&mut self, tile: &Neighbourhood) {
        if !tile.mixed.is_empty() {
            self.copy_mixed_of(tile);
        }
    }

    /// [`Self::copy_mixed`] for a tile with flags: kept out of the copies' code.
    #[cold]
    #[inline(never)]
    fn copy_mixed_of(&mut self, tile: &Neighbourhood) {
        let b = self.cells.intersect(&tile.cells);
        if b.is_empty() {
            return;
        }
        self.mixed.resize(self.kind.len(), false);
        let w = b.extent()[0].max(0) as usize;
        for z in b.lo[2]..b.hi[2] {
            for y in b.lo[1]..b.hi[1] {
                let (d, s) = (self.index([b.lo[0], y, z]), tile.index([b.lo[0], y, z]));
                self.mixed[d..d + w].copy_from_slice(&tile.mixed[s..s + w]);
            }
        }
    }

    /// [`Self::copy_rows_of`] for rows of `N` cells, a length known when compiled.
    ///
    /// # Safety
    ///
    /// As for [`Self::copy_rows_of`].
    #[inline(always)]
    unsafe fn copy_rows<const N: usize>(&mut self, tile: &Neighbourhood, rows: &Rows) {
        // SAFETY: the caller's.
        unsafe { self.copy_rows_of(tile, rows, N) }
    }

    /// Copies `rows` of `w` cells of `tile` (kinds, bounds) into these cells, with no bound
    /// checked: three slices of a few cells checked per row cost more than their copies.
    ///
    /// # Safety
    ///
    /// `rows` must be the rows of a box `w` cells wide inside both [`Self::cells`] and
    /// `tile.cells`, and each of the three arrays of both must hold exactly the cells of its
    /// box, as [`Self::copy_tile`] checks.
    #[inline(always)]
    unsafe fn copy_rows_of(&mut self, tile: &Neighbourhood, rows: &Rows, w: usize) {
        let dst = (
            self.kind.as_mut_ptr(),
            self.lo.as_mut_ptr(),
            self.hi.as_mut_ptr(),
        );
        let src = (tile.kind.as_ptr(), tile.lo.as_ptr(), tile.hi.as_ptr());
        // One loop over all rows, a plane's rows `ny` at a time: fewer live counters than a
        // loop per plane, for the few short rows of a tile's part.
        let (mut d, mut s) = (rows.dst, rows.src);
        let next_plane = (
            rows.dst_z - rows.ny * rows.dst_y,
            rows.src_z - rows.ny * rows.src_y,
        );
        let mut left = rows.ny;
        for _ in 0..rows.ny * rows.nz {
            // SAFETY: the rows are those of a box inside both boxes of cells, and each array
            // holds exactly its box's cells (the caller's contract), so every row lies inside
            // the three destination arrays and the three source arrays; the destinations are
            // this neighbourhood's own vectors, borrowed mutably, and the sources another's, so
            // no two overlap.
            unsafe {
                std::ptr::copy_nonoverlapping(src.0.add(s), dst.0.add(d), w);
                std::ptr::copy_nonoverlapping(src.1.add(s), dst.1.add(d), w);
                std::ptr::copy_nonoverlapping(src.2.add(s), dst.2.add(d), w);
            }
            debug_assert!(
                !tile.codes[s..s + w].iter().any(|&c| c & PENDING != 0),
                "a tile's pending cells copied"
            );
            d += rows.dst_y;
            s += rows.src_y;
            left -= 1;
            if left == 0 {
                left = rows.ny;
                d += next_plane.0;
                s += next_plane.1;
            }
        }
    }

    /// Makes the cells of `rows` of `w` cells [`LEAF`] cells with the values of the same rows
    /// of a brick's `values`.
    fn set_leaf_rows(&mut self, rows: &Rows, values: &[f32], w: i64) {
        // One loop per row length, so that each short row is moved by fixed-length moves.
        match w {
            1 => self.set_leaf_rows_of(rows, values, 1),
            2 => self.set_leaf_rows_of(rows, values, 2),
            3 => self.set_leaf_rows_of(rows, values, 3),
            4 => self.set_leaf_rows_of(rows, values, 4),
            5 => self.set_leaf_rows_of(rows, values, 5),
            6 => self.set_leaf_rows_of(rows, values, 6),
            7 => self.set_leaf_rows_of(rows, values, 7),
            8 => self.set_leaf_rows_of(rows, values, 8),
            w => self.set_leaf_rows_of(rows, values, w.max(0) as usize),
        }
    }

    /// [`Self::set_leaf_rows`], inlined for each row length. The bounds are checked once for
    /// all rows, as in [`Self::copy_rows_of`]; rows that do not fit are a bug, and set nothing.
    #[inline(always)]
    fn set_leaf_rows_of(&mut self, rows: &Rows, values: &[f32], w: usize) {
        let n = self.kind.len();
        let ok = self.lo.len() == n && rows.fit(n, values.len(), w);
        debug_assert!(ok, "brick rows outside the cells");
        if !ok {
            return;
        }
        let (kind, lo, src) = (
            self.kind.as_mut_ptr(),
            self.lo.as_mut_ptr(),
            values.as_ptr(),
        );
        let (mut dz, mut sz) = (rows.dst, rows.src);
        for _ in 0..rows.nz {
            let (mut d, mut s) = (dz, sz);
            for _ in 0..rows.ny {
                // SAFETY: every row lies below the ends checked above (`d + w <= n`, the length
                // of `kind` and of `lo`, and `s + w <= values.len()`); `values` is a brick's data,
                // not this neighbourhood's vectors, which are borrowed mutably.
                unsafe {
                    std::ptr::write_bytes(kind.add(d), LEAF, w);
                    std::ptr::copy_nonoverlapping(src.add(s), lo.add(d), w);
                }
                d += rows.dst_y;
                s += rows.src_y;
            }
            dz += rows.dst_z;
            sz += rows.src_z;
        }
    }

    /// Ends a fill begun by [`Self::begin_copies`]: the cells then hold what
    /// [`Self::fill_region`] of the same box gives, with the cells the tiles had settled
    /// settled.
    pub fn end_copies(&mut self) {
        // The cells copied are settled: `begin_copies` left every pending flag clear.
        self.finish_fill();
    }

    /// What every fill ends with: the flags, codes and box of the cells held.
    fn finish_fill(&mut self) {
        // An OR of every kind (`LEAF` is 0), without an early exit, so that it vectorizes.
        self.all_leaf = self.kind.iter().fold(LEAF, |acc, &k| acc | k) == LEAF;
        // Marked by `fill`, when the cells are extracted from.
        self.near_boundary.clear();
        // The codes before any classification are the pending flags the fill set.
        self.filled = Some((self.level, self.cells));
    }

    /// Cells held.
    #[inline]
    pub fn len(&self) -> usize {
        self.kind.len()
    }

    /// True when no cell is held.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.kind.is_empty()
    }

    /// The union of the bounds ([`Self::bound`]) of the cells of `b` (inside [`Self::cells`]);
    /// `(+inf, -inf)` when none holds a value.
    pub fn range_in(&self, b: &IBox) -> (f32, f32) {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let w = b.extent()[0].max(0) as usize;
        for z in b.lo[2]..b.hi[2] {
            for y in b.lo[1]..b.hi[1] {
                let r = self.index([b.lo[0], y, z]);
                let cells = self.kind[r..r + w]
                    .iter()
                    .zip(&self.lo[r..r + w])
                    .zip(&self.hi[r..r + w]);
                for ((&kind, &a), &b) in cells {
                    let b = if kind == LEAF { a } else { b };
                    // Comparisons, not f32::min: a NaN compares false and is left out.
                    if a < lo {
                        lo = a;
                    }
                    if b > hi {
                        hi = b;
                    }
                }
            }
        }
        (lo, hi)
    }

    /// Sets [`Self::near_boundary`]: a cell is near the boundary when one of the up to 27 cells
    /// around it (inside the neighbourhood) is not [`LEAF`]. The 3x3x3 dilation is done one axis
    /// at a time (three ORs of whole rows per cell instead of 27 writes per non-leaf cell).
    fn mark_near_boundary(&mut self) {
        let e = self.cells.extent().map(|v| v as usize);
        let n = self.kind.len();
        let (row, slab) = (e[0], e[0] * e[1]);
        self.dilated.clear();
        self.dilated.extend(self.kind.iter().map(|&k| k != LEAF));
        let not_leaf = &mut self.dilated;
        // Along x, within each row: over all cells at once (one long loop each way, not two
        // short ones per row), then each row's first and last cell again, which took their
        // neighbour in the row before or after.
        self.near_boundary.clear();
        self.near_boundary.extend_from_slice(not_leaf);
        let along = &mut self.near_boundary;
        if n > 1 {
            for (d, &s) in along[1..].iter_mut().zip(&not_leaf[..n - 1]) {
                *d |= s;
            }
            for (d, &s) in along[..n - 1].iter_mut().zip(&not_leaf[1..]) {
                *d |= s;
            }
        }
        if row == 1 {
            along.copy_from_slice(not_leaf);
        } else if row > 1 {
            for (a, c) in along.chunks_exact_mut(row).zip(not_leaf.chunks_exact(row)) {
                a[0] = c[0] | c[1];
                a[row - 1] = c[row - 2] | c[row - 1];
            }
        }
        // Along y, within each slab, then along z; `not_leaf` becomes the y-dilated cells. As
        // along x: over all cells at once (a row apart), then each slab's first and last row
        // again, which took their neighbour in the slab before or after.
        not_leaf.copy_from_slice(along);
        if n > row {
            or_into(&mut not_leaf[row..], &along[..n - row]);
            or_into(&mut not_leaf[..n - row], &along[row..]);
        }
        if n > 0 {
            for z in 0..e[2] {
                let (first, last) = (z * slab, z * slab + slab - row);
                let (top, bottom) = (first..first + row, last..last + row);
                not_leaf[top.clone()].copy_from_slice(&along[top]);
                not_leaf[bottom.clone()].copy_from_slice(&along[bottom]);
                if e[1] > 1 {
                    or_into(
                        &mut not_leaf[first..first + row],
                        &along[first + row..first + 2 * row],
                    );
                    or_into(&mut not_leaf[last..last + row], &along[last - row..last]);
                }
            }
        }
        along.copy_from_slice(not_leaf);
        for z in 0..e[2] {
            let r = z * slab;
            let dst = &mut along[r..r + slab];
            if z > 0 {
                or_into(dst, &not_leaf[r - slab..r]);
            }
            if z + 1 < e[2] {
                or_into(dst, &not_leaf[r + slab..r + 2 * slab]);
            }
        }
    }

    /// Widens the bounds of the cells holding the cells of brick `brick` of a finer level
    /// inside finest-level box `part`; `cells` maps finest boxes to that level's cells, `ratio`
    /// is the number of its cells per neighbourhood cell along each axis.
    fn bound_finer<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        (cells, ratio): FinerCells,
        part: &IBox,
        brick: u32,
    ) -> Result<()> {
        let bc = sampler.brick_cells(brick);
        let cells = cells.of(part).intersect(&bc);
        if cells.is_empty() {
            return Ok(());
        }
        let values = sampler.values(brick)?;
        fold_cell_bounds(
            &values,
            &bc,
            &cells,
            ratio,
            &self.cells,
            (&mut self.lo, &mut self.hi),
        );
        Ok(())
    }

    /// Makes the cells of `block` [`COARSER`] cells ([`Self::set_block`]) and flags them
    /// pending, counting those not flagged yet: one pass over each row of the block.
    fn set_coarser_block(&mut self, block: &IBox) {
        let g = self.cells;
        let e = g.extent();
        let w = (block.hi[0] - block.lo[0]).max(0) as usize;
        let mut newly = 0;
        for z in block.lo[2]..block.hi[2] {
            for y in block.lo[1]..block.hi[1] {
                let r = ((y - g.lo[1]) + (z - g.lo[2]) * e[1]) as usize;
                self.pending_rows[r / 64] |= 1 << (r % 64);
                let first = (block.lo[0] - g.lo[0]) as usize + r * e[0] as usize;
                let cells = first..first + w;
                let kinds = &mut self.kind[cells.clone()];
                let values = &self.lo[cells.clone()];
                let highs = &mut self.hi[cells.clone()];
                let codes = &mut self.codes[cells];
                let row = kinds.iter_mut().zip(values).zip(highs).zip(codes);
                for (((kind, &value), high), code) in row {
                    // A leaf cell overwritten keeps its value as both ends of its bound.
                    if *kind == LEAF {
                        *high = value;
                    }
                    *kind = COARSER;
                    // During a fill a code holds no bit but `PENDING`.
                    newly += usize::from(*code == 0);
                    *code = PENDING;
                }
            }
        }
        self.pending_left += newly;
    }

    /// Makes the cells of [`Self::cells`] outside box `inside` (the part inside the domain)
    /// [`OUTSIDE`] cells: whole rows outside it, and the ends of the rows crossing it.
    fn mark_outside(&mut self, inside: &IBox) {
        let g = self.cells;
        let w = g.extent()[0].max(0) as usize;
        // The x-range of a crossing row inside the domain, as offsets in the row.
        let x0 = (inside.lo[0] - g.lo[0]).clamp(0, w as i64) as usize;
        let x1 = (inside.hi[0] - g.lo[0]).clamp(x0 as i64, w as i64) as usize;
        for z in g.lo[2]..g.hi[2] {
            for y in g.lo[1]..g.hi[1] {
                let row = g.linear_index([g.lo[0], y, z]);
                let row_inside = (inside.lo[1]..inside.hi[1]).contains(&y)
                    && (inside.lo[2]..inside.hi[2]).contains(&z);
                if row_inside {
                    self.set_kinds(row..row + x0, OUTSIDE);
                    self.set_kinds(row + x1..row + w, OUTSIDE);
                } else {
                    self.set_kinds(row..row + w, OUTSIDE);
                }
            }
        }
    }

    /// Widens cell `i`'s bound to take in the exact range `(a, b)` of finer leaves inside it, by
    /// comparisons rather than `f32::min` (as the fold of their cells one by one).
    #[inline]
    fn widen_with_range(&mut self, i: usize, a: f32, b: f32) {
        if a < self.lo[i] {
            self.lo[i] = a;
        }
        if b > self.hi[i] {
            self.hi[i] = b;
        }
    }

    /// Sets the kind of the cells of `block` (not [`LEAF`]); a [`LEAF`] cell overwritten gets its
    /// value as both ends of its bound, as if it had been kept.
    fn set_block(&mut self, block: &IBox, kind: u8) {
        let g = self.cells;
        for z in block.lo[2]..block.hi[2] {
            for y in block.lo[1]..block.hi[1] {
                let dst = g.linear_index([block.lo[0], y, z]);
                let w = (block.hi[0] - block.lo[0]).max(0) as usize;
                self.set_kinds(dst..dst + w, kind);
            }
        }
    }

    /// [`Self::set_block`] for the cells of index range `cells`.
    fn set_kinds(&mut self, cells: std::ops::Range<usize>, kind: u8) {
        for i in cells {
            if self.kind[i] == LEAF {
                self.hi[i] = self.lo[i];
            }
            self.kind[i] = kind;
        }
    }

    /// Index of cell `c` (absolute level index, inside [`Self::cells`]).
    #[inline]
    pub fn index(&self, c: [i64; 3]) -> usize {
        self.cells.linear_index(c)
    }

    /// The kind of the cell at index `i`.
    #[inline]
    pub fn kind(&self, i: usize) -> u8 {
        self.kind[i]
    }

    /// The bound of the cell at index `i`: the smallest and largest value of the leaf cells of
    /// level `L` or finer inside it; `(+inf, -inf)` when there are none.
    #[inline]
    pub fn bound(&self, i: usize) -> (f32, f32) {
        if self.kind[i] == LEAF {
            (self.lo[i], self.lo[i])
        } else {
            (self.lo[i], self.hi[i])
        }
    }

    /// Computes every cell's code for `iso` from its bound and kind, keeping its pending flag.
    pub fn classify(&mut self, iso: f32) {
        if self.all_leaf {
            // Every cell a leaf cell, none pending: the code of its value alone.
            self.codes.clear();
            self.codes.extend(self.lo.iter().map(|&v| code(v, v, iso)));
            return;
        }
        let cells = self.lo.iter().zip(&self.hi).zip(&self.kind);
        for (c, ((&lo, &hi), &kind)) in self.codes.iter_mut().zip(cells) {
            let not_leaf = kind != LEAF;
            let hi = if not_leaf { hi } else { lo };
            *c = code(lo, hi, iso) | u8::from(not_leaf) << 2 | *c & PENDING;
        }
    }

    /// True when some cell lies in a coarser leaf cell whose octants are not yet in its bound.
    #[inline]
    pub fn has_pending(&self) -> bool {
        self.pending_left > 0
    }

    /// True when at least `enough` cells of `block` (at most 64 cells of a coarser level, each
    /// `r` cells of this level per axis) hold a pending cell of box `within`.
    pub fn pending_over(&self, block: &IBox, r: [i64; 3], within: &IBox, enough: u32) -> bool {
        let mine = IBox::new(axes(|a| block.lo[a] * r[a]), axes(|a| block.hi[a] * r[a]));
        let b = mine.intersect(&self.cells).intersect(within);
        // The cells of `block` over `b`, before any is counted.
        let over = IBox::new(
            axes(|a| div_floor(b.lo[a], r[a])),
            axes(|a| div_floor(b.hi[a] - 1, r[a]) + 1),
        );
        if b.is_empty() || over.num_cells().is_none_or(|n| n < u64::from(enough)) {
            return false;
        }
        let (g, ey, w) = (self.cells, self.cells.extent()[1], b.extent()[0] as usize);
        let mut bits = 0u64;
        for z in b.lo[2]..b.hi[2] {
            for y in b.lo[1]..b.hi[1] {
                let row = ((y - g.lo[1]) + (z - g.lo[2]) * ey) as usize;
                let flagged = self.pending_rows.get(row / 64);
                if flagged.is_none_or(|word| word >> (row % 64) & 1 == 0) {
                    continue;
                }
                let first = self.index([b.lo[0], y, z]);
                let row = block.linear_index([block.lo[0], div_floor(y, r[1]), div_floor(z, r[2])]);
                for (x, &c) in (b.lo[0]..).zip(&self.codes[first..first + w]) {
                    if c & PENDING != 0 {
                        bits |= 1 << (row + (div_floor(x, r[0]) - block.lo[0]) as usize);
                    }
                }
            }
        }
        bits.count_ones() >= enough
    }

    /// False when no cell of box `b` (inside [`Self::cells`]) is pending: none of its rows
    /// had a cell flagged pending by the fill. The rows of each plane of `b` are one run of
    /// bits.
    pub fn may_pend_in(&self, b: &IBox) -> bool {
        let (g, ey) = (self.cells, self.cells.extent()[1]);
        let words = &self.pending_rows;
        (b.lo[2]..b.hi[2]).any(|z| {
            let first = ((b.lo[1] - g.lo[1]) + (z - g.lo[2]) * ey) as usize;
            let end = first + (b.hi[1] - b.lo[1]).max(0) as usize;
            (first..end).any(|r| words.get(r / 64).is_some_and(|w| w >> (r % 64) & 1 == 1))
        })
    }

    /// The codes of [`Self::classify`].
    #[inline]
    pub fn codes(&self) -> &[u8] {
        &self.codes
    }

    /// Folds `lo..=hi` into the bound of the cell at index `i`, clears its pending flag and
    /// updates its code for `iso`.
    #[inline(always)]
    pub fn settle_coarse(&mut self, i: usize, (lo, hi): (f32, f32), iso: f32) {
        let (was_lo, was_hi, c) = (self.lo[i], self.hi[i], self.codes[i]);
        if c & PENDING != 0 {
            self.pending_left -= 1;
            if was_lo <= was_hi {
                self.mark_mixed(i);
            }
        }
        let (lo, hi) = (was_lo.min(lo), was_hi.max(hi));
        self.lo[i] = lo;
        self.hi[i] = hi;
        self.codes[i] = c & NOT_LEAF | code(lo, hi, iso);
    }

    /// Flags the cell at index `i` [`Self::mixed`] (rare: kept out of the settling's code).
    #[cold]
    #[inline(never)]
    fn mark_mixed(&mut self, i: usize) {
        self.mixed.resize(self.kind.len(), false);
        self.mixed[i] = true;
    }

    /// Settles, as [`Self::settle_coarse`] with `iso`, the pending cells of each block of cells
    /// the last fill found inside a coarser kd leaf for which `bound_of(leaf, level)` gives a
    /// bound (the block's cells lie inside that leaf).
    pub fn settle_coarser_blocks(
        &mut self,
        iso: f32,
        mut bound_of: impl FnMut(u32, u32) -> Option<(f32, f32)>,
    ) {
        for k in 0..self.coarser_blocks.len() {
            if self.pending_left == 0 {
                break;
            }
            let (block, leaf, level) = self.coarser_blocks[k];
            if let Some(bound) = bound_of(leaf, level) {
                self.settle_pending_in(&block, bound, iso);
            }
        }
    }

    /// Settles every pending cell of box `b` (inside [`Self::cells`]) with `bound`, as
    /// [`Self::settle_coarse`] with `iso`.
    pub fn settle_pending_in(&mut self, b: &IBox, bound: (f32, f32), iso: f32) {
        let w = b.extent()[0].max(0) as usize;
        for z in b.lo[2]..b.hi[2] {
            for y in b.lo[1]..b.hi[1] {
                let row = self.index([b.lo[0], y, z]);
                for i in row..row + w {
                    if self.codes[i] & PENDING != 0 {
                        self.settle_coarse(i, bound, iso);
                    }
                }
            }
        }
    }

    /// True when the bound of the cell at index `i` may be narrowed to its coarse octants'
    /// ([`super::cull::coarse_cell_bound`]): a settled cell inside a coarser leaf cell, with no
    /// bound of its own from the fill.
    #[inline]
    pub fn narrows(&self, i: usize) -> bool {
        self.kind[i] == COARSER
            && self.codes[i] & PENDING == 0
            && !self.mixed.get(i).copied().unwrap_or(false)
    }

    /// The bound of the cell at index `i` from its coarse octants alone, once given
    /// ([`Self::set_exact`]).
    #[inline]
    pub fn exact(&self, i: usize) -> Option<(f32, f32)> {
        let &(lo, hi) = self.exact.get(i)?;
        (!lo.is_nan()).then_some((lo, hi))
    }

    /// Keeps the bound of the cell at index `i` from its coarse octants alone.
    #[inline]
    pub fn set_exact(&mut self, i: usize, bound: (f32, f32)) {
        self.exact.resize(self.kind.len(), (f32::NAN, f32::NAN));
        self.exact[i] = bound;
    }

    /// The code for `iso` ([`ABOVE`], [`BELOW`]) of the values a vertex can take through the
    /// cell at index `i`: its bound's, narrowed to the coarse octants' when known; both bits
    /// while it is pending.
    #[inline]
    pub fn value_code(&self, i: usize, iso: f32) -> u8 {
        if self.codes[i] & PENDING != 0 {
            return ABOVE | BELOW;
        }
        match self.exact(i) {
            Some((lo, hi)) if self.narrows(i) => code(lo, hi, iso),
            _ => self.codes[i] & (ABOVE | BELOW),
        }
    }

    /// The cell (absolute level index) at index `i`.
    pub fn cell_at(&self, i: usize) -> [i64; 3] {
        let e = self.cells.extent();
        let i = i as i64;
        let d = [i % e[0], i / e[0] % e[1], i / (e[0] * e[1])];
        axes(|a| self.cells.lo[a] + d[a])
    }

    /// The value of the cell at index `i` (meaningful for [`LEAF`] cells).
    #[inline]
    pub fn value(&self, i: usize) -> f32 {
        self.lo[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pending cell's code keeps its [`PENDING`] bit through [`Neighbourhood::classify`] for
    /// any isovalue, and loses it, with the count of pending cells, when it is settled.
    #[test]
    fn classify_keeps_the_pending_bit_until_settled() {
        let mut hood = Neighbourhood {
            cells: IBox::new([0, 0, 0], [2, 1, 1]),
            ..Neighbourhood::default()
        };
        hood.kind = vec![LEAF, UNCOVERED];
        hood.lo = vec![1.0, f32::INFINITY];
        hood.hi = vec![f32::NEG_INFINITY; 2];
        hood.codes = vec![0, 0];
        hood.pending_rows = vec![0];
        hood.set_coarser_block(&IBox::new([1, 0, 0], [2, 1, 1]));
        hood.set_coarser_block(&IBox::new([1, 0, 0], [2, 1, 1]));
        assert_eq!(hood.pending_left, 1, "a cell flagged twice counts once");
        hood.finish_fill();
        for iso in [0.5, 5.0] {
            hood.classify(iso);
            assert_eq!(hood.codes()[1], NOT_LEAF | PENDING, "iso {iso}");
            assert_eq!(hood.codes()[0] & (NOT_LEAF | PENDING), 0, "iso {iso}");
        }
        hood.settle_coarse(1, (2.0, 3.0), 2.5);
        assert!(!hood.has_pending());
        assert_eq!(hood.codes()[1], NOT_LEAF | ABOVE | BELOW);
        hood.classify(4.0);
        assert_eq!(hood.codes()[1], NOT_LEAF | BELOW);
    }

    /// [`Neighbourhood::mark_near_boundary`] marks exactly the cells with a non-[`LEAF`] cell
    /// among the up to 27 around them, on boxes of every shape from 1 to 5 cells per axis.
    #[test]
    fn near_boundary_is_the_27_cell_dilation() {
        let mut seed = 12345u64;
        for (ex, ey, ez) in
            (1..=5).flat_map(|x| (1..=5).flat_map(move |y| (1..=5).map(move |z| (x, y, z))))
        {
            let cells = IBox::new([3, -2, 7], [3 + ex, -2 + ey, 7 + ez]);
            let n = (ex * ey * ez) as usize;
            let mut hood = Neighbourhood {
                cells,
                ..Neighbourhood::default()
            };
            hood.kind = (0..n)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    if seed >> 60 == 0 {
                        COARSER
                    } else {
                        LEAF
                    }
                })
                .collect();
            hood.mark_near_boundary();
            for i in 0..n {
                let c = hood.cell_at(i);
                let near = (0..27).any(|k| {
                    let d = [k % 3 - 1, k / 3 % 3 - 1, k / 9 - 1];
                    let q = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
                    cells.contains_cell(q) && hood.kind[hood.index(q)] != LEAF
                });
                assert_eq!(
                    hood.near_boundary[i], near,
                    "box {ex}x{ey}x{ez}, cell {c:?}"
                );
            }
        }
    }
}
