//! The ambient occlusion at every layer of a tile of rays, its rays traced for the whole tile at
//! once as packets ([`Tracer::occluded_in_turn`]), layer by layer, for
//! [`crate::shade::integrate::shade_hits`] to use ([`Layer::ao`]).

use crate::bvh::packet::{rays_of, Mask, PACKET};
use crate::shade::integrate::{facing, occluder_order, ray_off, world_normal, Lighting};
use crate::shade::layers::{Layer, TileLayers};
use crate::shade::sampling::{cosine_hemisphere, Rng};
use crate::trace::ray::GridRay;
use crate::trace::tracer::Tracer;

/// The ambient occlusion at every layer of up to [`PACKET`] pixels' rays.
///
/// Layer by layer, ray `j` of every pixel's hit goes into packet `j` (at most one ray per pixel
/// in a packet): the rays of a packet leave from neighbouring points of the surface and are
/// short (up to `ao_distance`), so they share the tree's nodes near their origins whatever their
/// directions; the walk splits each packet by direction octant.
#[derive(Default)]
pub struct TileAo {
    /// Ray `j` of pixel `k` at `j * PACKET + k`.
    rays: Vec<GridRay>,
    tmin: Vec<f64>,
    /// Each ray's transmittance so far.
    open: Vec<f64>,
    /// The surfaces in the order they are asked ([`occluder_order`]).
    order: Vec<usize>,
}

impl TileAo {
    /// Traces the ambient-occlusion rays of every layer of up to [`PACKET`] rays (`layers`;
    /// `dirs[k]` is ray `k`'s world direction and `rngs[k]` its pixel's generator, which moves
    /// on layer after layer as shading the layers moves it) and sets their [`Layer::ao`] where
    /// the layer is shaded with it. Each value is the one [`crate::shade::integrate::shade_hits`] computes
    /// for the layer alone: the same rays, each one's surfaces asked in the same order, up to the
    /// same one, the sum in the same order.
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
        let unused = GridRay {
            o: [0.0; 3],
            d: [1.0, 0.0, 0.0],
        };
        self.rays.resize(per_hit * PACKET, unused);
        self.tmin.resize(per_hit * PACKET, 0.0);
        self.open.resize(per_hit * PACKET, 0.0);
        self.order.clear();
        self.order
            .extend(occluder_order(light, tracer.num_surfaces()));
        let frame = tracer.frame();
        let deepest = (0..m).map(|k| layers.of(k).len()).max().unwrap_or(0);
        for l in 0..deepest {
            let mut shaded: Mask = 0;
            for (k, rng) in rngs.iter_mut().enumerate() {
                let Some(&Layer {
                    surface: i, hit, ..
                }) = layers.of(k).get(l)
                else {
                    continue;
                };
                if tracer.paint(i, &hit).is_some_and(|p| !p.lit) {
                    continue;
                }
                shaded |= 1 << k;
                let normal = world_normal(&frame.unit, hit.grad).unwrap_or(dirs[k].map(|x| -x));
                let nf = facing(&hit, normal);
                let mut put = |j: usize, (u1, u2)| {
                    let d = cosine_hemisphere(nf, u1, u2);
                    let (ray, tmin) = ray_off(&frame, &hit, nf, d, 0.0);
                    self.rays[j * PACKET + k] = ray;
                    self.tmin[j * PACKET + k] = tmin;
                    self.open[j * PACKET + k] = 1.0;
                };
                if light.ao_filter {
                    rng.ao_tile_pattern(light.ao_rays)
                        .enumerate()
                        .for_each(|(j, u)| put(j, u));
                } else {
                    rng.ao_pattern(light.ao_rays)
                        .enumerate()
                        .for_each(|(j, u)| put(j, u));
                }
            }
            for j in 0..per_hit {
                let at = j * PACKET;
                let open = &mut self.open[at..at + m];
                let mut live = shaded;
                tracer.occluded_in_turn(
                    &self.order,
                    &self.rays[at..at + m],
                    &self.tmin[at..at + m],
                    light.ao_distance,
                    live,
                    &mut |s, hit| {
                        for k in rays_of(hit) {
                            open[k] *= 1.0 - f64::from(light.opacity[s]);
                            if open[k] == 0.0 {
                                live &= !(1 << k);
                            }
                        }
                        live
                    },
                );
            }
            for k in rays_of(shaded) {
                let mut open = 0.0;
                for j in 0..per_hit {
                    open += self.open[j * PACKET + k];
                }
                layers.of_mut(k)[l].ao = Some(open / f64::from(light.ao_rays));
            }
        }
    }
}
