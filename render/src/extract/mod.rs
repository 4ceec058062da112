//! Active-voxel extraction for one field and one isovalue (Wang et al., section 4.2).
//!
//! - [`refs`]: the 64-bit references (`leaf << 32 | id`).
//! - [`local`]: the classified level-`L` neighbourhood of a leaf.
//! - [`leaf`]: the voxels one leaf owns: merged dual cells and boundary octants.
//! - [`parts`]: a large leaf extracted part by part, skipping parts whose stored block ranges
//!   exclude the isovalue.
//! - [`plain`]: the codes of a neighbourhood of leaf cells of one level, straight from the
//!   bricks.
//! - [`cull`]: skipping boundary cells whose neighbourhood cannot hold the isovalue, and the
//!   narrower bounds of cells inside coarser leaf cells that boundary octants are tested with.
//! - [`band`]: the bounds around coarse leaf cells the cull reads, kept for every leaf.
//! - [`vertices`]: a leaf's boundary vertex values, computed once each.
//! - [`blocks`]: per-brick ranges of blocks of cells (stored in the file, or built), for bounds
//!   that do not rescan cells.
//! - [`cell_tiles`]: the classified cells of each level, a tile at a time, which small leaves'
//!   neighbourhoods copy.
//! - [`leaf_tree`]: a box tree over the leaves, for region queries of ranges and levels.
//! - [`halo`]: the leaves around one leaf, gathered once for the bounds of its parts.
//! - [`small`]: the tight ranges of small leaves, from their neighbourhood.
//! - [`tight`]: per-leaf ranges from cell values, computed once, skipping leaves the file's
//!   looser stored ranges let through.
//! - [`region`]: limiting an extraction to a clip box or a view frustum.
//! - [`gather`]: the runs of leaves' refs appended to the result, in order.
//! - [`scratch_pool`]: one extraction scratch per worker thread, kept across its runs of leaves.
//! - [`stats`]: what an extraction did.
//! - [`decode_frame`]: what decoding keeps of the leaf decoded last.
//! - [`current`] and [`nearest`]: the active voxels of the `current` and `nearest`
//!   reconstructions, for the hybrid tracer's comparisons.
//!
//! An [`Extractor`] is made once per open file and field; each [`Extractor::extract`] call runs
//! one isovalue. Leaves whose conservative range cannot hold the isovalue are skipped without
//! touching their bricks. The result holds 8 bytes per active voxel, in leaf order and sorted
//! within each leaf, the same on every run and any number of threads.

pub mod around_block;
pub mod band;
pub mod blocks;
pub mod cell_tiles;
pub mod cull;
pub mod current;
pub mod decode_frame;
pub mod dual_index;
pub mod gather;
pub mod halo;
pub mod leaf;
pub mod leaf_tree;
pub mod local;
pub mod nearest;
pub mod parts;
pub mod plain;
pub mod refs;
pub mod region;
pub mod scratch_pool;
pub mod small;
pub mod spare_refs;
pub mod stats;
pub mod tight;
pub mod vertices;

use std::time::Instant;

use spare_refs::SpareRefs;

use amr_format::AmrkFile;

use crate::bvh::CellLattice;
use crate::error::{RenderError, Result};
use rayon::prelude::*;

use crate::mapping::PageRelease;
use crate::reconstruct::interp::straddles;
use crate::reconstruct::{Locate, Octant, SampleScratch, Sampler, VertexMemo};
pub use crate::voxel::Voxel;
use band::CoarseBounds;
use blocks::BlockRanges;
use cell_tiles::CellTiles;
use cull::Shared;
pub use decode_frame::DecodeFrame;
use gather::{append, Run};
use halo::Halo;
use leaf::{LeafCounts, LeafFrame, Scratch};
use leaf_tree::LeafTree;
use parts::{extract_in_parts, in_parts, leaf_part_ranges, PartRanges};
pub use refs::{make_ref, split_ref, LocalVoxel, DUAL_BASE};
pub use region::Region;
use scratch_pool::ScratchPool;
pub use stats::ExtractStats;
use tight::{box_range_in, TightRanges};

/// Leaves handed to the thread pool at a time, at most; bounds the memory held beside the result.
const CHUNK_LEAVES: usize = 4096;
/// Cell bytes of the leaves of one chunk (at each leaf's own level), at most, unless one leaf
/// holds more: bounds the map pages a chunk touches, released after it.
const CHUNK_BYTES: u64 = 64 << 20;

/// Refs a run of leaves makes room for when it starts (512 KiB, more than the CLI's mmap
/// threshold of 256 KiB): its vector is then a mapping of its own, whose pages are first touched
/// as refs are written and which grows by remapping, where a vector grown by doubling from
/// nothing wrote its refs again into each larger block, fresh pages of its thread's heap
/// (`tiny` iso 10: 33 and 47 faults fewer at one and two threads, `big` 36 at each).
const RUN_REFS: usize = 1 << 16;

/// The active voxels of one isovalue and what finding them took.
#[derive(Clone, Debug, Default)]
pub struct Extraction {
    /// References, in leaf order, sorted within each leaf.
    pub refs: Vec<u64>,
    /// Statistics.
    pub stats: ExtractStats,
}

/// A test of an extraction's refs so far (the isovalue, how many), run after each chunk of
/// leaves: an error stops the extraction with it ([`Extractor::set_refs_check`]).
pub type RefsCheck = Box<dyn Fn(f32, usize) -> Result<()> + Send + Sync>;

/// Extracts and decodes active voxels of one field of an open file.
pub struct Extractor<'f, D> {
    sampler: Sampler<'f, D>,
    file_cells: u64,
    tight: TightRanges<'f>,
    parts: PartRanges,
    blocks: BlockRanges,
    leaves: LeafTree,
    coarse: CoarseBounds,
    cells: CellTiles,
    /// Whether small leaves take their neighbourhoods from [`Self::cells`] ([`CellTiles::pays`]).
    tiled: bool,
    pages: Option<PageRelease<'f>>,
    refs_check: Option<RefsCheck>,
}

