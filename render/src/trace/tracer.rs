//! The interface the shader traces through, and its exact ("hybrid") implementation: a BVH per
//! isosurface and the implicit ray-voxel intersection.

use crate::bvh::packet::{rays_of, rays_where, Mask, PACKET};
use crate::camera::dot;
use crate::trace::ray::GridRay;
use crate::trace::source::{GridFrame, VoxelSource};
use crate::trace::traverse::{bvh_pad, AnyHitRays, Hit, Surface};

/// A hit as the shader sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Ray parameter (world distance for a unit world direction).
    pub t: f64,
    /// Hit position, grid coordinates.
    pub pos: [f64; 3],
    /// Field gradient per grid unit (not normalized; may be zero): the shading normal.
    pub grad: [f64; 3],
    /// Whether the field rises through the isovalue along the ray here: the crossing's
    /// direction, from the surface the ray crossed (the hit voxel's own interpolant), so the
    /// side the ray came from even where a smooth shading normal [`SurfaceHit::grad`] leans past
    /// the ray at a silhouette.
    pub rising: bool,
    /// AMR level of the voxel hit.
    pub level: u32,
    /// Size of the voxel hit (grid units), the scale for offsets that leave the surface.
    pub size: f64,
    /// Ref of the voxel hit (`u64::MAX` when not traced through voxels).
    pub r: u64,
}

/// The colour data gives a hit (see [`crate::paint`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Paint {
    /// Linear RGB.
    pub rgb: [f32; 3],
    /// The value painted (a field's value, or the level).
    pub value: f32,
}

/// Finds hits with a set of isosurfaces.
pub trait Tracer {
    /// The grid-to-world map.
    fn frame(&self) -> GridFrame;

    /// Number of isosurfaces.
    fn num_surfaces(&self) -> usize;

