//! One field of an open file as the tracer's voxel source, for every reconstruction: the one
//! place that picks octant voxels (the extraction of issue 4), clipped dual cells (`current`) or
//! cell faces (`nearest`), decodes them from their 32:32 refs through a per-thread cache that
//! this source owns, samples the same reconstruction at points, and keeps the first decode error
//! met while tracing so that a frame reports it instead of drawing a hole.
//!
//! Grid coordinates are the extraction's doubled finest-level coordinates.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;

use amr_format::{AmrkFile, FormatError};
use thread_local::ThreadLocal;

use crate::bvh::packet::{rays_where, Mask};
#[cfg(target_arch = "x86_64")]
use crate::bvh::wide::morton_bmi2;
use crate::bvh::BoxRun;
use crate::error::{RenderError, Result};
use crate::extract::current::CurrentVoxels;
use crate::extract::nearest::NearestFaces;
use crate::extract::{
    candidate_leaves, DecodeFrame, ExtractStats, Extraction, Extractor, LeafBoxes, RefsCheck,
    Region,
};
use crate::field_stats::format_vector;
use crate::mapping::PageRelease;
use crate::reconstruct::level_blend::{LevelWeights, NearLevels};
use crate::reconstruct::level_gradient::{LevelBlocks, PartialGradient};
use crate::reconstruct::{Reconstruction, SampleScratch, Sampler};
use crate::trace::face::intersect_face;
use crate::trace::octant::{
    self, intersect_voxel, intersect_voxel_clipped, intersect_voxel_packet, voxel_occluders_packet,
    voxel_occludes_clipped, voxel_occludes_with, VoxelHit,
};
use crate::trace::ray::GridRay;
use crate::trace::source::{
    occlusion_tests_by_lookup, AnyHitQuery, BoxClip, BoxedLookup, GridFrame, OcclusionTest, Voxel,
    VoxelLookup, VoxelSource,
};
use crate::trace::tracer::{central_difference_given, SurfaceHit};

/// Bytes of decompressed bricks the sampler may cache.
pub const BRICK_CACHE_BYTES: usize = 256 << 20;

/// Slots of each thread's cache of decoded voxels (a power of two).
const VOXEL_CACHE_SLOTS: usize = 4096;

/// Bytes of one thread's voxel cache: the decoded voxels with their refs, the cell blocks of
/// smooth normals and their memo of other-level leaves, plus the sampling scratch (bounded by
/// its own capacities, not counted here).
pub const VOXEL_CACHE_BYTES: usize = VOXEL_CACHE_SLOTS * std::mem::size_of::<(u64, Voxel)>()
    + LevelBlocks::BYTES
    + NearLevels::BYTES;