impl<'f, D: AsRef<[u8]> + Sync> Extractor<'f, D> {
    /// An extractor for field `field` of `file`, decoding compressed bricks through a shared
    /// cache of about `cache_bytes`.
    pub fn new(file: &'f AmrkFile<D>, field: usize, cache_bytes: usize) -> Result<Self> {
        let sampler = Sampler::new(file, field, cache_bytes)?;
        // Start the worker threads now, with the file open, not inside the first extraction.
        rayon::broadcast(|_| ());
        let file_cells = file
            .bricks()
            .map(|b| b.cells.num_cells().unwrap_or(0))
            .sum();
        Ok(Self {
            tight: TightRanges::of_file(file, field),
            parts: PartRanges::of_file(&sampler)?,
            blocks: BlockRanges::new(file),
            leaves: LeafTree::new(&sampler),
            coarse: CoarseBounds::default(),
            cells: CellTiles::default(),
            tiled: CellTiles::pays(&sampler),
            sampler,
            file_cells,
            pages: None,
            refs_check: None,
        })
    }

    /// True when small leaves take their neighbourhoods from cell tiles
    /// ([`CellTiles::pays`]), which depends on the file alone.
    pub fn uses_cell_tiles(&self) -> bool {
        self.tiled
    }

    /// Releases `pages` after each chunk of leaves, so that the map's resident bytes stay
    /// bounded by what one chunk touches; the statistics' `resident_bytes` becomes the sum over
    /// chunks of the map bytes resident at the end of each chunk.
    pub fn set_page_release(&mut self, pages: PageRelease<'f>) {
        self.pages = Some(pages);
    }

    /// Runs `check` on the refs found so far after each chunk of leaves an extraction takes
    /// (a file is taken in chunks when its map is larger than 64 MiB or its pages may be
    /// released, [`Self::set_page_release`]; a smaller one in one piece, unchecked): a caller
    /// that will need memory for each ref (a BVH) stops an extraction whose refs will not fit,
    /// before the refs themselves outgrow the memory left.
    pub fn set_refs_check(&mut self, check: RefsCheck) {
        self.refs_check = Some(check);
    }

