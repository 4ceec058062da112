//! The `.amrk` file as a voxel source for the `current` and `nearest` reconstructions, so the
//! hybrid tracer can be compared across reconstructions: `current` traces clipped dual cells with
//! the exact cubic intersector (`extract/current.rs`), `nearest` traces cell faces
//! (`extract/nearest.rs`, `trace/face.rs`). Grid coordinates are doubled finest-level
//! coordinates, as for [`super::amr_source::AmrSource`].

use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};

use amr_format::AmrkFile;

use crate::extract::current::CurrentVoxels;
use crate::extract::nearest::NearestFaces;
use crate::reconstruct::{Method as Recon, Sampler};
use crate::render_cmd::{ActiveSource, Reconstruction};
use crate::trace::face::intersect_face;
use crate::trace::octant::{intersect_voxel, VoxelHit};
use crate::trace::ray::GridRay;
use crate::trace::source::{GridFrame, Voxel, VoxelSource};

/// Bytes of decompressed bricks the sampler may cache.
const CACHE_BYTES: usize = 256 << 20;

/// Slots of each thread's cache of decoded voxels (a power of two).
const SLOTS: usize = 4096;

/// Source ids, so that a thread's cache never answers for another source.
static NEXT_ID: AtomicU64 = AtomicU64::new(1);

thread_local! {
    /// Decoded voxels, direct-mapped by ref and tagged with the source id.
    static DECODED: RefCell<Vec<(u64, u64, Voxel)>> = const { RefCell::new(Vec::new()) };
}

enum Voxels<'f, D> {
    Current(CurrentVoxels<'f, D>),
    Nearest(NearestFaces<'f, D>),
}

/// One field of an open file, reconstructed with `current` or `nearest`, as a [`VoxelSource`].
pub struct ReconSource<'f, D> {
    voxels: Voxels<'f, D>,
    method: Recon,
    frame: GridFrame,
    id: u64,
}

impl<'f, D: AsRef<[u8]> + Sync> ReconSource<'f, D> {
    /// The source for field `field` of `file` with `reconstruction`, which must be `current` or
    /// `nearest` (the octant method's source is [`super::amr_source::AmrSource`]).
    pub fn new(
        file: &'f AmrkFile<D>,
        field: usize,
        reconstruction: Reconstruction,
    ) -> anyhow::Result<Self> {
        let sampler = Sampler::new(file, field, CACHE_BYTES)?;
        let grid = sampler.grid();
        let origin = grid.to_world([0.0; 3]);
        let unit = [0, 1, 2].map(|a| {
            let mut e = [0.0; 3];
            e[a] = 1.0;
            grid.to_world(e)[a] - origin[a]
        });
        let extent = grid.extent().map(|e| 2.0 * e as f64);
        let (voxels, method) = match reconstruction {
            Reconstruction::Current => {
                (Voxels::Current(CurrentVoxels::new(sampler)), Recon::Current)
            }
            Reconstruction::Nearest => {
                (Voxels::Nearest(NearestFaces::new(sampler)), Recon::Nearest)
            }
            Reconstruction::Octant => {
                anyhow::bail!("the octant reconstruction is traced by AmrSource, not ReconSource")
            }
        };
        Ok(Self {
            voxels,
            method,
            frame: GridFrame {
                origin,
                unit,
                extent,
            },
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
        })
    }

    /// The sampler underneath.
    pub fn sampler(&self) -> &Sampler<'f, D> {
        match &self.voxels {
            Voxels::Current(v) => v.sampler(),
            Voxels::Nearest(v) => v.sampler(),
        }
    }

    /// Decodes `r` (a NaN voxel when it names none).
    fn decode(&self, r: u64) -> Voxel {
        let v = match &self.voxels {
            Voxels::Current(v) => v.decode(r),
            Voxels::Nearest(v) => v.decode(r),
        };
        match v {
            Ok(v) => Voxel {
                lo: v.lo_doubled.map(|x| x as f64),
                hi: v.hi_doubled.map(|x| x as f64),
                values: v.values,
                level: v.level,
            },
            Err(_) => Voxel {
                lo: [0.0; 3],
                hi: [0.0; 3],
                values: [f32::NAN; 8],
                level: 0,
            },
        }
    }
}

impl<D: AsRef<[u8]> + Sync> VoxelSource for ReconSource<'_, D> {
    fn frame(&self) -> GridFrame {
        self.frame
    }

    fn voxel(&self, r: u64) -> Voxel {
        DECODED.with(|cell| {
            let mut slots = cell.borrow_mut();
            // Fibonacci hashing of the ref: neighbouring refs land in different slots.
            let slot = (r.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 52) as usize % SLOTS;
            if let Some(e) = slots.get(slot) {
                if e.0 == self.id && e.1 == r {
                    return e.2;
                }
            }
            let v = self.decode(r);
            if slots.is_empty() {
                slots.resize(SLOTS, (0, u64::MAX, v));
            }
            slots[slot] = (self.id, r, v);
            v
        })
    }

    fn sample(&self, p: [f64; 3]) -> Option<(f32, u32)> {
        let s = self.sampler();
        let v = s.sample(p, self.method).ok().flatten()?;
        let ext = s.grid().extent();
        let finest = [0, 1, 2].map(|a| ((p[a] * 0.5).floor() as i64).clamp(0, ext[a] - 1));
        let level = s.locate(finest).ok().flatten().map_or(0, |c| c.level);
        Some((v, level))
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
            Voxels::Current(_) => intersect_voxel(voxel, iso, ray, tmin, tmax),
            Voxels::Nearest(_) => intersect_face(voxel, iso, ray, tmin, tmax),
        }
    }
}

impl<D: AsRef<[u8]> + Sync> ActiveSource for ReconSource<'_, D> {
    fn extract(&self, iso: f32) -> anyhow::Result<Vec<u64>> {
        Ok(match &self.voxels {
            Voxels::Current(v) => v.extract(iso)?,
            Voxels::Nearest(v) => v.extract(iso)?,
        })
    }
}