    /// The first hit with surface `i` with `t` in `[tmin, tmax]`.
    fn next_hit(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> Option<SurfaceHit>;

    /// The first hit with surface `i` of each of `rays` from its origin (`t` in `[0, tmax[k]]`),
    /// into `out[k]`: for each ray what [`Tracer::next_hit`] finds (by default it is asked ray
    /// by ray; tracers may trace the rays together, as packets).
    fn next_hits(&self, i: usize, rays: &[GridRay], tmax: &[f64], out: &mut [Option<SurfaceHit>]) {
        for ((ray, &tmax), out) in rays.iter().zip(tmax).zip(out) {
            *out = self.next_hit(i, ray, 0.0, tmax);
        }
    }

    /// The first hit with surface `i` of each of `rays` with `t` in `[tmin[k], tmax[k]]`, into
    /// `out[k]`: for each ray what [`Tracer::next_hit`] finds (by default it is asked ray by
    /// ray; tracers may trace the rays together, as packets). The continuations behind
    /// transparent hits ([`crate::shade::layers`]).
    fn next_hits_from(
        &self,
        i: usize,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
    ) {
        next_hits_one_by_one(self, i, rays, tmin, tmax, out)
    }

    /// The next crossing of surface `i` of each of `rays` behind the crossing `behind[k]` it
    /// has taken, up to `tmax[k]`, into `out[k]`: the first hit from [`Behind::start`] on that
    /// is not the same crossing again ([`Behind::again_after`]; the search goes on behind such
    /// a hit). By default the hits are asked of [`Tracer::next_hits_from`], again for the rays
    /// whose hit is the same crossing ([`next_crossings_by_queries`]); tracers may skip such a
    /// hit inside one query.
    fn next_crossings(
        &self,
        i: usize,
        rays: &[GridRay],
        behind: &[Behind],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
    ) {
        next_crossings_by_queries(self, i, rays, behind, tmax, out)
    }

    /// Drops the pages of the file traced from the resident set (between bands of a frame);
    /// a no-op unless the source holds a file.
    fn release_pages(&self) {}

    /// True when surface `i` is hit with `t` in `[tmin, tmax]`.
    fn occluded(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> bool {
        self.next_hit(i, ray, tmin, tmax).is_some()
    }

    /// The rays `k` of `active` (bit `k` for `rays[k]`, at most [`PACKET`] rays) for which
    /// surface `i` is hit with `t` in `[tmin[k], tmax]`: for each ray what [`Tracer::occluded`]
    /// answers (by default it is asked ray by ray; tracers may trace the rays as a packet).
    fn occluded_many(
        &self,
        i: usize,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: f64,
        active: Mask,
    ) -> Mask {
        rays_where(active, |k| self.occluded(i, &rays[k], tmin[k], tmax))
    }

    /// Asks the surfaces of `order` in turn which of the rays `active` (of `rays`, at most
    /// [`PACKET`]) they occlude with `t` in `[tmin[k], tmax]`: `answer(s, hit)` gets surface
    /// `s`'s answer ([`Tracer::occluded_many`] for the rays still asked) and returns the rays to
    /// ask the next surface about; the questions stop when none is left. `answer` is called
    /// once for every surface asked. By default each surface is asked by
    /// [`Tracer::occluded_many`]; tracers may share the rays' set-up between the surfaces.
    fn occluded_in_turn(
        &self,
        order: &[usize],
        rays: &[GridRay],
        tmin: &[f64],
        tmax: f64,
        active: Mask,
        answer: &mut dyn FnMut(usize, Mask) -> Mask,
    ) {
        let mut live = active;
        for &s in order {
            if live == 0 {
                break;
            }
            live = answer(s, self.occluded_many(s, rays, tmin, tmax, live));
        }
    }

    /// The colour data gives surface `i` at `hit`; `None` (the default) keeps the surface's own.
    fn paint(&self, _i: usize, _hit: &SurfaceHit) -> Option<Paint> {
        None
    }

    /// Whether surface `i` shows its painted colour as it is, not shaded by the lights (a
    /// slice): no shadow or AO ray leaves it. `false` by default.
    fn unlit(&self, _i: usize) -> bool {
        false
    }
}

/// A crossing of a surface a ray has taken, behind which the search for the surface's next
/// crossing goes on.
///
/// Where a ray passes through a face, edge or corner shared by two octants, both octants report
/// the crossing (their segments are widened so that none is lost), a hair apart along the ray.
/// Compositing such a duplicate would draw a transparent surface twice along every octant
/// boundary. A real next crossing of a surface leaves it on the other side, so a hit that is
/// close behind and crosses in the same direction is the same crossing, and is skipped.
#[derive(Clone, Copy, Debug)]
pub struct Behind {
    /// The crossing's `t`.
    pub t: f64,
    /// The crossing's direction ([`SurfaceHit::rising`]).
    pub rising: bool,
    /// How far behind a crossing the search goes on.
    pub step: f64,
    /// How close behind a crossing in the same direction is the same crossing.
    pub same_within: f64,
}

impl Behind {
    /// Where the search starts.
    pub fn start(&self) -> f64 {
        self.t + self.step
    }

    /// `None` when a hit at `t` crossing in direction `rising` is a new crossing; else where
    /// the search goes on.
    pub fn again_after(&self, t: f64, rising: bool) -> Option<f64> {
        let duplicate = t - self.t < self.same_within && rising == self.rising;
        duplicate.then_some(t + self.step)
    }
}

/// [`Tracer::next_crossings`] through [`Tracer::next_hits_from`], asked again for the rays whose
/// hit is the same crossing: what tracers without their own give.
pub fn next_crossings_by_queries<T: Tracer + ?Sized>(
    tracer: &T,
    i: usize,
    rays: &[GridRay],
    behind: &[Behind],
    tmax: &[f64],
    out: &mut [Option<SurfaceHit>],
) {
    for (((rays, behind), tmax), out) in rays
        .chunks(PACKET)
        .zip(behind.chunks(PACKET))
        .zip(tmax.chunks(PACKET))
        .zip(out.chunks_mut(PACKET))
    {
        let mut from = [0.0; PACKET];
        for (from, behind) in from.iter_mut().zip(behind) {
            *from = behind.start();
        }
        let mut pending: Mask = !0 >> (PACKET - rays.len());
        let mut r = [rays[0]; PACKET];
        let (mut t0, mut t1, mut found) = ([0.0; PACKET], [0.0; PACKET], [None; PACKET]);
        while pending != 0 {
            let mut c = 0;
            for k in rays_of(pending) {
                (r[c], t0[c], t1[c]) = (rays[k], from[k], tmax[k]);
                c += 1;
            }
            tracer.next_hits_from(i, &r[..c], &t0[..c], &t1[..c], &mut found[..c]);
            for (j, k) in rays_of(pending).enumerate() {
                match found[j].and_then(|h| behind[k].again_after(h.t, h.rising)) {
                    Some(t) => from[k] = t,
                    None => {
                        out[k] = found[j];
                        pending &= !(1 << k);
                    }
                }
            }
        }
    }
}

/// [`Tracer::next_hits_from`] asked ray by ray through [`Tracer::next_hit`]: what tracers that
/// do not trace packets give.
pub fn next_hits_one_by_one<T: Tracer + ?Sized>(
    tracer: &T,
    i: usize,
    rays: &[GridRay],
    tmin: &[f64],
    tmax: &[f64],
    out: &mut [Option<SurfaceHit>],
) {
    for (k, out) in out.iter_mut().enumerate().take(rays.len()) {
        *out = tracer.next_hit(i, &rays[k], tmin[k], tmax[k]);
    }
}

/// Exact tracing through BVHs over active voxels.
pub struct HybridTracer<'a, S: VoxelSource + ?Sized> {
    /// The voxel source: the frame's grid, and the voxels of every surface `sources` names none
    /// for.
    pub src: &'a S,
    /// One surface per isovalue.
    pub surfaces: &'a [Surface],
    /// The voxel source of each surface whose field is not `src`'s, by the surface's index:
    /// surface `i` reads `sources[i]` when it is there, else `src` (empty: every surface is of
    /// `src`'s field).
    pub sources: &'a [&'a S],
    /// Normals from central differences of the reconstruction one cell of the hit's level apart
    /// on each axis ([`VoxelSource::cell_size`]), which are continuous wherever the level does
    /// not change, instead of the hit voxel's trilinear gradient, which jumps at voxel faces.
    pub smooth_normals: bool,
}