    /// The page release set with [`Self::set_page_release`].
    pub fn page_release(&self) -> Option<&PageRelease<'f>> {
        self.pages.as_ref()
    }

    /// Drops the map's pages from the resident set when a [`PageRelease`] is set; returns the
    /// bytes that were resident.
    pub fn release_pages(&self) -> Option<u64> {
        self.pages.as_ref().and_then(PageRelease::release)
    }

    /// The sampler underneath.
    pub fn sampler(&self) -> &Sampler<'f, D> {
        &self.sampler
    }

    /// Whether [`Self::extract_leaves`] cuts its leaves into chunks: when a release set may drop
    /// the map's pages after each chunk, or the map is larger than one chunk's bytes. A smaller
    /// map, never dropped, would pay each chunk's barrier and helper thread for nothing.
    fn drops_pages(&self) -> bool {
        let map = self.sampler.file().bytes().len() as u64;
        self.pages.as_ref().is_some_and(|p| p.may_drop()) || map > CHUNK_BYTES
    }

    /// `leaves` cut into runs of at most [`CHUNK_LEAVES`] leaves and about [`CHUNK_BYTES`] of
    /// their cells.
    fn chunks<'l>(&self, leaves: &'l [u32]) -> Vec<&'l [u32]> {
        // A chunk touches at most the whole map: a map that small leaves the leaf count alone
        // to cut, without a serial pass over every leaf's box before the workers start.
        if self.sampler.file().bytes().len() as u64 <= CHUNK_BYTES {
            return leaves.chunks(CHUNK_LEAVES).collect();
        }
        let grid = self.sampler.grid();
        let tree = self.sampler.file().tree();
        let bytes = |l: u32| -> u64 {
            let Some((_, level)) = self.sampler.leaf_top(l) else {
                return 0;
            };
            let cells = grid.level_box(level, &tree.leaf_box(l)).num_cells();
            cells.unwrap_or(u64::MAX).saturating_mul(4)
        };
        let mut out = Vec::new();
        let (mut start, mut sum) = (0, 0u64);
        for (i, &l) in leaves.iter().enumerate() {
            let b = bytes(l);
            if i > start && (i - start == CHUNK_LEAVES || sum.saturating_add(b) > CHUNK_BYTES) {
                out.push(&leaves[start..i]);
                (start, sum) = (i, 0);
            }
            sum = sum.saturating_add(b);
        }
        if start < leaves.len() {
            out.push(&leaves[start..]);
        }
        out
    }

    /// Asks for the stored bytes of the bricks under `leaves` to be read ahead, when a
    /// [`PageRelease`] is set: a chunk's bricks are then read while the chunk before it is
    /// extracted, and the reads of one chunk are queued together rather than one fault at a time.
    fn read_ahead(&self, leaves: &[u32]) {
        /// Ranges closer than this are read as one.
        const GAP: u64 = 64 << 10;
        let Some(pages) = &self.pages else {
            return;
        };
        let file = self.sampler.file();
        let field = self.sampler.field();
        // Each brick once (neighbouring leaves share bricks), in brick order: one bit each.
        let mut wanted = vec![0u64; file.num_bricks().div_ceil(64)];
        for b in file.bricks_of_leaves(leaves).flatten() {
            let b = b.get() as usize;
            wanted[b / 64] |= 1 << (b % 64);
        }
        let mut merged = MergedRanges::default();
        for (w, &word) in wanted.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let b = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let d = file.brick_data(field, b);
                merged.add((d.offset, d.offset.saturating_add(d.len)), GAP);
            }
        }
        let merged = merged.finish(GAP);
        pages.read_ahead(merged.into_iter().map(|(start, end)| (start, end - start)));
    }

    /// The active voxels for `iso`: those whose corner values `v` satisfy
    /// `min v < iso <= max v`.
    pub fn extract(&self, iso: f32) -> Result<Extraction> {
        self.extract_leaves(iso, &self.candidate_leaves(iso))
    }

    /// The leaves whose stored value range may hold `iso`, in leaf order: their tight ranges
    /// when the file stores them, else the looser leaf ranges.
    pub fn candidate_leaves(&self, iso: f32) -> Vec<u32> {
        let file = self.sampler.file();
        let field = self.sampler.field();
        if !file.has_tight_ranges() {
            return candidate_leaves(&self.sampler, iso);
        }
        (0..file.num_leaves() as u32)
            .filter(|&l| {
                let (lo, hi) = file
                    .tight_range(field, l)
                    .unwrap_or((f32::NEG_INFINITY, f32::INFINITY));
                straddles(lo, hi, iso)
            })
            .collect()
    }

    /// [`Self::extract`] over the given `leaves` only (a subset of the candidates, as when MPI
    /// ranks share the extraction): their active voxels, in the order of `leaves`.
    pub fn extract_leaves(&self, iso: f32, leaves: &[u32]) -> Result<Extraction> {
        let start = Instant::now();
        let file = self.sampler.file();
        let field = self.sampler.field();
        let decodes = self.sampler.decodes();
        let mut refs = Vec::new();
        let mut totals = LeafCounts::default();
        let mut active_duals = 0;
        let mut touched: Option<u64> = None;
        // Tight ranges read the stored tables alone (no brick data) when the file has them.
        let loose = self.blocks.loose();
        let tight_blocks = if self.blocks.stored() {
            &loose
        } else {
            &self.blocks
        };
        let tiles = self.tiled.then_some(&self.cells);
        let scratches = ScratchPool::new(self.shared(), tiles);
        let spare = SpareRefs::default();
        let chunks = if self.drops_pages() {
            self.chunks(leaves)
        } else {
            vec![leaves]
        };
        if let [only] = chunks[..] {
            // Nothing to read ahead or append beside the workers. The chunk's reads are asked
            // for beside its extraction (one thread works out the ranges while the others take
            // leaves), and the map's pages are released (and measured) beside the result's copies.
            let ((), runs) = rayon::join(
                || self.read_ahead(only),
                || self.extract_chunk(iso, only, tight_blocks, (&scratches, &spare)),
            );
            let (released, appended) = rayon::join(
                || self.release_pages(),
                || {
                    append(
                        runs,
                        &mut refs,
                        (&mut totals, &mut active_duals),
                        &spare,
                        true,
                    )
                },
            );
            appended?;
            touched = released;
        } else {
            if let Some(first) = chunks.first() {
                self.read_ahead(first);
            }
            let mut done: Vec<Run> = Vec::new();
            for (k, chunk) in chunks.iter().enumerate() {
                let next = chunks.get(k + 1);
                let (parts, appended) = std::thread::scope(|s| {
                    // While the workers extract this chunk, another thread asks for the next
                    // chunk's reads and appends the chunk before's refs: neither waits for the
                    // other, and the workers no longer wait for them between chunks.
                    let before = std::mem::take(&mut done);
                    let (refs, totals, duals) = (&mut refs, &mut totals, &mut active_duals);
                    let spare = &spare;
                    let helper = s.spawn(move || {
                        if let Some(next) = next {
                            self.read_ahead(next);
                        }
                        append(before, refs, (totals, duals), spare, false)
                    });
                    let parts = self.extract_chunk(iso, chunk, tight_blocks, (&scratches, spare));
                    (parts, helper.join())
                });
                match appended {
                    Ok(r) => r?,
                    Err(panic) => std::panic::resume_unwind(panic),
                }
                done = parts;
                if let Some(b) = self.release_pages() {
                    touched = Some(touched.unwrap_or(0) + b);
                }
                if let Some(check) = &self.refs_check {
                    let pending: usize = done.iter().flatten().map(|(r, _)| r.len()).sum();
                    check(iso, refs.len() + pending)?;
                }
            }
            // The workers are done: the pool shares the copies.
            append(
                done,
                &mut refs,
                (&mut totals, &mut active_duals),
                &spare,
                true,
            )?;
        }
        refs.shrink_to_fit();
        let stats = ExtractStats {
            field: file.fields()[field].name.clone(),
            iso,
            active: refs.len() as u64,
            active_duals,
            leaves_visited: leaves.len() as u64,
            leaves_skipped: totals.skipped,
            leaves_total: file.num_leaves() as u64,
            evaluated: totals.evaluated,
            boundary_evaluated: totals.boundary,
            culled_cells: totals.culled,
            culled_octants: totals.octants_culled,
            parts_skipped: totals.parts_skipped,
            file_cells: self.file_cells,
            seconds: start.elapsed().as_secs_f64(),
            threads: rayon::current_num_threads(),
            decompressions: self.sampler.decodes() - decodes,
            resident_bytes: touched,
            file_bytes: file.bytes().len() as u64,
        };
        Ok(Extraction { refs, stats })
    }

    /// The refs and counts of `chunk`'s leaves, in parallel: one entry per run of consecutive
    /// leaves a worker extracted (the refs of its leaves one after the other, its counts
    /// summed), in order; tight ranges not known yet are bounded through `tight_blocks`. A run
    /// ends at its first error. One vector per run rather than per leaf: small leaves' few refs
    /// each were as many allocations, and their fresh pages. A run works in its thread's
    /// scratch from `scratches` and writes into a vector from `spare`.
    fn extract_chunk<'s>(
        &'s self,
        iso: f32,
        chunk: &[u32],
        tight_blocks: &BlockRanges,
        (scratches, spare): (&ScratchPool<'s>, &SpareRefs),
    ) -> Vec<Run> {
        chunk
            .par_iter()
            .fold(
                || {
                    let mut refs = spare.take();
                    refs.reserve(RUN_REFS);
                    (scratches.take(), Ok((refs, LeafCounts::default())))
                },
                |(mut scratch, run), &leaf| {
                    let run = run.and_then(|(mut out, mut totals)| {
                        let counts =
                            self.extract_one(&mut scratch, iso, leaf, tight_blocks, &mut out)?;
                        totals.add(&counts);
                        Ok((out, totals))
                    });
                    (scratch, run)
                },
            )
            .map(|(scratch, run)| {
                scratches.give(scratch);
                run
            })
            .collect()
    }

    /// Appends the refs of `leaf` for `iso` to `out`; its counts.
    fn extract_one(
        &self,
        scratch: &mut Scratch<'_>,
        iso: f32,
        leaf: u32,
        tight_blocks: &BlockRanges,
        out: &mut Vec<u64>,
    ) -> Result<LeafCounts> {
        let mut around = None;
        let (lo, hi) = self.tight.get_with(leaf, || {
            let (range, halo) = self.compute_tight(scratch, leaf, tight_blocks)?;
            around = halo;
            Ok(range)
        })?;
        if !straddles(lo, hi, iso) {
            return Ok(LeafCounts {
                skipped: 1,
                ..LeafCounts::default()
            });
        }
        let Some(frame) = LeafFrame::new(&self.sampler, leaf) else {
            return Ok(LeafCounts::default());
        };
        extract_in_parts(
            &self.sampler,
            &frame,
            iso,
            (scratch, (&self.blocks, &self.leaves), &self.parts),
            around.as_ref(),
            out,
        )
    }

    /// The tables every leaf's cull reads.
    fn shared(&self) -> Shared<'_> {
        Shared {
            blocks: &self.blocks,
            leaves: &self.leaves,
            coarse: &self.coarse,
            tight: &self.tight,
        }
    }

    /// The tight range of `leaf` computed from the file's data and tables, whatever the file
    /// stores, and for a leaf extracted in parts the leaves around it, gathered once for its
    /// tight range and its parts' bounds.
    fn compute_tight<'a>(
        &'a self,
        scratch: &mut Scratch<'_>,
        leaf: u32,
        tight_blocks: &'a BlockRanges,
    ) -> Result<RangeAndHalo<'a, 'f, D>> {
        let bounds = (tight_blocks, &self.leaves);
        let own = self.sampler.file().tree().leaf_box(leaf);
        if let Some((_, level)) = self.sampler.leaf_top(leaf) {
            let cells = self.sampler.grid().level_box(level, &own);
            if in_parts(&self.sampler, &cells) {
                let around = Halo::new(&self.sampler, bounds, &own, level);
                if let Some(h) = &around {
                    let range = box_range_in(&self.sampler, h, &own, level)?;
                    return Ok((range, around));
                }
            }
        }
        let range = match small::hood_range(&self.sampler, scratch, leaf)? {
            Some(range) => range,
            None => tight::compute(&self.sampler, bounds, leaf)?,
        };
        Ok((range, None))
    }

    /// The tight range of every leaf and the bounds of its parts, computed from the file's data
    /// and tables (what a file of layout version 4 stores, see [`tight_tables_of`]), whatever
    /// the file stores, passed to `each` leaf after leaf (the leaf, its tight range and its
    /// parts' bounds, empty for a leaf extracted whole); leaves in parallel, a chunk at
    /// a time, releasing the map's pages after each chunk when a [`PageRelease`] is set. Only
    /// one chunk's results are held at a time.
    pub fn computed_tables(
        &self,
        mut each: impl FnMut(u32, (f32, f32), &[(f32, f32)]) -> Result<()>,
    ) -> Result<()> {
        let loose = self.blocks.loose();
        let tight_blocks = if self.blocks.stored() {
            &loose
        } else {
            &self.blocks
        };
        let file = self.sampler.file();
        let all: Vec<u32> = (0..file.num_leaves() as u32).collect();
        for chunk in self.chunks(&all) {
            let tables: Vec<Result<LeafTables>> = chunk
                .par_iter()
                .map_init(
                    || {
                        let shared = self.shared();
                        let tiles = self.tiled.then_some(&self.cells);
                        Scratch::new(shared, tiles)
                    },
                    |scratch, &leaf| {
                        let (range, around) = self.compute_tight(scratch, leaf, tight_blocks)?;
                        let parts = match LeafFrame::new(&self.sampler, leaf) {
                            Some(frame) => leaf_part_ranges(
                                &self.sampler,
                                &frame,
                                (&self.blocks, &self.leaves),
                                around.as_ref(),
                            )?,
                            None => Vec::new(),
                        };
                        Ok((range, parts))
                    },
                )
                .collect();
            for (&leaf, t) in chunk.iter().zip(tables) {
                let (range, parts) = t?;
                each(leaf, range, &parts)?;
            }
            self.release_pages();
        }
        Ok(())
    }

    /// The tight range of every leaf computed from the file's data and tables, whatever the
    /// file stores ([`Self::computed_tables`] without the parts' bounds).
    pub fn computed_tight_ranges(&self) -> Result<Vec<(f32, f32)>> {
        let mut out = Vec::with_capacity(self.sampler.file().num_leaves());
        self.computed_tables(|_, range, _| {
            out.push(range);
            Ok(())
        })?;
        Ok(out)
    }

    /// True when the bounds of the parts of large leaves are read from the file (layout
    /// version 4), not computed.
    pub fn stored_part_ranges(&self) -> bool {
        self.parts.stored()
    }

    /// The voxel reference `r` names: its box and its eight corner values, recomputed from the
    /// file. An error when `r` names no voxel of this file.
    pub fn decode(&self, r: u64) -> Result<Voxel> {
        self.decode_memo(r, &mut VertexMemo::default())
    }

    /// [`Self::decode`], remembering vertex values in `memo` for the next calls (a memo must
    /// serve one sampler only: values are keyed by position).
    pub fn decode_memo(&self, r: u64, memo: &mut VertexMemo) -> Result<Voxel> {
        self.decode_in(r, &self.sampler, memo, &mut None)
    }

    /// [`Self::decode`] through a per-thread `scratch`, which remembers the leaves, vertex
    /// values and octant corners that nearby voxels and samples share, and `last`, the frame of
    /// the leaf decoded last (kept for the next call; it must serve this extractor only).
    // Inline: the tracer's voxel cache calls it on every miss, from another codegen unit.
    #[inline]
    pub fn decode_with(
        &self,
        r: u64,
        scratch: &mut SampleScratch,
        last: &mut Option<DecodeFrame>,
    ) -> Result<Voxel> {
        let (loc, memo) = scratch.bind(&self.sampler);
        self.decode_in(r, &loc, memo, last)
    }

    /// [`Self::decode_memo`], locating leaf cells through `loc` and reusing `last`
    /// ([`Self::resolve_in`]).
    #[inline]
    fn decode_in<L: Locate>(
        &self,
        r: u64,
        loc: &L,
        memo: &mut VertexMemo,
        last: &mut Option<DecodeFrame>,
    ) -> Result<Voxel> {
        let at = self.locate_in(r, last)?;
        let Some(frame) = last.as_ref() else {
            return Err(bad_ref(r, "no such leaf"));
        };
        self.values_in(r, &at, frame, loc, memo)
    }

    /// The voxel `r` names located in its leaf, with its box, its values not read: what
    /// [`Self::decode_located`] needs besides the leaf's frame, which `last` then holds
    /// ([`Self::resolve_in`]).
    #[inline(always)]
    pub fn locate_with(&self, r: u64, last: &mut Option<DecodeFrame>) -> Result<LocatedVoxel> {
        self.locate_in(r, last)
    }

    /// [`Self::decode_with`] of the voxel `r` that [`Self::locate_with`] located as `at`,
    /// `last` the frame it left.
    #[inline(always)]
    pub fn decode_located(
        &self,
        r: u64,
        at: &LocatedVoxel,
        scratch: &mut SampleScratch,
        last: &Option<DecodeFrame>,
    ) -> Result<Voxel> {
        let Some(frame) = last.as_ref().filter(|f| f.frame.leaf == split_ref(r).0) else {
            return Err(bad_ref(r, "no such leaf"));
        };
        let (loc, memo) = scratch.bind(&self.sampler);
        self.values_in(r, at, frame, &loc, memo)
    }

    /// The voxel `r` names located in its leaf (whose frame `last` then holds).
    #[inline(always)]
    fn locate_in(&self, r: u64, last: &mut Option<DecodeFrame>) -> Result<LocatedVoxel> {
        let (leaf, local) = split_ref(r);
        if last.is_none_or(|f| f.frame.leaf != leaf) {
            self.load_frame(r, last)?;
        }
        let Some(frame) = last.as_ref() else {
            return Err(bad_ref(r, "no such leaf"));
        };
        frame
            .locate(local)
            .ok_or_else(|| bad_ref(r, "cell index past the leaf"))
    }

    /// The voxel located as `at` in the leaf of `frame`, its values read.
    #[inline(always)]
    fn values_in<L: Locate>(
        &self,
        r: u64,
        at: &LocatedVoxel,
        frame: &DecodeFrame,
        loc: &L,
        memo: &mut VertexMemo,
    ) -> Result<Voxel> {
        let grid = self.sampler.grid();
        let LocatedVoxel {
            level,
            cell,
            octant,
            lo,
            hi,
        } = *at;
        let values = match octant {
            Some(octant) => {
                let o = Octant {
                    level,
                    cell,
                    octant,
                };
                self.sampler
                    .octant_values_in(loc, &o, memo)?
                    .ok_or_else(|| bad_ref(r, "no values there"))?
            }
            None => match self.dual_block_in_leaf(frame, cell) {
                Some(values) => values,
                None => {
                    // The corners that are corners of the leaf's dual cells are read from its
                    // brick, the others located.
                    let brick = frame.frame.brick;
                    let here = frame
                        .dual_index
                        .and_then(|_| self.sampler.values_in_place(brick));
                    let mut values = [0f32; 8];
                    for (n, v) in values.iter_mut().enumerate() {
                        let c = [0, 1, 2].map(|a| cell[a] + (n >> a & 1) as i64);
                        if let Some(x) = here.and_then(|values| frame.corner_value(values, c)) {
                            *v = x;
                            continue;
                        }
                        let at = grid.finest_cell(grid.centre(level, c), 7);
                        match loc.locate_cell(at)? {
                            Some(leaf_cell) if leaf_cell.level == level && leaf_cell.cell == c => {
                                *v = leaf_cell.value
                            }
                            _ => return Err(bad_ref(r, "not a merged dual cell")),
                        }
                    }
                    values
                }
            },
        };
        Ok(Voxel {
            lo: lo.map(|v| v as f64),
            hi: hi.map(|v| v as f64),
            values,
            level,
        })
    }

    /// The values of the merged dual cell whose lowest cell is `cell` (of `frame`'s level), read
    /// from the brick of `frame`'s leaf in one go when its eight cells lie in that leaf (whose
    /// cells are all of that level; [`DecodeFrame::duals`]) and the brick is read in place;
    /// `None` leaves them to be located one by one, which gives the same values where both do.
    #[inline(always)]
    fn dual_block_in_leaf(&self, frame: &DecodeFrame, cell: [i64; 3]) -> Option<[f32; 8]> {
        if !frame.duals.contains_cell(cell) {
            return None;
        }
        let brick = frame.frame.brick;
        match frame.dual_index {
            // The brick holds the eight cells of every dual cell of the box.
            Some(index) => index.block(self.sampler.values_in_place(brick)?, cell),
            None => self.sampler.brick_block(brick, cell, cell.map(|c| c + 1)),
        }
    }

    /// The box, in doubled coordinates, of the voxel `r` names, from the reference alone: no
    /// brick data is read (the BVH build needs only boxes).
    pub fn voxel_box(&self, r: u64) -> Result<([i64; 3], [i64; 3])> {
        let (frame, cell, octant) = self.resolve(r)?;
        Ok(self.doubled_box(frame.frame.level, cell, octant))
    }

    /// [`Self::voxel_box`] of each of `refs`, in order, passed to `out`; the frames of the last
    /// few leaves met are kept, so that refs of a few leaves interleaved (as a BVH orders them)
    /// or in runs (as the extraction emits them) find each leaf's frame once.
    pub fn voxel_boxes(&self, refs: &[u64], mut out: impl FnMut(Result<([i64; 3], [i64; 3])>)) {
        let mut frames: [Option<BoxFrame>; 16] = [None; 16];
        for &r in refs {
            let leaf = (r >> 32) as u32;
            let slot = &mut frames[leaf as usize % 16];
            let frame = match slot {
                Some(f) if f.leaf == leaf => Ok(&*f),
                _ => self.box_frame(r).map(|f| &*slot.insert(f)),
            };
            // One call of `out` and of `voxel_box`, which the compiler then puts inline.
            out(frame.and_then(|f| f.voxel_box(r)));
        }
    }

    /// [`Self::voxel_boxes`] a run of consecutive refs of one leaf at a time, for the BVH build:
    /// `run` gets the boxes of each run's refs ([`LeafBoxes`]), whose leaf is looked up once (the
    /// extraction emits a leaf's refs in one run). A ref that names no voxel gets the empty box
    /// at the origin (as [`crate::voxel::Voxel::EMPTY`]), and the first such ref of a run its
    /// error, passed to `bad` after the run.
    #[inline(always)]
    pub fn voxel_box_runs(
        &self,
        refs: &[u64],
        mut run: impl FnMut(LeafBoxes<'_, '_, 'f, D>),
        mut bad: impl FnMut(RenderError),
    ) {
        let mut frames: [Option<BoxFrame>; 16] = [None; 16];
        let mut error = None;
        let mut rest = refs;
        while let Some(&r) = rest.first() {
            let leaf = (r >> 32) as u32;
            let n = rest
                .iter()
                .position(|&q| (q >> 32) as u32 != leaf)
                .unwrap_or(rest.len());
            let (mine, after) = rest.split_at(n);
            rest = after;
            let slot = &mut frames[leaf as usize % 16];
            let frame = match slot {
                Some(f) if f.leaf == leaf => *f,
                // A leaf not in the file: a frame of no cells, past which every index falls.
                _ => match self.box_frame(r) {
                    Ok(f) => *slot.insert(f),
                    Err(_) => BoxFrame::NONE,
                },
            };
            run(LeafBoxes {
                refs: mine.iter(),
                frame,
                extractor: self,
                error: &mut error,
            });
            if let Some(e) = error.take() {
                bad(e);
            }
        }
    }

    /// What [`Self::voxel_boxes`] keeps of the leaf of `r` to compute its voxels' boxes.
    fn box_frame(&self, r: u64) -> Result<BoxFrame> {
        let leaf = (r >> 32) as u32;
        if leaf as usize >= self.sampler.file().num_leaves() {
            return Err(bad_ref(r, "no such leaf"));
        }
        let frame = LeafFrame::new(&self.sampler, leaf)
            .ok_or_else(|| bad_ref(r, "the leaf holds no brick"))?;
        let e = frame.cells.extent();
        let (Ok(e0), Ok(e1)) = (u32::try_from(e[0]), u32::try_from(e[1])) else {
            return Err(bad_ref(r, "the leaf's extent is out of range"));
        };
        let grid = self.sampler.grid();
        Ok(BoxFrame {
            leaf,
            extent: (e0, e1),
            cells: e[0] * e[1] * e[2],
            lowest: grid.centre(frame.level, frame.cells.lo),
            scale: grid.scale(frame.level),
        })
    }

    /// The leaf of the voxel `r` names, its level-`L` cell (absolute index) and its octant, or
    /// `None` for a merged dual cell (the cell is then the dual cell's lowest).
    fn resolve(&self, r: u64) -> Result<(DecodeFrame, [i64; 3], Option<u8>)> {
        let mut last = None;
        let (frame, cell, octant) = self.resolve_in(r, &mut last)?;
        Ok((*frame, cell, octant))
    }

    /// [`Self::resolve`], reusing `last`, the frame of the leaf resolved last, when `r` is in the
    /// same leaf (and keeping `r`'s there).
    fn resolve_in<'l>(
        &self,
        r: u64,
        last: &'l mut Option<DecodeFrame>,
    ) -> Result<(&'l DecodeFrame, [i64; 3], Option<u8>)> {
        let (leaf, local) = split_ref(r);
        if last.is_none_or(|f| f.frame.leaf != leaf) {
            self.load_frame(r, last)?;
        }
        let Some(frame) = last.as_ref() else {
            return Err(bad_ref(r, "no such leaf"));
        };
        let (index, octant) = match local {
            LocalVoxel::Octant { cell, octant } => (cell, Some(octant)),
            LocalVoxel::Dual { cell } => (cell, None),
        };
        let cell = frame
            .cell(index)
            .ok_or_else(|| bad_ref(r, "cell index past the leaf"))?;
        Ok((frame, cell, octant))
    }

    /// Puts the frame of the leaf of `r` in `last` (an error when `r` names no leaf of this
    /// file with a brick), for [`Self::resolve_in`] and [`Self::locate_in`]: out of line, as the
    /// voxels of a walk come from a few leaves at a time.
    #[cold]
    #[inline(never)]
    fn load_frame(&self, r: u64, last: &mut Option<DecodeFrame>) -> Result<()> {
        let leaf = split_ref(r).0;
        if leaf as usize >= self.sampler.file().num_leaves() {
            return Err(bad_ref(r, "no such leaf"));
        }
        let frame = LeafFrame::new(&self.sampler, leaf)
            .ok_or_else(|| bad_ref(r, "the leaf holds no brick"))?;
        let mut decode = DecodeFrame::new(self.sampler.grid(), frame)
            .ok_or_else(|| bad_ref(r, "the leaf's extent is out of range"))?;
        decode.index_duals_in(&self.sampler.brick_cells(frame.brick));
        *last = Some(decode);
        Ok(())
    }

    /// The doubled-coordinate box of octant `octant` of level-`level` cell `cell`, or of the dual
    /// cell whose lowest cell is `cell` when `octant` is `None`.
    fn doubled_box(&self, level: u32, cell: [i64; 3], octant: Option<u8>) -> ([i64; 3], [i64; 3]) {
        match octant {
            Some(octant) => self.sampler.octant_box(&Octant {
                level,
                cell,
                octant,
            }),
            None => {
                let lo = self.sampler.grid().centre(level, cell);
                let s = self.sampler.grid().scale(level);
                (lo, [0, 1, 2].map(|a| lo[a] + 2 * s[a]))
            }
        }
    }
}

