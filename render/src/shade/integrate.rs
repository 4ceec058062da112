//! One primary ray: its hits with every isosurface in depth order, each shaded and composited.

use crate::bvh::packet::{rays_of, Mask, PACKET};
use crate::camera::{dot, normalize, Camera};
use crate::output::frame::PixelSample;
use crate::shade::ao_filter::{AoLayer, FILTERED_HITS};
use crate::shade::layers::{ray_layers, Layer, TileLayers};
use crate::shade::sampling::{cosine_hemisphere, Rng};
use crate::trace::ray::GridRay;
use crate::trace::source::GridFrame;
use crate::trace::tracer::{SurfaceHit, Tracer};

/// Light and material settings for a frame.
#[derive(Clone, Debug)]
pub struct Lighting {
    /// Colour per surface (linear RGB).
    pub colors: Vec<[f32; 3]>,
    /// Opacity per surface.
    pub opacity: Vec<f32>,
    /// Unit direction towards the key light, world coordinates.
    pub key_dir: [f64; 3],
    /// Cast shadow rays towards the key light.
    pub shadows: bool,
    /// Ambient-occlusion rays per hit (0 disables).
    pub ao_rays: u32,
    /// Length of ambient-occlusion rays, world units.
    pub ao_distance: f64,
    /// Filter the ambient occlusion across pixels ([`crate::shade::ao_filter`]); its rays then
    /// follow the pattern spread over tiles of pixels.
    pub ao_filter: bool,
}

impl Lighting {
    /// Default lighting for `camera`: the key light comes from above the camera's left shoulder.
    pub fn for_camera(
        camera: &Camera,
        colors: Vec<[f32; 3]>,
        opacity: Vec<f32>,
        ao_distance: f64,
    ) -> Lighting {
        let f = camera.forward();
        let (r, u) = camera.basis();
        let key = [0, 1, 2].map(|a| -0.55 * f[a] - 0.45 * r[a] + 0.7 * u[a]);
        Lighting {
            colors,
            opacity,
            key_dir: normalize(key).unwrap_or(u),
            shadows: true,
            ao_rays: 0,
            ao_distance,
            ao_filter: false,
        }
    }
}

/// Surfaces whose next hits [`shade_ray`] keeps on the stack.
const INLINE_SURFACES: usize = 4;

/// Where [`shade_ray`] looks first: the opaque surface nearest along the previous ray (a hint
/// carried from pixel to pixel; it changes the work, never the result).
#[derive(Clone, Copy, Debug, Default)]
pub struct SearchHint {
    pub(crate) nearest_opaque: usize,
}

/// Shades the world ray `origin + t dir` (`dir` unit length). With `ao_layers`, records the
/// first [`FILTERED_HITS`] hits shaded with ambient occlusion there.
pub fn shade_ray<T: Tracer + ?Sized>(
    tracer: &T,
    light: &Lighting,
    (origin, dir): ([f64; 3], [f64; 3]),
    rng: &mut Rng,
    hint: &mut SearchHint,
    ao_layers: Option<&mut Vec<AoLayer>>,
) -> PixelSample {
    let frame = tracer.frame();
    let ray = GridRay::from_world(&frame, origin, dir);
    let n = tracer.num_surfaces();
    // Each surface's next hit: on the stack for the usual few surfaces (no allocation per ray).
    let mut inline = [None; INLINE_SURFACES];
    let mut spilled = Vec::new();
    let next: &mut [Option<SurfaceHit>] = if n <= INLINE_SURFACES {
        &mut inline[..n]
    } else {
        spilled.resize(n, None);
        &mut spilled
    };
    let mut opaque_near = f64::INFINITY;
    for i in search_order(light, n, hint.nearest_opaque) {
        next[i] = tracer.next_hit(i, &ray, 0.0, opaque_near);
        if let (true, Some(h)) = (light.opacity[i] >= 1.0, next[i]) {
            if h.t < opaque_near {
                opaque_near = h.t;
                hint.nearest_opaque = i;
            }
        }
    }
    let mut layers = Vec::new();
    ray_layers(tracer, light, &ray, next, &mut layers);
    shade_hits(
        tracer,
        &frame,
        light,
        (origin, dir),
        &layers,
        rng,
        ao_layers,
    )
}