impl<S: VoxelSource + ?Sized> Tracer for HybridTracer<'_, S> {
    fn frame(&self) -> GridFrame {
        self.src.frame()
    }

    fn num_surfaces(&self) -> usize {
        self.surfaces.len()
    }

    fn next_hit(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> Option<SurfaceHit> {
        let h = self.surfaces[i].closest_hit(self.source(i), ray, tmin, tmax)?;
        let mut hit = [Some(self.voxel_surface_hit(h, ray))];
        if self.smooth_normals {
            self.source(i).smooth_gradients(&mut hit);
        }
        hit[0]
    }

    fn next_hits(&self, i: usize, rays: &[GridRay], tmax: &[f64], out: &mut [Option<SurfaceHit>]) {
        let bounds = self.reach(i);
        self.hits_by_packets(i, rays, tmax, out, |_, rays, tmax, hits| {
            if misses_all(bounds, rays, tmax) {
                hits.fill(None);
                return;
            }
            let from_origin = &[0.0; PACKET][..rays.len()];
            self.surfaces[i].closest_hits(self.source(i), rays, from_origin, tmax, hits)
        });
    }

    fn next_hits_from(
        &self,
        i: usize,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
    ) {
        self.hits_by_packets(i, rays, tmax, out, |k, rays, tmax, hits| {
            let tmin = &tmin[k..k + rays.len()];
            self.surfaces[i].closest_hits(self.source(i), rays, tmin, tmax, hits)
        });
    }

    fn next_crossings(
        &self,
        i: usize,
        rays: &[GridRay],
        behind: &[Behind],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
    ) {
        self.hits_by_packets(i, rays, tmax, out, |k, rays, tmax, hits| {
            let behind = &behind[k..k + rays.len()];
            self.surfaces[i].closest_hits_behind(self.source(i), rays, behind, tmax, hits)
        });
    }

    fn occluded(&self, i: usize, ray: &GridRay, tmin: f64, tmax: f64) -> bool {
        self.surfaces[i].any_hit(self.source(i), ray, tmin, tmax)
    }

    fn occluded_many(
        &self,
        i: usize,
        rays: &[GridRay],
        tmin: &[f64],
        tmax: f64,
        active: Mask,
    ) -> Mask {
        self.surfaces[i].any_hits(self.source(i), rays, tmin, tmax, active)
    }

    fn occluded_in_turn(
        &self,
        order: &[usize],
        rays: &[GridRay],
        tmin: &[f64],
        tmax: f64,
        active: Mask,
        answer: &mut dyn FnMut(usize, Mask) -> Mask,
    ) {
        if active == 0 {
            return;
        }
        let mut ready = AnyHitRays::new(&self.src.frame(), rays, tmin, tmax, active);
        let mut live = active;
        for &s in order {
            if live == 0 {
                break;
            }
            live = answer(
                s,
                self.surfaces[s].any_hits_of(self.source(s), &mut ready, live),
            );
        }
    }

    fn release_pages(&self) {
        self.src.release_pages();
        for s in self.sources {
            s.release_pages();
        }
    }
}

