//! Closest-hit and any-hit queries of one isosurface: the `f32` BVH finds candidate voxels,
//! the exact `f64` intersection decides.

use glam::Vec3A;
use obvhs::ray::Ray;

use crate::bvh::packet::{rays_of, Mask, PACKET};
use crate::bvh::{BoxGrid, BoxRun, BvhBuilder, OctantBvh};
use crate::camera::dot;
use crate::trace::last_hit::{self, Query};
use crate::trace::octant::VoxelHit;
use crate::trace::ray::{bvh_rays, GridRay};
use crate::trace::source::{AnyHitQuery, BoxClip, GridFrame, Voxel, VoxelSource};
use crate::trace::tracer::Behind;

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
        let at = |a: usize| v.lo[a] + self.local[a] * (v.hi[a] - v.lo[a]);
        [at(0), at(1), at(2)]
    }

    /// Gradient of the voxel's trilinear interpolant at the hit, per grid unit.
    pub fn grid_gradient(&self) -> [f64; 3] {
        self.voxel.grad_grid(self.local)
    }
}

/// Whether the field rises through the isovalue along `ray` at its hit `h` in `voxel`: the
/// crossing's direction, as [`crate::trace::tracer::SurfaceHit::rising`] has it.
#[inline]
fn rising(voxel: &Voxel, h: &VoxelHit, ray: &GridRay) -> bool {
    dot(voxel.grad_grid(h.local), ray.d) > 0.0
}

/// The padding (grid units) by which voxel boxes are grown in the `f32` BVH: a few thousand `f32`
/// ulps of the largest grid coordinate, far below any voxel's size.
pub fn bvh_pad(frame: &GridFrame) -> f64 {
    1e-5 * frame.extent.iter().fold(1.0f64, |m, &e| m.max(e))
}

/// How the BVH of a surface of `frame`'s grid stores its voxels' boxes: grown by [`bvh_pad`],
/// their centres coded over the domain.
pub fn bvh_grid(frame: &GridFrame) -> BoxGrid {
    BoxGrid::new(
        bvh_pad(frame),
        frame.extent.iter().fold(1.0f64, |m, &e| m.max(e)),
    )
}

