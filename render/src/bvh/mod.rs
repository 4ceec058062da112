//! A two-level BVH of compressed wide BVHs (obvhs's CWBVH8 layout) over active voxel refs.
//!
//! Only the refs and the BVH nodes stay resident: a voxel's box is decoded from its ref while
//! building, and its corner values while tracing. The refs are split into chunks of
//! [`BvhBuilder::chunk_refs`] consecutive refs (the extraction emits them in kd-leaf order, so a
//! chunk is spatially compact); each chunk gets its own BVH, one chunk per thread at a time (the
//! threads take all the chunks in one parallel pass, each chunk whole), and a top-level
//! BVH is built over the chunks' boxes. Each BVH is built directly in Morton order
//! ([`wide`]) by default, or with obvhs's PLOC and CWBVH conversion ([`BuildMethod::Ploc`]). The
//! build scratch is bounded by the chunk size times the threads, not by the number of refs. After a chunk's build its refs are put in its BVH's leaf
//! order, so obvhs's primitive index array is dropped and a chunk's primitive `i` is simply its
//! `i`-th ref; the
//! chunks are likewise put in the top-level BVH's leaf order. [`BvhBuilder`] keeps the scratch so
//! that a new isovalue rebuilds without reallocating. A source writes each box straight into the
//! build's scratch ([`BoxRun`]), in `f32` and with its centre's Morton code on a grid fixed by the
//! domain ([`BoxGrid`]), so a chunk's sort keys need no pass over its boxes.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use obvhs::ploc::PlocBuilder;
use obvhs::ray::Ray;
use obvhs::BvhBuildParams;
use rayon::prelude::*;

mod lattice;
mod node_test;
pub mod packet;
mod packet_any;
#[cfg(target_arch = "x86_64")]
mod packet_mixed;
#[cfg(test)]
mod test_scene;
mod walk;
pub mod wide;

pub use lattice::CellLattice;
pub use node_test::T_MIN;
use packet::{Mask, PacketStack};
use packet_any::walk_packet_of;
use walk::{walk, Stack};
use wide::{centre_codes, morton, WideBuilder};

/// Refs whose boxes one task decodes when a lone chunk's boxes are decoded in parallel runs.
const DECODE_RUN: usize = 4096;

/// Refs whose boxes are decoded between two calls of the build's `between_chunks` (which
/// releases the file's pages that decoding touched: leaf metadata only, and each call costs a
/// scan of the process's page tables).
const RELEASE_REFS: usize = 1 << 20;

/// Bytes of one CWBVH node (obvhs: "repr(C), Pod, 80 bytes").
pub const NODE_BYTES: usize = 80;

/// Default refs per chunk: the build scratch stays near 18 MB per chunk, and the top level
/// stays small (about 100 chunks for 7.6 M refs).
pub const CHUNK_REFS: usize = 1 << 16;

/// A BVH over active voxels, each named by a 64-bit ref.
#[derive(Clone, Default, Debug)]
pub struct OctantBvh {
    refs: Vec<u64>,
    /// The chunks, in the top-level BVH's leaf order.
    chunks: Vec<Chunk>,
    /// Over the chunks' boxes; its primitive `c` is `chunks[c]`. Empty when there is one chunk.
    top: CwBvh,
    /// The union of the refs' boxes as given to the build, before padding.
    bounds: Option<([f64; 3], [f64; 3])>,
}

/// One chunk: its BVH, whose primitive `i` is `refs[first + i]`.
#[derive(Clone, Default, Debug)]
struct Chunk {
    first: usize,
    len: usize,
    bvh: CwBvh,
}

/// How each chunk's BVH (and the top level) is built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildMethod {
    /// Directly as a wide BVH from the boxes' Morton order ([`wide`]).
    #[default]
    Morton,
    /// obvhs's PLOC binary BVH, reinsertion, then its SAH conversion to CWBVH (the build before
    /// [`BuildMethod::Morton`], kept for comparison).
    Ploc,
}

/// Build scratch kept between builds: one [`Worker`] per thread, each building one chunk at a
/// time.
pub struct BvhBuilder {
    workers: Vec<Worker>,
    /// Refs per chunk (at least 1); `usize::MAX` builds one BVH over all refs.
    pub chunk_refs: usize,
    /// How the BVHs are built.
    pub method: BuildMethod,
    /// Bytes of scratch held at the end of the last build (boxes, PLOC buffers, binary BVH).
    pub last_scratch_bytes: usize,
}

/// How a build stores voxel boxes: each grown by a pad (grid units), and its centre's Morton
/// code on a grid of `2^21` steps per axis over `[0, extent]`, each step a power of two of grid
/// units, so that boxes with integer corners give the exact Morton order of their centres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxGrid {
    pad: f64,
    /// Grid steps per unit of a centre's coordinate sum `lo + hi`: `2^up / 2^down`.
    scale: f64,
    up: u32,
    down: u32,
}

impl BoxGrid {
    /// Boxes grown by `pad`, inside `[0, extent]` on every axis.
    pub fn new(pad: f64, extent: f64) -> Self {
        // A centre's sum `lo + hi` is below `2 extent`, below `2^e` with `e` the exponent of
        // `2 extent` plus one: `2^21` steps of `2^(e - 21)` cover it.
        let top = (2.0 * extent).max(1.0);
        let e = ((top.to_bits() >> 52) & 0x7ff) as i64 - 1023 + 1;
        Self {
            pad,
            scale: f64::from_bits(((1023 + 21 - e) as u64) << 52),
            up: (21 - e).clamp(0, 63) as u32,
            down: (e - 21).clamp(0, 63) as u32,
        }
    }
}

/// The boxes of a run of consecutive refs, as a source writes them for the build
/// ([`crate::trace::VoxelSource::voxel_boxes`]): [`BoxRun::push`] once per ref, in order.
pub struct BoxRun<'a> {
    boxes: &'a mut [Aabb],
    codes: &'a mut [u64],
    grid: BoxGrid,
    next: usize,
    /// The union of the boxes pushed in `f64`.
    union: Bounds,
    /// The union of the boxes pushed in integers.
    int_lo: [i64; 3],
    int_hi: [i64; 3],
}

impl<'a> BoxRun<'a> {
    /// A run writing to `boxes` and `codes` (as long as its refs) on `grid`.
    pub fn new(boxes: &'a mut [Aabb], codes: &'a mut [u64], grid: BoxGrid) -> Self {
        Self {
            boxes,
            codes,
            grid,
            next: 0,
            union: Bounds::EMPTY,
            int_lo: [i64::MAX; 3],
            int_hi: [i64::MIN; 3],
        }
    }

    /// Adds the box `(lo, hi)`, in grid coordinates, of the run's next ref.
    #[inline]
    pub fn push(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        self.union.add(lo, hi);
        // A NaN converts to step 0.
        let step = |a: usize| ((lo[a] + hi[a]) * self.grid.scale).clamp(0.0, STEPS as f64) as u32;
        let code = morton([step(0), step(1), step(2)]);
        self.put(lo, hi, code);
    }

    /// [`BoxRun::push`] of each box with integer corners `boxes` gives, in order, the union
    /// kept in registers over the run.
    #[inline(always)]
    pub fn push_ints(&mut self, boxes: impl Iterator<Item = ([i64; 3], [i64; 3])>) {
        self.push_ints_coded(boxes, morton);
    }