/// The order in which a ray's first hits with the `n` surfaces are searched: opaque surfaces
/// first, `first` (the one nearest in the previous pixel) first of all. A first crossing behind
/// the nearest opaque hit is never composited, so the other surfaces' searches stop there; the
/// order changes the work, not the hits found.
pub fn search_order(light: &Lighting, n: usize, first: usize) -> impl Iterator<Item = usize> + '_ {
    let opaque = move |i: usize| light.opacity[i] >= 1.0;
    (first < n && opaque(first))
        .then_some(first)
        .into_iter()
        .chain((0..n).filter(move |&i| i != first && opaque(i)))
        .chain((0..n).filter(move |&i| !opaque(i)))
}

/// Shades the world ray along `dir` (unit length) from its `layers` ([`crate::shade::layers`])
/// seen by a camera at `eye`, which the positions recorded for the ambient-occlusion filter are
/// taken from; `frame` is the tracer's. The key light's shadow ray and the ambient-occlusion
/// rays are traced here at the layers whose transmittance or occlusion is not given
/// ([`Layer::shadow`], [`Layer::ao`]). With `ao_layers`, records the first [`FILTERED_HITS`]
/// hits shaded with ambient occlusion there.
#[inline(always)]
pub fn shade_hits<T: Tracer + ?Sized>(
    tracer: &T,
    frame: &GridFrame,
    light: &Lighting,
    (eye, dir): ([f64; 3], [f64; 3]),
    layers: &[Layer],
    rng: &mut Rng,
    mut ao_layers: Option<&mut Vec<AoLayer>>,
) -> PixelSample {
    let mut c = Composite::EMPTY;
    for (layer, l) in layers.iter().enumerate() {
        let hit = (l.surface, &l.hit, (l.shadow, l.ao));
        let ao = ao_layers.as_deref_mut();
        c.add(tracer, frame, light, (eye, dir), hit, rng, ao, layer == 0);
    }
    c.finish()
}

/// Shades the world ray along `dir` (unit length), seen by a camera at `eye`, whose one layer
/// is `hit`, a hit of the opaque surface `i`, its shadow and AO rays (if any) traced here: what
/// [`shade_hits`] gives for that layer, without building it.
#[inline(always)]
pub fn shade_hit_alone<T: Tracer + ?Sized>(
    tracer: &T,
    frame: &GridFrame,
    light: &Lighting,
    (eye, dir): ([f64; 3], [f64; 3]),
    (i, hit): (usize, &SurfaceHit),
    rng: &mut Rng,
) -> PixelSample {
    let mut c = Composite::EMPTY;
    let hit = (i, hit, (None, None));
    c.add(tracer, frame, light, (eye, dir), hit, rng, None, true);
    c.finish()
}

/// A pixel's layers composited front to back so far.
struct Composite {
    /// The pixel, its colour and alpha set by [`Composite::finish`].
    out: PixelSample,
    /// Colour so far (premultiplied).
    rgb: [f32; 3],
    /// Light that gets through the layers so far.
    transmittance: f32,
    /// Layers recorded for the ambient-occlusion filter.
    recorded: usize,
}

impl Composite {
    /// No layer yet.
    const EMPTY: Composite = Composite {
        out: PixelSample::MISS,
        rgb: [0.0; 3],
        transmittance: 1.0,
        recorded: 0,
    };