/// The grid boxes of runs of voxels, from their refs.
fn voxel_boxes<S: VoxelSource + ?Sized>(src: &S) -> impl Fn(&[u64], &mut BoxRun<'_>) + Sync + '_ {
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
        let grid = bvh_grid(&src.frame());
        builder.build_into(&mut self.bvh, refs, grid, voxel_boxes(src), || {
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
        let grid = bvh_grid(&src.frame());
        builder.build_owned(&mut s.bvh, refs, grid, voxel_boxes(src), || {
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
        self.closest_hit_with(src, ray, tmin, tmax, tmin <= 0.0)
    }

    /// [`Surface::closest_hit`], with the last hit's memory used and updated only when
    /// `remember`.
    pub fn closest_hit_with<S: VoxelSource + ?Sized>(
        &self,
        src: &S,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
        remember: bool,
    ) -> Option<Hit> {
        let frame = src.frame();
        let pad = bvh_pad(&frame);
        let b = ray.bvh_ray(&frame, pad, tmin, tmax)?;
        let slack = 4.0 * pad;
        let key = remember.then(|| last_hit::key(self, Query::Closest));
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

    /// The first hit of each of `rays` (at most [`PACKET`]) with `t` in `[tmin[k], tmax[k]]`, into
    /// `out[k]`: the rays walk the BVH as packets ([`OctantBvh::traverse_packet`]), and a voxel
    /// that several rays reach is looked up once for all of them.
    ///
    /// Each ray's hit is the one [`Surface::closest_hit`] finds without the last hit's memory
    /// (the memory of queries from the origin; a query with `tmin > 0`, a continuation behind a
    /// hit, never uses it): the ray visits the same candidates in the same order under the same `tmax`, and the same
    /// exact test keeps the same nearest one. The memory is neither used nor changed (with it,
    /// only a hit exactly tied between two voxels could differ).
    pub fn closest_hits<S: VoxelSource + ?Sized>(
        &self,
        src: &S,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: &[f64],
        out: &mut [Option<Hit>],
    ) {
        self.closest_hits_skipping::<S, false>(src, rays, tmin, tmax, &[], out);
    }

    /// The next crossing of each of `rays` (at most [`PACKET`]) behind the crossing `behind[k]`
    /// it has taken, up to `tmax[k]`, into `out[k]`: [`Surface::closest_hits`] from
    /// [`Behind::start`], except that a voxel whose hit is that crossing again
    /// ([`Behind::again_after`], a neighbouring voxel's widened segment meeting it) is asked
    /// again behind its hit, in the same walk, instead of the whole query being asked again
    /// ([`crate::trace::tracer::next_crossings_by_queries`]). The two differ only where another
    /// voxel has a crossing less than [`Behind::step`] behind the repeated one, which a new
    /// query would skip.
    pub fn closest_hits_behind<S: VoxelSource + ?Sized>(
        &self,
        src: &S,
        rays: &[GridRay],
        behind: &[Behind],
        tmax: &[f64],
        out: &mut [Option<Hit>],
    ) {
        let n = rays.len();
        assert!(n <= PACKET && behind.len() == n);
        let mut tmin = [0.0; PACKET];
        for (t, b) in tmin.iter_mut().zip(behind) {
            *t = b.start();
        }
        self.closest_hits_skipping::<S, true>(src, rays, &tmin[..n], tmax, behind, out);
    }

    /// [`Surface::closest_hits`], a hit of ray `k` that is `behind[k]` again skipped when `SKIP`
    /// ([`Surface::closest_hits_behind`]; a parameter of the type, so that the primary rays'
    /// walk has no test of it).
    #[inline(always)]
    fn closest_hits_skipping<S: VoxelSource + ?Sized, const SKIP: bool>(
        &self,
        src: &S,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: &[f64],
        behind: &[Behind],
        out: &mut [Option<Hit>],
    ) {
        let n = rays.len();
        assert!(n <= PACKET && tmin.len() == n && tmax.len() == n && out.len() == n);
        let frame = src.frame();
        let pad = bvh_pad(&frame);
        let slack = 4.0 * pad;
        let unused = Ray::new(Vec3A::ZERO, Vec3A::X, 0.0, 0.0);
        let mut ray32 = [unused; PACKET];
        let mut back = [(0.0f64, 0.0f64); PACKET];
        let mut best_t = [0.0f64; PACKET];
        let mut recips = [[0.0f64; 3]; PACKET];
        for k in 0..n {
            out[k] = None;
            best_t[k] = tmax[k];
        }
        // A query behind a hit needs no voxel wholly before its `tmin`, which the exact test
        // rejects: its walk starts just before `tmin` (as any-hit walks do).
        let active = bvh_rays(
            rays,
            &frame,
            pad,
            tmin,
            tmax,
            &mut recips,
            &mut ray32,
            &mut back,
        );
        if active == 0 {
            return;
        }
        let mut found = [None; PACKET];
        src.with_boxed_voxels(&mut |voxel_of| {
            self.bvh
                .traverse_packet(&mut ray32[..n], active, |_, r, m, ray32| {
                    let (voxel, hit) = if m & (m - 1) == 0 {
                        // One ray: its own test, inlined (most candidates of a far view), the
                        // box clip it begins with first, before the voxel's values are decoded
                        // (about a third of a far view's candidates fail it: their leaf's box
                        // met the ray, their own does not).
                        let k = m.trailing_zeros() as usize;
                        let (ray, recip, t0, t1) = (&rays[k], &recips[k], tmin[k], best_t[k]);
                        let box_clip = BoxClip {
                            ray,
                            recip,
                            tmin: t0,
                            tmax: t1,
                        };
                        let Some((voxel, clip)) = voxel_of(r, Some(&box_clip)) else {
                            return;
                        };
                        found[k] = match clip {
                            Some(clip) => {
                                src.intersect_clipped(&voxel, self.iso, ray, (t0, t1), clip)
                            }
                            None => src.intersect(&voxel, self.iso, ray, t0, t1),
                        };
                        (voxel, if found[k].is_some() { m } else { 0 })
                    } else {
                        let Some((voxel, _)) = voxel_of(r, None) else {
                            return;
                        };
                        let hit = src.intersect_packet(
                            &voxel,
                            self.iso,
                            rays,
                            &recips[..n],
                            m,
                            &tmin[..n],
                            &best_t[..n],
                            &mut found[..n],
                        );
                        (voxel, hit)
                    };
                    'rays: for k in rays_of(hit) {
                        let Some(mut h) = found[k] else {
                            continue;
                        };
                        if SKIP {
                            while let Some(t) =
                                behind[k].again_after(h.t, rising(&voxel, &h, &rays[k]))
                            {
                                match src.intersect(&voxel, self.iso, &rays[k], t, best_t[k]) {
                                    Some(next) => h = next,
                                    None => continue 'rays,
                                }
                            }
                        }
                        if h.t < best_t[k] || out[k].is_none() {
                            best_t[k] = h.t;
                            out[k] = Some(Hit {
                                t: h.t,
                                r,
                                voxel,
                                local: h.local,
                            });
                            let (t_off, scale) = back[k];
                            ray32[k].tmax = ((h.t - t_off) * scale + slack) as f32;
                        }
                    }
                })
        });
    }

    /// True when the surface is hit anywhere with `t` in `[tmin, tmax]`. The walk skips the
    /// voxels that lie wholly before `tmin` ([`GridRay::bvh_ray_ahead`]), which the exact test
    /// rejects.
    pub fn any_hit<S: VoxelSource + ?Sized>(
        &self,
        src: &S,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
    ) -> bool {
        let frame = src.frame();
        let Some(b) = ray.bvh_ray_ahead(&frame, bvh_pad(&frame), tmin, tmax) else {
            return false;
        };
        // The traversal macro's `break` leaves only the current leaf's loop, so a hit must also
        // stay set and empty the ray's interval, or later candidates would overwrite it.
        let mut hit = false;
        let recip = ray.recip();
        src.with_voxels(&mut |voxel_of| {
            self.bvh.traverse(b.ray, |r, tmax32| {
                if !hit && src.occludes(&voxel_of(r), self.iso, ray, &recip, tmin, tmax) {
                    hit = true;
                    *tmax32 = f32::NEG_INFINITY;
                }
                hit
            })
        });
        hit
    }

    /// The rays of `active` (of `rays`, at most [`PACKET`]) that hit the surface anywhere with
    /// `t` in `[tmin[k], tmax]`: [`Surface::any_hits_of`] the rays made ready for this one walk.
    pub fn any_hits<S: VoxelSource + ?Sized>(
        &self,
        src: &S,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: f64,
        active: Mask,
    ) -> Mask {
        let mut ready = AnyHitRays::new(&src.frame(), rays, tmin, tmax, active);
        self.any_hits_of(src, &mut ready, active)
    }

    /// The rays of `active` among `rays` that hit the surface anywhere with `t` in
    /// `[tmin[k], tmax]` (their [`AnyHitRays`]): the rays walk the BVH as a packet, and a ray
    /// leaves the walk at its first occluding voxel. Each ray's answer is [`Surface::any_hit`]'s:
    /// until it is hit, a ray visits the candidates the single-ray walk gives it, under the same
    /// `tmax`, with the same exact test. The rays that reach a voxel are tested together
    /// ([`VoxelSource::occluders_packet`]), sharing the voxel's set-up. `rays` is left ready for
    /// the next surface's walk.
    pub fn any_hits_of<S: VoxelSource + ?Sized>(
        &self,
        src: &S,
        rays: &mut AnyHitRays<'_>,
        active: Mask,
    ) -> Mask {
        let live = active & rays.live;
        let mut hit: Mask = 0;
        if live == 0 {
            return hit;
        }
        let n = rays.rays.len();
        let AnyHitRays {
            rays: grid,
            tmin,
            tmax,
            recips,
            ray32,
            ..
        } = rays;
        let (grid, tmin, tmax) = (*grid, *tmin, &tmax[..n]);
        src.with_occlusion_tests(self.iso, &mut |test| {
            self.bvh
                .traverse_packet_any(&mut ray32[..n], live, |_, r, m, _| {
                    let found = if m & (m - 1) == 0 {
                        // One ray: its own test (no set-up to share), the box clip it begins
                        // with first, before the voxel's values are decoded (about a third of a
                        // far view's single-ray candidates fail it).
                        let k = m.trailing_zeros() as usize;
                        let box_clip = BoxClip {
                            ray: &grid[k],
                            recip: &recips[k],
                            tmin: tmin[k],
                            tmax: tmax[k],
                        };
                        if test(r, AnyHitQuery::One(&box_clip)) != 0 {
                            m
                        } else {
                            0
                        }
                    } else {
                        test(
                            r,
                            AnyHitQuery::Packet {
                                rays: grid,
                                recips: &recips[..n],
                                m,
                                tmin,
                                tmax,
                            },
                        )
                    };
                    hit |= found;
                    found
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

/// The shadow or occlusion rays of a packet (at most [`PACKET`]) made ready for any-hit walks
/// ([`Surface::any_hits_of`]): their reciprocal directions and `f32` BVH rays, computed once for
/// all the surfaces asked about them ([`bvh_rays`], four rays at a time).
pub struct AnyHitRays<'a> {
    rays: &'a [GridRay],
    tmin: &'a [f64],
    /// The query's `tmax`, per ray.
    tmax: [f64; PACKET],
    recips: [[f64; 3]; PACKET],
    ray32: [Ray; PACKET],
    /// The rays asked about that meet the domain.
    live: Mask,
}

impl<'a> AnyHitRays<'a> {
    /// The rays `active` of `rays`, each over `[tmin[k], tmax]`, in a grid of `frame`. Each `f32`
    /// ray is [`GridRay::bvh_ray_ahead`]'s, bit for bit (a ray from its origin, `tmin[k] <= 0`,
    /// which shadow and occlusion rays never are, takes it ray by ray).
    pub fn new(
        frame: &GridFrame,
        rays: &'a [GridRay],
        tmin: &'a [f64],
        tmax: f64,
        active: Mask,
    ) -> AnyHitRays<'a> {
        let n = rays.len();
        assert!(n <= PACKET && tmin.len() == n && (n == PACKET || active >> n == 0));
        let pad = bvh_pad(frame);
        let unused = Ray::new(Vec3A::ZERO, Vec3A::X, 0.0, 0.0);
        let mut ready = AnyHitRays {
            rays,
            tmin,
            tmax: [tmax; PACKET],
            recips: [[0.0; 3]; PACKET],
            ray32: [unused; PACKET],
            live: 0,
        };
        if active == 0 {
            return ready;
        }
        // `bvh_rays` gives a ray with `tmin > 0` the any-hit walk's shorter lead.
        if rays_of(active).all(|k| tmin[k] > 0.0) {
            let mut back = [(0.0, 0.0); PACKET];
            let met = bvh_rays(
                rays,
                frame,
                pad,
                tmin,
                &ready.tmax[..n],
                &mut ready.recips,
                &mut ready.ray32,
                &mut back,
            );
            ready.live = met & active;
        } else {
            for k in rays_of(active) {
                ready.recips[k] = rays[k].recip();
                let recip = &ready.recips[k];
                if let Some(b) = rays[k].bvh_ray_ahead_with(recip, frame, pad, tmin[k], tmax) {
                    ready.ray32[k] = b.ray;
                    ready.live |= 1 << k;
                }
            }
        }
        ready
    }
}