    /// [`BoxRun::push_ints`] with `code` for [`morton`] (which it must equal).
    #[inline(always)]
    pub fn push_ints_coded(
        &mut self,
        boxes: impl Iterator<Item = ([i64; 3], [i64; 3])>,
        code: impl Fn([u32; 3]) -> u64,
    ) {
        let (mut union_lo, mut union_hi) = (self.int_lo, self.int_hi);
        let (up, down, pad) = (self.grid.up, self.grid.down, self.grid.pad);
        // Locals rather than fields, which every store of a box might overwrite for all the
        // compiler knows.
        let start = self.next;
        let out = self.boxes.get_mut(start..).unwrap_or_default();
        let codes = self.codes.get_mut(start..).unwrap_or_default();
        let mut n = 0;
        for (lo, hi) in boxes {
            for a in 0..3 {
                union_lo[a] = union_lo[a].min(lo[a]);
                union_hi[a] = union_hi[a].max(hi[a]);
            }
            if n >= out.len() || n >= codes.len() {
                continue;
            }
            // Valid boxes lie in the grid; others only get a code of no meaning.
            let step = |a: usize| (lo[a].wrapping_add(hi[a]) << up >> down) as u32 & STEPS;
            codes[n] = code([step(0), step(1), step(2)]);
            let f = |p: [i64; 3]| p.map(|x| x as f64);
            out[n] = padded(f(lo), f(hi), pad);
            n += 1;
        }
        self.next = start + n;
        (self.int_lo, self.int_hi) = (union_lo, union_hi);
    }

    /// Writes the next box, padded, and its code.
    #[inline(always)]
    fn put(&mut self, lo: [f64; 3], hi: [f64; 3], code: u64) {
        let i = self.next;
        if i >= self.boxes.len() || i >= self.codes.len() {
            return;
        }
        self.boxes[i] = padded(lo, hi, self.grid.pad);
        self.codes[i] = code;
        self.next = i + 1;
    }

    /// The union of the boxes pushed, unpadded.
    fn union(&self) -> Bounds {
        let mut u = self.union;
        if (0..3).all(|a| self.int_lo[a] <= self.int_hi[a]) {
            let f = |p: [i64; 3]| [p[0] as f64, p[1] as f64, p[2] as f64];
            u.add(f(self.int_lo), f(self.int_hi));
        }
        u
    }
}

/// The `f32` box of `(lo, hi)` grown by `pad` on every side.
#[inline(always)]
fn padded(lo: [f64; 3], hi: [f64; 3], pad: f64) -> Aabb {
    let v =
        |p: [f64; 3], s: f64| Vec3A::new((p[0] + s) as f32, (p[1] + s) as f32, (p[2] + s) as f32);
    Aabb::new(v(lo, -pad), v(hi, pad))
}

/// The last grid step of a Morton code's axis.
const STEPS: u32 = (1 << 21) - 1;

/// One thread's build scratch.
#[derive(Default)]
struct Worker {
    boxes: Vec<Aabb>,
    /// The Morton codes of the boxes' centres.
    codes: Vec<u64>,
    wide: WideBuilder,
    ploc: PlocBuilder,
    bvh2: Bvh2,
    reinsertion: ReinsertionOptimizer,
}

impl Default for BvhBuilder {
    fn default() -> Self {
        Self {
            workers: Vec::new(),
            chunk_refs: CHUNK_REFS,
            method: BuildMethod::default(),
            last_scratch_bytes: 0,
        }
    }
}

impl BvhBuilder {
    /// A builder with no scratch allocated yet and chunks of [`CHUNK_REFS`].
    pub fn new() -> Self {
        Self::default()
    }