/// A voxel located from its ref ([`Extractor::locate_with`]): its level, cell and octant (none
/// for a merged dual cell), and its box in doubled coordinates.
#[derive(Clone, Copy, Debug)]
pub struct LocatedVoxel {
    level: u32,
    cell: [i64; 3],
    octant: Option<u8>,
    /// The box's lower corner.
    pub lo: [i64; 3],
    /// The box's upper corner.
    pub hi: [i64; 3],
}

/// A leaf's tight range and its parts' bounds.
type LeafTables = ((f32, f32), Vec<(f32, f32)>);

/// A leaf's tight range, and the leaves around it when they were gathered to compute it.
type RangeAndHalo<'a, 'f, D> = ((f32, f32), Option<Halo<'a, 'f, D>>);

/// A leaf's cells as [`Extractor::voxel_boxes`] needs them: the boxes of its voxels from their
/// local indices alone.
#[derive(Clone, Copy)]
struct BoxFrame {
    leaf: u32,
    /// The leaf's level-`L` cells per axis along x and y.
    extent: (u32, u32),
    /// Its level-`L` cells.
    cells: i64,
    /// The doubled centre of its lowest level-`L` cell.
    lowest: [i64; 3],
    /// The width of a level-`L` cell in finest cells.
    scale: [i64; 3],
}

