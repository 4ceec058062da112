//! The ambient occlusion at every layer of a tile of rays, its rays traced for the whole tile at
//! once as packets of one direction octant ([`Tracer::occluded_in_turn`]), for
//! [`crate::shade::integrate::shade_hits`] to use ([`Layer::ao`]).

use crate::bvh::packet::{rays_of, Mask, PACKET};
use crate::shade::integrate::{facing, occluder_order, ray_off, world_normal, Lighting};
use crate::shade::layers::{Layer, TileLayers};
use crate::shade::sampling::{cosine_hemisphere, Rng};
use crate::trace::ray::GridRay;
use crate::trace::tracer::Tracer;

/// The ambient occlusion at every layer of up to [`PACKET`] pixels' rays.
///
/// The rays of all the tile's layers are made first, then traced in packets of up to [`PACKET`]
/// rays of one direction octant: the BVH walk takes a packet's rays octant by octant, each
/// octant from the root, and rays of the same octant from neighbouring points of the surfaces
/// (short rays, up to `ao_distance`) share the tree's nodes. How the rays are grouped changes
/// the work, never a ray's answer.
#[derive(Default)]
pub struct TileAo {
    /// The rays, layer by layer, pixel by pixel, a hit's rays in the order of its pattern.
    rays: Vec<GridRay>,
    tmin: Vec<f64>,
    /// Each ray's transmittance so far.
    open: Vec<f64>,
    /// The hits shaded with ambient occlusion: pixel, layer, and their first ray.
    hits: Vec<(usize, usize, usize)>,
    /// The rays in the order they are traced: octant by octant.
    by_octant: Vec<u32>,
    /// The surfaces in the order they are asked ([`occluder_order`]).
    order: Vec<usize>,
    /// One packet's rays and `tmin`, gathered.
    packet: Vec<GridRay>,
    packet_tmin: Vec<f64>,
}

impl TileAo {
    /// Traces the ambient-occlusion rays of every layer of up to [`PACKET`] rays (`layers`;
    /// `dirs[k]` is ray `k`'s world direction and `rngs[k]` its pixel's generator, which moves
    /// on layer after layer as shading the layers moves it) and sets their [`Layer::ao`] where
    /// the layer is shaded with it. Each value is the one [`crate::shade::integrate::shade_hits`] computes
    /// for the layer alone: the same rays, each one's surfaces asked in the same order, up to the
    /// same one, the sum in the same order.
    // Out of line: inlined into the strip's loop it cost the close-up's frame 3.8 M
    // instructions (callgrind, 512x384), the loop's own code no longer as tight.
    #[inline(never)]
    pub fn trace<T: Tracer + ?Sized>(
        &mut self,
        tracer: &T,
        light: &Lighting,
        dirs: &[[f64; 3]],
        rngs: &mut [Rng],
        layers: &mut TileLayers,
    ) {
        let m = dirs.len();
        assert!(m <= PACKET && rngs.len() == m);
        let per_hit = light.ao_rays as usize;
        if per_hit == 0 {
            return;
        }
        self.rays.clear();
        self.tmin.clear();
        self.hits.clear();
        self.order.clear();
        self.order
            .extend(occluder_order(light, tracer.num_surfaces()));
        let frame = tracer.frame();
        let deepest = (0..m).map(|k| layers.of(k).len()).max().unwrap_or(0);
        for l in 0..deepest {
            for (k, rng) in rngs.iter_mut().enumerate() {
                let Some(&Layer {
                    surface: i, hit, ..
                }) = layers.of(k).get(l)
                else {
                    continue;
                };
                if tracer.unlit(i) {
                    continue;
                }
                self.hits.push((k, l, self.rays.len()));
                let normal = world_normal(&frame.unit, hit.grad).unwrap_or(dirs[k].map(|x| -x));
                let nf = facing(&hit, normal);
                let mut put = |(u1, u2)| {
                    let d = cosine_hemisphere(nf, u1, u2);
                    let (ray, tmin) = ray_off(&frame, &hit, nf, d, 0.0);
                    self.rays.push(ray);
                    self.tmin.push(tmin);
                };
                if light.ao_filter {
                    rng.ao_tile_pattern(light.ao_rays).for_each(&mut put);
                } else {
                    rng.ao_pattern(light.ao_rays).for_each(&mut put);
                }
            }
        }
        self.open.clear();
        self.open.resize(self.rays.len(), 1.0);
        self.sort_by_octant();
        for chunk in self.by_octant.chunks(PACKET) {
            self.packet.clear();
            self.packet_tmin.clear();
            for &r in chunk {
                self.packet.push(self.rays[r as usize]);
                self.packet_tmin.push(self.tmin[r as usize]);
            }
            let open = &mut self.open;
            let mut live: Mask = if chunk.len() == PACKET {
                !0
            } else {
                (1 << chunk.len()) - 1
            };
            tracer.occluded_in_turn(
                &self.order,
                &self.packet,
                &self.packet_tmin,
                light.ao_distance,
                live,
                &mut |s, hit| {
                    for c in rays_of(hit) {
                        let t = &mut open[chunk[c] as usize];
                        *t *= 1.0 - f64::from(light.opacity[s]);
                        if *t == 0.0 {
                            live &= !(1 << c);
                        }
                    }
                    live
                },
            );
        }
        for &(k, l, first) in &self.hits {
            let mut open = 0.0;
            for t in &self.open[first..first + per_hit] {
                open += t;
            }
            layers.of_mut(k)[l].ao = Some(open / f64::from(light.ao_rays));
        }
    }

    /// Fills [`TileAo::by_octant`] with the rays' indices, grouped by their direction's octant
    /// (in their order within each).
    fn sort_by_octant(&mut self) {
        let octant = |r: &GridRay| {
            usize::from(r.d[0] < 0.0)
                | usize::from(r.d[1] < 0.0) << 1
                | usize::from(r.d[2] < 0.0) << 2
        };
        let mut start = [0usize; 9];
        for r in &self.rays {
            start[octant(r) + 1] += 1;
        }
        for o in 0..8 {
            start[o + 1] += start[o];
        }
        self.by_octant.clear();
        self.by_octant.resize(self.rays.len(), 0);
        for (i, r) in self.rays.iter().enumerate() {
            let o = octant(r);
            self.by_octant[start[o]] = i as u32;
            start[o] += 1;
        }
    }
}