    /// Builds a BVH over `refs`, whose boxes `boxes(refs, out)` pushes to `out` in order, in grid
    /// coordinates (it is called on runs of consecutive refs); every box is grown by the grid's
    /// pad so that `f32` traversal never misses a voxel the exact
    /// `f64` intersection would hit. `between_chunks` is called from the pool's threads (one
    /// call at a time) about every million refs decoded, and after the last chunk, to release
    /// what decoding the boxes touched. Reuses the scratch and `out`'s buffers.
    pub fn build_into(
        &mut self,
        out: &mut OctantBvh,
        refs: &[u64],
        grid: BoxGrid,
        boxes: impl Fn(&[u64], &mut BoxRun<'_>) + Sync,
        between_chunks: impl Fn() + Sync,
    ) {
        out.refs.clear();
        out.refs.extend_from_slice(refs);
        self.build_refs(out, grid, boxes, between_chunks);
    }

    /// [`BvhBuilder::build_into`] taking the refs by value, which saves a copy of them.
    pub fn build_owned(
        &mut self,
        out: &mut OctantBvh,
        refs: Vec<u64>,
        grid: BoxGrid,
        boxes: impl Fn(&[u64], &mut BoxRun<'_>) + Sync,
        between_chunks: impl Fn() + Sync,
    ) {
        out.refs = refs;
        self.build_refs(out, grid, boxes, between_chunks);
    }

    /// Builds the BVH over `out.refs`.
    fn build_refs(
        &mut self,
        out: &mut OctantBvh,
        grid: BoxGrid,
        boxes: impl Fn(&[u64], &mut BoxRun<'_>) + Sync,
        between_chunks: impl Fn() + Sync,
    ) {
        out.chunks.clear();
        out.top = CwBvh::default();
        out.bounds = None;
        out.refs.shrink_to_fit();
        // Decodes the boxes of `refs` and their codes, and returns their union unpadded.
        let decode = |refs: &[u64], out: &mut [Aabb], codes: &mut [u64]| -> Bounds {
            let mut run = BoxRun::new(out, codes, grid);
            boxes(refs, &mut run);
            run.union()
        };
        let size = self.chunk_refs.max(1);
        let method = self.method;
        let mut parts: Vec<&mut [u64]> = out.refs.chunks_mut(size).collect();
        // The workers' scratch, one taken by each chunk being built: one per thread, as a chunk
        // task waits on nothing in the pool (but obvhs's parallel PLOC build may).
        let pool = Mutex::new(std::mem::take(&mut self.workers));
        let take = || -> Worker {
            let mut workers = pool.lock().unwrap_or_else(PoisonError::into_inner);
            workers.pop().unwrap_or_default()
        };
        let give = |w: Worker| pool.lock().unwrap_or_else(PoisonError::into_inner).push(w);
        // All chunks are built in one parallel pass, in any order on any thread (each chunk's
        // BVH depends only on its refs), and kept in their order. The task whose decoding
        // passes a multiple of `RELEASE_REFS` decoded refs calls `between_chunks`, unless
        // another such call is still running: no thread waits for the others between groups.
        // A lone chunk's boxes are decoded in parallel runs; with more chunks, each task
        // decodes its own.
        let runs = if parts.len() == 1 { DECODE_RUN } else { size };
        let decoded = AtomicUsize::new(0);
        let releasing = Mutex::new(());
        let bvhs: Vec<(CwBvh, Bounds)> = parts
            .par_iter_mut()
            .with_max_len(1)
            .map(|part| {
                let mut w = take();
                w.boxes.clear();
                w.boxes.resize(part.len(), Aabb::empty());
                w.codes.clear();
                w.codes.resize(part.len(), 0);
                let union = w
                    .boxes
                    .par_chunks_mut(runs)
                    .zip(w.codes.par_chunks_mut(runs))
                    .zip(part.par_chunks(runs))
                    .map(|((out, codes), refs)| decode(refs, out, codes))
                    .reduce(|| Bounds::EMPTY, Bounds::union);
                let before = decoded.fetch_add(part.len(), Ordering::Relaxed);
                if (before + part.len()) / RELEASE_REFS > before / RELEASE_REFS {
                    if let Ok(_one) = releasing.try_lock() {
                        between_chunks();
                    }
                }
                let bvh = w.build_level(part, method);
                give(w);
                (bvh, union)
            })
            .collect();
        between_chunks();
        let mut boxes = Vec::with_capacity(bvhs.len());
        let mut first = 0;
        let mut bounds = Bounds::EMPTY;
        for ((bvh, union), part) in bvhs.into_iter().zip(parts.iter()) {
            bounds = bounds.union(union);
            boxes.push(bvh.total_aabb);
            out.chunks.push(Chunk {
                first,
                len: part.len(),
                bvh,
            });
            first += part.len();
        }
        self.workers = pool.into_inner().unwrap_or_else(PoisonError::into_inner);
        if self.workers.is_empty() {
            self.workers.push(Worker::default());
        }
        if out.chunks.len() > 1 {
            let w = &mut self.workers[0];
            w.boxes.clear();
            w.boxes.extend_from_slice(&boxes);
            centre_codes(&w.boxes, &mut w.codes);
            let mut order: Vec<u64> = (0..out.chunks.len() as u64).collect();
            out.top = w.build_level(&mut order, self.method);
            let mut chunks = std::mem::take(&mut out.chunks);
            out.chunks = order
                .iter()
                .map(|&c| std::mem::take(&mut chunks[c as usize]))
                .collect();
        }
        out.bounds = bounds.get();
        self.last_scratch_bytes = self.workers.iter().map(Worker::scratch_bytes).sum();
    }

    /// Builds a new BVH (see [`BvhBuilder::build_into`]) over boxes given one ref at a time,
    /// grown by `pad`, on the grid over the largest of their coordinates.
    pub fn build(
        &mut self,
        refs: &[u64],
        pad: f64,
        bounds: impl Fn(u64) -> ([f64; 3], [f64; 3]) + Sync,
    ) -> OctantBvh {
        let mut out = OctantBvh::default();
        let extent = refs.iter().fold(0.0f64, |m, &r| {
            let (lo, hi) = bounds(r);
            (0..3).fold(m, |m, a| m.max(lo[a].abs()).max(hi[a].abs()))
        });
        let boxes = |refs: &[u64], out: &mut BoxRun<'_>| {
            for &r in refs {
                let (lo, hi) = bounds(r);
                out.push(lo, hi);
            }
        };
        self.build_into(&mut out, refs, BoxGrid::new(pad, extent), boxes, || {});
        out
    }

    /// Frees the scratch (the chunk size and the method are kept).
    pub fn release(&mut self) {
        *self = Self {
            chunk_refs: self.chunk_refs,
            method: self.method,
            ..Self::default()
        };
    }
}

/// A union of boxes, built up one box at a time.
#[derive(Clone, Copy)]
struct Bounds {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Bounds {
    const EMPTY: Self = Self {
        lo: [f64::INFINITY; 3],
        hi: [f64::NEG_INFINITY; 3],
    };

    fn add(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        for k in 0..3 {
            self.lo[k] = self.lo[k].min(lo[k]);
            self.hi[k] = self.hi[k].max(hi[k]);
        }
    }

    fn union(mut self, other: Self) -> Self {
        self.add(other.lo, other.hi);
        self
    }

    /// The union, `None` when no box (or only empty ones) was added.
    fn get(self) -> Option<([f64; 3], [f64; 3])> {
        (0..3)
            .all(|k| self.lo[k] <= self.hi[k])
            .then_some((self.lo, self.hi))
    }
}

impl Worker {
    /// A CWBVH over `self.boxes`, whose primitive `i` is `items[i]` (the items are permuted into
    /// the BVH's leaf order and its primitive index array is handed back to the Morton builder for
    /// the next build).
    fn build_level(&mut self, items: &mut [u64], method: BuildMethod) -> CwBvh {
        let mut bvh = match method {
            BuildMethod::Morton => self.wide.build_coded(&self.boxes, &self.codes),
            BuildMethod::Ploc => self.build_ploc(items.len()),
        };
        let perm = std::mem::take(&mut bvh.primitive_indices);
        gather(items, &perm, self.wide.spare());
        self.wide.recycle(perm);
        bvh.nodes.shrink_to_fit();
        bvh
    }

    /// obvhs's PLOC build, reinsertion and CWBVH conversion over the `n` boxes `self.boxes`.
    fn build_ploc(&mut self, n: usize) -> CwBvh {
        let params = BvhBuildParams::fast_build();
        let indices: Vec<u32> = (0..n as u32).collect();
        self.ploc.build_with_bvh(
            &mut self.bvh2,
            params.ploc_search_distance,
            &self.boxes,
            indices,
            params.sort_precision,
            params.search_depth_threshold,
        );
        self.reinsertion
            .run(&mut self.bvh2, params.reinsertion_batch_ratio, None);
        bvh2_to_cwbvh(
            &self.bvh2,
            params.max_prims_per_leaf.clamp(1, 3),
            true,
            false,
        )
    }

    /// Bytes of scratch held (boxes, sort keys, PLOC buffers, binary BVH).
    fn scratch_bytes(&self) -> usize {
        self.boxes.capacity() * size_of::<Aabb>()
            + self.codes.capacity() * 8
            + self.wide.scratch_bytes()
            + (self.ploc.current_nodes.capacity()
                + self.ploc.next_nodes.capacity()
                + self.bvh2.nodes.capacity())
                * size_of::<Bvh2Node>()
            + self.ploc.mortons.capacity() * 32
            + self.bvh2.primitive_indices.capacity() * 4
    }
}

/// The rays of `active` among `rays` (at most [`packet::PACKET`]) by direction octant: mask
/// `o` holds the rays of octant `o`. Each ray's `-0.0` direction components become `+0.0`
/// first, as the node tests need.
fn by_octant(rays: &mut [Ray], active: Mask) -> [Mask; 8] {
    assert!(
        rays.len() <= packet::PACKET,
        "{} rays in a packet",
        rays.len()
    );
    let mut octants = [0 as Mask; 8];
    for k in packet::rays_of(active) {
        rays[k] = positive_zeros(rays[k]);
        octants[(node_test::octant_inv4(rays[k].direction) & 7) as usize] |= 1 << k;
    }
    octants
}

/// `ray` with `+0.0` for any `-0.0` in its direction. obvhs's node test takes a component's
/// near planes from its sign bit (`< 0.0`, false for `-0.0`) but its inverse from
/// `signum` (negative for `-0.0`): a ray with a `-0.0` component would enter no child at all.
#[inline(always)]
fn positive_zeros(ray: Ray) -> Ray {
    if ray.direction.cmpeq(Vec3A::ZERO).any() {
        Ray::new(ray.origin, ray.direction + Vec3A::ZERO, ray.tmin, ray.tmax)
    } else {
        ray
    }
}

/// `values[i] = old values[perm[i]]`, through `tmp` (independent reads, where following the
/// permutation's cycles in place makes each read wait for the one before).
fn gather(values: &mut [u64], perm: &[u32], tmp: &mut Vec<u64>) {
    tmp.clear();
    tmp.extend(perm.iter().map(|&k| values[k as usize]));
    values.copy_from_slice(tmp);
}

impl OctantBvh {
    /// The union of the refs' boxes, as the build's `boxes` gave them (not padded): the
    /// componentwise least and greatest corners; `None` when there are no refs.
    pub fn voxel_bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        self.bounds
    }

    /// The refs, chunk after chunk, each chunk in its BVH's leaf order.
    pub fn refs(&self) -> &[u64] {
        &self.refs
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.refs.len()
    }

    /// True when the BVH holds no voxel.
    pub fn is_empty(&self) -> bool {
        self.refs.is_empty()
    }

    /// Number of chunks, each with its own BVH under the top level.
    pub fn num_chunks(&self) -> usize {
        self.chunks.len()
    }

    /// Resident bytes of the refs.
    pub fn refs_bytes(&self) -> usize {
        self.refs.capacity() * 8
    }

    /// Resident bytes of the BVH nodes (top level and chunks, and of the chunk list).
    pub fn bvh_bytes(&self) -> usize {
        let nodes: usize = self.chunks.iter().map(|c| c.bvh.nodes.capacity()).sum();
        (nodes + self.top.nodes.capacity()) * NODE_BYTES
            + self.chunks.capacity() * size_of::<Chunk>()
    }

    /// Number of BVH nodes (top level and chunks).
    pub fn num_nodes(&self) -> usize {
        self.top.nodes.len() + self.chunks.iter().map(|c| c.bvh.nodes.len()).sum::<usize>()
    }

    /// Calls `visit(r, &mut tmax)` for the refs of every leaf the `f32` ray reaches before its
    /// `tmax`, nearer leaves roughly first; `visit` may lower `tmax` (closest-hit search) and
    /// returns `true` to stop (any-hit search). The refs and their order are those of obvhs's
    /// traversal; the node test runs eight children wide with AVX2 when the CPU has it
    /// (the `node_test` module). A `-0.0` in the direction is taken as `+0.0`.
    #[inline]
    pub fn traverse(&self, ray: Ray, mut visit: impl FnMut(u64, &mut f32) -> bool) {
        self.traverse_indexed(ray, |_, r, tmax| visit(r, tmax));
    }

    /// [`OctantBvh::traverse`] telling `visit` also where each ref is in [`OctantBvh::refs`]:
    /// `visit(i, refs()[i], &mut tmax)`.
    #[inline]
    pub fn traverse_indexed(&self, ray: Ray, mut visit: impl FnMut(usize, u64, &mut f32) -> bool) {
        let mut ray = positive_zeros(ray);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            unsafe { self.traverse_avx2(&mut ray, &mut visit) };
            return;
        }
        self.traverse_with(&mut ray, &mut visit, node_test::hits_portable);
    }

    /// [`OctantBvh::traverse`] as on a CPU without AVX2 (obvhs's node test), to compare the two.
    pub fn traverse_portable(&self, ray: Ray, mut visit: impl FnMut(u64, &mut f32) -> bool) {
        let mut ray = positive_zeros(ray);
        self.traverse_with(
            &mut ray,
            &mut |_, r, tmax: &mut f32| visit(r, tmax),
            node_test::hits_portable,
        );
    }

    /// [`OctantBvh::traverse_indexed`] with the AVX2 node test, the whole walk compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn traverse_avx2(&self, ray: &mut Ray, visit: &mut impl FnMut(usize, u64, &mut f32) -> bool) {
        let consts = node_test::Avx2Ray::new(ray, node_test::octant_inv4(ray.direction));
        self.traverse_with(ray, visit, |node, ray, _| consts.hits(node, ray.tmax));
    }

