//! A ray's layers: its crossings of the isosurfaces in depth order, as many as are composited
//! (up to an opaque one, or until little light gets through), found ray by ray or for a tile of
//! rays at once, the continuations behind transparent hits traced as packets.

use crate::bvh::packet::{rays_of, Mask, PACKET};
use crate::shade::integrate::{grid_len, Lighting};
use crate::shade::packets::{RayHits, TileHits};
use crate::trace::ray::GridRay;
use crate::trace::tracer::{Behind, SurfaceHit, Tracer};

/// Most surfaces composited along one ray.
pub const MAX_LAYERS: usize = 32;
/// Stop compositing once less than this much light gets through.
pub const MIN_TRANSMITTANCE: f32 = 1e-3;

/// One layer of a ray: its hit with a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layer {
    /// The surface hit.
    pub surface: usize,
    /// The hit.
    pub hit: SurfaceHit,
    /// The key light's transmittance at the hit, when already traced
    /// ([`crate::shade::integrate::KeyShadow`]); `None` leaves the shadow ray to the shading.
    pub shadow: Option<f64>,
    /// The ambient occlusion at the hit, when already traced
    /// ([`crate::shade::ao_packets::TileAo`], which moved the pixel's generator on as tracing it
    /// in the shading would); `None` leaves the AO rays to the shading.
    pub ao: Option<f64>,
}

/// Where a ray is in the search for its layers: the light that gets through the layers taken so
/// far, and their number.
#[derive(Clone, Copy, Debug)]
struct LayerSearch {
    transmittance: f32,
    taken: usize,
}

impl Default for LayerSearch {
    fn default() -> Self {
        Self {
            transmittance: 1.0,
            taken: 0,
        }
    }
}

impl LayerSearch {
    /// Moves the nearest of `next` (each surface's next hit; the first of a tie) to `out` as the
    /// ray's next layer. Returns its surface and, when the ray goes on behind it, the `tmax` of
    /// the search for that surface's next crossing: the nearest pending opaque hit of the other
    /// surfaces. `None` when there is no hit left or the ray has all its layers.
    #[inline(always)]
    fn take(
        &mut self,
        light: &Lighting,
        next: &mut RayHits<'_>,
        out: &mut Vec<Layer>,
    ) -> Option<(usize, Option<f64>)> {
        if self.taken >= MAX_LAYERS {
            return None;
        }
        let mut nearest: Option<(usize, f64)> = None;
        for i in 0..next.len() {
            if let Some(h) = next.get(i) {
                if nearest.is_none_or(|(_, t)| h.t.total_cmp(&t).is_lt()) {
                    nearest = Some((i, h.t));
                }
            }
        }
        let (i, _) = nearest?;
        let hit = next.get_mut(i).take()?;
        out.push(Layer {
            surface: i,
            hit,
            shadow: None,
            ao: None,
        });
        self.taken += 1;
        self.transmittance *= 1.0 - light.opacity[i];
        let goes_on = self.transmittance >= MIN_TRANSMITTANCE && self.taken < MAX_LAYERS;
        // A crossing behind a pending opaque hit of another surface is never composited: the
        // search for this surface's next one stops there.
        let tmax = goes_on.then(|| {
            (0..next.len())
                .filter(|&k| k != i && next.get(k).is_some() && light.opacity[k] >= 1.0)
                .filter_map(|k| next.get(k).map(|h| h.t))
                .fold(f64::INFINITY, f64::min)
        });
        Some((i, tmax))
    }
}

/// The crossing `hit` of `ray`, to search behind: a hundredth of its voxel's size counts as the
/// same crossing, and the search starts a ten-thousandth of it behind.
fn behind(ray: &GridRay, hit: &SurfaceHit) -> Behind {
    let per_t = grid_len(ray.d);
    Behind {
        t: hit.t,
        rising: hit.rising,
        step: 1e-4 * hit.size / per_t,
        same_within: 1e-2 * hit.size / per_t,
    }
}

/// The next hit of surface `i` along `ray` after `hit` that is a new crossing, up to `tmax`: the
/// tracer's [`Tracer::next_crossings`] for the ray alone.
fn next_crossing<T: Tracer + ?Sized>(
    tracer: &T,
    i: usize,
    ray: &GridRay,
    hit: &SurfaceHit,
    tmax: f64,
) -> Option<SurfaceHit> {
    let mut next = [None];
    tracer.next_crossings(
        i,
        std::slice::from_ref(ray),
        &[behind(ray, hit)],
        &[tmax],
        &mut next,
    );
    next[0]
}

/// Appends the layers of `ray` to `out`, from `next`, its first hit with each surface (up to the
/// nearest opaque one); `next` is used up. Continuations are traced ray by ray.
pub fn ray_layers<T: Tracer + ?Sized>(
    tracer: &T,
    light: &Lighting,
    ray: &GridRay,
    next: &mut [Option<SurfaceHit>],
    out: &mut Vec<Layer>,
) {
    let mut search = LayerSearch::default();
    let mut next = RayHits::of(next);
    while let Some((i, tmax)) = search.take(light, &mut next, out) {
        let Some(tmax) = tmax else { break };
        let hit = out.last().expect("a layer was taken").hit;
        *next.get_mut(i) = next_crossing(tracer, i, ray, &hit, tmax);
    }
}

