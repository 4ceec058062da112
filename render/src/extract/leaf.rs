//! Extraction inside one leaf: the merged dual cells and the boundary octants it owns.
//!
//! A leaf owns a voxel when it holds the voxel's lowest finest-level cell (the finest cell
//! whose half-open box holds the voxel's lower corner), so every voxel belongs to exactly one
//! leaf. A dual cell of level `L` is merged (one voxel for its eight octants) when its eight
//! cells are all leaf cells of level `L`; every other octant of the leaf's cells is a voxel of
//! its own, with corners from [`Sampler::corners`], unless the bounds of the cells around it
//! (and the corners already known) show it cannot straddle the isovalue: then its other corners
//! are never evaluated.

use super::blocks::level_box;
use crate::error::Result;
use amr_format::IBox;

use super::band::AroundMemo;
use super::cell_tiles::CellTiles;
use super::cull::{
    around_offsets, cell_may_hold, coarse_cell_bound, settle_by_leaf_ranges, settle_pending, Shared,
};
use super::local::{code, div_floor, Neighbourhood, ABOVE, BELOW, LEAF, NOT_LEAF, PENDING};
use super::plain::PlainCodes;
use super::refs::{make_ref, LocalVoxel};
use super::small::MAX_CELLS;
use super::vertices::LeafVertices;
use crate::reconstruct::grid::axes;
use crate::reconstruct::interp::{avg8, corners_straddle};
use crate::reconstruct::{LeafCell, Sampler, VertexMemo};

/// Per-thread scratch of [`extract_leaf`].
pub struct Scratch<'s> {
    /// The leaf's classified neighbourhood.
    pub hood: Neighbourhood,
    /// The codes of a neighbourhood of leaf cells of the leaf's level alone.
    pub plain: PlainCodes,
    /// Vertex values met while stitching to coarser levels.
    pub memo: VertexMemo,
    /// The leaf's boundary vertex values.
    pub verts: LeafVertices,
    /// One row of merged-dual-cell codes.
    pub rows: Vec<u8>,
    /// The block ranges, the leaf tree (for region queries) and the bounds of coarser
    /// neighbours.
    pub shared: Shared<'s>,
    /// The bounds around coarse cells this thread asked for last.
    pub near: AroundMemo,
    /// The settled cells of small leaves' neighbourhoods, a tile at a time, when the file's
    /// leaves are small ([`CellTiles::pays`]).
    pub tiles: Option<&'s CellTiles>,
}

impl<'s> Scratch<'s> {
    /// Empty scratch for extracting, reading the tables of `shared` and the cell tiles `tiles`.
    pub fn new(shared: Shared<'s>, tiles: Option<&'s CellTiles>) -> Self {
        Self {
            hood: Neighbourhood::default(),
            plain: PlainCodes::default(),
            memo: VertexMemo::default().with_octants_together(),
            verts: LeafVertices::default(),
            rows: Vec::new(),
            shared,
            near: AroundMemo::default(),
            tiles,
        }
    }
}

/// Counts one leaf contributes to the statistics.
#[derive(Clone, Copy, Debug, Default)]
pub struct LeafCounts {
    /// Voxels whose corners were evaluated.
    pub evaluated: u64,
    /// 1 when the leaf's tight range excluded the isovalue, so nothing was evaluated.
    pub skipped: u64,
    /// Of those, boundary octants (the rest are merged dual cells).
    pub boundary: u64,
    /// Boundary cells skipped because their neighbourhood's bound excludes the isovalue.
    pub culled: u64,
    /// Parts of the leaf skipped because their block bound excludes the isovalue
    /// ([`super::parts`]).
    pub parts_skipped: u64,
    /// Boundary octants left unevaluated because the values of some corners and the bounds
    /// around the others exclude the isovalue ([`boundary_corners`]).
    pub octants_culled: u64,
}