/// The voxels of one reconstruction.
// One value per source, matched on every lookup: boxing the large variant would add an
// indirection to the hot path to save bytes of which there is one copy.
#[allow(clippy::large_enum_variant)]
enum Voxels<'f, D> {
    /// Octants and merged dual cells of the octant method.
    Octant(Extractor<'f, D>),
    /// Dual cells of each level, clipped to the level's cells ([`CurrentVoxels`]).
    Current(Sampler<'f, D>),
    /// Cell faces between cells of different values ([`NearestFaces`]).
    Nearest(Sampler<'f, D>),
}

/// One thread's decoded voxels, direct-mapped by ref, and its scratch for decoding and sampling.
struct VoxelCache {
    slots: Vec<(u64, Voxel)>,
    scratch: SampleScratch,
    /// The frames of the leaves of the voxels decoded last, direct-mapped by leaf
    /// ([`leaf_slot`]): the candidates of a walk come from a few leaves at a time.
    leaves: [Option<DecodeFrame>; LEAF_SLOTS],
    blocks: LevelBlocks,
    /// The other-level leaves around the dual cells of smooth normals near level boundaries.
    near_levels: NearLevels,
}

/// One field of an open file, reconstructed one way, as a [`VoxelSource`].
pub struct FieldSource<'f, D> {
    voxels: Voxels<'f, D>,
    reconstruction: Reconstruction,
    frame: GridFrame,
    caches: ThreadLocal<RefCell<VoxelCache>>,
    cache_threads: AtomicU64,
    failed: AtomicBool,
    failure: Mutex<Option<RenderError>>,
}

impl<'f, D: AsRef<[u8]> + Sync> FieldSource<'f, D> {
    /// The source for field `field` of `file` with `reconstruction` (any but `finest`, which
    /// has no voxels to trace).
    pub fn new(
        file: &'f AmrkFile<D>,
        field: usize,
        reconstruction: Reconstruction,
    ) -> Result<Self> {
        let voxels =
            match reconstruction {
                Reconstruction::Octant => {
                    Voxels::Octant(Extractor::new(file, field, BRICK_CACHE_BYTES)?)
                }
                Reconstruction::Current => {
                    Voxels::Current(Sampler::new(file, field, BRICK_CACHE_BYTES)?)
                }
                Reconstruction::Nearest => {
                    Voxels::Nearest(Sampler::new(file, field, BRICK_CACHE_BYTES)?)
                }
                Reconstruction::Finest => return Err(RenderError::Unsupported(
                    "the finest reconstruction is for point sampling; its voxels are not traced"
                        .into(),
                )),
            };
        let mut source = FieldSource {
            voxels,
            reconstruction,
            frame: GridFrame::default(),
            caches: ThreadLocal::new(),
            cache_threads: AtomicU64::new(0),
            failed: AtomicBool::new(false),
            failure: Mutex::new(None),
        };
        source.frame = GridFrame::of_grid(source.sampler().grid());
        Ok(source)
    }
}

impl<'f, D: AsRef<[u8]> + Sync> FieldSource<'f, D> {
    /// The reconstruction.
    pub fn reconstruction(&self) -> Reconstruction {
        self.reconstruction
    }

    /// The sampler underneath.
    pub fn sampler(&self) -> &Sampler<'f, D> {
        match &self.voxels {
            Voxels::Octant(e) => e.sampler(),
            Voxels::Current(s) | Voxels::Nearest(s) => s,
        }
    }

    /// The octant method's extractor, `None` for the other reconstructions.
    pub fn extractor(&self) -> Option<&Extractor<'f, D>> {
        match &self.voxels {
            Voxels::Octant(e) => Some(e),
            _ => None,
        }
    }

    /// Releases `pages` (the map of this source's file) after each chunk of the octant
    /// extraction and between the stages of a render.
    pub fn set_page_release(&mut self, pages: PageRelease<'f>) {
        if let Voxels::Octant(e) = &mut self.voxels {
            e.set_page_release(pages);
        }
    }

    /// Runs `check` on the refs an octant extraction has found after each chunk of leaves
    /// ([`Extractor::set_refs_check`]).
    pub fn set_refs_check(&mut self, check: RefsCheck) {
        if let Voxels::Octant(e) = &mut self.voxels {
            e.set_refs_check(check);
        }
    }

    /// The most map bytes measured resident at once, when pages are released.
    pub fn mapped_resident_peak_bytes(&self) -> Option<u64> {
        self.extractor()
            .and_then(Extractor::page_release)
            .map(PageRelease::peak_bytes)
    }

    /// The active voxels for `iso` and what finding them took.
    pub fn extract(&self, iso: f32) -> Result<Extraction> {
        match &self.voxels {
            Voxels::Octant(e) => e.extract(iso),
            Voxels::Current(s) => self.timed(iso, || CurrentVoxels::new(s).extract(iso)),
            Voxels::Nearest(s) => self.timed(iso, || NearestFaces::new(s).extract(iso)),
        }
    }

    /// [`Self::extract`] limited to `region` (see [`Region`]): only the leaves whose voxels may
    /// meet it are visited, only the voxels whose box meets it are kept.
    pub fn extract_in(&self, iso: f32, region: &Region) -> Result<Extraction> {
        if region.is_everything() {
            return self.extract(iso);
        }
        // The refs of the candidate leaves that may meet the region, kept by their decoded boxes.
        let in_region = |leaves_of: &dyn Fn(&[u32]) -> Result<Vec<u64>>,
                         decode: &dyn Fn(u64) -> Result<Voxel>|
         -> Result<Vec<u64>> {
            let s = self.sampler();
            let leaves = region.leaves(s, candidate_leaves(s, iso));
            let mut refs = leaves_of(&leaves)?;
            region.retain_refs(&mut refs, |r| decode(r).map(|v| (v.lo, v.hi)))?;
            Ok(refs)
        };
        match &self.voxels {
            Voxels::Octant(e) => e.extract_in(iso, region),
            Voxels::Current(s) => self.timed(iso, || {
                let v = CurrentVoxels::new(s);
                in_region(&|l| v.extract_leaves(iso, l), &|r| v.decode(r))
            }),
            Voxels::Nearest(s) => self.timed(iso, || {
                let v = NearestFaces::new(s);
                in_region(&|l| v.extract_leaves(iso, l), &|r| v.decode(r))
            }),
        }
    }

    /// An extraction of the `current` or `nearest` voxels, with the statistics these report.
    fn timed(&self, iso: f32, run: impl FnOnce() -> Result<Vec<u64>>) -> Result<Extraction> {
        let start = std::time::Instant::now();
        let refs = run()?;
        let file = self.sampler().file();
        let stats = ExtractStats {
            field: file.fields()[self.sampler().field()].name.clone(),
            iso,
            active: refs.len() as u64,
            seconds: start.elapsed().as_secs_f64(),
            threads: rayon::current_num_threads(),
            leaves_total: file.num_leaves() as u64,
            file_bytes: file.bytes().len() as u64,
            ..ExtractStats::default()
        };
        Ok(Extraction { refs, stats })
    }

    /// Bytes held by the per-thread voxel caches.
    pub fn voxel_cache_bytes(&self) -> u64 {
        self.cache_threads.load(Ordering::Relaxed) * VOXEL_CACHE_BYTES as u64
    }

    /// The first error met while decoding voxels or sampling since the last call, if any:
    /// tracing cannot stop at an error, so it records it and treats the voxel as missing.
    pub fn take_failure(&self) -> Option<RenderError> {
        if !self.failed.load(Ordering::Acquire) {
            return None;
        }
        let mut slot = self.failure.lock().unwrap_or_else(|p| p.into_inner());
        self.failed.store(false, Ordering::Release);
        slot.take()
    }

    /// Keeps `e` unless an earlier error is kept.
    fn record(&self, e: RenderError) {
        let mut slot = self.failure.lock().unwrap_or_else(|p| p.into_inner());
        if slot.is_none() {
            *slot = Some(e);
        }
        self.failed.store(true, Ordering::Release);
    }

    /// Decodes `r` (`last`: the frame of the leaf of the last voxel decoded, kept for the next).
    fn decode(
        &self,
        r: u64,
        scratch: &mut SampleScratch,
        last: &mut Option<DecodeFrame>,
    ) -> Result<Voxel> {
        match &self.voxels {
            Voxels::Octant(e) => e.decode_with(r, scratch, last),
            Voxels::Current(s) => CurrentVoxels::new(s).decode(r),
            Voxels::Nearest(s) => NearestFaces::new(s).decode(r),
        }
    }

    /// This thread's voxel cache and scratch.
    fn thread_cache(&self) -> &RefCell<VoxelCache> {
        self.caches.get_or(|| {
            self.cache_threads.fetch_add(1, Ordering::Relaxed);
            RefCell::new(VoxelCache {
                slots: vec![(u64::MAX, Voxel::EMPTY); VOXEL_CACHE_SLOTS],
                scratch: SampleScratch::default(),
                leaves: [None; LEAF_SLOTS],
                blocks: LevelBlocks::default(),
                near_levels: NearLevels::default(),
            })
        })
    }

    /// The voxel `r` names, from this thread's cache when it holds it.
    fn cached_voxel(&self, r: u64) -> Voxel {
        self.voxel_in(&mut self.thread_cache().borrow_mut(), r)
    }

    /// The voxel `r` names, from `cache` when it holds it.
    #[inline]
    fn voxel_in(&self, cache: &mut VoxelCache, r: u64) -> Voxel {
        match cache.held(r) {
            Ok(v) => v,
            Err(slot) => self.decode_into(cache, slot, r),
        }
    }

    /// The octant voxel `r` names ([`Self::voxel_in`]) and, when it is not in `cache` and
    /// `clip` is given, `clip`'s interval in its box, located from the ref and the leaf's frame
    /// alone; `None` when that interval is empty: then its values are not decoded
    /// ([`VoxelSource::with_boxed_voxels`]). A located voxel's values are decoded from where it
    /// was located.
    #[inline]
    fn octant_voxel_if(
        &self,
        e: &Extractor<'f, D>,
        cache: &mut VoxelCache,
        r: u64,
        clip: Option<&BoxClip<'_>>,
    ) -> Option<(Voxel, Option<(f64, f64)>)> {
        let slot = match cache.held(r) {
            Ok(v) => return Some((v, None)),
            Err(slot) => slot,
        };
        let last = &mut cache.leaves[leaf_slot(r)];
        let at = match e.locate_with(r, last) {
            Ok(at) => at,
            Err(err) => {
                self.record(err);
                return Some((Voxel::EMPTY, None));
            }
        };
        let clipped = match clip {
            Some(clip) => Some(clip.of(at.lo.map(|x| x as f64), at.hi.map(|x| x as f64))?),
            None => None,
        };
        let Some(v) = self.checked(e.decode_located(r, &at, &mut cache.scratch, last)) else {
            return Some((Voxel::EMPTY, None));
        };
        cache.slots[slot] = (r, v);
        Some((v, clipped))
    }

    /// [`VoxelSource::with_occlusion_tests`]' test of the octant voxel `r`: what
    /// [`occlusion_tests_by_lookup`] answers from [`Self::octant_voxel_if`]'s voxel, the voxel
    /// tested where `cache` holds it rather than copied out. `AVX2` when the caller is compiled
    /// for AVX2 and calls the tests' AVX2 compilations directly ([`occluders_of`]).
    #[inline(always)]
    fn octant_occluders<const AVX2: bool>(
        &self,
        e: &Extractor<'f, D>,
        cache: &mut VoxelCache,
        iso: f32,
        r: u64,
        query: AnyHitQuery<'_>,
    ) -> Mask {
        match cache.held_at(r) {
            Ok(at) => occluders_of::<AVX2>(&cache.slots[at].1, iso, query),
            Err(slot) => self.octant_occluders_missed::<AVX2>(e, cache, slot, iso, r, query),
        }
    }

    /// [`Self::octant_occluders`] of a voxel `cache` does not hold, to go in its slot `slot`:
    /// out of line, so that the test of a voxel held needs none of its registers.
    #[inline(never)]
    fn octant_occluders_missed<const AVX2: bool>(
        &self,
        e: &Extractor<'f, D>,
        cache: &mut VoxelCache,
        slot: usize,
        iso: f32,
        r: u64,
        query: AnyHitQuery<'_>,
    ) -> Mask {
        let last = &mut cache.leaves[leaf_slot(r)];
        let at = match e.locate_with(r, last) {
            Ok(at) => at,
            Err(err) => {
                self.record(err);
                return occluders_of::<AVX2>(&Voxel::EMPTY, iso, query);
            }
        };
        let clip = match query {
            AnyHitQuery::One(c) => Some(c.of(at.lo.map(|x| x as f64), at.hi.map(|x| x as f64))),
            AnyHitQuery::Packet { .. } => None,
        };
        if clip == Some(None) {
            return 0;
        }
        let Some(v) = self.checked(e.decode_located(r, &at, &mut cache.scratch, last)) else {
            return occluders_of::<AVX2>(&Voxel::EMPTY, iso, query);
        };
        cache.slots[slot] = (r, v);
        match (query, clip) {
            (AnyHitQuery::One(c), Some(Some(clip))) => {
                let t = (c.tmin, c.tmax);
                #[cfg(target_arch = "x86_64")]
                if AVX2 {
                    // SAFETY: `AVX2` only when the CPU has it (`octant_occlusion_tests_avx2`).
                    return unsafe {
                        Mask::from(octant::voxel_occludes_clipped_avx2(&v, iso, c.ray, t, clip))
                    };
                }
                Mask::from(voxel_occludes_clipped(&v, iso, c.ray, t, clip))
            }
            _ => occluders_of::<AVX2>(&v, iso, query),
        }
    }

    /// [`VoxelSource::with_occlusion_tests`] of the octant method with [`Self::octant_occluders`]
    /// compiled for AVX2 into the test `f` is given (a closure inherits its function's target
    /// features): the same answers (the same operations; three-operand forms spare register
    /// copies), and one call less per candidate.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn octant_occlusion_tests_avx2(
        &self,
        e: &Extractor<'f, D>,
        cache: &mut VoxelCache,
        iso: f32,
        f: &mut dyn FnMut(&mut OcclusionTest<'_>),
    ) {
        f(&mut |r, query| self.octant_occluders::<true>(e, cache, iso, r, query))
    }

    /// Decodes the voxel `r` names into `cache`'s slot `slot`; the empty voxel, its error
    /// recorded, when it cannot be decoded.
    #[inline]
    fn decode_into(&self, cache: &mut VoxelCache, slot: usize, r: u64) -> Voxel {
        let last = &mut cache.leaves[leaf_slot(r)];
        let Some(v) = self.checked(self.decode(r, &mut cache.scratch, last)) else {
            return Voxel::EMPTY;
        };
        cache.slots[slot] = (r, v);
        v
    }

    /// A decoded voxel, or `None` with the error recorded: the decode's, or
    /// [`Self::not_finite`]'s for a voxel with a NaN or infinite corner.
    #[inline(always)]
    fn checked(&self, decoded: Result<Voxel>) -> Option<Voxel> {
        match decoded {
            Ok(v) if v.values.iter().all(|x| x.is_finite()) => Some(v),
            Ok(v) => {
                let centre = std::array::from_fn(|a| 0.5 * (v.lo[a] + v.hi[a]));
                let bad = v.values.into_iter().find(|x| !x.is_finite());
                self.record(self.not_finite(bad.unwrap_or(f32::NAN), centre, v.level));
                None
            }
            Err(e) => {
                self.record(e);
                None
            }
        }
    }

    /// The error for value `bad` (a NaN or an infinity) met at grid point `centre`, in a cell of
    /// level `level`: a voxel's corner or a sample. No converter writes one, so the file's data
    /// was damaged after it was written (a raw brick is read in place, its checksum unchecked;
    /// `verify` checks every brick). The extraction keeps voxels with a NaN corner
    /// ([`crate::reconstruct::interp::corners_straddle`]; an infinity compares as a value) so
    /// that this error, and not a hole in the surface, is what the damage gives where a ray
    /// meets it.
    #[cold]
    fn not_finite(&self, bad: f32, centre: [f64; 3], level: u32) -> RenderError {
        let sampler = self.sampler();
        let file = sampler.file();
        let e = FormatError::Corrupt(format!(
            "field '{}' is {bad} near {} (level {}): no converter writes a value that is not \
             finite, so the data was damaged after the file was written (`amr-render verify` \
             checks every brick)",
            file.fields()[sampler.field()].name,
            format_vector(self.frame.to_world(centre)),
            level,
        ));
        RenderError::Format(match file.path() {
            Some(path) => e.in_file(path),
            None => e,
        })
    }
}