impl BoxFrame {
    /// The frame of no leaf: every ref's cell index is past it.
    const NONE: Self = Self {
        leaf: u32::MAX,
        extent: (1, 1),
        cells: 0,
        lowest: [0; 3],
        scale: [0; 3],
    };

    /// [`Extractor::voxel_box`] of `r`, a ref of this leaf: the same boxes as
    /// [`Extractor::doubled_box`] of [`Extractor::resolve`].
    #[inline(always)]
    fn voxel_box(&self, r: u64) -> Result<([i64; 3], [i64; 3])> {
        self.box_of(r)
            .ok_or_else(|| bad_ref(r, "cell index past the leaf"))
    }

    /// [`BoxFrame::voxel_box`] with `None` for a cell index past the leaf: no error to carry,
    /// so that a run's boxes stay in registers.
    #[inline(always)]
    fn box_of(&self, r: u64) -> Option<([i64; 3], [i64; 3])> {
        let (index, octant) = match LocalVoxel::from_id(r as u32) {
            LocalVoxel::Octant { cell, octant } => (cell, Some(octant)),
            LocalVoxel::Dual { cell } => (cell, None),
        };
        if i64::from(index) >= self.cells {
            return None;
        }
        let (e0, e1) = self.extent;
        let row = index / e0;
        let d = [index % e0, row % e1, row / e1].map(i64::from);
        let s = self.scale;
        let c = [0, 1, 2].map(|a| self.lowest[a] + 2 * d[a] * s[a]);
        Some(match octant {
            None => (c, [0, 1, 2].map(|a| c[a] + 2 * s[a])),
            Some(octant) => {
                // Octant bit `a` set: the upper half of the cell on axis `a`, which starts at `c`.
                let up = |a: usize| octant >> a & 1 != 0;
                let lo = [0, 1, 2].map(|a| if up(a) { c[a] } else { c[a] - s[a] });
                (lo, [0, 1, 2].map(|a| lo[a] + s[a]))
            }
        })
    }
}