impl LeafCounts {
    /// Adds `other`'s counts to these.
    pub fn add(&mut self, other: &Self) {
        self.evaluated += other.evaluated;
        self.skipped += other.skipped;
        self.boundary += other.boundary;
        self.culled += other.culled;
        self.parts_skipped += other.parts_skipped;
        self.octants_culled += other.octants_culled;
    }
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
    /// The level-`level` cells (absolute indices) overlapping it.
    pub cells: IBox,
    /// The level-`level` cells overlapping the whole leaf: local cell indices in references
    /// count these (equal to `cells` unless this frame is a part of the leaf).
    pub refs: IBox,
}

impl LeafFrame {
    /// The frame of `leaf`, `None` when no brick covers it.
    pub fn new<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, leaf: u32) -> Option<Self> {
        let (brick, level) = sampler.leaf_top(leaf)?;
        let finest = sampler.file().tree().leaf_box(leaf);
        let cells = level_box(sampler.grid(), level, &finest);
        Some(Self {
            leaf,
            level,
            brick,
            finest,
            cells,
            refs: cells,
        })
    }

    /// The part of this frame inside finest-level box `finest` (a box inside the leaf): it
    /// owns the voxels of the leaf whose lower corner lies in it, referenced as the leaf's.
    pub fn part<D: AsRef<[u8]>>(&self, sampler: &Sampler<'_, D>, finest: IBox) -> Self {
        Self {
            finest,
            cells: level_box(sampler.grid(), self.level, &finest),
            ..*self
        }
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
    scratch: &mut Scratch<'_>,
    out: &mut Vec<u64>,
) -> Result<LeafCounts> {
    let Scratch {
        hood,
        plain: codes_of,
        memo,
        verts,
        rows,
        shared,
        near,
        tiles,
    } = scratch;
    let mut counts = LeafCounts::default();
    let start = out.len();
    let level = frame.level;
    let g = frame.cells.grow([1; 3]);
    let small = frame.cells.extent().iter().all(|&e| e <= MAX_CELLS);
    let held = hood.holds(level, &g);
    let tiled = tiles.is_some() && small;
    if let (Some(tiles), true, false) = (tiles, small, held) {
        tiles.fill((sampler, *shared), hood, (memo, near), level, g)?;
    }
    // A large leaf's neighbourhood of leaf cells of this level alone is coded straight from
    // the bricks, unless the cells are held already (or come from the tiles). Small leaves'
    // neighbourhoods gather many leaves' short rows, which the fill copies faster.
    let large = frame.refs.extent().iter().any(|&e| e > MAX_CELLS);
    let plain =
        large && !held && !tiled && codes_of.code((sampler, shared.leaves), level, g, iso)?;
    let (codes, cells) = if plain {
        (codes_of.codes(), codes_of.cells)
    } else {
        hood.fill((sampler, shared.leaves), level, &frame.cells)?;
        hood.classify(iso);
        settle_by_leaf_ranges(sampler, shared.tight, hood, iso);
        (hood.codes(), hood.cells)
    };
    let grid = sampler.grid();
    let s = grid.scale(level);
    let o = grid.offset();

    // Merged dual cells: the lowest cell c0 is owned when its centre's finest cell is ours.
    let first = [0, 1, 2].map(|a| -(-(frame.finest.lo[a] + o[a] - s[a] / 2)).div_euclid(s[a]));
    let last = [0, 1, 2].map(|a| (frame.finest.hi[a] - 1 + o[a] - s[a] / 2).div_euclid(s[a]));
    let e = cells.extent();
    let step = [1usize, e[0] as usize, (e[0] * e[1]) as usize];
    let offsets: [usize; 8] = std::array::from_fn(|n| (0..3).map(|a| (n >> a & 1) * step[a]).sum());
    let width = (last[0] - first[0] + 1).max(0) as usize;
    let any_duals = width > 0 && first[1] <= last[1] && first[2] <= last[2];
    if any_duals {
        let dual_rows = ((last[1] - first[1] + 1) * (last[2] - first[2] + 1)) as usize;
        let lowest = cells.linear_index(first);
        let span = cells.linear_index([last[0] + 1, last[1] + 1, last[2] + 1]) + 1 - lowest;
        let scan = DualScan {
            frame,
            first,
            last,
            width,
        };
        if span <= FLAT_SPAN * width * dual_rows || span <= FLAT_CELLS {
            let duals = dual_codes_flat(&codes[lowest..lowest + span], step, rows);
            scan.emit(
                |[y, z]| cells.linear_index([first[0], y, z]) - lowest,
                duals,
                &mut counts,
                out,
            );
        } else {
            let duals = dual_codes_by_row(&cells, codes, (first, last, width), step, rows);
            let row = |[y, z]: [i64; 2]| {
                ((z - first[2]) * (last[1] - first[1] + 1) + (y - first[1])) as usize * width
            };
            scan.emit(row, duals, &mut counts, out);
        }
    }

    // Octants that touch a level boundary, the domain boundary or an uncovered region.
    if !plain && !hood.all_leaf {
        // The vertex grid is prepared when a first cell survives culling; the locator table once
        // enough queries ask for it.
        let mut verts_started = false;
        let lowest = grid.centre(level, frame.cells.lo);
        let c = &frame.cells;
        let around = around_offsets(step[1], step[2]);
        for z in c.lo[2]..c.hi[2] {
            for y in c.lo[1]..c.hi[1] {
                let row = hood.index([c.lo[0], y, z]);
                let width = c.extent()[0] as usize;
                if !hood.near_boundary[row..row + width].contains(&true) {
                    continue;
                }
                for (k, x) in (c.lo[0]..c.hi[0]).enumerate() {
                    let cell = [x, y, z];
                    let i = row + k;
                    if !hood.near_boundary[i] {
                        continue;
                    }
                    if !cell_may_hold((sampler, *shared), hood, (memo, near), (i, &around), iso)? {
                        counts.culled += 1;
                        continue;
                    }
                    if !verts_started {
                        verts.start(&frame.cells, axes(|a| lowest[a] - s[a]), s);
                        verts_started = true;
                    }
                    let centre = grid.centre(level, cell);
                    let local = axes(|a| (cell[a] - c.lo[a]) as usize);
                    for octant in 0..8u8 {
                        let lo = axes(|a| {
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
                        // The octant's vertices lie in its closure, so the cells around them
                        // are among the eight around its outer corner: the octant is skipped
                        // when those are all leaf cells of the level (a merged dual cell), or
                        // when their bounds, settled, exclude `iso` ([`super::cull`]'s argument
                        // for these eight cells).
                        let block = |hood: &Neighbourhood| {
                            offsets.iter().fold(0u8, |m, &d| m | hood.codes()[low + d])
                        };
                        let mut m = block(hood);
                        if m & NOT_LEAF == 0 {
                            continue;
                        }
                        if m & PENDING != 0 {
                            for d in offsets {
                                settle_pending(
                                    (sampler, *shared),
                                    hood,
                                    (memo, near),
                                    low + d,
                                    iso,
                                )?;
                            }
                            m = block(hood);
                        }
                        if m & (ABOVE | BELOW) != ABOVE | BELOW {
                            counts.octants_culled += 1;
                            continue;
                        }
                        // Again with the cells inside coarser leaf cells bounded by the corners
                        // of the coarse octants over them alone: dearer, and tighter.
                        let cells = offsets.map(|d| low + d);
                        if !narrowed_may_straddle(sampler, hood, memo, (level, iso), &cells)? {
                            counts.octants_culled += 1;
                            continue;
                        }
                        let v = match boundary_corners(
                            sampler,
                            hood,
                            (memo, verts),
                            (level, iso),
                            i,
                            local,
                            lo,
                            octant,
                        )? {
                            Corners::Values(v) => v,
                            Corners::Uncovered => {
                                counts.evaluated += 1;
                                counts.boundary += 1;
                                continue;
                            }
                            Corners::Culled => {
                                counts.octants_culled += 1;
                                continue;
                            }
                        };
                        counts.evaluated += 1;
                        counts.boundary += 1;
                        if corners_straddle(&v, iso) {
                            let local = frame.refs.linear_index(cell) as u32;
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

/// False when the codes of neighbourhood cells `cells` (the eight around a boundary octant's
/// outer corner, none pending) exclude `iso` once those inside coarser leaf cells are narrowed
/// to their coarse octants' corners ([`Neighbourhood::narrows`], `cull::coarse_cell_bound`).
/// They are narrowed one at a time, first those whose codes could give the bit the others lack,
/// until the answer is known; narrowing only drops bits, so the answer is that of all cells
/// narrowed, whichever the neighbourhood had narrowed before.
#[inline(always)]
fn narrowed_may_straddle<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    hood: &mut Neighbourhood,
    memo: &mut VertexMemo,
    (level, iso): (u32, f32),
    cells: &[usize; 8],
) -> Result<bool> {
    let both = ABOVE | BELOW;
    // The codes of the cells narrowed or not to be narrowed, and a bit per cell left.
    let mut fixed = 0u8;
    let mut open = 0u8;
    for (k, &j) in cells.iter().enumerate() {
        if hood.narrows(j) && hood.exact(j).is_none() {
            open |= 1 << k;
        } else {
            fixed |= hood.value_code(j, iso);
        }
    }
    loop {
        let code_of = |k: usize| hood.value_code(cells[k], iso);
        let rest = (0..8).fold(0u8, |u, k| {
            u | if open >> k & 1 == 1 { code_of(k) } else { 0 }
        });
        if (fixed | rest) & both != both {
            return Ok(false);
        }
        if fixed & both == both || open == 0 {
            return Ok(true);
        }
        let k = next_deciding(open, fixed, code_of);
        open &= !(1 << k);
        narrow(sampler, hood, memo, level, cells[k])?;
        fixed |= hood.value_code(cells[k], iso);
    }
}

/// Of the items whose bits are set in `open` (at least one), the first whose code
/// (`code_of`) could give a bit ([`ABOVE`], [`BELOW`]) that `known` lacks, else the first: asked
/// first, an item that does not give it settles the decision sooner.
#[inline(always)]
fn next_deciding(open: u8, known: u8, code_of: impl Fn(usize) -> u8) -> usize {
    let missing = (ABOVE | BELOW) & !known;
    let wanted = (0..8).fold(0u8, |w, k| {
        w | u8::from(open >> k & 1 == 1 && code_of(k) & missing != 0) << k
    });
    if wanted != 0 { wanted } else { open }.trailing_zeros() as usize
}

/// Narrows neighbourhood cell `j` to its coarse octants' bound
/// ([`super::cull::coarse_cell_bound`]) when it may be narrowed and is not yet.
#[inline(always)]
fn narrow<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    hood: &mut Neighbourhood,
    memo: &mut VertexMemo,
    level: u32,
    j: usize,
) -> Result<()> {
    if hood.narrows(j) && hood.exact(j).is_none() {
        let bound = coarse_cell_bound((sampler, memo), level, hood.cell_at(j))?;
        hood.set_exact(j, bound);
    }
    Ok(())
}

/// What [`boundary_corners`] finds for an octant.
enum Corners {
    /// The eight corner values.
    Values([f32; 8]),
    /// A cell touching a corner is not covered by any brick: the octant is no voxel.
    Uncovered,
    /// Some corners were left unevaluated: the values of the others and the bounds of the cells
    /// around the rest exclude the isovalue, so the octant is not active.
    Culled,
}

/// The corner values of octant `octant` of the leaf-cell at neighbourhood index `i` (local
/// cell position `local` in the leaf's box), whose lower corner is doubled point `lo`:
/// [`Sampler::corners`], reading the eight cells around a vertex from the neighbourhood when
/// they are all leaf cells of the octant's level (the same values in the same order), and asking
/// the sampler otherwise. Every vertex is computed once per leaf, and those the sampler gives
/// are kept for the leaves after it ([`LeafVertices::kept`]).
///
/// The vertices the sampler would give are asked for last, and only while the octant may still
/// straddle `iso`: such a vertex's value lies in the union of the bounds of the level-`L` cells
/// around it (the argument of [`super::cull`], for the cells around one vertex instead of the 27
/// around a cell), so when the values known and those bounds exclude `iso`, the octant is
/// [`Corners::Culled`].
#[allow(clippy::too_many_arguments)]
fn boundary_corners<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    hood: &mut Neighbourhood,
    (memo, verts): (&mut VertexMemo, &mut LeafVertices),
    (level, iso): (u32, f32),
    i: usize,
    local: [usize; 3],
    lo: [i64; 3],
    octant: u8,
) -> Result<Corners> {
    let e = hood.cells.extent();
    let step = [1isize, e[0] as isize, (e[0] * e[1]) as isize];
    let s = sampler.grid().scale(level);
    // The neighbourhood cells around corner `n` (not the cell's centre), numbered as
    // [`Sampler::around`] numbers a vertex's sides: on an axis where the corner lies on the
    // octant's outer face, the side beyond it is the neighbour that way, else the cell itself.
    let around_of = |n: usize| -> [usize; 8] {
        let d = axes(|a| {
            let up = octant >> a & 1 == 1;
            if (n >> a & 1 == 1) != up {
                [0, 0]
            } else if up {
                [0, step[a]]
            } else {
                [-step[a], 0]
            }
        });
        std::array::from_fn(|m| {
            (i as isize + d[0][m & 1] + d[1][m >> 1 & 1] + d[2][m >> 2 & 1]) as usize
        })
    };
    let centre = usize::from(!octant & 7);
    let mut out = [0f32; 8];
    // The union of the codes of the values known, and per other corner: its vertex slot and the
    // code of the bounds of the cells around it.
    let mut known = 0u8;
    let mut other = [(0usize, 0u8); 8];
    let mut left = 0u8;
    for (n, slot) in out.iter_mut().enumerate() {
        let value = if n == centre {
            Some(hood.value(i))
        } else {
            let k = axes(|a| 2 * local[a] + (octant as usize >> a & 1) + (n >> a & 1));
            let vi = verts.slot_at(k);
            match verts.get_slot(vi) {
                Some(value) => value,
                None => {
                    let around = around_of(n);
                    if !around.iter().all(|&j| hood.kind(j) == LEAF) {
                        let mut bound = 0u8;
                        for &j in &around {
                            narrow(sampler, hood, memo, level, j)?;
                            bound |= hood.value_code(j, iso);
                        }
                        other[n] = (vi, bound);
                        left |= 1 << n;
                        continue;
                    }
                    let value = Some(avg8(&around.map(|j| hood.value(j))));
                    verts.put_slot(vi, value);
                    value
                }
            }
        };
        match value {
            Some(x) => {
                *slot = x;
                known |= code(x, x, iso);
            }
            None => return Ok(Corners::Uncovered),
        }
    }
    // The other corners in order, each while the values so far and the bounds of those left may
    // straddle `iso`. The leaf's slots are filled in the same order whatever the thread, so the
    // decision is too; values kept from other leaves, which depend on what the thread did
    // before, only spare computing a value.
    while left != 0 {
        let bounds = (0..8).fold(known, |u, n| {
            u | if left >> n & 1 == 1 { other[n].1 } else { 0 }
        });
        if bounds & (ABOVE | BELOW) != ABOVE | BELOW {
            return Ok(Corners::Culled);
        }
        let n = next_deciding(left, known, |n| other[n].1);
        left &= !(1 << n);
        let (vi, _) = other[n];
        let v = axes(|a| lo[a] + (n >> a & 1) as i64 * s[a]);
        let value = match verts.kept(v, level) {
            Some(kept) => kept,
            None => {
                let value = vertex_value(sampler, hood, memo, (v, level), &around_of(n))?;
                verts.keep(v, level, value);
                value
            }
        };
        verts.put_slot(vi, value);
        match value {
            Some(x) => {
                out[n] = x;
                known |= code(x, x, iso);
            }
            None => return Ok(Corners::Uncovered),
        }
    }
    Ok(Corners::Values(out))
}

/// [`Sampler::vertex_value_unmemoized_in`] at vertex `v` seen from level `level`, whose eight
/// sides (as [`Sampler::around`] numbers them) lie in the neighbourhood cells `around`: the
/// same value from the same cells, but a side in a [`LEAF`] cell is that cell (of level
/// `level`, its index from the side's finest cell, its value the neighbourhood's) rather than
/// located again. Such a side's kd-tree leaf and brick are not known (they are `u32::MAX`):
/// [`Sampler::vertex_value_from_in`] reads a side whole only when it is of the coarsest level
/// there, coarser than `level`, and otherwise only its level and value.
fn vertex_value<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    hood: &Neighbourhood,
    memo: &mut VertexMemo,
    (v, level): ([i64; 3], u32),
    around: &[usize; 8],
) -> Result<Option<f32>> {
    let grid = sampler.grid();
    // On the axes of `same` the two nudges coincide: there side `n` repeats side `n` without
    // the axis's bit.
    let (lo, hi, same) = sampler.nudges(v);
    let mut cells = [LeafCell {
        leaf: u32::MAX,
        brick: u32::MAX,
        level,
        cell: [0; 3],
        value: 0.0,
    }; 8];
    let (s, o) = (grid.scale(level), grid.offset());
    // The kd-tree leaf of the side located last: the next sides outside the neighbourhood
    // often lie in it.
    let mut last = None;
    for (n, &j) in around.iter().enumerate() {
        let m = n & !same;
        if m != n {
            cells[n] = cells[m];
            continue;
        }
        let f = axes(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
        if hood.kind(j) == LEAF {
            cells[n].cell = axes(|a| div_floor(f[a] + o[a], s[a]));
            cells[n].value = hood.value(j);
        } else {
            match sampler.locate_near(f, memo, &mut last)? {
                Some(c) => cells[n] = c,
                None => return Ok(None),
            }
        }
    }
    sampler.vertex_value_from_in(sampler, v, level, &cells, memo)
}

/// The merged dual cells are coded over the whole stretch of the neighbourhood's cells from the
/// first dual cell's lowest cell to the last one's highest ([`dual_codes_flat`]) when that
/// stretch holds at most this many cells per dual cell; otherwise row by row
/// ([`dual_codes_by_row`]), as for a small leaf inside a neighbourhood filled for a run of
/// leaves.
const FLAT_SPAN: usize = 4;

/// A stretch of at most this many cells is coded whole ([`dual_codes_flat`]) whatever its
/// share of dual cells: a small leaf's few rows cost more one by one, each with its setup, than
/// three vectorized passes over its neighbourhood.
const FLAT_CELLS: usize = 512;

/// The code of every dual cell whose lowest cell lies in `codes` (cell codes, of a stretch of
/// the neighbourhood whose rows and slabs are `step[1]` and `step[2]` cells apart), at the
/// position of that lowest cell: the OR of its eight cells' codes, taken along x, then y, then
/// z, each over the whole stretch at once (long runs of bytes, which vectorize). Positions whose
/// eight cells are not all in the stretch hold no meaningful code (whatever `scratch`, which
/// holds the result, held before).
fn dual_codes_flat<'r>(codes: &[u8], step: [usize; 3], scratch: &'r mut Vec<u8>) -> &'r [u8] {
    let n = codes.len();
    // Only grown, never cleared: every position read is written first.
    if scratch.len() < 2 * n {
        scratch.resize(2 * n, 0);
    }
    let (a, b) = scratch[..2 * n].split_at_mut(n);
    let or_shifted = |dst: &mut [u8], src: &[u8], shift: usize| {
        let len = n.saturating_sub(shift);
        for ((d, &x), &y) in dst[..len].iter_mut().zip(&src[..len]).zip(&src[shift..]) {
            *d = x | y;
        }
    };
    or_shifted(a, codes, 1);
    or_shifted(b, a, step[1]);
    or_shifted(a, b, step[2]);
    a
}

/// The codes of the dual cells `first..=last` (lowest cells; `width` per row), row after row
/// (z, then y), each row `width` codes long: a dual cell's code is the OR of its eight cells',
/// ORed along z, then y, then x, each pair of rows once (the z-pairs of a row serve the two
/// dual rows beside it). `scratch` holds the result.
fn dual_codes_by_row<'r>(
    cells: &IBox,
    codes: &[u8],
    (first, last, width): ([i64; 3], [i64; 3], usize),
    step: [usize; 3],
    scratch: &'r mut Vec<u8>,
) -> &'r [u8] {
    let w1 = width + 1;
    let dual_rows = ((last[1] - first[1] + 1) * (last[2] - first[2] + 1)) as usize;
    scratch.clear();
    scratch.resize(3 * w1 + dual_rows * width, 0);
    let (work, out) = scratch.split_at_mut(3 * w1);
    let (mut prev, rest) = work.split_at_mut(w1);
    let (mut cur, yz) = rest.split_at_mut(w1);
    let or_rows = |dst: &mut [u8], a: &[u8], b: &[u8]| {
        for ((d, &x), &y) in dst.iter_mut().zip(a).zip(b) {
            *d = x | y;
        }
    };
    let mut rows = out.chunks_exact_mut(width.max(1));
    for z in first[2]..=last[2] {
        let r0 = cells.linear_index([first[0], first[1], z]);
        or_rows(
            prev,
            &codes[r0..r0 + w1],
            &codes[r0 + step[2]..r0 + step[2] + w1],
        );
        for y in first[1]..=last[1] {
            let r = cells.linear_index([first[0], y + 1, z]);
            or_rows(
                cur,
                &codes[r..r + w1],
                &codes[r + step[2]..r + step[2] + w1],
            );
            or_rows(yz, prev, cur);
            if let Some(row) = rows.next() {
                or_rows(row, &yz[..width], &yz[1..]);
            }
            std::mem::swap(&mut prev, &mut cur);
        }
    }
    out
}

/// The merged dual cells of a frame, `first..=last` (lowest cells), `width` per row.
struct DualScan<'a> {
    frame: &'a LeafFrame,
    first: [i64; 3],
    last: [i64; 3],
    width: usize,
}

impl DualScan<'_> {
    /// Counts the dual cells of leaf cells whose codes `duals` holds (the row of `[y, z]`
    /// starting at `row([y, z])`) and pushes the refs of the active ones to `out`, in row order.
    fn emit(
        &self,
        row: impl Fn([i64; 2]) -> usize,
        duals: &[u8],
        counts: &mut LeafCounts,
        out: &mut Vec<u64>,
    ) {
        let (first, last, width) = (self.first, self.last, self.width);
        for z in first[2]..=last[2] {
            for y in first[1]..=last[1] {
                let r = row([y, z]);
                let masks = &duals[r..r + width];
                // Cells along x are numbered one after another: the ref of the row's k-th dual
                // cell is the first one's plus k.
                let cell = self.frame.refs.linear_index([first[0], y, z]) as u32;
                let first_ref = make_ref(self.frame.leaf, LocalVoxel::Dual { cell });
                let mut chunks = masks.chunks_exact(16);
                for (c, chunk) in (&mut chunks).enumerate() {
                    let (leaf, mut on) = sixteen_bits(chunk);
                    counts.evaluated += u64::from(leaf.count_ones());
                    while on != 0 {
                        let k = c * 16 + on.trailing_zeros() as usize;
                        on &= on - 1;
                        out.push(first_ref + k as u64);
                    }
                }
                let rest = chunks.remainder();
                let done = width - rest.len();
                if rest.is_empty() {
                    continue;
                }
                // Short rows (small leaves) are all remainder: sixteen codes read at once where
                // `duals` holds them, the bits past the row's end dropped.
                if let Some(sixteen) = duals.get(r + done..r + done + 16) {
                    let (leaf, on) = sixteen_bits(sixteen);
                    let row_bits = (1u32 << rest.len()) - 1;
                    counts.evaluated += u64::from((leaf & row_bits).count_ones());
                    let mut on = on & row_bits;
                    while on != 0 {
                        let k = done + on.trailing_zeros() as usize;
                        on &= on - 1;
                        out.push(first_ref + k as u64);
                    }
                    continue;
                }
                for (k, &m) in rest.iter().enumerate() {
                    counts.evaluated += u64::from(m & NOT_LEAF == 0);
                    if active(m) {
                        out.push(first_ref + (done + k) as u64);
                    }
                }
            }
        }
    }
}