    /// Adds the layer behind the others: `hit` of surface `i` with the shadow and AO `given`
    /// ([`Layer::shadow`], [`Layer::ao`]), seen along `dir` by a camera at `eye` (what the
    /// position recorded for the AO filter is taken from); the `first` layer also sets the
    /// pixel's depth, normal, position and level.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn add<T: Tracer + ?Sized>(
        &mut self,
        tracer: &T,
        frame: &GridFrame,
        light: &Lighting,
        (eye, dir): ([f64; 3], [f64; 3]),
        (i, hit, given): (usize, &SurfaceHit, (Option<f64>, Option<f64>)),
        rng: &mut Rng,
        ao_layers: Option<&mut Vec<AoLayer>>,
        first: bool,
    ) {
        let transmittance = self.transmittance;
        let normal = world_normal(&frame.unit, hit.grad).unwrap_or(dir.map(|x| -x));
        let paint = tracer.paint(i, hit);
        let alpha = light.opacity[i];
        let colour = match paint {
            Some(p) if tracer.unlit(i) => p.rgb,
            _ => {
                let base = paint.map_or(light.colors[i], |p| p.rgb);
                let shaded = shade_hit(tracer, frame, light, base, hit, normal, dir, given, rng);
                if let (Some(layers), Some(ao)) = (ao_layers, shaded.ao) {
                    if self.recorded < FILTERED_HITS {
                        self.recorded += 1;
                        let p = frame.to_world(hit.pos);
                        layers.push(AoLayer {
                            surface: i as u32,
                            p: [0, 1, 2].map(|a| (p[a] - eye[a]) as f32),
                            n: shaded.facing.map(|x| x as f32),
                            ao: ao.value as f32,
                            weight: ao.weight.map(|w| transmittance * alpha * w),
                        });
                    }
                }
                shaded.rgb
            }
        };
        if let (Some(p), true) = (paint, self.out.color_value.is_nan()) {
            self.out.color_value = p.value;
        }
        for c in 0..3 {
            self.rgb[c] += transmittance * alpha * colour[c];
        }
        if first {
            let p = frame.to_world(hit.pos);
            self.out.z = hit.t as f32;
            self.out.n = normal.map(|x| x as f32);
            self.out.p = [0, 1, 2].map(|a| (p[a] - frame.origin[a]) as f32);
            self.out.level = hit.level as f32;
        }
        self.transmittance *= 1.0 - alpha;
    }

    /// The pixel.
    fn finish(mut self) -> PixelSample {
        self.out.rgb = self.rgb;
        self.out.alpha = 1.0 - self.transmittance;
        self.out
    }
}

/// The unit world-space normal for a grid-space gradient.
pub(crate) fn world_normal(unit: &[f64; 3], grad: [f64; 3]) -> Option<[f64; 3]> {
    normalize([0, 1, 2].map(|a| grad[a] / unit[a]))
}

/// The length of a grid-space direction, never zero.
pub(crate) fn grid_len(d: [f64; 3]) -> f64 {
    dot(d, d).sqrt().max(f64::MIN_POSITIVE)
}

/// A shaded hit.
struct Shaded {
    /// Its colour.
    rgb: [f32; 3],
    /// The unit normal on the viewer's side.
    facing: [f64; 3],
    /// Its ambient occlusion, when traced.
    ao: Option<Occlusion>,
}

/// The ambient occlusion a hit was shaded with.
struct Occlusion {
    /// Fraction of the ambient light that reaches the hit.
    value: f64,
    /// Change of the hit's colour per unit of `value` (the colour is linear in it).
    weight: [f32; 3],
}

/// How far a shadow ray starts off the surface, in voxel sizes, where the key light grazes it
/// (scaled by one minus the cosine): the interpolated surface of coarse cells is faceted under
/// its smooth normals, and without the lift the facets shadow their own neighbours where the
/// smooth shading still says lit, a staircase along the voxels at the shadow terminator.
const TERMINATOR_LIFT: f64 = 0.25;

/// The normal on the side the ray came from, which the crossing's direction tells; not the one
/// facing the viewer, which at a silhouette can be the inside when the smooth normal leans past
/// the ray, and would send the shadow and AO rays into the surface (black pixels).
pub(crate) fn facing(hit: &SurfaceHit, normal: [f64; 3]) -> [f64; 3] {
    if hit.rising {
        normal.map(|x| -x)
    } else {
        normal
    }
}

/// The shadow ray towards the key light from `hit` (facing normal `nf`), when one is cast: the
/// ray and its `tmin`.
fn key_ray(
    frame: &GridFrame,
    light: &Lighting,
    hit: &SurfaceHit,
    nf: [f64; 3],
) -> Option<(GridRay, f64)> {
    let key = dot(nf, light.key_dir).max(0.0);
    (key > 0.0 && light.shadows).then(|| {
        let lift = TERMINATOR_LIFT * (1.0 - key) * hit.size;
        ray_off(frame, hit, nf, light.key_dir, lift)
    })
}

