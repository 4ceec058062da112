//! What the tracer needs from a volume: active voxels decoded from 64-bit refs, and point samples.

use crate::bvh::packet::{rays_where, Mask};
use crate::bvh::BoxRun;
use crate::reconstruct::level_blend::LevelWeights;
use crate::reconstruct::Grid;
use crate::trace::octant::{intersect_voxel, VoxelHit};
use crate::trace::ray::GridRay;
use crate::trace::tracer::{central_difference, SurfaceHit};
pub use crate::voxel::Voxel;

/// The affine map from grid coordinates to world coordinates, and the grid's extent.
///
/// Tracing happens in grid coordinates (relative to the domain's lower corner, in units of a
/// cell of some level), so a domain far from the world origin with tiny cells is traced with the
/// same precision as the unit cube.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GridFrame {
    /// World position of grid point `(0, 0, 0)`: the domain's lower corner.
    pub origin: [f64; 3],
    /// World size of one grid unit on each axis.
    pub unit: [f64; 3],
    /// The domain is `[0, extent]` in grid coordinates.
    pub extent: [f64; 3],
}

impl GridFrame {
    /// The frame of a file's grid: doubled finest-level coordinates from the domain's lower
    /// corner.
    pub fn of_grid(grid: &Grid) -> GridFrame {
        let origin = grid.to_world([0.0; 3]);
        let unit = [0, 1, 2].map(|a| {
            let mut e = [0.0; 3];
            e[a] = 1.0;
            grid.to_world(e)[a] - origin[a]
        });
        GridFrame {
            origin,
            unit,
            extent: grid.extent().map(|e| 2.0 * e as f64),
        }
    }

    /// World position of grid point `g`.
    pub fn to_world(&self, g: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.origin[a] + g[a] * self.unit[a])
    }

    /// Grid position of world point `w`.
    pub fn to_grid(&self, w: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| (w[a] - self.origin[a]) / self.unit[a])
    }

    /// Grid-space vector of world vector `v` (a direction: no origin).
    #[inline]
    pub fn to_grid_dir(&self, v: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| v[a] / self.unit[a])
    }

    /// World-space lower and upper corners of the domain.
    pub fn world_bounds(&self) -> ([f64; 3], [f64; 3]) {
        (self.origin, self.to_world(self.extent))
    }
}

/// A lookup of voxels by ref ([`VoxelSource::with_voxels`]).
pub type VoxelLookup<'a> = dyn FnMut(u64) -> Voxel + 'a;

/// A lookup of voxels by ref that may skip a voxel on its box alone
/// ([`VoxelSource::with_boxed_voxels`]): `lookup(r, clip)` gives the voxel `r` names and, when
/// it clipped `clip`'s ray to the voxel's box, the interval [`BoxClip::of`] gave; or, given a
/// `clip`, it may give `None` when that interval is empty.
pub type BoxedLookup<'a> =
    dyn FnMut(u64, Option<&BoxClip<'_>>) -> Option<(Voxel, Option<(f64, f64)>)> + 'a;

/// What an any-hit walk asks of a candidate voxel ([`OcclusionTest`]).
#[derive(Clone, Copy)]
pub enum AnyHitQuery<'a> {
    /// One ray over its interval, clipped to the voxel's box first: [`VoxelSource::occludes`].
    One(&'a BoxClip<'a>),
    /// The rays `m` of a packet: [`VoxelSource::occluders_packet`]'s arguments.
    Packet {
        /// The packet's rays.
        rays: &'a [GridRay],
        /// Their reciprocal directions ([`GridRay::recip`]).
        recips: &'a [[f64; 3]],
        /// The rays asked about.
        m: Mask,
        /// Each ray's `tmin`.
        tmin: &'a [f64],
        /// Each ray's `tmax`.
        tmax: &'a [f64],
    },
}

/// An any-hit test of voxels by ref ([`VoxelSource::with_occlusion_tests`]): `test(r, query)`
/// gives the rays of `query` that the voxel `r` names occludes, a single ray's answer as 1 or 0.
pub type OcclusionTest<'a> = dyn FnMut(u64, AnyHitQuery<'_>) -> Mask + 'a;