/// Leaf frames a thread's voxel cache keeps (a power of two).
const LEAF_SLOTS: usize = 8;

/// The slot of the frame of ref `r`'s leaf in a thread's voxel cache.
#[inline(always)]
fn leaf_slot(r: u64) -> usize {
    (r >> 32) as usize % LEAF_SLOTS
}

/// The rays of `query` that the octant method's `voxel` occludes ([`voxel_occludes_with`],
/// [`voxel_occluders_packet`]), a single ray's answer as 1 or 0; their AVX2 compilations
/// called directly when `AVX2`, which the CPU must then have.
#[inline(always)]
fn occluders_of<const AVX2: bool>(voxel: &Voxel, iso: f32, query: AnyHitQuery<'_>) -> Mask {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: `AVX2` only when the CPU has it (`octant_occlusion_tests_avx2`).
        return unsafe {
            match query {
                AnyHitQuery::One(c) => Mask::from(octant::voxel_occludes_with_avx2(
                    voxel, iso, c.ray, c.recip, c.tmin, c.tmax,
                )),
                AnyHitQuery::Packet {
                    rays,
                    recips,
                    m,
                    tmin,
                    tmax,
                } => octant::voxel_occluders_packet_avx2(voxel, iso, rays, recips, m, tmin, tmax),
            }
        };
    }
    match query {
        AnyHitQuery::One(c) => Mask::from(voxel_occludes_with(
            voxel, iso, c.ray, c.recip, c.tmin, c.tmax,
        )),
        AnyHitQuery::Packet {
            rays,
            recips,
            m,
            tmin,
            tmax,
        } => voxel_occluders_packet(voxel, iso, rays, recips, m, tmin, tmax),
    }
}