/// The layers of a tile of up to [`PACKET`] rays, found together: the rays take their layers in
/// lockstep, and the continuations behind the layers of one step are traced as one packet per
/// surface ([`Tracer::next_crossings`], each ray behind its own crossing up to its own `tmax`).
/// Each ray's layers are the ones [`ray_layers`] finds for it alone: the same crossings (a tracer
/// may skip a crossing seen again inside one query, where `ray_layers` asks again).
pub struct TileLayers {
    layers: Vec<Vec<Layer>>,
    /// Per surface, the rays whose next crossing of it is searched.
    pending: Vec<Mask>,
    behind: [Option<Behind>; PACKET],
    tmax: [f64; PACKET],
    /// One packet's rays, `tmin`, `tmax` and hits, gathered.
    rays: [GridRay; PACKET],
    behind_of: [Behind; PACKET],
    tmax_of: [f64; PACKET],
    found: [Option<SurfaceHit>; PACKET],
}

impl Default for TileLayers {
    fn default() -> Self {
        let unused = GridRay {
            o: [0.0; 3],
            d: [1.0, 0.0, 0.0],
        };
        Self {
            layers: (0..PACKET).map(|_| Vec::new()).collect(),
            pending: Vec::new(),
            behind: [None; PACKET],
            tmax: [0.0; PACKET],
            rays: [unused; PACKET],
            behind_of: [Behind {
                t: 0.0,
                rising: false,
                step: 0.0,
                same_within: 0.0,
            }; PACKET],
            tmax_of: [0.0; PACKET],
            found: [None; PACKET],
        }
    }
}

impl TileLayers {
    /// Finds the layers of `rays` (at most [`PACKET`]) from their first hits in `hits` (which are
    /// used up).
    pub fn trace<T: Tracer + ?Sized>(
        &mut self,
        tracer: &T,
        light: &Lighting,
        rays: &[GridRay],
        hits: &mut TileHits,
    ) {
        let m = rays.len();
        assert!(m <= PACKET);
        let n = tracer.num_surfaces();
        for layers in &mut self.layers[..m] {
            layers.clear();
        }
        if n == 1 && light.opacity[0] >= 1.0 {
            // One opaque surface: each ray's one layer is its hit, if any (what
            // `LayerSearch::take` gives, without its search over surfaces).
            for (k, layers) in self.layers[..m].iter_mut().enumerate() {
                if let Some(hit) = hits.ray_hits(k).get_mut(0).take() {
                    layers.push(Layer {
                        surface: 0,
                        hit,
                        shadow: None,
                        ao: None,
                    });
                }
            }
            return;
        }
        let mut search = [LayerSearch::default(); PACKET];
        if light.opacity[..n].iter().all(|&a| a >= 1.0) {
            // Behind an opaque hit nothing is composited: each ray's one layer is its nearest
            // first hit, and no continuation is searched.
            for (k, (search, layers)) in search.iter_mut().zip(&mut self.layers[..m]).enumerate() {
                let _ = search.take(light, &mut hits.ray_hits(k), layers);
            }
            return;
        }
        self.pending.clear();
        self.pending.resize(n, 0);
        let mut live: Mask = if m == PACKET { !0 } else { (1 << m) - 1 };
        while live != 0 {
            for k in rays_of(live) {
                let layers = &mut self.layers[k];
                let Some((i, Some(tmax))) = search[k].take(light, &mut hits.ray_hits(k), layers)
                else {
                    live &= !(1 << k);
                    continue;
                };
                let behind = behind(&rays[k], &layers.last().expect("a layer was taken").hit);
                self.tmax[k] = tmax;
                self.behind[k] = Some(behind);
                self.pending[i] |= 1 << k;
            }
            for i in 0..n {
                self.continue_surface(tracer, i, rays, hits);
            }
        }
    }

    /// Traces the pending continuations of surface `i` as one packet; writes their new
    /// crossings into `hits`.
    fn continue_surface<T: Tracer + ?Sized>(
        &mut self,
        tracer: &T,
        i: usize,
        rays: &[GridRay],
        hits: &mut TileHits,
    ) {
        let pending = std::mem::take(&mut self.pending[i]);
        if pending == 0 {
            return;
        }
        let mut c = 0;
        for k in rays_of(pending) {
            self.rays[c] = rays[k];
            self.behind_of[c] = self.behind[k].expect("a pending ray has its hit");
            self.tmax_of[c] = self.tmax[k];
            c += 1;
        }
        tracer.next_crossings(
            i,
            &self.rays[..c],
            &self.behind_of[..c],
            &self.tmax_of[..c],
            &mut self.found[..c],
        );
        for (j, k) in rays_of(pending).enumerate() {
            *hits.ray_hits(k).get_mut(i) = self.found[j];
        }
    }

    /// Ray `k`'s layers, nearest first.
    pub fn of(&self, k: usize) -> &[Layer] {
        &self.layers[k]
    }

    /// Ray `k`'s layers, to fill in their shadows.
    pub fn of_mut(&mut self, k: usize) -> &mut [Layer] {
        &mut self.layers[k]
    }
}
