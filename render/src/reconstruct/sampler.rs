//! The sampler: locating leaf cells and evaluating the octant method's vertex values.
//!
//! All location is integer arithmetic in doubled finest-level coordinates ([`Grid`]). The value
//! of an octant vertex is a function of the vertex's position alone (and of whether the asking
//! octant's level is finer than the coarsest leaf cell touching it), computed by the same
//! operations in the same order whichever octant asks, so octants sharing a vertex get
//! bit-identical values there. The rules are in `docs/reconstruction.md`.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hash, Hasher};
use std::ops::Deref;
use std::sync::Arc;

use amr_format::kdtree::TreeView;
use amr_format::{AmrkFile, IBox};

use crate::error::RenderError;
use crate::error::Result;

use super::cache::BrickCache;
use super::cell_octants::CellOctants;
use super::grid::{axes, index_in, Grid};
use super::interp::{avg2, avg8, trilinear};
use super::leaf_grid::{Entry, LazyLeafGrid};
use super::leaf_hints::LeafHints;
use super::mixed::{distinct_sides, holds, sides_in};
use super::whole_bricks::LeafCover;

/// The leaf cell at a point: the finest cell any brick holds there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafCell {
    /// The kd-tree leaf the point lies in.
    pub leaf: u32,
    /// The brick holding the cell.
    pub brick: u32,
    /// The cell's level.
    pub level: u32,
    /// The cell's index in its level's index space.
    pub cell: [i64; 3],
    /// The cell's value.
    pub value: f32,
}

/// A placeholder for the unused slots of a fixed array of leaf cells.
pub(super) const NO_CELL: LeafCell = LeafCell {
    leaf: 0,
    brick: 0,
    level: 0,
    cell: [0; 3],
    value: 0.0,
};

/// One octant of one cell: the eighth of the cell between its centre and corner `octant`
/// (bit `a` set: the upper side of axis `a`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Octant {
    /// The cell's level.
    pub level: u32,
    /// The cell's index in its level's index space.
    pub cell: [i64; 3],
    /// Which octant, 0 to 7.
    pub octant: u8,
}

/// A brick's values: borrowed from the file when stored raw, shared from the cache otherwise.
pub enum Slab<'f> {
    /// Read in place.
    Borrowed(&'f [f32]),
    /// Decoded into the cache.
    Shared(Arc<[f32]>),
}

impl Deref for Slab<'_> {
    type Target = [f32];
    fn deref(&self) -> &[f32] {
        match self {
            Slab::Borrowed(s) => s,
            Slab::Shared(s) => s,
        }
    }
}

/// Vertex values already computed, keyed by position and asking level: a per-thread scratch
/// that saves recomputing the vertices octants share. Values are pure functions of the key, so
/// a memo never changes a result. It forgets everything when it reaches its capacity.
pub struct VertexMemo {
    map: HashMap<VertexKey, Option<f32>, BuildHasherDefault<VertexHasher>>,
    capacity: usize,
    /// Direct-mapped corner values of octants (allocated on first use: `2^octant_bits` slots of
    /// 72 bytes).
    octants: Vec<(Octant, Option<[f32; 8]>)>,
    /// log2 of the octant table's slots; 0: no table.
    octant_bits: u32,
    /// log2 of the slots the table grows to (by [`OCTANT_GROWTH`] at a time) once it has taken
    /// as many octants as it has slots: a memo kept for many octants gets a table that holds
    /// more of them, one used for a few keeps a small one.
    octant_max_bits: u32,
    /// Octants put in the table since it was last allocated.
    octant_puts: usize,
    /// The kd-tree leaves located last, tried first by the next vertices' sides.
    pub(super) hints: LeafHints,
    /// True when a cell's octants next to other levels are computed together
    /// ([`Self::with_octants_together`]).
    together: bool,
    /// Scratch for computing a cell's octants together (allocated on first use).
    pub(super) cell_octants: Option<Box<CellOctants>>,
}

/// log2 of the slots of [`VertexMemo`]'s octant table at first by default.
const OCTANT_BITS: u32 = 10;

/// log2 of the most slots [`VertexMemo`]'s octant table grows to by default (1.2 MB).
const OCTANT_MAX_BITS: u32 = 14;

/// log2 of the factor the octant table grows by at a time.
const OCTANT_GROWTH: u32 = 2;

impl Default for VertexMemo {
    fn default() -> Self {
        Self {
            map: HashMap::default(),
            capacity: 1 << 16,
            octants: Vec::new(),
            octant_bits: OCTANT_BITS,
            octant_max_bits: OCTANT_MAX_BITS,
            octant_puts: 0,
            hints: LeafHints::default(),
            together: false,
            cell_octants: None,
        }
    }
}

impl VertexMemo {
    /// Forgets every value.
    pub fn clear(&mut self) {
        self.map.clear();
        self.octants.clear();
        self.hints.clear();
    }

    /// A memo whose octant table holds `2^bits` octants (by default 1024, growing to 16384
    /// with use; none for 0, which suits a memo used once: the table is allocated whole on
    /// first use).
    pub fn with_octant_bits(bits: u32) -> Self {
        Self {
            octant_bits: bits.min(24),
            octant_max_bits: bits.min(24),
            ..Self::default()
        }
    }

    /// This memo, computing the octants of a cell next to other levels that are likely to be
    /// asked for together: when an octant missing from the octant table is asked for, the
    /// cell's other octants next to a neighbour of another level are computed with it (sharing
    /// their neighbours and corners, [`super::cell_octants`]) and put in the table. For callers
    /// that ask for the octants of a whole region, such as the extraction; the values are the
    /// same either way.
    pub fn with_octants_together(mut self) -> Self {
        self.together = true;
        self
    }

    /// True when the octant table holds octant `o`'s corners.
    pub fn knows_octant(&self, o: &Octant) -> bool {
        self.octant_get(o).is_some()
    }

    /// True when octants missing from the table are computed a cell at a time.
    #[inline]
    pub(super) fn octants_together(&self) -> bool {
        self.together && self.octant_bits != 0
    }

    /// The value remembered at vertex `v` as seen by an octant of level `level`, if any.
    #[inline]
    pub(super) fn vertex(&self, v: [i64; 3], level: u32) -> Option<Option<f32>> {
        self.map.get(&VertexKey(v, level)).copied()
    }

    /// Remembers the value at vertex `v` as seen by an octant of level `level`.
    #[inline]
    pub(super) fn remember_vertex(&mut self, v: [i64; 3], level: u32, value: Option<f32>) {
        if self.map.len() >= self.capacity {
            self.map.clear();
        }
        self.map.insert(VertexKey(v, level), value);
    }