/// [`VoxelSource::with_occlusion_tests`] by [`VoxelSource::with_boxed_voxels`]: each voxel
/// looked up (a single ray's clipped to its box first), then [`VoxelSource::occludes_clipped`],
/// [`VoxelSource::occludes`] or [`VoxelSource::occluders_packet`].
pub fn occlusion_tests_by_lookup<S: VoxelSource + ?Sized>(
    src: &S,
    iso: f32,
    f: &mut dyn FnMut(&mut OcclusionTest<'_>),
) {
    src.with_boxed_voxels(&mut |voxel_of| {
        f(&mut |r, query| match query {
            AnyHitQuery::One(c) => {
                let Some((voxel, clip)) = voxel_of(r, Some(c)) else {
                    return 0;
                };
                let (ray, recip, t) = (c.ray, c.recip, (c.tmin, c.tmax));
                Mask::from(match clip {
                    Some(clip) => src.occludes_clipped(&voxel, iso, ray, recip, t, clip),
                    None => src.occludes(&voxel, iso, ray, recip, t.0, t.1),
                })
            }
            AnyHitQuery::Packet {
                rays,
                recips,
                m,
                tmin,
                tmax,
            } => {
                let Some((voxel, _)) = voxel_of(r, None) else {
                    return 0;
                };
                src.occluders_packet(&voxel, iso, rays, recips, m, tmin, tmax)
            }
        })
    })
}

/// A ray over `[tmin, tmax]`, to be clipped to a candidate voxel's box before the voxel's values
/// are read ([`BoxedLookup`]).
#[derive(Clone, Copy)]
pub struct BoxClip<'a> {
    /// The ray.
    pub ray: &'a GridRay,
    /// The reciprocals of its direction's components ([`GridRay::recip`]).
    pub recip: &'a [f64; 3],
    /// The start of its interval.
    pub tmin: f64,
    /// The end of its interval.
    pub tmax: f64,
}

impl BoxClip<'_> {
    /// The ray's interval in the box `lo..hi` ([`GridRay::clip_with`]): the clip
    /// [`intersect_voxel`] begins with.
    #[inline(always)]
    pub fn of(&self, lo: [f64; 3], hi: [f64; 3]) -> Option<(f64, f64)> {
        self.ray.clip_with(self.recip, lo, hi, self.tmin, self.tmax)
    }
}

/// A volume seen as a source of trilinear voxels, each named by a 64-bit ref (the paper's
/// *VoxelSource*, section 4.1.1), plus point sampling of the same reconstruction.
pub trait VoxelSource: Sync {
    /// The grid-to-world map and the domain's extent.
    fn frame(&self) -> GridFrame;

    /// The voxel named by `r`; `r` must come from this source's extraction.
    fn voxel(&self, r: u64) -> Voxel;