/// For sixteen dual-cell codes: a bit per code of eight leaf cells, and a bit per active one
/// ([`active`]), bit `k` for code `k`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn sixteen_bits(codes: &[u8]) -> (u32, u32) {
    use std::arch::x86_64::*;
    debug_assert!(codes.len() >= 16);
    if codes.len() < 16 {
        return (0, 0);
    }
    // SAFETY: SSE2 is part of every x86-64 target; the unaligned load reads `codes[..16]`,
    // which the check above keeps inside the slice.
    unsafe {
        let v = _mm_loadu_si128(codes.as_ptr().cast());
        let kind = _mm_and_si128(v, _mm_set1_epi8(NOT_LEAF as i8));
        let leaf = _mm_cmpeq_epi8(kind, _mm_setzero_si128());
        let bits = _mm_and_si128(v, _mm_set1_epi8((NOT_LEAF | ABOVE | BELOW) as i8));
        let on = _mm_cmpeq_epi8(bits, _mm_set1_epi8((ABOVE | BELOW) as i8));
        (_mm_movemask_epi8(leaf) as u32, _mm_movemask_epi8(on) as u32)
    }
}

/// [`sixteen_bits`] one code at a time, on other targets.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn sixteen_bits(codes: &[u8]) -> (u32, u32) {
    codes
        .iter()
        .take(16)
        .enumerate()
        .fold((0, 0), |(leaf, on), (k, &m)| {
            (
                leaf | u32::from(m & NOT_LEAF == 0) << k,
                on | u32::from(active(m)) << k,
            )
        })
}

/// True for the code of a dual cell of eight leaf cells whose values straddle the isovalue.
#[inline(always)]
fn active(m: u8) -> bool {
    m & (NOT_LEAF | ABOVE | BELOW) == ABOVE | BELOW
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::local::PENDING;

    /// The vector bits of sixteen codes are those of each code: every code of the four bits,
    /// at each of the sixteen places.
    #[test]
    fn sixteen_bits_equal_each_code() {
        for start in 0..32u8 {
            let codes: [u8; 16] = std::array::from_fn(|k| {
                let m = (start + 7 * k as u8) % 16;
                m & (ABOVE | BELOW | NOT_LEAF | PENDING)
            });
            let (leaf, on) = sixteen_bits(&codes);
            for (k, &m) in codes.iter().enumerate() {
                assert_eq!(leaf >> k & 1 == 1, m & NOT_LEAF == 0, "code {m:#b}");
                assert_eq!(on >> k & 1 == 1, active(m), "code {m:#b}");
            }
            assert_eq!((leaf >> 16, on >> 16), (0, 0));
        }
    }
}
