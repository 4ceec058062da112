//! A ray's layers: its crossings of the isosurfaces in depth order, as many as are composited
//! (up to an opaque one, or until little light gets through), found ray by ray or for a tile of
//! rays at once, the continuations behind transparent hits traced as packets.

use crate::bvh::packet::{rays_of, Mask, PACKET};
use crate::shade::integrate::{grid_len, Lighting};
use crate::shade::packets::TileHits;
use crate::trace::ray::GridRay;
use crate::trace::tracer::{SurfaceHit, Tracer};

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
        next: &mut [Option<SurfaceHit>],
        out: &mut Vec<Layer>,
    ) -> Option<(usize, Option<f64>)> {
        if self.taken >= MAX_LAYERS {
            return None;
        }
        let mut nearest: Option<(usize, f64)> = None;
        for (i, h) in next.iter().enumerate() {
            if let Some(h) = h {
                if nearest.is_none_or(|(_, t)| h.t.total_cmp(&t).is_lt()) {
                    nearest = Some((i, h.t));
                }
            }
        }
        let (i, _) = nearest?;
        let hit = next[i].take()?;
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
            next.iter()
                .enumerate()
                .filter(|&(k, h)| k != i && h.is_some() && light.opacity[k] >= 1.0)
                .filter_map(|(_, h)| h.map(|h| h.t))
                .fold(f64::INFINITY, f64::min)
        });
        Some((i, tmax))
    }
}

/// The search for a surface's next crossing behind a hit.
///
/// Where a ray passes through a face, edge or corner shared by two octants, both octants report
/// the crossing (their segments are widened so that none is lost), a hair apart along the ray.
/// Compositing such a duplicate would draw a transparent surface twice along every octant
/// boundary. A real next crossing of a surface leaves it on the other side, so a hit that is
/// close behind and crosses in the same direction is the same crossing, and is skipped.
#[derive(Clone, Copy, Debug)]
struct Behind {
    /// The hit's `t` and crossing direction.
    t: f64,
    rising: bool,
    /// How far behind a hit the search goes on.
    step: f64,
    /// How close behind a crossing in the same direction is the same crossing.
    same_within: f64,
}

impl Behind {
    fn new(ray: &GridRay, hit: &SurfaceHit) -> Self {
        let per_t = grid_len(ray.d);
        Self {
            t: hit.t,
            rising: hit.rising,
            step: 1e-4 * hit.size / per_t,
            same_within: 1e-2 * hit.size / per_t,
        }
    }

    /// Where the search starts.
    fn start(&self) -> f64 {
        self.t + self.step
    }

    /// `None` when `next` is a new crossing; else where the search goes on.
    fn again_after(&self, next: &SurfaceHit) -> Option<f64> {
        let duplicate = next.t - self.t < self.same_within && next.rising == self.rising;
        duplicate.then_some(next.t + self.step)
    }
}

/// The next hit of surface `i` along `ray` after `hit` that is a new crossing, up to `tmax`.
fn next_crossing<T: Tracer + ?Sized>(
    tracer: &T,
    i: usize,
    ray: &GridRay,
    hit: &SurfaceHit,
    tmax: f64,
) -> Option<SurfaceHit> {
    let behind = Behind::new(ray, hit);
    let mut from = behind.start();
    loop {
        let next = tracer.next_hit(i, ray, from, tmax)?;
        match behind.again_after(&next) {
            None => return Some(next),
            Some(t) => from = t,
        }
    }
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
    while let Some((i, tmax)) = search.take(light, next, out) {
        let Some(tmax) = tmax else { break };
        let hit = out.last().expect("a layer was taken").hit;
        next[i] = next_crossing(tracer, i, ray, &hit, tmax);
    }
}

/// The layers of a tile of up to [`PACKET`] rays, found together: the rays take their layers in
/// lockstep, and the continuations behind the layers of one step are traced as one packet per
/// surface ([`Tracer::next_hits_from`], each ray from its own `tmin` up to its own `tmax`). Each
/// ray's layers are the ones [`ray_layers`] finds for it alone: the same queries, each with the
/// same answer.
pub struct TileLayers {
    layers: Vec<Vec<Layer>>,
    /// Per surface, the rays whose next crossing of it is searched.
    pending: Vec<Mask>,
    behind: [Option<Behind>; PACKET],
    from: [f64; PACKET],
    tmax: [f64; PACKET],
    /// One packet's rays, `tmin`, `tmax` and hits, gathered.
    rays: [GridRay; PACKET],
    tmin_of: [f64; PACKET],
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
            from: [0.0; PACKET],
            tmax: [0.0; PACKET],
            rays: [unused; PACKET],
            tmin_of: [0.0; PACKET],
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
        let mut search = [LayerSearch::default(); PACKET];
        for layers in &mut self.layers[..m] {
            layers.clear();
        }
        if light.opacity[..n].iter().all(|&a| a >= 1.0) {
            // Behind an opaque hit nothing is composited: each ray's one layer is its nearest
            // first hit, and no continuation is searched.
            for (k, (search, layers)) in search.iter_mut().zip(&mut self.layers[..m]).enumerate() {
                let _ = search.take(light, hits.ray_hits(k), layers);
            }
            return;
        }
        self.pending.clear();
        self.pending.resize(n, 0);
        let mut live: Mask = if m == PACKET { !0 } else { (1 << m) - 1 };
        while live != 0 {
            for k in rays_of(live) {
                let layers = &mut self.layers[k];
                let Some((i, Some(tmax))) = search[k].take(light, hits.ray_hits(k), layers) else {
                    live &= !(1 << k);
                    continue;
                };
                let behind = Behind::new(&rays[k], &layers.last().expect("a layer was taken").hit);
                self.from[k] = behind.start();
                self.tmax[k] = tmax;
                self.behind[k] = Some(behind);
                self.pending[i] |= 1 << k;
            }
            for i in 0..n {
                self.continue_surface(tracer, i, rays, hits);
            }
        }
    }

    /// Traces the pending continuations of surface `i` as packets until each has a new crossing
    /// or none; writes them into `hits`.
    fn continue_surface<T: Tracer + ?Sized>(
        &mut self,
        tracer: &T,
        i: usize,
        rays: &[GridRay],
        hits: &mut TileHits,
    ) {
        while self.pending[i] != 0 {
            let pending = self.pending[i];
            let mut c = 0;
            for k in rays_of(pending) {
                self.rays[c] = rays[k];
                self.tmin_of[c] = self.from[k];
                self.tmax_of[c] = self.tmax[k];
                c += 1;
            }
            tracer.next_hits_from(
                i,
                &self.rays[..c],
                &self.tmin_of[..c],
                &self.tmax_of[..c],
                &mut self.found[..c],
            );
            for (j, k) in rays_of(pending).enumerate() {
                let behind = self.behind[k].expect("a pending ray has its hit");
                let again = self.found[j].and_then(|next| behind.again_after(&next));
                match again {
                    Some(t) => self.from[k] = t,
                    None => {
                        hits.ray_hits(k)[i] = self.found[j];
                        self.pending[i] &= !(1 << k);
                    }
                }
            }
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