impl VoxelCache {
    /// The voxel of ref `r` if this cache holds it, else the slot it goes in ([`Self::held_at`]).
    #[inline(always)]
    fn held(&self, r: u64) -> std::result::Result<Voxel, usize> {
        self.held_at(r).map(|at| self.slots[at].1)
    }

    /// The slot of ref `r`'s voxel, `Ok` when this cache holds it: Fibonacci hashing of the ref,
    /// so that neighbouring refs land in different slots.
    #[inline(always)]
    fn held_at(&self, r: u64) -> std::result::Result<usize, usize> {
        let slot = (r.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 52) as usize % VOXEL_CACHE_SLOTS;
        match self.slots[slot] {
            (key, _) if key == r && r != u64::MAX => Ok(slot),
            _ => Err(slot),
        }
    }
}

impl<'f, D: AsRef<[u8]> + Sync> FieldSource<'f, D> {
    /// [`VoxelSource::voxel_boxes`] of the octant method's voxels.
    #[inline(always)]
    fn octant_boxes(&self, e: &Extractor<'f, D>, refs: &[u64], out: &mut BoxRun<'_>) {
        e.voxel_box_runs(refs, |boxes| out.push_ints(boxes), |err| self.record(err));
    }

    /// [`Self::octant_boxes`] compiled for AVX2 and BMI2 (variable shifts without a count
    /// register, Morton codes by bit deposit): the same boxes and codes in fewer instructions.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi2")]
    fn octant_boxes_v3(&self, e: &Extractor<'f, D>, refs: &[u64], out: &mut BoxRun<'_>) {
        /// One run's boxes, the loop compiled for AVX2 and BMI2.
        #[target_feature(enable = "avx2,bmi2")]
        fn push<I: Iterator<Item = ([i64; 3], [i64; 3])>>(out: &mut BoxRun<'_>, boxes: I) {
            // SAFETY: this function runs only where the CPU has BMI2.
            out.push_ints_coded(boxes, |q| unsafe { morton_bmi2(q) });
        }
        // A closure in this function has its target features: `push` is safe to call there.
        // A leaf's merged dual cells go four at a time, the other refs one at a time.
        let run = |mut boxes: LeafBoxes<'_, '_, 'f, D>| {
            let Some(duals) = boxes.duals() else {
                return push(out, boxes);
            };
            loop {
                let done = out.push_lattice(&duals, boxes.rest());
                boxes.skip_refs(done);
                if boxes.rest().is_empty() {
                    return;
                }
                push(out, boxes.by_ref().take(4));
            }
        };
        e.voxel_box_runs(refs, run, |err| self.record(err));
    }
}