    /// [`OctantBvh::traverse_indexed`] for the rays of `active` among `rays` (at most
    /// [`packet::PACKET`]) together: `visit(i, refs()[i], m, rays)` is called with the rays `m`
    /// that reach the ref, and may lower their `tmax` (closest-hit searches; there is no stop).
    /// Each ray gets exactly the visits, in the same order and under the same `tmax`, that
    /// [`OctantBvh::traverse_indexed`] would give it alone; rays are grouped by direction octant
    /// into packets ([`packet`]). Each ray's `-0.0` direction components become `+0.0`.
    pub fn traverse_packet(
        &self,
        rays: &mut [Ray],
        active: Mask,
        mut visit: impl FnMut(usize, u64, Mask, &mut [Ray]),
    ) {
        let octants = by_octant(rays, active);
        let mut stack = PacketStack::with_capacity(256);
        let mut visit = |i: usize, r: u64, m: Mask, rays: &mut [Ray]| -> Mask {
            visit(i, r, m, rays);
            0
        };
        for (o, &m) in octants.iter().enumerate() {
            if m == 0 {
                continue;
            }
            let oct = (o as u32) * 0x0101_0101;
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2, checked just above.
                unsafe { self.packet_avx2::<false>(rays, m, oct, &mut stack, &mut visit) };
                continue;
            }
            self.packet_portable::<false>(rays, m, oct, &mut stack, &mut visit);
        }
    }

    /// The any-hit walk of the rays of `active` among `rays` (at most [`packet::PACKET`]) in
    /// one walk whatever their direction octants: `visit(i, refs()[i], m, rays)` is called with
    /// the rays `m` that reach the ref and are still live, and returns those of them it ends
    /// (their walk stops there). Until it is ended, each ray reaches exactly the refs
    /// [`OctantBvh::traverse_indexed`] would give it alone under the same `tmax` (at a node, the
    /// rays of each octant take [`OctantBvh::traverse_packet`]'s test of that octant), but the
    /// children are taken farthest first in the order of one octant for all
    /// ([`packet_any`]): for queries whose answer does not depend on the order (any-hit), the
    /// rays of all the octants then share the walk's nodes and the visits of the voxels they
    /// reach, where [`OctantBvh::traverse_packet`] walks each octant from the root. Each ray's
    /// `-0.0` direction components become `+0.0`.
    pub fn traverse_packet_any(
        &self,
        rays: &mut [Ray],
        active: Mask,
        visit: impl FnMut(usize, u64, Mask, &mut [Ray]) -> Mask,
    ) {
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::arch::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        self.packet_any_on(rays, active, avx2, visit);
    }

    /// [`OctantBvh::traverse_packet_any`] with the AVX2 node test when `avx2` (the CPU must have
    /// it), else the portable one.
    fn packet_any_on(
        &self,
        rays: &mut [Ray],
        active: Mask,
        avx2: bool,
        mut visit: impl FnMut(usize, u64, Mask, &mut [Ray]) -> Mask,
    ) {
        let octants = by_octant(rays, active);
        if active == 0 {
            return;
        }
        let first = active.trailing_zeros() as usize;
        let oct = (node_test::octant_inv4(rays[first].direction) & 7) * 0x0101_0101;
        let mut stack = PacketStack::with_capacity(256);
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: the caller's promise: the CPU has AVX2.
            unsafe {
                if octants.contains(&active) {
                    // One octant (shadow rays, all parallel): its test alone, no loop over
                    // the octants at every node.
                    self.packet_avx2::<true>(rays, active, oct, &mut stack, &mut visit);
                } else {
                    self.packet_any_avx2(rays, active, &octants, oct, &mut stack, &mut visit);
                }
            };
            return;
        }
        let _ = avx2;
        self.packet_with::<true>(
            rays,
            active,
            oct,
            &mut stack,
            &mut visit,
            |node, rays, m, e| {
                let mut slots = 0;
                for (o, &of_o) in octants.iter().enumerate() {
                    if m & of_o != 0 {
                        let oct = (o as u32) * 0x0101_0101;
                        slots |= packet::children_portable(node, rays, m & of_o, oct, e);
                    }
                }
                slots
            },
            |node, ray| {
                packet::ray_children_portable(node, ray, node_test::octant_inv4(ray.direction))
            },
        );
    }

    /// [`OctantBvh::traverse_packet_any`] with the AVX2 node tests of a packet of several
    /// octants (`octants[o]`, the rays of octant `o`), the whole walk compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn packet_any_avx2(
        &self,
        rays: &mut [Ray],
        m: Mask,
        octants: &[Mask; 8],
        oct: u32,
        stack: &mut PacketStack,
        visit: &mut impl FnMut(usize, u64, Mask, &mut [Ray]) -> Mask,
    ) {
        let mut lanes: packet_mixed::MixedLanes =
            [const { std::mem::MaybeUninit::uninit() }; packet::PACKET / 8];
        let test = packet_mixed::MixedPacket::new(&mut lanes, rays, m);
        self.packet_with::<true>(
            rays,
            m,
            oct,
            stack,
            visit,
            |node, rays, m, e| {
                if m.count_ones() < packet_any::OCTANTS_RAY_BY_RAY_BELOW {
                    return packet_any::children_of_octants(node, rays, m, octants, e);
                }
                test.children(node, rays, m, e)
            },
            // The ray's octant, as `by_octant` found it (no `-0.0` left in its direction).
            |node, ray| packet::ray_children(node, ray, node_test::octant_inv4(ray.direction)),
        );
    }

    /// [`OctantBvh::traverse_packet`] on a CPU without AVX2, to compare with the AVX2 test.
    #[cfg(test)]
    fn traverse_packet_portable(
        &self,
        rays: &mut [Ray],
        active: Mask,
        mut visit: impl FnMut(usize, u64, Mask, &mut [Ray]),
    ) {
        let mut octants = [0 as Mask; 8];
        for k in packet::rays_of(active) {
            rays[k] = positive_zeros(rays[k]);
            octants[(node_test::octant_inv4(rays[k].direction) & 7) as usize] |= 1 << k;
        }
        let mut stack = PacketStack::new();
        let mut visit = |i: usize, r: u64, m: Mask, rays: &mut [Ray]| -> Mask {
            visit(i, r, m, rays);
            0
        };
        for (o, &m) in octants.iter().enumerate() {
            let oct = (o as u32) * 0x0101_0101;
            self.packet_portable::<false>(rays, m, oct, &mut stack, &mut visit);
        }
    }

    /// One octant's packet (`oct`) with the AVX2 node test, the whole walk compiled for AVX2:
    /// any-hit when `ANY`, else closest-hit ([`OctantBvh::packet_with`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn packet_avx2<const ANY: bool>(
        &self,
        rays: &mut [Ray],
        m: Mask,
        oct: u32,
        stack: &mut PacketStack,
        visit: &mut impl FnMut(usize, u64, Mask, &mut [Ray]) -> Mask,
    ) {
        let mut lanes: packet::Avx2Lanes =
            [const { std::mem::MaybeUninit::uninit() }; packet::PACKET / 8];
        let test = packet::Avx2Packet::new(&mut lanes, rays, m, oct);
        self.packet_with::<ANY>(
            rays,
            m,
            oct,
            stack,
            visit,
            |node, rays, m, e| test.children(node, rays, m, e),
            |node, ray| packet::ray_children(node, ray, oct),
        );
    }

    /// The packet walk of `m`'s rays of octant `oct` with the portable node tests.
    fn packet_portable<const ANY: bool>(
        &self,
        rays: &mut [Ray],
        m: Mask,
        oct: u32,
        stack: &mut PacketStack,
        visit: &mut impl FnMut(usize, u64, Mask, &mut [Ray]) -> Mask,
    ) {
        self.packet_with::<ANY>(
            rays,
            m,
            oct,
            stack,
            visit,
            |node, rays, m, e| packet::children_portable(node, rays, m, oct, e),
            |node, ray| packet::ray_children_portable(node, ray, oct),
        );
    }

    /// One packet's walk, children in the order of octant `oct`: the top level, then each chunk
    /// it reaches, with the node test `test` (and `test_one` at an any-hit walk's node reached
    /// by one ray, [`walk_packet_any`]). Any-hit ([`walk_packet_any`]) when `ANY`, where
    /// `visit` returns the rays it ends; else closest-hit ([`walk_packet`]), where it ends none
    /// and what it returns is ignored.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn packet_with<const ANY: bool>(
        &self,
        rays: &mut [Ray],
        m: Mask,
        oct: u32,
        stack: &mut PacketStack,
        visit: &mut impl FnMut(usize, u64, Mask, &mut [Ray]) -> Mask,
        test: impl Fn(&CwBvhNode, &[Ray], Mask, &mut [Mask; 8]) -> u32 + Copy,
        test_one: impl Fn(&CwBvhNode, &Ray) -> u32 + Copy,
    ) {
        let mut chunk_walk = |chunk: &Chunk, rays: &mut [Ray], m: Mask, stack: &mut PacketStack| {
            let refs = &self.refs[chunk.first..chunk.first + chunk.len];
            walk_packet_of::<ANY>(
                &chunk.bvh.nodes,
                rays,
                m,
                oct,
                stack,
                test,
                test_one,
                |i, m, rays, _| {
                    let i = i as usize;
                    visit(chunk.first + i, refs[i], m, rays)
                },
            )
        };
        if let [chunk] = self.chunks.as_slice() {
            chunk_walk(chunk, rays, m, stack);
            return;
        }
        walk_packet_of::<ANY>(
            &self.top.nodes,
            rays,
            m,
            oct,
            stack,
            test,
            test_one,
            |c, m, rays, stack| chunk_walk(&self.chunks[c as usize], rays, m, stack),
        );
    }

    /// The top level, then each chunk it reaches, with the node test `test`.
    #[inline(always)]
    fn traverse_with(
        &self,
        ray: &mut Ray,
        visit: &mut impl FnMut(usize, u64, &mut f32) -> bool,
        test: impl Fn(&CwBvhNode, &Ray, u32) -> u32 + Copy,
    ) {
        let oct = node_test::octant_inv4(ray.direction);
        let mut stack = Stack::new();
        if let [chunk] = self.chunks.as_slice() {
            self.walk_chunk(chunk, ray, oct, &mut stack, test, visit);
            return;
        }
        walk(
            &self.top.nodes,
            ray,
            oct,
            &mut stack,
            test,
            |c, ray, stack| self.walk_chunk(&self.chunks[c as usize], ray, oct, stack, test, visit),
        );
    }

    /// The walk in one chunk; true when `visit` asked to stop.
    #[inline(always)]
    fn walk_chunk(
        &self,
        chunk: &Chunk,
        ray: &mut Ray,
        oct: u32,
        stack: &mut Stack,
        test: impl Fn(&CwBvhNode, &Ray, u32) -> u32,
        visit: &mut impl FnMut(usize, u64, &mut f32) -> bool,
    ) -> bool {
        let refs = &self.refs[chunk.first..chunk.first + chunk.len];
        walk(&chunk.bvh.nodes, ray, oct, stack, test, |i, ray, _| {
            let i = i as usize;
            visit(chunk.first + i, refs[i], &mut ray.tmax)
        })
    }

    /// [`OctantBvh::traverse`] with obvhs's own `traverse!` loop and node test: the reference
    /// the walk must match visit for visit.
    #[cfg(test)]
    fn traverse_obvhs(&self, mut ray: Ray, mut visit: impl FnMut(u64, &mut f32) -> bool) {
        use glam::UVec2;
        let chunk_walk =
            |chunk: &Chunk, ray: &mut Ray, visit: &mut dyn FnMut(u64, &mut f32) -> bool| {
                let bvh = &chunk.bvh;
                if bvh.nodes.is_empty() {
                    return false;
                }
                let refs = &self.refs[chunk.first..chunk.first + chunk.len];
                let mut state = bvh.new_traversal(ray.direction);
                let mut node;
                let mut stopped = false;
                obvhs::traverse!(bvh, node, state, node.intersect_ray(ray, state.oct_inv4), {
                    if visit(refs[state.primitive_id as usize], &mut ray.tmax) {
                        stopped = true;
                        state.stack.clear();
                        state.current_group = UVec2::ZERO;
                        break;
                    }
                });
                stopped
            };
        if let [chunk] = self.chunks.as_slice() {
            chunk_walk(chunk, &mut ray, &mut visit);
            return;
        }
        if self.top.nodes.is_empty() {
            return;
        }
        let top = &self.top;
        let mut state = top.new_traversal(ray.direction);
        let mut node;
        obvhs::traverse!(
            top,
            node,
            state,
            node.intersect_ray(&ray, state.oct_inv4),
            {
                let chunk = &self.chunks[state.primitive_id as usize];
                if chunk_walk(chunk, &mut ray, &mut visit) {
                    state.stack.clear();
                    state.current_group = UVec2::ZERO;
                    break;
                }
            }
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gather_permutes() {
        let mut v: Vec<u64> = vec![10, 11, 12, 13, 14];
        let p: Vec<u32> = vec![3, 0, 4, 1, 2];
        gather(&mut v, &p, &mut Vec::new());
        assert_eq!(v, vec![13, 10, 14, 11, 12]);
    }

    fn grid_boxes(r: u64) -> ([f64; 3], [f64; 3]) {
        let (x, y, z) = ((r % 10) as f64, ((r / 10) % 10) as f64, (r / 100) as f64);
        ([x, y, z], [x + 1.0, y + 1.0, z + 1.0])
    }

    /// Every ref visited by a ray, sorted.
    fn visited(bvh: &OctantBvh, ray: Ray) -> Vec<u64> {
        let mut seen = Vec::new();
        bvh.traverse(ray, |r, _| {
            seen.push(r);
            false
        });
        seen.sort();
        seen
    }

    /// Refs whose box, shrunk by a margin, the ray crosses (slab test).
    fn clearly_hit(refs: &[u64], origin: Vec3A, dir: Vec3A) -> Vec<u64> {
        refs.iter()
            .copied()
            .filter(|&r| {
                let (lo, hi) = grid_boxes(r);
                let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
                for a in 0..3 {
                    let (o, d) = (f64::from(origin[a]), f64::from(dir[a]));
                    let (l, h) = (lo[a] + 1e-3, hi[a] - 1e-3);
                    if d == 0.0 {
                        if o <= l || o >= h {
                            return false;
                        }
                        continue;
                    }
                    let (ta, tb) = ((l - o) / d, (h - o) / d);
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                }
                t0 < t1
            })
            .collect()
    }

    #[test]
    fn chunks_visit_every_box_a_ray_crosses_and_stop_when_asked() {
        let refs: Vec<u64> = (0..1000).collect();
        let one = BvhBuilder::new().build(&refs, 1e-4, grid_boxes);
        let mut builder = BvhBuilder::new();
        builder.chunk_refs = 64;
        let chunked = builder.build(&refs, 1e-4, grid_boxes);
        assert_eq!(one.num_chunks(), 1);
        assert_eq!(chunked.num_chunks(), 16);
        let mut sorted = chunked.refs().to_vec();
        sorted.sort();
        assert_eq!(sorted, refs);
        let mut crossed = 0;
        for k in 0..50 {
            let a = k as f32 * 0.37;
            let origin = Vec3A::new(-2.0, 5.0 + 3.0 * a.sin(), 5.0 + 3.0 * a.cos());
            let dir = Vec3A::new(1.0, 0.2 * a.cos(), -0.3 * a.sin()).normalize();
            let ray = Ray::new(origin, dir, 0.0, f32::INFINITY);
            let seen = visited(&chunked, ray);
            let hit = clearly_hit(&refs, origin, dir);
            crossed += hit.len();
            for r in &hit {
                assert!(seen.contains(r), "ray {k}: chunked BVH missed {r}");
                assert!(
                    visited(&one, ray).contains(r),
                    "ray {k}: one BVH missed {r}"
                );
            }
            if seen.is_empty() {
                continue;
            }
            let mut calls = 0;
            chunked.traverse(ray, |_, _| {
                calls += 1;
                true
            });
            assert_eq!(calls, 1, "ray {k}: the traversal went on after a stop");
        }
        assert!(crossed > 200, "the rays cross only {crossed} boxes");
    }

    #[test]
    fn one_pass_over_the_chunks_releases_pages_and_builds_what_one_thread_builds() {
        let refs: Vec<u64> = (0..(RELEASE_REFS + RELEASE_REFS / 8) as u64).collect();
        let build = |threads: usize| {
            let calls = AtomicUsize::new(0);
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let bvh = pool.install(|| {
                let mut out = OctantBvh::default();
                let boxes = |refs: &[u64], run: &mut BoxRun<'_>| {
                    for &r in refs {
                        let (lo, hi) = grid_boxes(r);
                        run.push(lo, hi);
                    }
                };
                let grid = BoxGrid::new(1e-4, 20_000.0);
                BvhBuilder::new().build_into(&mut out, &refs, grid, boxes, || {
                    calls.fetch_add(1, Ordering::Relaxed);
                });
                out
            });
            (bvh, calls.into_inner())
        };
        let (one, one_calls) = build(1);
        let (two, two_calls) = build(2);
        // One release past the first million refs decoded, one after the last chunk.
        assert_eq!((one_calls, two_calls), (2, 2));
        assert_eq!(one.refs(), two.refs());
        assert_eq!(one.num_chunks(), two.num_chunks());
        assert_eq!(one.num_nodes(), two.num_nodes());
        assert_eq!(one.voxel_bounds(), two.voxel_bounds());
    }

    /// Boxes of mixed sizes scattered in a 100-cube, one per ref.
    /// 20,000 scattered boxes built in chunks, in one piece and by PLOC.
    fn scattered_builds() -> [(&'static str, OctantBvh); 3] {
        let refs: Vec<u64> = (0..20_000).collect();
        let mut builder = BvhBuilder::new();
        builder.chunk_refs = 1500;
        let chunked = builder.build(&refs, 1e-4, scattered_boxes);
        let one = BvhBuilder::new().build(&refs, 1e-4, scattered_boxes);
        builder.method = BuildMethod::Ploc;
        let ploc = builder.build(&refs, 1e-4, scattered_boxes);
        [("chunked", chunked), ("one", one), ("ploc", ploc)]
    }

    fn scattered_boxes(r: u64) -> ([f64; 3], [f64; 3]) {
        let h = |k: u64| {
            let x = (r * 4 + k + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            ((x ^ (x >> 29)).wrapping_mul(0xbf58_476d_1ce4_e5b9) >> 11) as f64 / (1u64 << 53) as f64
        };
        let lo = [h(0) * 100.0, h(1) * 100.0, h(2) * 100.0];
        let s = 0.2 + 3.0 * h(3) * h(3);
        (lo, [lo[0] + s, lo[1] + s * 0.7, lo[2] + s * 1.3])
    }

    /// The refs a traversal visits, in order, each with the `tmax` it was visited under; every
    /// seventh visit lowers `tmax` (as a closest hit does) and, with `stop_at`, the traversal
    /// stops at that visit.
    fn visits(
        traverse: impl FnOnce(Ray, &mut dyn FnMut(u64, &mut f32) -> bool),
        ray: Ray,
        stop_at: Option<usize>,
    ) -> Vec<(u64, u32)> {
        let mut seen = Vec::new();
        traverse(ray, &mut |r, tmax| {
            seen.push((r, tmax.to_bits()));
            if seen.len() % 7 == 0 {
                *tmax *= 0.9;
            }
            stop_at == Some(seen.len())
        });
        seen
    }

    #[test]
    fn walk_visits_what_obvhs_visits_nearest_first() {
        let mut visited = 0;
        for (name, bvh) in &scattered_builds() {
            for k in 0..300u32 {
                let a = k as f32 * 0.618;
                let origin = Vec3A::new(
                    50.0 + 80.0 * a.cos(),
                    50.0 + 80.0 * a.sin(),
                    30.0 + (k % 40) as f32,
                );
                let mut dir = (Vec3A::new(50.0, 50.0, 50.0) - origin
                    + Vec3A::new((a * 3.1).sin(), (a * 2.3).cos(), (a * 1.7).sin()) * 30.0)
                    .normalize();
                if k % 9 == 0 {
                    dir[(k % 3) as usize] = 0.0;
                }
                let tmax = if k % 4 == 0 { 60.0 } else { f32::INFINITY };
                let ray = Ray::new(origin, dir, 0.0, tmax);
                let stop = (k % 5 == 0).then_some(1 + (k as usize % 13));
                let want = visits(|r, v| bvh.traverse(r, v), ray, stop);
                assert_eq!(
                    visits(|r, v| bvh.traverse_portable(r, v), ray, stop),
                    want,
                    "{name} ray {k}, portable"
                );
                // obvhs visits the same refs, in another order.
                let mut by_obvhs = Vec::new();
                bvh.traverse_obvhs(ray, |r, _| {
                    by_obvhs.push(r);
                    false
                });
                by_obvhs.sort();
                assert_eq!(
                    self::visited(bvh, ray),
                    by_obvhs,
                    "{name} ray {k}, against obvhs"
                );
                visited += want.len();
            }
        }
        // Enough visits for the comparison to mean something (18,420 with the centres' exact
        // Morton order, 20,000 and more with the order of the quantized centres before).
        assert!(visited > 15_000, "only {visited} visits");
    }

    /// What each ray of `rays` visits in a packet walk, as [`visits`] records it for one ray:
    /// every seventh visit of a ray lowers its `tmax`. Rays outside `active` visit nothing.
    fn packet_visits(
        bvh: &OctantBvh,
        rays: &[Ray],
        active: Mask,
        portable: bool,
    ) -> Vec<Vec<(u64, u32)>> {
        let mut rs = rays.to_vec();
        let mut seen = vec![Vec::new(); rays.len()];
        let visit = |_: usize, r: u64, m: Mask, rays: &mut [Ray]| {
            for k in packet::rays_of(m) {
                seen[k].push((r, rays[k].tmax.to_bits()));
                if seen[k].len() % 7 == 0 {
                    rays[k].tmax *= 0.9;
                }
            }
        };
        if portable {
            bvh.traverse_packet_portable(&mut rs, active, visit);
        } else {
            bvh.traverse_packet(&mut rs, active, visit);
        }
        seen
    }

    #[test]
    fn a_packet_visits_for_each_ray_what_its_own_walk_visits() {
        let mut visited = 0;
        for (name, bvh) in &scattered_builds() {
            for p in 0..24u32 {
                let a = p as f32 * 0.618;
                let origin = Vec3A::new(
                    50.0 + 80.0 * a.cos(),
                    50.0 + 80.0 * a.sin(),
                    30.0 + (p % 40) as f32,
                );
                let target = Vec3A::new(50.0, 50.0, 50.0)
                    + Vec3A::new((a * 3.1).sin(), (a * 2.3).cos(), (a * 1.7).sin()) * 30.0;
                // An 8x8 tile of directions around the target; every third packet spread so
                // wide that its rays fall in several octants, some with zero components, and
                // from one origin.
                let spread = if p % 3 == 0 { 2.0 } else { 0.02 };
                let rays: Vec<Ray> = (0..64u32)
                    .map(|k| {
                        let (u, v) = ((k % 8) as f32 - 3.5, (k / 8) as f32 - 3.5);
                        let mut dir = ((target - origin).normalize()
                            + Vec3A::new(u, v, u - v) * spread * 0.25)
                            .normalize();
                        if p % 3 == 0 && k % 9 == 0 {
                            dir[(k % 3) as usize] = if k % 2 == 0 { 0.0 } else { -0.0 };
                        }
                        let tmax = if (p + k) % 4 == 0 {
                            60.0
                        } else {
                            f32::INFINITY
                        };
                        // The other packets' rays start apart, as the tracer's do: moved
                        // along their directions by different amounts, or moved sideways
                        // too, into the boxes.
                        let start = match p % 3 {
                            1 => origin + dir * (k as f32 * 1.7),
                            2 => origin + dir * 40.0 + Vec3A::new(u, v, -u) * 3.0,
                            _ => origin,
                        };
                        Ray::new(start, dir, 0.0, tmax)
                    })
                    .collect();
                let active = if p % 4 == 1 {
                    0x5555_aaaa_f0f0_0ff1
                } else {
                    u64::MAX
                };
                let got = packet_visits(bvh, &rays, active, false);
                let portable = packet_visits(bvh, &rays, active, true);
                for (k, ray) in rays.iter().enumerate() {
                    let want = if active >> k & 1 != 0 {
                        visits(|r, v| bvh.traverse(r, v), *ray, None)
                    } else {
                        Vec::new()
                    };
                    assert_eq!(got[k], want, "{name} packet {p} ray {k}");
                    assert_eq!(portable[k], want, "{name} packet {p} ray {k}, portable");
                    visited += want.len();
                }
            }
        }
        assert!(visited > 50_000, "only {visited} visits");
    }

    #[test]
    fn an_any_hit_packet_visits_for_each_ray_the_refs_its_own_walk_visits() {
        let mut visited = 0;
        for (name, bvh) in &scattered_builds() {
            for p in 0..16u32 {
                let a = p as f32 * 0.618;
                let origin = Vec3A::new(
                    50.0 + 30.0 * a.cos(),
                    50.0 + 30.0 * a.sin(),
                    40.0 + (p % 20) as f32,
                );
                // Rays every way from points near one another, as a tile's AO rays go: all
                // eight octants in one packet, some with zero components; or one octant.
                let rays: Vec<Ray> = (0..64u32)
                    .map(|k| {
                        let b = k as f32 * 2.399 + a;
                        let z = 1.0 - 2.0 * ((k as f32 + 0.5) / 64.0);
                        let r = (1.0 - z * z).sqrt();
                        let mut dir = Vec3A::new(r * b.cos(), r * b.sin(), z);
                        if k % 11 == 0 {
                            dir[(k % 3) as usize] = if k % 2 == 0 { 0.0 } else { -0.0 };
                        }
                        // Every fifth packet of one octant (as shadow rays are).
                        if p % 5 == 4 {
                            dir = dir.abs();
                        }
                        let start = origin + Vec3A::new((k % 4) as f32, (k / 16) as f32, 0.5);
                        let tmax = if (p + k) % 3 == 0 {
                            25.0
                        } else {
                            f32::INFINITY
                        };
                        Ray::new(start, dir, 0.0, tmax)
                    })
                    .collect();
                let active = if p % 4 == 1 {
                    0x5555_aaaa_f0f0_0ff1
                } else {
                    u64::MAX
                };
                let any = |avx2: bool| {
                    let mut rs = rays.clone();
                    let mut got = vec![Vec::new(); rays.len()];
                    bvh.packet_any_on(&mut rs, active, avx2, |_, r, m, _| {
                        for k in packet::rays_of(m) {
                            got[k].push(r);
                        }
                        0
                    });
                    got
                };
                #[cfg(target_arch = "x86_64")]
                let avx2 = std::arch::is_x86_feature_detected!("avx2");
                #[cfg(not(target_arch = "x86_64"))]
                let avx2 = false;
                let (mut got, mut portable) = (any(avx2), any(false));
                for (k, ray) in rays.iter().enumerate() {
                    let mut want = Vec::new();
                    if active >> k & 1 != 0 {
                        bvh.traverse(*ray, |r, _| {
                            want.push(r);
                            false
                        });
                    }
                    want.sort_unstable();
                    got[k].sort_unstable();
                    portable[k].sort_unstable();
                    assert_eq!(got[k], want, "{name} packet {p} ray {k}");
                    assert_eq!(portable[k], want, "{name} packet {p} ray {k}, portable");
                    visited += want.len();
                }
            }
        }
        assert!(visited > 10_000, "only {visited} visits");
    }

    #[test]
    fn a_negative_zero_in_the_direction_visits_as_a_positive_one() {
        let refs: Vec<u64> = (0..1000).collect();
        let bvh = BvhBuilder::new().build(&refs, 1e-4, grid_boxes);
        let origin = Vec3A::new(-1.0, 4.5, 4.5);
        let plus = visited(&bvh, Ray::new(origin, Vec3A::X, 0.0, f32::INFINITY));
        // The ten boxes the ray crosses, and any others sharing a leaf with them.
        assert!((0..10).all(|x| plus.contains(&(x + 40 + 400))), "{plus:?}");
        for d in [Vec3A::new(1.0, -0.0, 0.0), Vec3A::new(1.0, 0.0, -0.0)] {
            let ray = Ray::new(origin, d, 0.0, f32::INFINITY);
            assert_eq!(visited(&bvh, ray), plus, "{d}");
            let mut portable = Vec::new();
            bvh.traverse_portable(ray, |r, _| {
                portable.push(r);
                false
            });
            portable.sort();
            assert_eq!(portable, plus, "{d}, portable");
        }
    }

    #[test]
    fn every_box_hit_by_a_ray_is_visited() {
        let refs: Vec<u64> = (0..1000).collect();
        let bounds = |r: u64| {
            let (x, y, z) = ((r % 10) as f64, ((r / 10) % 10) as f64, (r / 100) as f64);
            ([x, y, z], [x + 1.0, y + 1.0, z + 1.0])
        };
        let bvh = BvhBuilder::new().build(&refs, 1e-4, bounds);
        assert_eq!(bvh.len(), 1000);
        let mut sorted = bvh.refs().to_vec();
        sorted.sort();
        assert_eq!(sorted, refs);
        let ray = Ray::new(
            Vec3A::new(-1.0, 4.5, 4.5),
            Vec3A::new(1.0, 0.0, 0.0),
            0.0,
            f32::INFINITY,
        );
        let mut seen = Vec::new();
        bvh.traverse(ray, |r, _| {
            seen.push(r);
            false
        });
        for x in 0..10 {
            assert!(seen.contains(&(x + 40 + 400)), "missing {x}");
        }
    }

    /// Times the walk (AVX2 and portable node tests) against obvhs's `traverse!` on the same
    /// rays, in alternating rounds in one process so that a loaded machine slows all alike:
    /// `cargo test --release -p amr-render --lib walk_speed -- --ignored --nocapture`.
    #[test]
    #[ignore = "prints the time per ray of the walk and of obvhs's traversal"]
    fn walk_speed() {
        use std::time::Instant;
        let refs: Vec<u64> = (0..200_000).collect();
        let bvh = BvhBuilder::new().build(&refs, 1e-4, scattered_boxes);
        let rays: Vec<Ray> = (0..20_000u32)
            .map(|k| {
                let a = k as f32 * 0.618;
                let b = k as f32 * 0.414;
                let origin = Vec3A::new(
                    50.0 + 90.0 * a.cos() * b.sin(),
                    50.0 + 90.0 * a.sin() * b.sin(),
                    50.0 + 90.0 * b.cos(),
                );
                let target = Vec3A::new(
                    50.0 + 30.0 * (a * 3.1).sin(),
                    50.0 + 30.0 * (a * 2.3).cos(),
                    50.0 + 30.0 * (b * 1.7).sin(),
                );
                Ray::new(origin, (target - origin).normalize(), 0.0, f32::INFINITY)
            })
            .collect();
        type Visit<'a> = &'a mut dyn FnMut(u64, &mut f32) -> bool;
        // A closest-hit search: each visited box's slab entry lowers `tmax`.
        let run = |traverse: &dyn Fn(Ray, Visit)| {
            let mut visits = 0u64;
            let t = Instant::now();
            for ray in &rays {
                traverse(*ray, &mut |r, tmax| {
                    visits += 1;
                    let (lo, hi) = scattered_boxes(r);
                    let (mut t0, mut t1) = (0.0f32, *tmax);
                    for a in 0..3 {
                        let (ta, tb) = (
                            (lo[a] as f32 - ray.origin[a]) * ray.inv_direction[a],
                            (hi[a] as f32 - ray.origin[a]) * ray.inv_direction[a],
                        );
                        t0 = t0.max(ta.min(tb));
                        t1 = t1.min(ta.max(tb));
                    }
                    if t0 <= t1 {
                        *tmax = t0.max(1e-3) + 1.0;
                    }
                    false
                });
            }
            (t.elapsed().as_secs_f64() * 1e9 / rays.len() as f64, visits)
        };
        let mut times = [Vec::new(), Vec::new(), Vec::new()];
        let mut visits = [0; 3];
        for _ in 0..15 {
            for (m, times) in times.iter_mut().enumerate() {
                let (ns, v) = match m {
                    0 => run(&|r, v| bvh.traverse_obvhs(r, v)),
                    1 => run(&|r, v| bvh.traverse(r, v)),
                    _ => run(&|r, v| bvh.traverse_portable(r, v)),
                };
                times.push(ns);
                visits[m] = v;
            }
        }
        assert!(visits.iter().all(|&v| v == visits[0]), "{visits:?}");
        for (name, mut t) in [
            "obvhs traverse!",
            "walk (dispatched)",
            "walk, obvhs node test",
        ]
        .into_iter()
        .zip(times)
        {
            t.sort_by(f64::total_cmp);
            println!(
                "{name}: {:.0} ns per ray (median of 15 rounds), {:.0} min; {:.1} candidates per ray",
                t[7],
                t[0],
                visits[0] as f64 / rays.len() as f64
            );
        }
    }
}