    #[inline]
    fn octant_slot(&self, o: &Octant) -> usize {
        let h = (o.cell[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (o.cell[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ (o.cell[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
            ^ (u64::from(o.level) << 3 | u64::from(o.octant)).wrapping_mul(0x27D4_EB2F_1656_67C5);
        (h >> (64 - self.octant_bits)) as usize
    }

    #[inline]
    pub(super) fn octant_get(&self, o: &Octant) -> Option<Option<[f32; 8]>> {
        if self.octants.is_empty() {
            return None;
        }
        let e = &self.octants[self.octant_slot(o)];
        (e.0 == *o).then_some(e.1)
    }

    #[inline]
    pub(super) fn octant_put(&mut self, o: &Octant, corners: Option<[f32; 8]>) {
        if self.octant_bits == 0 {
            return;
        }
        if self.octants.is_empty() {
            let empty = Octant {
                level: u32::MAX,
                cell: [0; 3],
                octant: 0,
            };
            self.octants.resize(1 << self.octant_bits, (empty, None));
            self.octant_puts = 0;
        } else if self.octant_puts >= self.octants.len() && self.octant_bits < self.octant_max_bits
        {
            // Forgetting changes no value: the table starts again, larger.
            self.octant_bits = (self.octant_bits + OCTANT_GROWTH).min(self.octant_max_bits);
            self.octants.clear();
            return self.octant_put(o, corners);
        }
        self.octant_puts += 1;
        let slot = self.octant_slot(o);
        self.octants[slot] = (*o, corners);
    }
}

/// A neighbour position of [`Sampler::corners_gathered`]: the leaf cell located there and its
/// kd-tree leaf's box.
#[derive(Clone, Copy)]
pub(super) struct Position {
    pub(super) cell: LeafCell,
    /// True when every finest cell of the position (in the domain) lies in `cell`.
    pub(super) whole: bool,
    pub(super) leaf_box: IBox,
}

/// The largest cell value magnitude for which [`Sampler::bounded`] holds: sums of two vertex
/// values, and interpolants of them, stay finite.
const BOUND: f32 = f32::MAX / 8.0;

/// A vertex and the level asking for its value.
#[derive(Clone, Copy, PartialEq, Eq)]
struct VertexKey([i64; 3], u32);

impl Hash for VertexKey {
    fn hash<H: Hasher>(&self, state: &mut H) {
        let v = self.0;
        let h = (v[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (v[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ (v[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
            ^ u64::from(self.1).wrapping_mul(0x27D4_EB2F_1656_67C5);
        state.write_u64(h);
    }
}

/// Finishes a [`VertexKey`]'s premixed word with the MurmurHash3 finaliser.
#[derive(Default)]
struct VertexHasher(u64);

impl Hasher for VertexHasher {
    fn finish(&self) -> u64 {
        let mut h = self.0;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        h ^ (h >> 33)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 ^= x;
    }
}

/// Finds the leaf cell holding a finest-level cell. The sampler answers through its leaf grid
/// over the kd-tree; [`super::recent::RecentLocator`] first tries the leaves it met last.
/// Every implementation must give exactly [`Sampler::locate`]'s answer.
pub trait Locate {
    /// The leaf cell holding finest-level cell `finest` (relative to the domain, inside it).
    fn locate_cell(&self, finest: [i64; 3]) -> Result<Option<LeafCell>>;

    /// The values of the eight finest cells `lo`/`hi` per axis (side `n` takes `hi` on axis `a`
    /// when bit `a` of `n` is set) when a cheap check shows that all eight are leaf cells of
    /// `level`; `None` leaves the caller to locate them one by one.
    #[inline]
    fn block_of_level(&self, _lo: [i64; 3], _hi: [i64; 3], _level: u32) -> Option<[f32; 8]> {
        None
    }
}

impl<D: AsRef<[u8]>> Locate for Sampler<'_, D> {
    #[inline(always)]
    fn locate_cell(&self, finest: [i64; 3]) -> Result<Option<LeafCell>> {
        self.locate(finest)
    }

    /// With the shortcuts on: when `lo` and `hi` lie in one kd-tree leaf whose finest brick is
    /// of `level` and read in place, from that brick.
    #[inline]
    fn block_of_level(&self, lo: [i64; 3], hi: [i64; 3], level: u32) -> Option<[f32; 8]> {
        self.leaf_grid.as_ref()?;
        let leaf = self.find_leaf(lo)?;
        let t = self.tops[leaf as usize].as_ref()?;
        if t.level != level || !self.read_box(leaf).contains_cell(hi) {
            return None;
        }
        let b = &self.bricks[t.brick as usize];
        let (clo, chi) = (self.grid.cell_of(level, lo), self.grid.cell_of(level, hi));
        block_in_brick(&b.cells, t.values?, clo, chi)
    }
}

/// The values of the eight cells `clo`/`hi` per axis (cell `n` takes `chi` on axis `a` when bit
/// `a` of `n` is set; `chi` is `clo` or one more on every axis) of a brick of cells `cells` and
/// values `values`: one index and three strides. `None` when a cell lies outside the brick.
#[inline]
pub(super) fn block_in_brick(
    cells: &IBox,
    values: &[f32],
    clo: [i64; 3],
    chi: [i64; 3],
) -> Option<[f32; 8]> {
    if !cells.contains_cell(clo) || !cells.contains_cell(chi) {
        return None;
    }
    let e = cells.extent();
    let stride = [1, e[0], e[0] * e[1]];
    let step: [usize; 3] = axes(|a| ((chi[a] - clo[a]) * stride[a]) as usize);
    let first = index_in(cells, clo);
    let last = first + step[0] + step[1] + step[2];
    let block = values.get(first..=last)?;
    let mut out = [0f32; 8];
    for (n, slot) in out.iter_mut().enumerate() {
        let at = (n & 1) * step[0] + (n >> 1 & 1) * step[1] + (n >> 2 & 1) * step[2];
        *slot = block[at];
    }
    Some(out)
}

/// [`Sampler::corners_from_block`] for any values, `own` being the side of the outer corner the
/// cell lies on: corner `own ^ face` is the [`avg8`] of the cells `(m & face) | (own & !face)`.
#[inline]
fn corners_from_block_general(block: &[f32; 8], value: f32, own: usize) -> [f32; 8] {
    let mut out = [0f32; 8];
    for (n, slot) in out.iter_mut().enumerate() {
        // Axes on which corner n lies on the outer face rather than at the cell's centre.
        let face = n ^ own;
        if face == 0 {
            *slot = value;
            continue;
        }
        let mut cells = [0f32; 8];
        for (m, c) in cells.iter_mut().enumerate() {
            *c = block[((m & face) | (own & !face)) & 7];
        }
        *slot = avg8(&cells);
    }
    out
}

/// [`Sampler::corners_from_block`] when every value is finite and at most `f32::MAX / 8` in
/// magnitude ([`Sampler::bounded`]), `own` being the side of the outer corner the cell lies on.
///
/// The corner at the cell's centre is the cell's value; corner `own ^ face` is the [`avg8`] of
/// the cells `(m & face) | (own & !face)`, where the axes outside `face` repeat each cell. There
/// `avg2(a, a) = (a + a) * 0.5` is `a` bit for bit (the doubling cannot overflow and halving it
/// is exact), so each corner is the same nested mean of its distinct cells alone, x pairs first,
/// and the x pairs are shared between corners: 15 means instead of 49.
#[inline]
fn corners_from_block_bounded(b: &[f32; 8], value: f32, own: usize) -> [f32; 8] {
    let (ox, oy, oz) = (own & 1, own & 2, own & 4);
    // The x pairs, by their y and z bits (`y + 2 z`).
    let px = [
        avg2(b[0], b[1]),
        avg2(b[2], b[3]),
        avg2(b[4], b[5]),
        avg2(b[6], b[7]),
    ];
    let (py, pz) = (oy >> 1, oz >> 1);
    let mut out = [0f32; 8];
    out[own] = value;
    out[own ^ 1] = px[py + pz];
    out[own ^ 2] = avg2(b[ox | oz], b[ox | 2 | oz]);
    out[own ^ 4] = avg2(b[ox | oy], b[ox | oy | 4]);
    out[own ^ 3] = avg2(px[pz], px[1 + pz]);
    out[own ^ 5] = avg2(px[py], px[py + 2]);
    out[own ^ 6] = avg2(avg2(b[ox], b[ox | 2]), avg2(b[ox | 4], b[ox | 6]));
    out[own ^ 7] = avg2(avg2(px[0], px[1]), avg2(px[2], px[3]));
    out
}

/// A kd-tree leaf's finest brick as point location reads it: one record per leaf, so a locate
/// reads no other table. Its fields are as narrow as the file's checks allow: the table is
/// touched whole when a file is opened, each of its pages a fault.
#[derive(Clone, Copy)]
struct LeafTop<'f> {
    brick: u32,
    level: u32,
    /// log2 of the level's cell width in finest cells, when every axis is a power of two (at
    /// most 31: the finest domain spans at most `u32::MAX` cells per axis).
    shift: Option<[u8; 3]>,
    /// The brick's lowest cell (absolute index of `level`).
    lo: [i64; 3],
    /// The brick's extent along x and y (a brick lies inside its level's domain, at most
    /// `u32::MAX` cells per axis).
    ex: u32,
    ey: u32,
    /// The brick's extent along z when no finer brick overlaps the brick (then every cell of
    /// it is a leaf cell, whichever kd-tree leaf holds the cell: [`Sampler::read_box`]); zero
    /// otherwise.
    whole_ez: u32,
    /// The brick's values when they can be read in place.
    values: Option<&'f [f32]>,
}

/// A leaf's record in 64 bytes, so that a file of many small leaves opens with fewer fresh pages.
#[cfg(target_pointer_width = "64")]
const _: () = assert!(size_of::<Option<LeafTop<'_>>>() == 64);

impl LeafTop<'_> {
    /// The cell of the brick's level holding finest-level cell `finest` (relative).
    #[inline(always)]
    fn cell_of(&self, grid: &Grid, finest: [i64; 3]) -> [i64; 3] {
        match self.shift {
            Some(sh) => {
                let offset = grid.offset();
                axes(|a| (finest[a] + offset[a]) >> sh[a])
            }
            None => grid.cell_of(self.level, finest),
        }
    }

    /// The brick's finest cells (relative), when no finer brick overlaps it.
    #[inline(always)]
    fn whole_box(&self, grid: &Grid) -> Option<IBox> {
        if self.whole_ez == 0 {
            return None;
        }
        let hi = [
            self.lo[0] + i64::from(self.ex),
            self.lo[1] + i64::from(self.ey),
            self.lo[2] + i64::from(self.whole_ez),
        ];
        Some(grid.level_finest_box(self.level, &IBox::new(self.lo, hi)))
    }

    /// The index of cell `cell` (which the brick holds) in the brick's values.
    #[inline(always)]
    fn index(&self, cell: [i64; 3]) -> usize {
        let d = axes(|a| cell[a] - self.lo[a]);
        (d[0] + i64::from(self.ex) * (d[1] + i64::from(self.ey) * d[2])) as usize
    }
}

/// A kd-tree leaf's finest brick as [`Sampler::leaf_side_parts`] reads a vertex's sides from it.
#[derive(Clone, Copy)]
pub(super) struct SideParts<'f> {
    /// The brick's values.
    pub(super) values: &'f [f32],
    /// The brick's level.
    pub(super) level: u32,
    /// Per axis, the index parts of the nudge toward `-` and toward `+`.
    pub(super) parts: [[i64; 2]; 3],
}

/// One brick as the sampler reads it.
struct BrickRef<'f> {
    /// Its cells in its level's index space.
    cells: IBox,
    /// Its values when they can be read in place.
    values: Option<&'f [f32]>,
}

/// Reconstructs one field of an open file.
pub struct Sampler<'f, D> {
    file: &'f AmrkFile<D>,
    field: usize,
    grid: Grid,
    /// Per leaf: its finest brick, `None` where no brick covers it.
    tops: Vec<Option<LeafTop<'f>>>,
    /// Per brick: its cells and its values when they can be read in place.
    bricks: Vec<BrickRef<'f>>,
    tree: TreeView<'f>,
    /// Point location in one table read and a short walk (the table built on first need);
    /// `None` with the shortcuts off.
    leaf_grid: Option<LazyLeafGrid>,
    /// True when octant corners are gathered around the octant's outer corner
    /// ([`Self::corners_gathered`]): shortcuts on, and every level's cells nest in the cells of
    /// the coarser levels.
    gather: bool,
    cache: BrickCache,
    /// True when every stored brick range of the field lies within `BOUND`: every vertex value
    /// is then finite ([`super::stitch`]).
    bounded: bool,
    /// This sampler's identity, which scratch memory serving it remembers.
    id: u64,
}

impl<'f, D: AsRef<[u8]>> Sampler<'f, D> {
    /// A sampler of field `field` of `file`, decoding compressed bricks through a cache of about
    /// `cache_bytes`.
    pub fn new(file: &'f AmrkFile<D>, field: usize, cache_bytes: usize) -> Result<Self> {
        if field >= file.fields().len() {
            return Err(RenderError::Invalid(format!(
                "field {field} does not exist ({} fields)",
                file.fields().len()
            )));
        }
        // One pass over each table: the bricks with their stored values, then the leaves.
        let mut bounded = true;
        let mut levels = Vec::with_capacity(file.num_bricks());
        let bricks: Vec<BrickRef<'f>> = file
            .bricks()
            .zip(file.brick_locations(field))
            .map(|(b, at)| {
                bounded &= at.min.abs() <= BOUND && at.max.abs() <= BOUND;
                levels.push(b.level);
                // Only raw bricks are read in place: a compressed one is decoded on demand.
                BrickRef {
                    cells: b.cells,
                    values: file.raw_values(&at),
                }
            })
            .collect();
        let grid = Grid::new(file);
        let mut cover = LeafCover::new(bricks.len());
        let mut tops = file
            .leaves()
            .map(|l| {
                l.bricks.first().map(|b| {
                    let brick = b.get();
                    cover.add(brick, &l.bounds);
                    let level = levels[brick as usize];
                    let BrickRef { cells, values } = &bricks[brick as usize];
                    let extent = |a: usize| {
                        u32::try_from(cells.hi[a] - cells.lo[a])
                            .expect("brick boxes lie inside the checked domain")
                    };
                    LeafTop {
                        brick,
                        level,
                        shift: grid.shift(level).map(|sh| sh.map(|s| s as u8)),
                        lo: cells.lo,
                        ex: extent(0),
                        ey: extent(1),
                        whole_ez: 0,
                        values: *values,
                    }
                })
            })
            .collect::<Vec<_>>();
        let whole = cover.whole_bricks(
            levels
                .iter()
                .zip(&bricks)
                .map(|(&l, b)| grid.level_finest_box(l, &b.cells)),
        );
        for t in tops.iter_mut().flatten() {
            if whole[t.brick as usize] {
                t.whole_ez = u32::try_from(bricks[t.brick as usize].cells.extent()[2])
                    .expect("brick boxes lie inside the checked domain");
            }
        }
        let sampler = Self {
            bricks,
            leaf_grid: None,
            gather: false,
            tree: file.tree(),
            file,
            field,
            grid,
            tops,
            cache: BrickCache::new(cache_bytes),
            bounded,
            id: super::recent::next_sampler_id(),
        };
        Ok(sampler.with_shortcuts(true))
    }

    /// This sampler with its shortcuts (the leaf grid of [`Self::locate`], the gathered octant
    /// corners of [`Self::corners`]) on or off: the same values either way, computed by the
    /// general rules when off, for tests and benchmarks that compare the two.
    pub fn with_shortcuts(mut self, on: bool) -> Self {
        let file = self.file;
        self.leaf_grid = on.then(|| LazyLeafGrid::new(&file.tree()));
        let g = &self.grid;
        let nested = (1..g.num_levels() as u32).all(|l| {
            let (coarse, fine) = (g.scale(l - 1), g.scale(l));
            (0..3).all(|a| fine[a] > 0 && coarse[a] % fine[a] == 0)
        });
        self.gather = on && nested;
        self
    }

    /// The file.
    pub fn file(&self) -> &'f AmrkFile<D> {
        self.file
    }

    /// The field sampled.
    pub fn field(&self) -> usize {
        self.field
    }

    /// The file's geometry.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// True when every cell value of the field is finite and at most `f32::MAX / 8` in
    /// magnitude, as the bricks' stored ranges say: then every vertex value and every
    /// interpolant of them is finite.
    #[inline]
    pub fn bounded(&self) -> bool {
        self.bounded
    }

    /// This sampler's identity, unique in the process (scratch memory is keyed by it).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Kd-tree leaf `leaf`'s box in finest-level cells relative to the domain.
    pub fn leaf_box(&self, leaf: u32) -> IBox {
        self.tree.leaf_box(leaf)
    }

    /// Calls `f` with every kd-tree leaf whose closed box touches the closed `region` (finest-level
    /// cells relative to the domain).
    pub fn for_each_leaf_touching(&self, region: &IBox, f: impl FnMut(u32)) {
        self.tree.for_each_leaf_touching(region, f)
    }

    /// The finest cells whose leaf cells kd-tree leaf `leaf`'s finest brick holds, as far as the
    /// sampler knows: the whole brick when no finer brick overlaps it (then any kd-tree leaf
    /// whose finest brick it is reads every cell of it), else the leaf's box. The octant
    /// corners read cells from a leaf's brick wherever they lie in this box, so a brick that the
    /// kd-tree cut into leaves near a level boundary is read as one.
    #[inline(always)]
    pub(super) fn read_box(&self, leaf: u32) -> IBox {
        self.tops[leaf as usize]
            .as_ref()
            .and_then(|t| t.whole_box(&self.grid))
            .unwrap_or_else(|| self.tree.leaf_box(leaf))
    }

    /// Leaf `leaf`'s finest brick and its level, `None` for a leaf no brick covers.
    pub fn leaf_top(&self, leaf: u32) -> Option<(u32, u32)> {
        self.tops[leaf as usize].map(|t| (t.brick, t.level))
    }

    /// Brick `brick`'s cells in its level's index space.
    pub fn brick_cells(&self, brick: u32) -> IBox {
        self.bricks[brick as usize].cells
    }

    /// Number of bricks decoded into the cache so far.
    pub fn decodes(&self) -> u64 {
        self.cache.decodes()
    }

    /// Brick `brick`'s values when they are read in place (stored raw), else `None`.
    #[inline]
    pub fn values_in_place(&self, brick: u32) -> Option<&'f [f32]> {
        self.bricks[brick as usize].values
    }

    /// The values of the eight level cells `clo`/`chi` per axis (cell `n` takes `chi` on axis
    /// `a` when bit `a` of `n` is set; `chi` is `clo` or one more on every axis) of brick
    /// `brick`, when all eight lie in it and it is read in place; else `None`.
    #[inline]
    pub fn brick_block(&self, brick: u32, clo: [i64; 3], chi: [i64; 3]) -> Option<[f32; 8]> {
        let b = self.bricks.get(brick as usize)?;
        block_in_brick(&b.cells, b.values?, clo, chi)
    }

    /// Brick `brick`'s values of the sampled field.
    pub fn values(&self, brick: u32) -> Result<Slab<'f>> {
        let file: &'f AmrkFile<D> = self.file;
        let b = &self.bricks[brick as usize];
        if let Some(v) = b.values {
            return Ok(Slab::Borrowed(v));
        }
        let cells = b.cells.num_cells().unwrap_or(0) as usize;
        let shared = self.cache.get(brick, cells, || {
            let mut out = Vec::with_capacity(cells);
            file.brick_values_into(self.field, brick as usize, &mut out)?;
            Ok(out)
        })?;
        Ok(Slab::Shared(shared))
    }

    /// The leaf cell holding finest-level cell `finest` (relative to the domain), `None` outside
    /// the domain or where no brick covers it.
    #[inline(always)]
    pub fn locate(&self, finest: [i64; 3]) -> Result<Option<LeafCell>> {
        match self.find_leaf(finest) {
            Some(leaf) => self.leaf_cell(leaf, finest),
            None => Ok(None),
        }
    }

    /// The leaf cell holding finest-level cell `finest`, which lies in kd-tree leaf `leaf`;
    /// `None` where no brick covers the leaf.
    #[inline(always)]
    pub fn leaf_cell(&self, leaf: u32, finest: [i64; 3]) -> Result<Option<LeafCell>> {
        let Some(t) = &self.tops[leaf as usize] else {
            return Ok(None);
        };
        let cell = t.cell_of(&self.grid, finest);
        let index = t.index(cell);
        let value = match t.values {
            Some(v) => v[index],
            None => self.decoded_value(t.brick, index)?,
        };
        Ok(Some(LeafCell {
            leaf,
            brick: t.brick,
            level: t.level,
            cell,
            value,
        }))
    }

    /// Value `index` of brick `brick`, which is decoded (through the cache) to be read.
    #[cold]
    #[inline(never)]
    fn decoded_value(&self, brick: u32, index: usize) -> Result<f32> {
        Ok(self.values(brick)?[index])
    }

    /// The kd-tree leaf holding finest-level cell `finest`, `None` outside the domain.
    #[inline]
    pub fn find_leaf(&self, finest: [i64; 3]) -> Option<u32> {
        match &self.leaf_grid {
            Some(g) => g.find_leaf(&self.tree, finest),
            None => self.tree.find_leaf(finest),
        }
    }

    /// Where the leaf grid places finest-level cell `finest`: the leaf or the node to walk from
    /// ([`super::leaf_grid::LeafGrid::entry`]); `None` outside the domain, or when there is no
    /// table yet (or with the shortcuts off), for [`Self::find_leaf`] to answer.
    #[inline]
    pub(super) fn grid_entry(&self, finest: [i64; 3]) -> Option<Entry> {
        self.leaf_grid.as_ref()?.built()?.entry(finest)
    }

    /// The kd-tree leaf holding finest-level cell `finest`, walking down from node `node`,
    /// whose region holds it.
    #[inline]
    pub(super) fn find_leaf_from(&self, node: usize, finest: [i64; 3]) -> Option<u32> {
        self.tree.find_leaf_from(node, finest)
    }

    /// The leaf cells touching doubled point `v` from its eight sides (side `n`: nudged toward
    /// `+` on axis `a` when bit `a` of `n` is set), clamped into the domain.
    pub fn around(&self, v: [i64; 3]) -> Result<Option<[LeafCell; 8]>> {
        self.around_in(self, v)
    }

    /// The finest cells holding doubled point `v` nudged toward `-` and toward `+` on every
    /// axis, and the axes (bit `a`) on which they coincide (odd coordinate, or clamped at the
    /// domain's edge): there side `n` of `v` repeats the side without that bit.
    #[inline(always)]
    pub(crate) fn nudges(&self, v: [i64; 3]) -> ([i64; 3], [i64; 3], usize) {
        let lo = self.grid.finest_cell(v, 0);
        let hi = self.grid.finest_cell(v, 7);
        let same = (0..3).fold(0usize, |m, a| m | usize::from(lo[a] == hi[a]) << a);
        (lo, hi, same)
    }

    /// [`Self::around`], locating through `loc`.
    #[inline]
    pub fn around_in<L: Locate>(&self, loc: &L, v: [i64; 3]) -> Result<Option<[LeafCell; 8]>> {
        let mut out = [NO_CELL; 8];
        let found = self.sides_into(loc, self.nudges(v), &mut out, &mut LeafHints::default())?;
        Ok(found.then_some(out))
    }

    /// The value at octant vertex `v` as seen by an octant of level `level`.
    ///
    /// Where a leaf cell coarser than `level` touches `v` (the fine side of a level boundary),
    /// the value is the coarse side's interpolant at `v` ([`Self::coarse_value`]); everywhere
    /// else it is the mean of the eight leaf cells touching `v` ([`avg8`]), which is the mean of
    /// the dual cell's corners away from boundaries and the finest-level lerp on a boundary's
    /// coarse side. `None` where a cell touching `v` is not covered by any brick.
    pub fn vertex_value(
        &self,
        v: [i64; 3],
        level: u32,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        self.vertex_value_in(self, v, level, memo)
    }

    /// [`Self::vertex_value`], locating through `loc`.
    pub fn vertex_value_in<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        level: u32,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        if let Some(known) = memo.vertex(v, level) {
            return Ok(known);
        }
        let value = self.vertex_value_unmemoized_in(loc, v, level, memo)?;
        memo.remember_vertex(v, level, value);
        Ok(value)
    }

    /// [`Self::vertex_value_in`] without looking `v` itself up in (or adding it to) `memo`: for
    /// callers that remember their own vertices. The same value, computed the same way.
    #[inline]
    pub fn vertex_value_unmemoized_in<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        level: u32,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        self.vertex_value_lean_in(loc, v, level, memo)
    }

    /// [`Self::vertex_value`] given the leaf cells around `v` (as [`Self::around`] finds them).
    pub fn vertex_value_from(
        &self,
        v: [i64; 3],
        level: u32,
        cells: &[LeafCell; 8],
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        self.vertex_value_from_in(self, v, level, cells, memo)
    }

    /// [`Self::vertex_value_from`], locating through `loc`.
    pub fn vertex_value_from_in<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        level: u32,
        cells: &[LeafCell; 8],
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        let coarsest = cells.iter().map(|c| c.level).min().unwrap_or(level);
        if coarsest < level {
            return self.coarse_value_in(loc, v, cells, coarsest, memo);
        }
        Ok(Some(avg8(&cells.map(|c| c.value))))
    }

    /// The interpolant of the coarsest leaf cell touching `v` (level `coarsest`), evaluated at
    /// `v`. The cell is the first of the eight sides of `v` holding that level, so the choice
    /// depends on `v` only, never on who asks.
    pub fn coarse_value(
        &self,
        v: [i64; 3],
        cells: &[LeafCell; 8],
        coarsest: u32,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        self.coarse_value_in(self, v, cells, coarsest, memo)
    }

    /// [`Self::coarse_value`], locating through `loc`. The coarse octant's corner values are
    /// remembered in `memo` (they are a pure function of the octant).
    pub fn coarse_value_in<L: Locate>(
        &self,
        loc: &L,
        v: [i64; 3],
        cells: &[LeafCell; 8],
        coarsest: u32,
        memo: &mut VertexMemo,
    ) -> Result<Option<f32>> {
        let (q, octant) = self.coarse_octant(v, cells, coarsest);
        let Some(corners) = self.leaf_octant_corners_in(loc, &q, octant, memo)? else {
            return Ok(None);
        };
        Ok(Some(self.coarse_lerp(v, &q, octant, &corners)))
    }

    /// The leaf cell [`Self::coarse_value_in`] interpolates at `v` and its octant holding `v`.
    #[inline]
    pub(super) fn coarse_octant(
        &self,
        v: [i64; 3],
        cells: &[LeafCell; 8],
        coarsest: u32,
    ) -> (LeafCell, u8) {
        let side = cells
            .iter()
            .position(|c| c.level == coarsest)
            .expect("the coarsest level is present");
        let q = cells[side];
        (q, self.octant_toward(v, &q, side))
    }

    /// The octant of leaf cell `q` holding `v`, which `q` touches from side `side` of `v`.
    #[inline]
    pub(super) fn octant_toward(&self, v: [i64; 3], q: &LeafCell, side: usize) -> u8 {
        let centre = self.grid.centre(q.level, q.cell);
        let mut octant = 0u8;
        for a in 0..3 {
            if v[a] > centre[a] || (v[a] == centre[a] && side >> a & 1 == 1) {
                octant |= 1 << a;
            }
        }
        octant
    }

    /// The trilinear interpolant at `v` of octant `octant` of leaf cell `q`, whose corner
    /// values are `corners`.
    #[inline]
    pub(super) fn coarse_lerp(
        &self,
        v: [i64; 3],
        q: &LeafCell,
        octant: u8,
        corners: &[f32; 8],
    ) -> f32 {
        let key = Octant {
            level: q.level,
            cell: q.cell,
            octant,
        };
        let (lo, _) = self.octant_box(&key);
        let s = self.grid.scale(q.level);
        let t = axes(|a| ((v[a] - lo[a]) as f64 / s[a] as f64) as f32);
        trilinear(corners, t)
    }

    /// [`Self::corners_in`] for octant `octant` of leaf cell `q`, remembered in `memo`'s octant
    /// table (the corners are a pure function of the octant). Inlined: most calls find the
    /// octant in the table.
    #[inline]
    pub fn leaf_octant_corners_in<L: Locate>(
        &self,
        loc: &L,
        q: &LeafCell,
        octant: u8,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let key = Octant {
            level: q.level,
            cell: q.cell,
            octant,
        };
        if let Some(known) = memo.octant_get(&key) {
            return Ok(known);
        }
        self.leaf_octant_corners_computed(loc, q, &key, memo)
    }

    /// [`Self::leaf_octant_corners_in`] for octant `key` of `q` missing from `memo`'s table:
    /// computed and remembered there.
    #[inline(never)]
    fn leaf_octant_corners_computed<L: Locate>(
        &self,
        loc: &L,
        q: &LeafCell,
        key: &Octant,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let c = if self.gather {
            self.corners_gathered(loc, key, q.value, Some(q), memo)?
        } else {
            self.corners_in(loc, q.level, q.cell, q.value, key.octant, memo)?
        };
        memo.octant_put(key, c);
        Ok(c)
    }

    /// The box of an octant in doubled coordinates: `(lo, hi)`.
    pub fn octant_box(&self, o: &Octant) -> ([i64; 3], [i64; 3]) {
        let c = self.grid.centre(o.level, o.cell);
        let s = self.grid.scale(o.level);
        let lo = axes(|a| {
            if o.octant >> a & 1 == 1 {
                c[a]
            } else {
                c[a] - s[a]
            }
        });
        (lo, axes(|a| lo[a] + s[a]))
    }

    /// The corner values of octant `octant` of leaf cell `cell` of `level`, whose value is `value`.
    pub fn corners(
        &self,
        level: u32,
        cell: [i64; 3],
        value: f32,
        octant: u8,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        self.corners_in(self, level, cell, value, octant, memo)
    }

    /// [`Self::corners`], locating through `loc`.
    pub fn corners_in<L: Locate>(
        &self,
        loc: &L,
        level: u32,
        cell: [i64; 3],
        value: f32,
        octant: u8,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let o = Octant {
            level,
            cell,
            octant,
        };
        if self.gather {
            return self.corners_gathered(loc, &o, value, None, memo);
        }
        if let Some(out) = self.corners_one_level(loc, &o, value)? {
            return Ok(Some(out));
        }
        self.corners_per_vertex(loc, &o, value, memo)
    }

    /// [`Self::corners_in`] by the general rule: [`Self::vertex_value_in`] at every corner but
    /// the cell's centre, which carries the cell's value.
    fn corners_per_vertex<L: Locate>(
        &self,
        loc: &L,
        o: &Octant,
        value: f32,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let Octant { level, octant, .. } = *o;
        let (lo, _) = self.octant_box(o);
        let s = self.grid.scale(level);
        let mut out = [0f32; 8];
        for (n, slot) in out.iter_mut().enumerate() {
            // The corner at the cell centre carries the cell's value.
            if (0..3).all(|a| ((n >> a) & 1) as u8 == ((octant >> a) & 1) ^ 1) {
                *slot = value;
                continue;
            }
            let v = axes(|a| lo[a] + (n >> a & 1) as i64 * s[a]);
            match self.vertex_value_in(loc, v, level, memo)? {
                Some(x) => *slot = x,
                None => return Ok(None),
            }
        }
        Ok(Some(out))
    }

    /// [`Self::corners_in`] for octant `o` of a leaf cell of value `value` where the eight leaf
    /// cells around the octant's outer corner (the cell's corner on the octant's side) are all
    /// of the octant's level: then no vertex is stitched, every
    /// vertex's eight cells are among those eight, and each value is their [`avg8`] in
    /// [`Self::vertex_value_from_in`]'s order, from 8 locates instead of one [`Self::around_in`]
    /// per vertex. `None` when a cell there is of another level or not covered (the general
    /// rule then decides).
    #[inline]
    fn corners_one_level<L: Locate>(
        &self,
        loc: &L,
        o: &Octant,
        value: f32,
    ) -> Result<Option<[f32; 8]>> {
        let level = o.level;
        let (up, lo, hi, same) = self.outer_corner(o);
        if let Some(block) = loc.block_of_level(lo, hi, level) {
            return Ok(Some(self.corners_from_block(&block, value, up)));
        }
        let mut block = [0f32; 8];
        for n in 0..8 {
            let m = n & !same;
            if m != n {
                block[n] = block[m];
                continue;
            }
            let f = axes(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
            match loc.locate_cell(f)? {
                Some(c) if c.level == level => block[n] = c.value,
                _ => return Ok(None),
            }
        }
        Ok(Some(self.corners_from_block(&block, value, up)))
    }

    /// The sides of octant `o` (`up[a]`: the upper side of axis `a`) and the finest cells around
    /// its outer corner (the cell's corner on the octant's side), as [`Self::nudges`] gives them.
    #[inline]
    fn outer_corner(&self, o: &Octant) -> ([bool; 3], [i64; 3], [i64; 3], usize) {
        let centre = self.grid.centre(o.level, o.cell);
        let s = self.grid.scale(o.level);
        let up = axes(|a| o.octant >> a & 1 == 1);
        let outer = axes(|a| {
            if up[a] {
                centre[a] + s[a]
            } else {
                centre[a] - s[a]
            }
        });
        let (lo, hi, same) = self.nudges(outer);
        (up, lo, hi, same)
    }

    /// The corners of an octant on the `up` side of a leaf cell of value `value`, from the
    /// values `block` of the eight leaf cells around the octant's outer corner, all of the
    /// cell's level ([`Self::corners_one_level`]).
    #[inline]
    fn corners_from_block(&self, block: &[f32; 8], value: f32, up: [bool; 3]) -> [f32; 8] {
        // The side of the outer corner the cell itself lies on.
        let own = (0..3).fold(0usize, |k, a| k | usize::from(!up[a]) << a);
        if self.bounded {
            corners_from_block_bounded(block, value, own)
        } else {
            corners_from_block_general(block, value, own)
        }
    }

    /// [`Self::corners_in`] from the leaf cells gathered around the octant's outer corner (the
    /// cell's corner on the octant's side): the cell and its seven neighbours of the same level
    /// there, its positions, each located once at the finest cell next to the outer corner.
    ///
    /// When all eight are leaf cells of the octant's level, the corners follow from them as in
    /// [`Self::corners_one_level`]. Otherwise each corner but the centre is
    /// [`Self::vertex_value_in`]'s value, computed from the eight leaf cells touching it, which
    /// are the ones [`Self::around_in`] finds: a finest cell in a position whose located leaf
    /// cell is of the octant's level or coarser and whose kd-tree leaf contains the whole
    /// position is in that leaf cell (every finest cell of the position then lies in that leaf,
    /// whose finest brick has one cell over the position); one in the kd-tree leaf of its
    /// position's located cell is read from that leaf's brick; the others are located. A coarse
    /// octant met at several corners is evaluated once.
    ///
    /// `located`, when given, is the octant's leaf cell as located: cells in its kd-tree leaf are
    /// then read from that leaf's brick without locating them.
    fn corners_gathered<L: Locate>(
        &self,
        loc: &L,
        o: &Octant,
        value: f32,
        located: Option<&LeafCell>,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let level = o.level;
        let (up, lo, hi, same) = self.outer_corner(o);
        // A leaf cell and the box its kd-tree leaf's brick is read in ([`Self::read_box`]):
        // finest cells there are read from that brick.
        let mut near = located.map(|c| (*c, self.read_box(c.leaf)));
        let block = match near {
            // Otherwise the sides are located one by one below: the same values either way.
            Some((c, b)) if b.contains_cell(lo) && b.contains_cell(hi) => self
                .block_in_leaf(&c, lo, hi, level)
                .or_else(|| loc.block_of_level(lo, hi, level)),
            Some(_) => None,
            None => loc.block_of_level(lo, hi, level),
        };
        if let Some(block) = block {
            return Ok(Some(self.corners_from_block(&block, value, up)));
        }
        if memo.octants_together() {
            return self.corners_together(loc, o, value, near, memo);
        }
        // Side `n` of the outer corner, as in `corners_one_level`: first the sides in `near`'s
        // kd-tree leaf, read from its brick, then the others located.
        let side = |n: usize| axes(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
        let mut around = [None::<LeafCell>; 8];
        let mut todo = distinct_sides(same);
        if let Some((c, b)) = near {
            let mut take = sides_in(&b, lo, hi) & todo;
            todo &= !take;
            while take != 0 {
                let n = take.trailing_zeros() as usize;
                take &= take - 1;
                around[n] = self.cell_in_own_leaf(&c, side(n));
                todo |= u8::from(around[n].is_none()) << n;
            }
        }
        while todo != 0 {
            let n = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let found = self.locate_hinted(loc, side(n), &mut memo.hints)?;
            around[n] = found.map(|(c, _)| c);
            // The later sides in the located cell's kd-tree leaf, read from its brick.
            if let Some((c, b)) = found {
                let mut take = sides_in(&b, lo, hi) & todo;
                while take != 0 {
                    let m = take.trailing_zeros() as usize;
                    take &= take - 1;
                    if let Some(x) = self.cell_in_leaf_numbered(c.leaf, side(m)) {
                        around[m] = Some(x);
                        todo &= !(1 << m);
                    }
                }
            }
            if near.is_none() {
                near = around[n].map(|c| (c, self.read_box(c.leaf)));
            }
        }
        if same != 0 {
            for n in 1..8 {
                around[n] = around[n & !same];
            }
        }
        let one_level = around.iter().fold(true, |all, c| {
            all & matches!(c, Some(c) if c.level == level)
        });
        if one_level {
            let block = around.map(|c| c.map_or(0.0, |c| c.value));
            return Ok(Some(self.corners_from_block(&block, value, up)));
        }
        self.corners_mixed(loc, o, value, (up, same), &around, near, memo)
    }

    /// The leaf cell at finest cell `f` of a position gathered by [`Self::corners_gathered`]:
    /// the position's cell when it covers the whole position, else read from the brick of the
    /// position's kd-tree leaf or of `near`'s when `f` lies in that leaf, else located through
    /// `loc` ([`Self::locate_hinted`], trying the leaves of `hints` where the leaf grid names a
    /// node).
    #[inline]
    pub(super) fn position_cell<L: Locate>(
        &self,
        loc: &L,
        p: Option<&Position>,
        near: Option<&(LeafCell, IBox)>,
        f: [i64; 3],
        hints: &mut LeafHints,
    ) -> Result<Option<LeafCell>> {
        if let Some(p) = p {
            if p.whole {
                return Ok(Some(p.cell));
            }
            if let Some(c) = self.cell_in_leaf(&p.cell, &p.leaf_box, f) {
                return Ok(Some(c));
            }
        }
        if let Some(c) = near.and_then(|(c, b)| self.cell_in_leaf(c, b, f)) {
            return Ok(Some(c));
        }
        Ok(self.locate_hinted(loc, f, hints)?.map(|(c, _)| c))
    }

    /// The values of the eight cells at finest cells `lo`/`hi` per axis (as in
    /// [`Locate::block_of_level`]), which lie in the kd-tree leaf of leaf cell `c`, from that
    /// leaf's brick when it is of `level` and read in place.
    #[inline]
    fn block_in_leaf(
        &self,
        c: &LeafCell,
        lo: [i64; 3],
        hi: [i64; 3],
        level: u32,
    ) -> Option<[f32; 8]> {
        let t = self.tops[c.leaf as usize].as_ref()?;
        if t.level != level {
            return None;
        }
        let b = &self.bricks[t.brick as usize];
        block_in_brick(
            &b.cells,
            t.values?,
            t.cell_of(&self.grid, lo),
            t.cell_of(&self.grid, hi),
        )
    }

    /// The value of finest cell `f`, which lies in kd-tree leaf `leaf`, read from the leaf's
    /// finest brick when that brick is read in place: [`Self::cell_in_leaf`] without the box
    /// test, for callers that tested a box holding many cells once.
    #[inline(always)]
    pub(super) fn value_in_leaf(&self, leaf: u32, f: [i64; 3]) -> Option<f32> {
        let t = self.tops[leaf as usize].as_ref()?;
        t.values?.get(t.index(t.cell_of(&self.grid, f))).copied()
    }

    /// The leaf cell at finest cell `f` read from the brick of leaf cell `c`'s kd-tree leaf
    /// (box `leaf_box`) when `f` lies in that leaf and the brick is read in place: the leaf's
    /// finest brick holds every cell of the leaf, so this is [`Self::locate`]'s answer. `None`
    /// otherwise.
    #[inline(always)]
    pub(super) fn cell_in_leaf(
        &self,
        c: &LeafCell,
        leaf_box: &IBox,
        f: [i64; 3],
    ) -> Option<LeafCell> {
        if !holds(leaf_box, f) {
            return None;
        }
        self.cell_in_own_leaf(c, f)
    }

    /// [`Self::cell_in_leaf`] for a finest cell `f` known to lie in leaf cell `c`'s kd-tree leaf.
    #[inline(always)]
    pub(super) fn cell_in_own_leaf(&self, c: &LeafCell, f: [i64; 3]) -> Option<LeafCell> {
        let t = self.tops[c.leaf as usize].as_ref()?;
        let cell = t.cell_of(&self.grid, f);
        let &value = t.values?.get(t.index(cell))?;
        Some(LeafCell { cell, value, ..*c })
    }

    /// The level and value of [`Self::cell_in_leaf_numbered`]'s cell.
    #[inline(always)]
    pub(super) fn side_in_leaf(&self, leaf: u32, f: [i64; 3]) -> Option<(u32, f32)> {
        let t = self.tops[leaf as usize].as_ref()?;
        let &value = t.values?.get(t.index(t.cell_of(&self.grid, f)))?;
        Some((t.level, value))
    }

    /// [`Self::cell_in_own_leaf`] for a finest cell `f` known to lie in kd-tree leaf `leaf`.
    #[inline(always)]
    pub(super) fn cell_in_leaf_numbered(&self, leaf: u32, f: [i64; 3]) -> Option<LeafCell> {
        let t = self.tops[leaf as usize].as_ref()?;
        let cell = t.cell_of(&self.grid, f);
        let &value = t.values?.get(t.index(cell))?;
        Some(LeafCell {
            leaf,
            brick: t.brick,
            level: t.level,
            cell,
            value,
        })
    }

    /// Kd-tree leaf `leaf`'s finest brick's values when read in place, its level, and per axis
    /// `a` the parts of an index into the values that finest coordinates `lo[a]` and `hi[a]`
    /// give: side `n` of a vertex (`hi` on axis `a` when bit `a` of `n` is set), when it lies
    /// in the leaf, is the value at the sum of its three parts, as [`Self::cell_in_own_leaf`]
    /// reads it, from six coordinates instead of three per side.
    #[inline(always)]
    pub(super) fn leaf_side_parts(
        &self,
        leaf: u32,
        lo: [i64; 3],
        hi: [i64; 3],
    ) -> Option<SideParts<'f>> {
        let t = self.tops[leaf as usize].as_ref()?;
        let values = t.values?;
        let (clo, chi) = (t.cell_of(&self.grid, lo), t.cell_of(&self.grid, hi));
        let (ex, ey) = (i64::from(t.ex), i64::from(t.ey));
        let stride = [1, ex, ex * ey];
        let parts = axes(|a| {
            [
                stride[a] * (clo[a] - t.lo[a]),
                stride[a] * (chi[a] - t.lo[a]),
            ]
        });
        Some(SideParts {
            values,
            level: t.level,
            parts,
        })
    }

    /// The corner values of an octant of a leaf cell; `None` when the cell is not a leaf cell or
    /// a cell touching the octant is not covered by any brick.
    pub fn octant_values(&self, o: &Octant) -> Result<Option<[f32; 8]>> {
        let centre = self.grid.centre(o.level, o.cell);
        let Some(c) = self.locate(self.grid.finest_cell(centre, 7))? else {
            return Ok(None);
        };
        if c.level != o.level || c.cell != o.cell {
            return Ok(None);
        }
        self.corners(
            o.level,
            o.cell,
            c.value,
            o.octant,
            &mut VertexMemo::default(),
        )
    }

    /// [`Self::octant_values`] remembering vertex values in `memo` for the next calls.
    pub fn octant_values_memo(
        &self,
        o: &Octant,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        self.octant_values_in(self, o, memo)
    }

    /// [`Self::octant_values_memo`], locating through `loc` and remembering the octant's
    /// corners in `memo`'s octant table.
    pub fn octant_values_in<L: Locate>(
        &self,
        loc: &L,
        o: &Octant,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let centre = self.grid.centre(o.level, o.cell);
        let Some(c) = loc.locate_cell(self.grid.finest_cell(centre, 7))? else {
            return Ok(None);
        };
        if c.level != o.level || c.cell != o.cell {
            return Ok(None);
        }
        self.leaf_octant_corners_in(loc, &c, o.octant, memo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shared-pair corners have the general corners' bits for every side and any values
    /// within the bound: zeros of both signs, subnormals, values near the bound.
    #[test]
    fn bounded_block_corners_have_the_general_bits() {
        let pool = [
            0.0f32,
            -0.0,
            1.5,
            -2.25,
            1.0e-45,
            -3.0e-39,
            0.1,
            -7.0e12,
            BOUND,
            -BOUND,
            BOUND * 0.75,
            1.0 / 3.0,
        ];
        let mut seed = 0x2545_F491_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as usize
        };
        for _ in 0..20_000 {
            let block: [f32; 8] = std::array::from_fn(|_| pool[next() % pool.len()]);
            let value = pool[next() % pool.len()];
            for own in 0..8 {
                let fast = corners_from_block_bounded(&block, value, own);
                let slow = corners_from_block_general(&block, value, own);
                assert_eq!(
                    fast.map(f32::to_bits),
                    slow.map(f32::to_bits),
                    "{block:?} {own}"
                );
            }
        }
    }

    /// The octant table grows by steps to its largest size once it has taken as many octants
    /// as it has slots, and answers for the octants put since it last grew; a memo made with a
    /// size keeps it.
    #[test]
    fn octant_table_grows_with_use() {
        let octant = |i: i64| Octant {
            level: 2,
            cell: [i, -i, 3 * i],
            octant: (i & 7) as u8,
        };
        let corners = |i: i64| Some([i as f32; 8]);
        let mut memo = VertexMemo::default();
        let mut sizes = Vec::new();
        for i in 0..40_000 {
            memo.octant_put(&octant(i), corners(i));
            assert_eq!(memo.octant_get(&octant(i)), Some(corners(i)));
            if sizes.last() != Some(&memo.octants.len()) {
                sizes.push(memo.octants.len());
            }
        }
        assert_eq!(
            sizes,
            [1 << OCTANT_BITS, 1 << 12, 1 << OCTANT_MAX_BITS].to_vec()
        );
        let mut fixed = VertexMemo::with_octant_bits(10);
        for i in 0..5_000 {
            fixed.octant_put(&octant(i), corners(i));
        }
        assert_eq!(fixed.octants.len(), 1 << 10);
    }
}