    /// Calls `f` with a lookup that gives what [`Self::voxel`] gives, for the many refs one
    /// ray's traversal asks for: sources with a per-thread cache bind it once for all of them
    /// (the default looks each up by [`Self::voxel`]). The lookup must not be used to reenter
    /// this source's other methods.
    fn with_voxels(&self, f: &mut dyn FnMut(&mut VoxelLookup<'_>)) {
        f(&mut |r| self.voxel(r))
    }

    /// [`Self::with_voxels`] for a query that tests each voxel's box first: the lookup's
    /// [`BoxClip`] is the box clip [`intersect_voxel`] begins with. A source whose
    /// [`Self::intersect`] finds hits only in voxels whose box passes that clip, and which can
    /// tell a box from its ref alone, may give `None` for a voxel whose box the clip rejects,
    /// without decoding its values. By default every voxel is given, not clipped.
    fn with_boxed_voxels(&self, f: &mut dyn FnMut(&mut BoxedLookup<'_>)) {
        self.with_voxels(&mut |voxel_of| f(&mut |r, _| Some((voxel_of(r), None))))
    }

    /// Calls `f` with an any-hit test of candidate voxels by ref for surface `iso`
    /// ([`OcclusionTest`]), for the many candidates of an any-hit walk: by default
    /// [`occlusion_tests_by_lookup`]; a source with a cache may test a voxel where its cache
    /// holds it. The answers must be [`occlusion_tests_by_lookup`]'s.
    fn with_occlusion_tests(&self, iso: f32, f: &mut dyn FnMut(&mut OcclusionTest<'_>)) {
        occlusion_tests_by_lookup(self, iso, f)
    }

    /// The box `(lo, hi)` of the voxel named by `r`: by default [`Self::voxel`]'s; sources that
    /// can tell it from the reference alone skip reading its values.
    fn voxel_box(&self, r: u64) -> ([f64; 3], [f64; 3]) {
        let v = self.voxel(r);
        (v.lo, v.hi)
    }

    /// [`Self::voxel_box`] of each of `refs`, pushed in order to `out`; sources may share work
    /// between neighbouring refs (the BVH build decodes all boxes through this).
    fn voxel_boxes(&self, refs: &[u64], out: &mut BoxRun<'_>) {
        for &r in refs {
            let (lo, hi) = self.voxel_box(r);
            out.push(lo, hi);
        }
    }

    /// The reconstructed field and the AMR level at grid point `p`, or `None` outside the data.
    fn sample(&self, p: [f64; 3]) -> Option<(f32, u32)>;

    /// The gradient of [`Self::sample`]'s field at `p` by central differences `h[a]` apart on
    /// axis `a` ([`central_difference`]); sources may compute the same values faster.
    fn gradient(&self, p: [f64; 3], h: [f64; 3]) -> Option<[f64; 3]> {
        central_difference(self, p, h)
    }

    /// The gradient smooth normals take at `p` on a hit of AMR level `level`: [`Self::gradient`]
    /// one cell of a level apart on each axis ([`Self::cell_size`], `step` when the source has
    /// no levels), for each level [`Self::level_weights`] gives, weighed by it. Sources may
    /// compute the same values faster.
    fn level_gradient(&self, p: [f64; 3], level: u32, step: [f64; 3]) -> Option<[f64; 3]> {
        self.level_weights(p, level)
            .blend(|l| self.gradient(p, self.cell_size(l).unwrap_or(step)))
    }

    /// The levels whose cells smooth normals step by at `p` on a hit of level `level`, and
    /// their weights: by default `level` alone; a source with levels blends two near a level
    /// boundary, so that the normal does not jump there ([`crate::reconstruct::level_blend`]).
    fn level_weights(&self, _p: [f64; 3], level: u32) -> LevelWeights {
        LevelWeights::one(level)
    }

    /// Gives each of `hits` [`Self::level_gradient`] at its position, for its level, with its
    /// voxel's size as the step, as its gradient where that is `Some`: the smooth normals of a
    /// packet's hits. By default asked hit by hit; sources may share work between the hits.
    /// (A source with levels steps by the level's cell, not by the voxel's shape, an octant or
    /// a merged dual cell, so that neighbouring hits of one level use the same step.)
    fn smooth_gradients(&self, hits: &mut [Option<SurfaceHit>]) {
        for hit in hits.iter_mut().flatten() {
            if let Some(g) = self.level_gradient(hit.pos, hit.level, [hit.size; 3]) {
                hit.grad = g;
            }
        }
    }

    /// The size of a cell of AMR level `level` in grid units, per axis; `None` (the default)
    /// when the source has no levels to tell.
    fn cell_size(&self, _level: u32) -> Option<[f64; 3]> {
        None
    }

    /// Drops pages of the underlying file from the resident set, between stages that touch it;
    /// a no-op for sources that hold no file.
    fn release_pages(&self) {}

    /// The first hit of `ray` with the surface `iso` inside `voxel` with `t` in `[tmin, tmax]`:
    /// by default the exact intersection with the voxel's trilinear interpolant.
    #[inline]
    fn intersect(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
    ) -> Option<VoxelHit> {
        intersect_voxel(voxel, iso, ray, tmin, tmax)
    }

    /// [`Self::intersect`] of a voxel that [`Self::with_boxed_voxels`]' lookup clipped, given
    /// `clip`, the ray's interval in the voxel's box it gave ([`GridRay::clip_with`] for `tmin`
    /// and `tmax`): sources that clip there skip clipping again. By default
    /// [`Self::intersect`].
    #[inline]
    fn intersect_clipped(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        (tmin, tmax): (f64, f64),
        clip: (f64, f64),
    ) -> Option<VoxelHit> {
        let _ = clip;
        self.intersect(voxel, iso, ray, tmin, tmax)
    }

    /// [`Self::intersect`] for the rays `m` of a packet (each with its reciprocal direction,
    /// [`GridRay::recip`], and its own `tmin` and `tmax`) that reach `voxel`: the rays of `m`
    /// for which [`Self::intersect`] finds a hit, each hit in `hits[k]` (the entries of the
    /// other rays are left unspecified). Sources may share the voxel's own work between the
    /// rays.
    #[allow(clippy::too_many_arguments)]
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
        let _ = recips;
        rays_where(m, |k| {
            hits[k] = self.intersect(voxel, iso, &rays[k], tmin[k], tmax[k]);
            hits[k].is_some()
        })
    }

    /// True when [`Self::intersect`] would find a hit: the any-hit test of shadow and occlusion
    /// rays, given `recip`, the ray's reciprocal direction ([`GridRay::recip`]), which a ray
    /// keeps for all its candidates. Sources may answer without computing where the hit is.
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
        let _ = recip;
        self.intersect(voxel, iso, ray, tmin, tmax).is_some()
    }

    /// [`Self::occludes`] of a voxel that [`Self::with_boxed_voxels`]' lookup clipped the ray
    /// to, given `clip`, the ray's interval in the voxel's box that the lookup gave
    /// ([`BoxClip::of`] for `tmin` and `tmax`): the same answer, without clipping again. By
    /// default [`Self::occludes`].
    #[inline]
    fn occludes_clipped(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        recip: &[f64; 3],
        (tmin, tmax): (f64, f64),
        clip: (f64, f64),
    ) -> bool {
        let _ = clip;
        self.occludes(voxel, iso, ray, recip, tmin, tmax)
    }

    /// [`Self::occludes`] for the rays `m` of a packet (each with its reciprocal direction,
    /// [`GridRay::recip`], and its own `tmin` and `tmax`) that reach `voxel`: the rays of `m` for
    /// which it is true. Sources may share the voxel's own work between the rays.
    #[allow(clippy::too_many_arguments)]
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
        rays_where(m, |k| {
            self.occludes(voxel, iso, &rays[k], &recips[k], tmin[k], tmax[k])
        })
    }
}