impl<S: VoxelSource + ?Sized> HybridTracer<'_, S> {
    /// The voxel source of surface `i`.
    #[inline(always)]
    fn source(&self, i: usize) -> &S {
        self.sources.get(i).copied().unwrap_or(self.src)
    }

    /// The box surface `i`'s hits lie in: its voxels' bounds grown by [`REACH_PADS`] times the
    /// BVH's pad (`None` when it has no voxel).
    fn reach(&self, i: usize) -> Option<([f64; 3], [f64; 3])> {
        let grow = REACH_PADS * bvh_pad(&self.src.frame());
        let (lo, hi) = self.surfaces[i].bvh.voxel_bounds()?;
        Some((lo.map(|x| x - grow), hi.map(|x| x + grow)))
    }

    /// Surface `i`'s hits of `rays` up to `tmax` into `out`, a packet at a time: `query(k, rays,
    /// tmax, hits)` finds the hits of the packet whose first ray is ray `k`.
    #[inline(always)]
    fn hits_by_packets(
        &self,
        i: usize,
        rays: &[GridRay],
        tmax: &[f64],
        out: &mut [Option<SurfaceHit>],
        query: impl Fn(usize, &[GridRay], &[f64], &mut [Option<Hit>]),
    ) {
        let mut hits = [None; PACKET];
        for (((k, rays), tmax), out) in (0..)
            .step_by(PACKET)
            .zip(rays.chunks(PACKET))
            .zip(tmax.chunks(PACKET))
            .zip(out.chunks_mut(PACKET))
        {
            let hits = &mut hits[..rays.len()];
            query(k, rays, tmax, hits);
            for ((out, h), ray) in out.iter_mut().zip(hits.iter()).zip(rays) {
                *out = h.map(|h| self.voxel_surface_hit(h, ray));
            }
            if self.smooth_normals {
                self.source(i).smooth_gradients(out);
            }
        }
    }

    /// The hit the shader sees for `h`, a hit of `ray`, with the hit voxel's own gradient: smooth
    /// normals replace it after ([`VoxelSource::smooth_gradients`]). Inlined into the packets'
    /// loop: a call per hit passed the whole hit and its voxel by value.
    #[inline(always)]
    fn voxel_surface_hit(&self, h: Hit, ray: &GridRay) -> SurfaceHit {
        let pos = h.grid_pos();
        let size = (0..3)
            .map(|a| h.voxel.hi[a] - h.voxel.lo[a])
            .fold(f64::INFINITY, f64::min);
        let grad = h.grid_gradient();
        let rising = dot(grad, ray.d) > 0.0;
        SurfaceHit {
            t: h.t,
            pos,
            grad,
            rising,
            level: h.voxel.level,
            size,
            r: h.r,
        }
    }
}

/// How many BVH pads ([`bvh_pad`]) the box a surface's hits are looked for in is grown by
/// around its voxels' bounds: far more than the rounding of a ray's clip to a voxel, so a ray
/// that misses the grown box meets no voxel, and the walk would find no candidate for it.
const REACH_PADS: f64 = 4.0;