/// The colour of a surface of colour `base` at `hit`, seen along `dir`; `shadow` is the key
/// light's transmittance there and `ao` its ambient occlusion, when already traced.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn shade_hit<T: Tracer + ?Sized>(
    tracer: &T,
    frame: &GridFrame,
    light: &Lighting,
    base: [f32; 3],
    hit: &SurfaceHit,
    normal: [f64; 3],
    dir: [f64; 3],
    (shadow, ao): (Option<f64>, Option<f64>),
    rng: &mut Rng,
) -> Shaded {
    let view = dir.map(|x| -x);
    let nf = facing(hit, normal);
    let head = dot(nf, view).max(0.0);
    let spec = head.powi(48);
    let mut key = dot(nf, light.key_dir).max(0.0);
    if let Some(s) = shadow {
        key *= s;
    } else if key > 0.0 && light.shadows {
        key *= key_transmittance(tracer, frame, light, hit, nf);
    }
    let ao = (light.ao_rays > 0)
        .then(|| ao.unwrap_or_else(|| occlusion(tracer, frame, light, hit, nf, rng)));
    let a = ao.unwrap_or(1.0);
    let diffuse = 0.22 * a + 0.55 * key + 0.35 * head * (0.5 + 0.5 * a);
    Shaded {
        rgb: base.map(|c| (f64::from(c) * diffuse + 0.25 * spec) as f32),
        facing: nf,
        ao: ao.map(|value| Occlusion {
            value,
            weight: base.map(|c| (f64::from(c) * (0.22 + 0.175 * head)) as f32),
        }),
    }
}

/// The key light's transmittance at `hit` (facing normal `nf`, lit by the key light), its
/// shadow ray traced here: out of line, as the frame's shadow rays are mostly traced as packets
/// ([`KeyShadow`]).
#[inline(never)]
fn key_transmittance<T: Tracer + ?Sized>(
    tracer: &T,
    frame: &GridFrame,
    light: &Lighting,
    hit: &SurfaceHit,
    nf: [f64; 3],
) -> f64 {
    match key_ray(frame, light, hit, nf) {
        Some((ray, tmin)) => transmittance_along(tracer, light, &ray, tmin, f64::INFINITY),
        None => 1.0,
    }
}

/// The ambient occlusion at `hit` (facing normal `nf`), its rays traced here from the pattern
/// `rng` gives: out of line, as the frame's ambient-occlusion rays are mostly traced as packets
/// ([`crate::shade::ao_packets::TileAo`]).
#[inline(never)]
fn occlusion<T: Tracer + ?Sized>(
    tracer: &T,
    frame: &GridFrame,
    light: &Lighting,
    hit: &SurfaceHit,
    nf: [f64; 3],
    rng: &mut Rng,
) -> f64 {
    let mut open = 0.0;
    let mut trace = |(u1, u2)| {
        let d = cosine_hemisphere(nf, u1, u2);
        open += transmittance_towards(tracer, frame, light, hit, nf, d, light.ao_distance, 0.0);
    };
    if light.ao_filter {
        rng.ao_tile_pattern(light.ao_rays).for_each(&mut trace);
    } else {
        rng.ao_pattern(light.ao_rays).for_each(&mut trace);
    }
    open / f64::from(light.ao_rays)
}

/// Fraction of light reaching `hit` from direction `d` (world, unit) within `max_t`: the
/// product of `1 - opacity` over the surfaces in the way, seen from `lift` grid units (besides
/// a small fixed offset) off the surface along the normal `nf`.
#[allow(clippy::too_many_arguments)]
fn transmittance_towards<T: Tracer + ?Sized>(
    tracer: &T,
    frame: &GridFrame,
    light: &Lighting,
    hit: &SurfaceHit,
    nf: [f64; 3],
    d: [f64; 3],
    max_t: f64,
    lift: f64,
) -> f64 {
    let (ray, tmin) = ray_off(frame, hit, nf, d, lift);
    transmittance_along(tracer, light, &ray, tmin, max_t)
}

