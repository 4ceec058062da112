//! Closest-hit and any-hit queries of one isosurface: the `f32` BVH finds candidate voxels,
//! the exact `f64` intersection decides.

use crate::bvh::{BvhBuilder, OctantBvh};
use crate::trace::last_hit::{self, Query};
use crate::trace::ray::GridRay;
use crate::trace::source::{GridFrame, Voxel, VoxelSource};

/// One isosurface ready to trace: its isovalue and the BVH over its active voxels.
#[derive(Clone, Debug, Default)]
pub struct Surface {
    /// The isovalue.
    pub iso: f32,
    /// BVH over the voxels whose corner range contains `iso`.
    pub bvh: OctantBvh,
}

/// A ray's hit with an isosurface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter.
    pub t: f64,
    /// The ref of the voxel hit.
    pub r: u64,
    /// The voxel hit.
    pub voxel: Voxel,
    /// Voxel-local coordinates of the hit.
    pub local: [f64; 3],
}

impl Hit {
    /// Grid position of the hit, from the voxel-local coordinates.
    pub fn grid_pos(&self) -> [f64; 3] {
        let v = &self.voxel;
        [0, 1, 2].map(|a| v.lo[a] + self.local[a] * (v.hi[a] - v.lo[a]))
    }

    /// Gradient of the voxel's trilinear interpolant at the hit, per grid unit.
    pub fn grid_gradient(&self) -> [f64; 3] {
        let g = self.voxel.grad_local(self.local);
        [0, 1, 2].map(|a| g[a] / (self.voxel.hi[a] - self.voxel.lo[a]))
    }
}

/// The padding (grid units) by which voxel boxes are grown in the `f32` BVH: a few thousand `f32`
/// ulps of the largest grid coordinate, far below any voxel's size.
pub fn bvh_pad(frame: &GridFrame) -> f64 {
    1e-5 * frame.extent.iter().fold(1.0f64, |m, &e| m.max(e))
}

/// The grid boxes of runs of voxels, from their refs.
fn voxel_boxes<S: VoxelSource + ?Sized>(
    src: &S,
) -> impl Fn(&[u64], &mut dyn FnMut([f64; 3], [f64; 3])) + Sync + '_ {
    |refs, out| src.voxel_boxes(refs, out)
}

impl Surface {
    /// Builds the surface for `iso` from its active refs, reusing `builder`'s scratch.
    pub fn build<S: VoxelSource + ?Sized>(
        src: &S,
        iso: f32,
        refs: &[u64],
        builder: &mut BvhBuilder,
    ) -> Surface {
        let mut s = Surface {
            iso,
            bvh: OctantBvh::default(),
        };
        s.rebuild(src, iso, refs, builder);
        s
    }

    /// Replaces the surface with the one for a new isovalue, reusing buffers.
    pub fn rebuild<S: VoxelSource + ?Sized>(
        &mut self,
        src: &S,
        iso: f32,
        refs: &[u64],
        builder: &mut BvhBuilder,
    ) {
        self.iso = iso;
        let pad = bvh_pad(&src.frame());
        builder.build_into(&mut self.bvh, refs, pad, voxel_boxes(src), || {
            src.release_pages()
        });
    }

    /// [`Surface::build`] taking the refs by value, which saves a copy of them.
    pub fn build_owned<S: VoxelSource + ?Sized>(
        src: &S,
        iso: f32,
        refs: Vec<u64>,
        builder: &mut BvhBuilder,
    ) -> Surface {
        let mut s = Surface {
            iso,
            bvh: OctantBvh::default(),
        };
        let pad = bvh_pad(&src.frame());
        builder.build_owned(&mut s.bvh, refs, pad, voxel_boxes(src), || {
            src.release_pages()
        });
        s
    }

    /// The first hit with `t` in `[tmin, tmax]`.
    ///
    /// For a query from the ray's origin (`tmin <= 0`: primary rays), the voxel of this thread's
    /// last such hit on this surface is tested before the walk while such hits keep repeating
    /// voxels ([`last_hit`]): the walk then starts with `tmax` at its hit and enters nothing
    /// behind it. The hit is the nearest of all candidates either way. Queries that continue
    /// behind a hit (`tmin > 0`) have left that voxel, and neither use nor change the memory.
    pub fn closest_hit<S: VoxelSource + ?Sized>(
        &self,
        src: &S,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
    ) -> Option<Hit> {
        let frame = src.frame();
        let pad = bvh_pad(&frame);
        let b = ray.bvh_ray(&frame, pad, tmin, tmax)?;
        let slack = 4.0 * pad;
        let key = (tmin <= 0.0).then(|| last_hit::key(self, Query::Closest));
        let seed = key.and_then(|key| self.seed(key));
        let mut best: Option<Hit> = None;
        let mut best_at = usize::MAX;
        let mut best_t = tmax;
        src.with_voxels(&mut |voxel_of| {
            let mut test = |at: usize, r: u64, tmax32: &mut f32| {
                let voxel = voxel_of(r);
                if let Some(h) = src.intersect(&voxel, self.iso, ray, tmin, best_t) {
                    if h.t < best_t || best.is_none() {
                        best_t = h.t;
                        best_at = at;
                        best = Some(Hit {
                            t: h.t,
                            r,
                            voxel,
                            local: h.local,
                        });
                        *tmax32 = ((h.t - b.t_off) * b.scale + slack) as f32;
                    }
                }
            };
            let mut ray32 = b.ray;
            if let Some((at, r)) = seed {
                test(at, r, &mut ray32.tmax);
            }
            let skip = seed.map_or(usize::MAX, |(at, _)| at);
            self.bvh.traverse_indexed(ray32, |at, r, tmax32| {
                if at != skip {
                    test(at, r, tmax32);
                }
                false
            })
        });
        if let Some(key) = key {
            last_hit::record(key, best.is_some().then_some(best_at));
        }
        best
    }

    /// True when the surface is hit anywhere with `t` in `[tmin, tmax]`.
    pub fn any_hit<S: VoxelSource + ?Sized>(
        &self,
        src: &S,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
    ) -> bool {
        let frame = src.frame();
        let Some(b) = ray.bvh_ray(&frame, bvh_pad(&frame), tmin, tmax) else {
            return false;
        };
        // The traversal macro's `break` leaves only the current leaf's loop, so a hit must also
        // stay set and empty the ray's interval, or later candidates would overwrite it.
        let mut hit = false;
        src.with_voxels(&mut |voxel_of| {
            self.bvh.traverse(b.ray, |r, tmax32| {
                if !hit && src.occludes(&voxel_of(r), self.iso, ray, tmin, tmax) {
                    hit = true;
                    *tmax32 = f32::NEG_INFINITY;
                }
                hit
            })
        });
        hit
    }

    /// The position and ref of the voxel to test before the walk, if this thread remembers one
    /// for `key` with confidence and it is one of this surface's.
    #[inline]
    fn seed(&self, key: usize) -> Option<(usize, u64)> {
        match last_hit::recall(key)? {
            (at, true) => Some((at, *self.bvh.refs().get(at)?)),
            _ => None,
        }
    }
}