impl<D: AsRef<[u8]> + Sync> FieldSource<'_, D> {
    /// [`VoxelSource::gradient`] taking the components `given` has as they are. Kept out of
    /// line: most smooth normals never sample.
    #[inline(never)]
    fn gradient_given(
        &self,
        p: [f64; 3],
        h: [f64; 3],
        given: [Option<f64>; 3],
    ) -> Option<[f64; 3]> {
        let mut cache = self.thread_cache().borrow_mut();
        let sampler = self.sampler();
        // Bound once for the samples: `sample_with` without binding each time.
        let (loc, memo) = cache.scratch.bind(sampler);
        central_difference_given(
            |q| match sampler.sample_in(&loc, q, self.reconstruction, memo) {
                Ok(v) => v.map(|s| s.0),
                Err(e) => {
                    self.record(e);
                    None
                }
            },
            p,
            h,
            given,
        )
    }
}

/// What the cells of one level around a point give toward a smooth normal's gradient
/// ([`FieldSource::block_gradient`]).
enum BlockGradient {
    /// All of it: the cells are all leaf cells of the level.
    Whole([f64; 3]),
    /// Some components, or none; the others are to be sampled.
    Partial(PartialGradient),
    /// An error, recorded.
    Failed,
}

impl<D: AsRef<[u8]> + Sync> FieldSource<'_, D> {
    /// The smooth normal's gradient at `p` one cell of `level` apart, as far as the cells of
    /// `level` around it give it: both fields are the dual cells' trilinear interpolant where
    /// they are leaf cells of the level, whose central differences the brick gives directly.
    #[inline]
    fn block_gradient(&self, p: [f64; 3], level: u32) -> BlockGradient {
        let mut partial = PartialGradient::default();
        if !matches!(self.voxels, Voxels::Octant(_) | Voxels::Current(_)) {
            return BlockGradient::Partial(partial);
        }
        let found = {
            let mut cache = self.thread_cache().borrow_mut();
            cache
                .blocks
                .gradient(self.sampler(), p, level, &mut partial)
        };
        match found {
            Ok(Some(g)) => BlockGradient::Whole(g),
            Ok(None) => BlockGradient::Partial(partial),
            Err(e) => {
                self.record(e);
                BlockGradient::Failed
            }
        }
    }

    /// The smooth normal's gradient at `p` on a hit of `level` whose cells' block did not give
    /// all of it (`partial`: what it gave): `level`'s differences, the missing components
    /// sampled, or near a level boundary those of the levels [`Sampler::level_weights`] gives,
    /// weighed. Kept out of line: most smooth normals come from whole blocks.
    #[inline(never)]
    fn blended_gradient(
        &self,
        p: [f64; 3],
        level: u32,
        step: [f64; 3],
        partial: PartialGradient,
    ) -> Option<[f64; 3]> {
        let one_level =
            |given| self.gradient_given(p, self.cell_size(level).unwrap_or(step), given);
        if partial.core_is_whole {
            return one_level(partial.given);
        }
        let weights = {
            let mut cache = self.thread_cache().borrow_mut();
            self.sampler()
                .level_weights_near(p, level, &mut cache.near_levels)
        };
        if weights.single().is_some() {
            return one_level(partial.given);
        }
        // Another level's block is not looked up: every axis's differences read its cell
        // holding `p`, which is a leaf cell of it only where `p` lies in a leaf of that level
        // and not of `level` (the hit's voxel and its leaf disagree: counted, it never gave a
        // component on the demo close-up or `tiny`), and its look-up would evict blocks that
        // neighbouring hits use. Its differences are sampled: the same function.
        weights.blend(|l| {
            let given = if l == level { partial.given } else { [None; 3] };
            self.gradient_given(p, self.cell_size(l).unwrap_or(step), given)
        })
    }
}