/// The boxes of a run of refs of one leaf ([`Extractor::voxel_box_runs`]): each ref's
/// [`Extractor::voxel_box`], in order.
pub struct LeafBoxes<'r, 'e, 'f, D> {
    refs: std::slice::Iter<'r, u64>,
    /// The leaf's frame ([`BoxFrame::NONE`] when the leaf is not one of the file's).
    frame: BoxFrame,
    extractor: &'e Extractor<'f, D>,
    /// The error of the first ref that names no voxel.
    error: &'r mut Option<RenderError>,
}

impl<D: AsRef<[u8]> + Sync> Iterator for LeafBoxes<'_, '_, '_, D> {
    type Item = ([i64; 3], [i64; 3]);

    #[inline(always)]
    fn next(&mut self) -> Option<Self::Item> {
        let &r = self.refs.next()?;
        Some(match self.frame.box_of(r) {
            Some(b) => b,
            None => {
                self.bad(r);
                ([0; 3], [0; 3])
            }
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.refs.size_hint()
    }
}

impl<'r, D: AsRef<[u8]> + Sync> LeafBoxes<'r, '_, '_, D> {
    /// The leaf's merged dual cells as a lattice: the boxes [`Extractor::voxel_box`] gives
    /// their refs. `None` for a leaf not in the file or of more cells than ids.
    pub fn duals(&self) -> Option<CellLattice> {
        let f = &self.frame;
        if f.leaf == BoxFrame::NONE.leaf {
            return None;
        }
        let double = f.scale.map(|s| 2 * s);
        Some(CellLattice {
            first_id: DUAL_BASE,
            extent: [f.extent.0, f.extent.1],
            cells: u32::try_from(f.cells).ok()?,
            lowest: f.lowest,
            step: double,
            size: double,
        })
    }

    /// The refs whose boxes are still to come.
    pub fn rest(&self) -> &'r [u64] {
        self.refs.as_slice()
    }

    /// Passes over the next `n` refs (whose boxes were pushed otherwise).
    pub fn skip_refs(&mut self, n: usize) {
        let rest = self.refs.as_slice();
        self.refs = rest[n.min(rest.len())..].iter();
    }

    /// Keeps the error of `r` (the one [`Extractor::voxel_box`] gives) unless one is kept (its
    /// box is then the empty box at the origin).
    #[cold]
    #[inline(never)]
    fn bad(&mut self, r: u64) {
        if self.error.is_none() {
            let e = match self.extractor.voxel_box(r) {
                Err(e) => e,
                Ok(_) => bad_ref(r, "no such voxel"),
            };
            *self.error = Some(e);
        }
    }
}