/// The grid ray in world direction `d` (unit) from `lift` grid units (besides a small fixed
/// offset) off `hit` along the normal `nf`, and the `tmin` its search starts from.
pub(crate) fn ray_off(
    frame: &GridFrame,
    hit: &SurfaceHit,
    nf: [f64; 3],
    d: [f64; 3],
    lift: f64,
) -> (GridRay, f64) {
    let offset = 1e-3 * hit.size + lift;
    let n_grid = frame.to_grid_dir(nf);
    let n_len = grid_len(n_grid);
    let o = [0, 1, 2].map(|a| hit.pos[a] + n_grid[a] / n_len * offset);
    let ray = GridRay {
        o,
        d: frame.to_grid_dir(d),
    };
    let tmin = 1e-3 * hit.size / grid_len(ray.d);
    (ray, tmin)
}

/// The surfaces in the order a transmittance is searched: opaque surfaces first, as one in the
/// way ends the search. The transparent surfaces' factors are multiplied in the same order
/// either way, so the result does not change.
pub(crate) fn occluder_order(light: &Lighting, n: usize) -> impl Iterator<Item = usize> + '_ {
    let opaque = move |s: usize| light.opacity[s] >= 1.0;
    (0..n)
        .filter(move |&s| opaque(s))
        .chain((0..n).filter(move |&s| !opaque(s)))
}

/// Fraction of light reaching along `ray` with `t` in `[tmin, max_t]`: the product of
/// `1 - opacity` over the surfaces in the way.
fn transmittance_along<T: Tracer + ?Sized>(
    tracer: &T,
    light: &Lighting,
    ray: &GridRay,
    tmin: f64,
    max_t: f64,
) -> f64 {
    let mut t = 1.0;
    for s in occluder_order(light, tracer.num_surfaces()) {
        if tracer.occluded(s, ray, tmin, max_t) {
            t *= 1.0 - f64::from(light.opacity[s]);
            if t == 0.0 {
                break;
            }
        }
    }
    t
}

/// The key light's transmittance at every layer of a tile of rays, traced for the tile at once
/// as packets of up to [`PACKET`] shadow rays ([`Tracer::occluded_in_turn`]), for [`shade_hits`]
/// to use ([`Layer::shadow`]). The shadow rays are all parallel, so any of them make a packet;
/// they are taken layer by layer, each layer's rays in the tile's order.
pub struct KeyShadow {
    rays: [GridRay; PACKET],
    tmin: [f64; PACKET],
    /// Per ray of the packet, its transmittance so far, and its ray and layer in the tile.
    shadow: [f64; PACKET],
    at: [(usize, usize); PACKET],
    /// The surfaces in the order they are asked ([`occluder_order`]).
    order: Vec<usize>,
}

impl Default for KeyShadow {
    fn default() -> Self {
        Self {
            rays: [GridRay {
                o: [0.0; 3],
                d: [1.0, 0.0, 0.0],
            }; PACKET],
            tmin: [0.0; PACKET],
            shadow: [0.0; PACKET],
            at: [(0, 0); PACKET],
            order: Vec::new(),
        }
    }
}