impl<D: AsRef<[u8]> + Sync> VoxelSource for FieldSource<'_, D> {
    fn frame(&self) -> GridFrame {
        self.frame
    }

    fn voxel(&self, r: u64) -> Voxel {
        self.cached_voxel(r)
    }

    fn with_voxels(&self, f: &mut dyn FnMut(&mut VoxelLookup<'_>)) {
        let mut cache = self.thread_cache().borrow_mut();
        f(&mut |r| self.voxel_in(&mut cache, r))
    }

    fn with_boxed_voxels(&self, f: &mut dyn FnMut(&mut BoxedLookup<'_>)) {
        let mut cache = self.thread_cache().borrow_mut();
        match &self.voxels {
            // The octant method's test begins with the box clip, and its boxes come from the
            // refs and the leaf's frame.
            Voxels::Octant(e) => f(&mut |r, clip| self.octant_voxel_if(e, &mut cache, r, clip)),
            _ => f(&mut |r, _| Some((self.voxel_in(&mut cache, r), None))),
        }
    }

    fn with_occlusion_tests(&self, iso: f32, f: &mut dyn FnMut(&mut OcclusionTest<'_>)) {
        let Voxels::Octant(e) = &self.voxels else {
            return occlusion_tests_by_lookup(self, iso, f);
        };
        let mut cache = self.thread_cache().borrow_mut();
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            return unsafe { self.octant_occlusion_tests_avx2(e, &mut cache, iso, f) };
        }
        f(&mut |r, query| self.octant_occluders::<false>(e, &mut cache, iso, r, query))
    }

    fn voxel_box(&self, r: u64) -> ([f64; 3], [f64; 3]) {
        let Voxels::Octant(e) = &self.voxels else {
            let v = self.voxel(r);
            return (v.lo, v.hi);
        };
        match e.voxel_box(r) {
            Ok((lo, hi)) => (lo.map(|x| x as f64), hi.map(|x| x as f64)),
            Err(err) => {
                self.record(err);
                (Voxel::EMPTY.lo, Voxel::EMPTY.hi)
            }
        }
    }

    fn voxel_boxes(&self, refs: &[u64], out: &mut BoxRun<'_>) {
        let Voxels::Octant(e) = &self.voxels else {
            for &r in refs {
                let (lo, hi) = self.voxel_box(r);
                out.push(lo, hi);
            }
            return;
        };
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("bmi2")
        {
            // SAFETY: the CPU has AVX2 and BMI2, checked just above.
            unsafe { self.octant_boxes_v3(e, refs, out) };
            return;
        }
        self.octant_boxes(e, refs, out);
    }

    fn sample(&self, p: [f64; 3]) -> Option<(f32, u32)> {
        let mut cache = self.thread_cache().borrow_mut();
        match self
            .sampler()
            .sample_with(p, self.reconstruction, &mut cache.scratch)
        {
            Ok(Some((v, level))) if !v.is_finite() => {
                self.record(self.not_finite(v, p, level));
                None
            }
            Ok(v) => v,
            Err(e) => {
                self.record(e);
                None
            }
        }
    }

    fn cell_size(&self, level: u32) -> Option<[f64; 3]> {
        let grid = self.sampler().grid();
        // A cell of `level` spans `scale` finest cells, two grid units each.
        ((level as usize) < grid.num_levels()).then(|| grid.scale(level).map(|s| 2.0 * s as f64))
    }

    fn gradient(&self, p: [f64; 3], h: [f64; 3]) -> Option<[f64; 3]> {
        self.gradient_given(p, h, [None; 3])
    }

    #[inline]
    fn level_gradient(&self, p: [f64; 3], level: u32, step: [f64; 3]) -> Option<[f64; 3]> {
        match self.block_gradient(p, level) {
            BlockGradient::Whole(g) => Some(g),
            BlockGradient::Partial(partial) => self.blended_gradient(p, level, step, partial),
            BlockGradient::Failed => None,
        }
    }

    fn level_weights(&self, p: [f64; 3], level: u32) -> LevelWeights {
        self.sampler().level_weights(p, level)
    }

    fn smooth_gradients(&self, hits: &mut [Option<SurfaceHit>]) {
        if !matches!(self.voxels, Voxels::Octant(_) | Voxels::Current(_)) {
            for hit in hits.iter_mut().flatten() {
                if let Some(g) = self.level_gradient(hit.pos, hit.level, [hit.size; 3]) {
                    hit.grad = g;
                }
            }
            return;
        }
        // [`Self::level_gradient`] hit by hit, in order, the thread's cache borrowed once for
        // each run of hits whose blocks give the gradient, and let go for a hit that needs
        // samples.
        let mut k = 0;
        while k < hits.len() {
            let mut partial = None;
            {
                let mut cache = self.thread_cache().borrow_mut();
                let sampler = self.sampler();
                while k < hits.len() {
                    if let Some(hit) = &mut hits[k] {
                        let mut part = PartialGradient::default();
                        match cache
                            .blocks
                            .gradient(sampler, hit.pos, hit.level, &mut part)
                        {
                            Ok(Some(g)) => hit.grad = g,
                            Ok(None) => {
                                partial = Some(part);
                                break;
                            }
                            Err(e) => self.record(e),
                        }
                    }
                    k += 1;
                }
            }
            // Hit `k` (when the run stopped short of the end) needs samples.
            let Some(partial) = partial else {
                continue;
            };
            if let Some(hit) = &mut hits[k] {
                if let Some(g) = self.blended_gradient(hit.pos, hit.level, [hit.size; 3], partial) {
                    hit.grad = g;
                }
            }
            k += 1;
        }
    }

    fn release_pages(&self) {
        if let Voxels::Octant(e) = &self.voxels {
            e.release_pages();
        }
    }

    #[inline]
    fn intersect(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
    ) -> Option<VoxelHit> {
        match self.voxels {
            Voxels::Nearest(_) => intersect_face(voxel, iso, ray, tmin, tmax),
            _ => intersect_voxel(voxel, iso, ray, tmin, tmax),
        }
    }

    #[inline]
    fn intersect_clipped(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        (tmin, tmax): (f64, f64),
        clip: (f64, f64),
    ) -> Option<VoxelHit> {
        match self.voxels {
            Voxels::Nearest(_) => intersect_face(voxel, iso, ray, tmin, tmax),
            _ => intersect_voxel_clipped(voxel, iso, ray, (tmin, tmax), clip),
        }
    }

    #[inline]
    fn intersect_packet(
        &self,
        voxel: &Voxel,
        iso: f32,
        rays: &[GridRay],
        recips: &[[f64; 3]],
        m: Mask,
        tmin: &[f64],
        tmax: &[f64],
        hits: &mut [Option<VoxelHit>],
    ) -> Mask {
        match self.voxels {
            Voxels::Nearest(_) => rays_where(m, |k| {
                hits[k] = intersect_face(voxel, iso, &rays[k], tmin[k], tmax[k]);
                hits[k].is_some()
            }),
            _ => intersect_voxel_packet(voxel, iso, rays, recips, m, tmin, tmax, hits),
        }
    }

    #[inline]
    fn occludes(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        recip: &[f64; 3],
        tmin: f64,
        tmax: f64,
    ) -> bool {
        match self.voxels {
            Voxels::Nearest(_) => intersect_face(voxel, iso, ray, tmin, tmax).is_some(),
            _ => voxel_occludes_with(voxel, iso, ray, recip, tmin, tmax),
        }
    }

    #[inline]
    fn occludes_clipped(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        _recip: &[f64; 3],
        (tmin, tmax): (f64, f64),
        clip: (f64, f64),
    ) -> bool {
        match self.voxels {
            Voxels::Nearest(_) => intersect_face(voxel, iso, ray, tmin, tmax).is_some(),
            _ => voxel_occludes_clipped(voxel, iso, ray, (tmin, tmax), clip),
        }
    }

    #[inline]
    fn occluders_packet(
        &self,
        voxel: &Voxel,
        iso: f32,
        rays: &[GridRay],
        recips: &[[f64; 3]],
        m: Mask,
        tmin: &[f64],
        tmax: &[f64],
    ) -> Mask {
        match self.voxels {
            Voxels::Nearest(_) => rays_where(m, |k| {
                intersect_face(voxel, iso, &rays[k], tmin[k], tmax[k]).is_some()
            }),
            _ => voxel_occluders_packet(voxel, iso, rays, recips, m, tmin, tmax),
        }
    }
}