/// Byte ranges with those closer than a gap joined, built one range at a time: writers store
/// bricks in order, so the ranges usually come sorted by start and are merged as they come,
/// without gathering them first.
#[derive(Default)]
struct MergedRanges {
    ranges: Vec<(u64, u64)>,
    /// A range came with a start below the one before.
    unsorted: bool,
}

impl MergedRanges {
    /// Adds `(start, end)`, joined to the last range when it starts within `gap` of its end
    /// and not before its start.
    fn add(&mut self, (start, end): (u64, u64), gap: u64) {
        match self.ranges.last_mut() {
            Some(last) if last.0 <= start && start <= last.1.saturating_add(gap) => {
                last.1 = last.1.max(end);
            }
            Some(last) => {
                self.unsorted |= start < last.0;
                self.ranges.push((start, end));
            }
            None => self.ranges.push((start, end)),
        }
    }

    /// The ranges sorted by start, those closer than `gap` joined (a joined range covers the
    /// same bytes, gaps included, as its parts, so joining some early changes nothing).
    fn finish(mut self, gap: u64) -> Vec<(u64, u64)> {
        if !self.unsorted {
            return self.ranges;
        }
        self.ranges.sort_unstable();
        let mut sorted = MergedRanges::default();
        for r in self.ranges {
            sorted.add(r, gap);
        }
        sorted.ranges
    }
}