impl KeyShadow {
    /// Traces the shadow rays of the layers of up to [`PACKET`] rays (`layers`; `dirs[k]` is
    /// ray `k`'s world direction) and sets [`Layer::shadow`] where one is cast. Each value is the
    /// one [`shade_hits`] computes for its layer alone: the same shadow ray, the surfaces asked
    /// in the same order, up to the same one.
    pub fn trace<T: Tracer + ?Sized>(
        &mut self,
        tracer: &T,
        light: &Lighting,
        dirs: &[[f64; 3]],
        layers: &mut TileLayers,
    ) {
        let m = dirs.len();
        assert!(m <= PACKET);
        if !light.shadows {
            return;
        }
        self.order.clear();
        self.order
            .extend(occluder_order(light, tracer.num_surfaces()));
        let frame = tracer.frame();
        let mut c = 0;
        let deepest = (0..m).map(|k| layers.of(k).len()).max().unwrap_or(0);
        for l in 0..deepest {
            for (k, dir) in dirs.iter().enumerate() {
                let Some(layer) = layers.of(k).get(l) else {
                    continue;
                };
                let hit = layer.hit;
                if tracer.unlit(layer.surface) {
                    continue;
                }
                let normal = world_normal(&frame.unit, hit.grad).unwrap_or(dir.map(|x| -x));
                if let Some((ray, tmin)) = key_ray(&frame, light, &hit, facing(&hit, normal)) {
                    self.rays[c] = ray;
                    self.tmin[c] = tmin;
                    self.at[c] = (k, l);
                    c += 1;
                    if c == PACKET {
                        self.trace_packet(tracer, light, c, layers);
                        c = 0;
                    }
                }
            }
        }
        self.trace_packet(tracer, light, c, layers);
    }

    /// Traces the first `c` shadow rays gathered and writes their transmittances.
    fn trace_packet<T: Tracer + ?Sized>(
        &mut self,
        tracer: &T,
        light: &Lighting,
        c: usize,
        layers: &mut TileLayers,
    ) {
        if c == 0 {
            return;
        }
        let mut live: Mask = if c == PACKET { !0 } else { (1 << c) - 1 };
        self.shadow[..c].fill(1.0);
        let shadow = &mut self.shadow;
        tracer.occluded_in_turn(
            &self.order,
            &self.rays[..c],
            &self.tmin[..c],
            f64::INFINITY,
            live,
            &mut |s, hit| {
                for j in rays_of(hit) {
                    shadow[j] *= 1.0 - f64::from(light.opacity[s]);
                    if shadow[j] == 0.0 {
                        live &= !(1 << j);
                    }
                }
                live
            },
        );
        for j in 0..c {
            let (k, l) = self.at[j];
            layers.of_mut(k)[l].shadow = Some(self.shadow[j]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tracer that finds nothing (the shading of a given hit asks it only for its frame and
    /// the hit's paint).
    struct Empty;

    impl Tracer for Empty {
        fn frame(&self) -> GridFrame {
            GridFrame {
                origin: [-1.0, 0.5, 2.0],
                unit: [0.5, 0.25, 1.0],
                extent: [8.0; 3],
            }
        }

        fn num_surfaces(&self) -> usize {
            1
        }

        fn next_hit(&self, _: usize, _: &GridRay, _: f64, _: f64) -> Option<SurfaceHit> {
            None
        }
    }

    #[test]
    fn one_opaque_hit_alone_is_shaded_as_its_one_layer() {
        let light = Lighting {
            colors: vec![[0.8, 0.5, 0.2]],
            opacity: vec![1.0],
            key_dir: normalize([-0.3, 0.7, 0.5]).unwrap(),
            shadows: false,
            ao_rays: 0,
            ao_distance: 1.0,
            ao_filter: false,
        };
        let frame = Empty.frame();
        let mut rng = Rng::for_pixel(0, 0, 0);
        for (j, grad) in [[0.3, -1.0, 0.2], [0.0; 3], [-2.0, 0.5, 1.5]]
            .into_iter()
            .enumerate()
        {
            for rising in [false, true] {
                let hit = SurfaceHit {
                    t: 1.25 + j as f64,
                    pos: [1.5, 2.25, 3.0 + j as f64],
                    grad,
                    rising,
                    level: j as u32,
                    size: 0.5,
                    r: 7,
                };
                let dir = normalize([0.2, -0.4, -1.0 + 0.3 * j as f64]).unwrap();
                let ray = ([0.1, 0.2, 5.0], dir);
                let layer = Layer {
                    surface: 0,
                    hit,
                    shadow: None,
                    ao: None,
                };
                let layers = std::slice::from_ref(&layer);
                let of_layers = shade_hits(&Empty, &frame, &light, ray, layers, &mut rng, None);
                let alone = shade_hit_alone(&Empty, &frame, &light, ray, (0, &hit), &mut rng);
                assert_eq!(format!("{alone:?}"), format!("{of_layers:?}"));
            }
        }
    }
}
