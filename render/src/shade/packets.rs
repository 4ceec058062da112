//! The first hits of a tile of primary rays, found surface by surface for the whole tile at once
//! ([`Tracer::next_hits`]: packets of rays through the BVH), then shaded ray by ray.

use crate::bvh::packet::PACKET;
use crate::shade::integrate::{search_order, Lighting, SearchHint};
use crate::trace::ray::GridRay;
use crate::trace::tracer::{SurfaceHit, Tracer};

/// Rays of one tile: 8x8 pixels.
pub const TILE_RAYS: usize = PACKET;

/// The first hits of up to [`TILE_RAYS`] rays from their origins with every surface, up to each
/// ray's nearest opaque hit, as [`crate::shade::integrate::shade_ray`] searches them.
pub struct TileHits {
    surfaces: usize,
    /// Ray `k`'s hit with surface `i` at `i * TILE_RAYS + k`: each surface's hits of the tile
    /// together, where the tracer writes them.
    hits: Vec<Option<SurfaceHit>>,
    /// Each ray's nearest opaque hit so far.
    opaque_near: [f64; TILE_RAYS],
}

impl TileHits {
    /// Room for the hits of a tile with `surfaces` surfaces.
    pub fn new(surfaces: usize) -> Self {
        Self {
            surfaces,
            hits: vec![None; surfaces * TILE_RAYS],
            opaque_near: [f64::INFINITY; TILE_RAYS],
        }
    }

    /// Finds the first hits of `rays` (at most [`TILE_RAYS`]) with each surface of `tracer`:
    /// opaque surfaces first, `hint`'s first of all, each searched up to the ray's nearest opaque
    /// hit so far. For each ray, the hits [`crate::shade::integrate::shade_ray`] would find
    /// (the order changes the work, not the hits); `hint` becomes the opaque surface nearest
    /// for most of the rays. Returns whether any ray hit any surface.
    pub fn trace<T: Tracer + ?Sized>(
        &mut self,
        tracer: &T,
        light: &Lighting,
        rays: &[GridRay],
        hint: &mut SearchHint,
    ) -> bool {
        let (n, m) = (self.surfaces, rays.len());
        assert!(m <= TILE_RAYS && tracer.num_surfaces() == n);
        self.opaque_near[..m].fill(f64::INFINITY);
        let mut nearest = [0u32; 64];
        let mut any = false;
        if n == 1 {
            // The tile's hits are the one surface's: found in place.
            let hits = &mut self.hits[..m];
            tracer.next_hits(0, rays, &self.opaque_near[..m], hits);
            let opaque = light.opacity[0] >= 1.0;
            for h in hits.iter().flatten() {
                any = true;
                if opaque && h.t < f64::INFINITY {
                    hint.nearest_opaque = 0;
                }
            }
            return any;
        }
        for i in search_order(light, n, hint.nearest_opaque) {
            let found = &mut self.hits[i * TILE_RAYS..][..m];
            tracer.next_hits(i, rays, &self.opaque_near[..m], found);
            let opaque = light.opacity[i] >= 1.0;
            for (k, h) in found.iter().enumerate() {
                any |= h.is_some();
                if let (true, Some(h)) = (opaque, h) {
                    if h.t < self.opaque_near[k] {
                        self.opaque_near[k] = h.t;
                        if let Some(c) = nearest.get_mut(i) {
                            *c += 1;
                        }
                    }
                }
            }
        }
        let nearest = &nearest[..n.min(64)];
        if let Some((i, _)) = nearest.iter().enumerate().max_by_key(|&(i, &c)| (c, !i)) {
            if nearest[i] > 0 {
                hint.nearest_opaque = i;
            }
        }
        any
    }

    /// Ray `k`'s first hit with surface `i`.
    pub fn hit(&self, k: usize, i: usize) -> &Option<SurfaceHit> {
        &self.hits[i * TILE_RAYS + k]
    }

    /// Ray `k`'s first hit with each surface.
    pub fn hits_of(&self, k: usize) -> impl Iterator<Item = &Option<SurfaceHit>> {
        (0..self.surfaces).map(move |i| self.hit(k, i))
    }

    /// Ray `k`'s first hit with each surface, to shade ([`crate::shade::integrate::shade_hits`]
    /// uses it up).
    pub fn ray_hits(&mut self, k: usize) -> RayHits<'_> {
        RayHits {
            hits: &mut self.hits,
            first: k,
            stride: TILE_RAYS,
            surfaces: self.surfaces,
        }
    }
}

/// One ray's next hit with each surface, wherever they are stored: `surfaces` entries `stride`
/// apart from `first` in `hits`.
pub struct RayHits<'a> {
    hits: &'a mut [Option<SurfaceHit>],
    first: usize,
    stride: usize,
    surfaces: usize,
}

impl<'a> RayHits<'a> {
    /// The hits of a ray held one per surface in `hits`.
    pub fn of(hits: &'a mut [Option<SurfaceHit>]) -> Self {
        let surfaces = hits.len();
        RayHits {
            hits,
            first: 0,
            stride: 1,
            surfaces,
        }
    }

    /// The number of surfaces.
    pub fn len(&self) -> usize {
        self.surfaces
    }

    /// True when there is no surface.
    pub fn is_empty(&self) -> bool {
        self.surfaces == 0
    }

    /// The next hit with surface `i`.
    #[inline(always)]
    pub fn get(&self, i: usize) -> &Option<SurfaceHit> {
        debug_assert!(i < self.surfaces);
        &self.hits[self.first + i * self.stride]
    }

    /// The next hit with surface `i`, to change.
    #[inline(always)]
    pub fn get_mut(&mut self, i: usize) -> &mut Option<SurfaceHit> {
        debug_assert!(i < self.surfaces);
        &mut self.hits[self.first + i * self.stride]
    }
}