/// The leaves of `sampler`'s file whose stored value range of its field may hold `iso`, in leaf
/// order.
pub fn candidate_leaves<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, iso: f32) -> Vec<u32> {
    let file = sampler.file();
    let field = sampler.field();
    (0..file.num_leaves() as u32)
        .filter(|&l| {
            let (lo, hi) = file.leaf_range(field, l);
            straddles(lo, hi, iso)
        })
        .collect()
}

/// The refs `per_leaf` gives for each candidate leaf of `iso` ([`candidate_leaves`]), leaves in
/// parallel, concatenated in leaf order; the first error stops it.
pub fn over_candidate_leaves<D: AsRef<[u8]> + Sync>(
    sampler: &Sampler<'_, D>,
    iso: f32,
    per_leaf: impl Fn(u32) -> Result<Vec<u64>> + Sync,
) -> Result<Vec<u64>> {
    over_leaves(&candidate_leaves(sampler, iso), per_leaf)
}

/// The refs `per_leaf` gives for each of `leaves`, in parallel, concatenated in the order given;
/// the first error stops it.
pub fn over_leaves(
    leaves: &[u32],
    per_leaf: impl Fn(u32) -> Result<Vec<u64>> + Sync,
) -> Result<Vec<u64>> {
    let parts: Vec<Result<Vec<u64>>> = leaves.par_iter().map(|&leaf| per_leaf(leaf)).collect();
    let mut refs = Vec::new();
    for p in parts {
        refs.extend_from_slice(&p?);
    }
    Ok(refs)
}

/// The tight range of every leaf of every field of the `.amrk` file at `path` and the bounds of
/// the parts of its large leaves, computed from its data and handed to `sink` leaf after leaf,
/// field after field: what a file of layout version 4 stores ([`amr_format::WriterOptions::tight`]).
/// Maps the file, releasing its pages after each chunk of leaves, and holds one chunk's results
/// at a time, so that memory stays bounded on large files.
pub fn tight_tables_of(
    path: &std::path::Path,
    sink: &mut amr_format::TightSink<'_, '_>,
) -> std::result::Result<(), String> {
    /// Bytes of the shared cache of decoded compressed bricks.
    const CACHE_BYTES: usize = 256 << 20;
    let file = crate::mapping::open_mapped(path).map_err(|e| e.to_string())?;
    if let Some(k) = file.block_cells().and_then(parts::part_cells) {
        sink.set_part_cells(k)?;
    }
    for field in 0..file.fields().len() {
        let mut ex = Extractor::new(&file, field, CACHE_BYTES).map_err(|e| e.to_string())?;
        ex.set_page_release(PageRelease::new(&file));
        ex.computed_tables(|_, range, parts| sink.push(range, parts).map_err(RenderError::Invalid))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// [`amr_format::WriterOptions`] with `compression` that store the tight leaf ranges
/// ([`tight_tables_of`]): what every writer of this workspace uses by default.
pub fn writer_options(compression: amr_format::Compression) -> amr_format::WriterOptions {
    amr_format::WriterOptions {
        compression,
        tight: Some(tight_tables_of),
    }
}

/// The error for a reference that names no voxel of the file.
fn bad_ref(r: u64, what: &str) -> RenderError {
    RenderError::BadVoxelRef {
        r,
        what: what.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::MergedRanges;

    /// Sorted first, then joined: what [`MergedRanges`] must give whatever the order.
    fn sorted_then_joined(mut ranges: Vec<(u64, u64)>, gap: u64) -> Vec<(u64, u64)> {
        ranges.sort_unstable();
        let mut out: Vec<(u64, u64)> = Vec::new();
        for (start, end) in ranges {
            match out.last_mut() {
                Some(last) if start <= last.1.saturating_add(gap) => last.1 = last.1.max(end),
                _ => out.push((start, end)),
            }
        }
        out
    }

    #[test]
    fn merged_ranges_match_a_sort_then_a_join() {
        let mut x = 12345u64;
        let mut next = |m: u64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x % m
        };
        for case in 0..200 {
            let n = 1 + next(40) as usize;
            let mut at = 0;
            let ranges: Vec<(u64, u64)> = (0..n)
                .map(|_| {
                    // Mostly in order, as writers store bricks; some cases shuffled.
                    let start = if case % 3 == 0 {
                        next(1000)
                    } else {
                        at + next(30)
                    };
                    at = start;
                    (start, start + 1 + next(20))
                })
                .collect();
            let gap = next(16);
            let mut merged = MergedRanges::default();
            for &r in &ranges {
                merged.add(r, gap);
            }
            assert_eq!(merged.finish(gap), sorted_then_joined(ranges, gap));
        }
    }
}