/// True when no ray of `rays` meets `reach` (a surface's [`HybridTracer::reach`]) with `t` in
/// `[0, tmax[k]]`: the surface has no hit for any of them, which a packet of primary rays that
/// passes beside a surface (most of a frame's empty tiles) learns here without its BVH rays
/// and walk.
fn misses_all(reach: Option<([f64; 3], [f64; 3])>, rays: &[GridRay], tmax: &[f64]) -> bool {
    let Some((lo, hi)) = reach else {
        return true;
    };
    rays.iter()
        .zip(tmax)
        .all(|(ray, &tmax)| ray.clip_with(&ray.recip(), lo, hi, 0.0, tmax).is_none())
}

/// The gradient of the reconstruction at `p` by central differences `h[a]` apart on axis `a`
/// (one-sided at the domain's edge); `None` if no neighbour can be sampled on some axis.
pub fn central_difference<S: VoxelSource + ?Sized>(
    src: &S,
    p: [f64; 3],
    h: [f64; 3],
) -> Option<[f64; 3]> {
    central_difference_of(|q| src.sample(q).map(|s| s.0), p, h)
}

/// [`central_difference`] of the field `sample` gives.
pub fn central_difference_of(
    sample: impl FnMut([f64; 3]) -> Option<f32>,
    p: [f64; 3],
    h: [f64; 3],
) -> Option<[f64; 3]> {
    central_difference_given(sample, p, h, [None; 3])
}

/// [`central_difference_of`] taking the components `given` has as they are: only the other
/// axes are sampled.
pub fn central_difference_given(
    mut sample: impl FnMut([f64; 3]) -> Option<f32>,
    p: [f64; 3],
    h: [f64; 3],
    given: [Option<f64>; 3],
) -> Option<[f64; 3]> {
    let mut g = [0.0; 3];
    // The value at `p` itself is needed only for a one-sided difference.
    let mut centre: Option<Option<f64>> = None;
    for a in 0..3 {
        if let Some(x) = given[a] {
            g[a] = x;
            continue;
        }
        let h = h[a];
        let mut at = |d: f64| {
            let mut q = p;
            q[a] += d;
            sample(q).map(f64::from)
        };
        let (f1, f0) = (at(h), at(-h));
        let mut centre_value = || *centre.get_or_insert_with(|| sample(p).map(f64::from));
        g[a] = match (f1, f0) {
            (Some(f1), Some(f0)) => (f1 - f0) / (2.0 * h),
            (Some(f1), None) => (f1 - centre_value()?) / h,
            (None, Some(f0)) => (centre_value()? - f0) / h,
            (None, None) => return None,
        };
    }
    Some(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f64; 3], d: [f64; 3]) -> GridRay {
        GridRay { o, d }
    }

    #[test]
    fn a_packet_misses_all_only_when_every_ray_passes_beside_the_box() {
        let reach = Some(([1.0, 1.0, 1.0], [2.0, 2.0, 2.0]));
        let o = [0.0, 0.0, 0.0];
        let away = [
            ray(o, [-1.0, 0.2, 0.1]),
            ray(o, [1.0, 0.0, 0.0]),
            ray(o, [0.0, 0.0, 1.0]),
        ];
        let inf = [f64::INFINITY; 3];
        assert!(misses_all(reach, &away, &inf));
        // One ray through the box is enough to walk the packet.
        let mut some = away;
        some[1] = ray(o, [1.0, 1.0, 1.2]);
        assert!(!misses_all(reach, &some, &inf));
        // ... unless its search ends before the box.
        assert!(misses_all(
            reach,
            &some,
            &[f64::INFINITY, 0.5, f64::INFINITY]
        ));
        // A ray parallel to an axis, inside and outside that axis's slab.
        let o = [0.0, 1.5, 1.5];
        assert!(!misses_all(reach, &[ray(o, [1.0, 0.0, 0.0])], &inf));
        let o = [0.0, 2.5, 1.5];
        assert!(misses_all(reach, &[ray(o, [1.0, 0.0, 0.0])], &inf));
        // A surface with no voxels is missed by every ray.
        assert!(misses_all(None, &some, &inf));
    }
}
