//! Primary rays traced as packets ([`Surface::closest_hits`]) find for every ray exactly the hit
//! the single-ray search finds ([`Surface::closest_hit_with`] without the last hit's memory),
//! from the origin and, each ray with its own `tmin`, from behind its first hit:
//! tiles of camera rays over a multi-level sphere file, and rays from inside aimed at
//! finest-cell corners, which lie on faces, edges and corners shared by several voxels. Shadow
//! rays traced as packets ([`Surface::any_hits`]) answer for every ray what the single-ray
//! occlusion query ([`Surface::any_hit`]) answers, on the same rays, also when asked in turn
//! ([`Tracer::occluded_in_turn`], the rays' set-up shared). A tile's layers behind
//! transparent hits found with packets ([`TileLayers`]) are the single-ray search's. A
//! source's own any-hit test of candidate voxels answers what its test by lookup answers.

use amr_format::AmrkFile;
use amr_render::bvh::BvhBuilder;
use amr_render::shade::integrate::{shade_hits, KeyShadow, Lighting, SearchHint};
use amr_render::shade::layers::{ray_layers, Layer, TileLayers};
use amr_render::shade::packets::TileHits;
use amr_render::shade::sampling::Rng as PixelRng;
use amr_render::trace::source::{occlusion_tests_by_lookup, AnyHitQuery, BoxClip};
use amr_render::trace::tracer::{HybridTracer, Tracer};
use amr_render::trace::traverse::Surface;
use amr_render::trace::FieldSource;
use amr_render::trace::{GridRay, VoxelSource};
use amr_render::Reconstruction;

use crate::support::half_refined::write_half_refined_sphere;
use crate::support::rng::Rng;

const CENTRE: [f64; 3] = [0.47, 0.52, 0.5];

/// The reconstructions whose packets and single rays are compared.
const ALL_METHODS: [Reconstruction; 3] = [
    Reconstruction::Octant,
    Reconstruction::Current,
    Reconstruction::Nearest,
];

/// The half-refined sphere (three levels, ratio 2, a base of 8 cells) the tests trace, read
/// into memory.
fn half_refined_sphere() -> AmrkFile<Vec<u8>> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.amrk");
    write_half_refined_sphere(&path, 3, 2, 8);
    AmrkFile::open(std::fs::read(&path).unwrap()).unwrap()
}

/// Compares packet and single-ray hits, and packet and single-ray occlusion, for each packet of
/// `(origin, direction)` pairs; returns the hits found from the origins and behind them.
fn compare(
    src: &(impl VoxelSource + ?Sized),
    surface: &Surface,
    name: &str,
    packets: &[Vec<([f64; 3], [f64; 3])>],
) -> (usize, usize) {
    let frame = src.frame();
    let mut found = 0;
    let (mut occluded_rays, mut open_rays) = (0, 0);
    let mut behind_found = 0;
    for (p, packet) in packets.iter().enumerate() {
        let rays: Vec<GridRay> = packet
            .iter()
            .map(|&(o, d)| GridRay::from_world(&frame, o, d))
            .collect();
        // Every fifth ray searches only up to a limit, as behind an opaque hit.
        let tmax: Vec<f64> = (0..rays.len())
            .map(|k| if k % 5 == 2 { 0.3 } else { f64::INFINITY })
            .collect();
        let mut hits = vec![None; rays.len()];
        surface.closest_hits(src, &rays, &vec![0.0; rays.len()], &tmax, &mut hits);
        for (k, ray) in rays.iter().enumerate() {
            let want = surface.closest_hit_with(src, ray, 0.0, tmax[k], false);
            assert_eq!(hits[k], want, "{name}: packet {p}, ray {k}");
            found += usize::from(want.is_some());
        }
        // Continuations: each ray again from a little behind its hit (or from a fixed start when
        // it has none), each with its own `tmin`, as the layers behind a transparent hit.
        let from: Vec<f64> = hits
            .iter()
            .map(|h| h.as_ref().map_or(0.02, |h| h.t + 1e-4))
            .collect();
        let mut behind = vec![None; rays.len()];
        surface.closest_hits(src, &rays, &from, &tmax, &mut behind);
        for (k, ray) in rays.iter().enumerate() {
            let want = surface.closest_hit(src, ray, from[k], tmax[k]);
            assert_eq!(
                behind[k], want,
                "{name}: packet {p}, ray {k} behind its hit"
            );
            behind_found += usize::from(want.is_some());
        }
        // Occlusion: some rays left out, some starting a little along, every other packet up to
        // a limit.
        let active = (0..rays.len())
            .filter(|k| k % 7 != 4)
            .fold(0u64, |m, k| m | 1 << k);
        let tmin: Vec<f64> = (0..rays.len())
            .map(|k| if k % 3 == 1 { 0.05 } else { 0.0 })
            .collect();
        let limit = if p % 2 == 0 { f64::INFINITY } else { 0.3 };
        let occluded = surface.any_hits(src, &rays, &tmin, limit, active);
        for (k, ray) in rays.iter().enumerate() {
            let want = active >> k & 1 != 0 && surface.any_hit(src, ray, tmin[k], limit);
            assert_eq!(
                occluded >> k & 1 != 0,
                want,
                "{name}: packet {p}, ray {k} occlusion"
            );
            if active >> k & 1 != 0 {
                *if want {
                    &mut occluded_rays
                } else {
                    &mut open_rays
                } += 1;
            }
        }
        // Shadow and AO rays start past their origin (`tmin > 0`): their BVH rays are made four
        // at a time, once for the surfaces asked in turn; asking the surface twice, every ray
        // again the second time, checks that the first walk left the rays ready.
        let ahead: Vec<f64> = tmin.iter().map(|&t| t.max(1e-4)).collect();
        let tracer = HybridTracer {
            src,
            surfaces: std::slice::from_ref(surface),
            sources: &[],
            smooth_normals: false,
        };
        let mut answers = Vec::new();
        tracer.occluded_in_turn(&[0, 0], &rays, &ahead, limit, active, &mut |s, hit| {
            answers.push((s, hit));
            active
        });
        assert_eq!(answers.len(), 2, "{name}: packet {p}");
        for (k, ray) in rays.iter().enumerate() {
            let want = active >> k & 1 != 0 && surface.any_hit(src, ray, ahead[k], limit);
            for &(s, hit) in &answers {
                assert_eq!(s, 0);
                assert_eq!(
                    hit >> k & 1 != 0,
                    want,
                    "{name}: packet {p}, ray {k} occlusion in turn"
                );
            }
        }
    }
    assert!(
        occluded_rays > 100 && open_rays > 100,
        "{name}: {occluded_rays} rays occluded, {open_rays} open"
    );
    (found, behind_found)
}

#[test]
fn packets_find_the_single_ray_hits() {
    let file = half_refined_sphere();
    let finest = file.levels().last().unwrap().cell_size[0];
    for method in ALL_METHODS {
        let src = FieldSource::new(&file, 0, method).unwrap();
        let refs = src.extract(0.0).unwrap().refs;
        let surface = Surface::build(&src, 0.0, &refs, &mut BvhBuilder::new());
        let mut rng = Rng(11);
        // 8x8 tiles of a camera's rays, some tiles straddling the view axis (mixed octants),
        // and tiles cut short at an image edge.
        let mut packets = Vec::new();
        for t in 0..40 {
            let eye = [1.6 - 0.03 * t as f64, 0.2 + 0.02 * t as f64, 1.3];
            let look = [0, 1, 2].map(|a| CENTRE[a] + 0.4 * (rng.f64() - 0.5) - eye[a]);
            let pitch = if t % 4 == 0 { 0.05 } else { 0.002 };
            let (w, h) = if t % 7 == 3 { (5, 3) } else { (8, 8) };
            let mut tile = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    let (u, v) = (x as f64 - 3.5, y as f64 - 3.5);
                    let d = [
                        look[0] + pitch * u,
                        look[1] + pitch * v,
                        look[2] + pitch * u,
                    ];
                    tile.push((eye, d));
                }
            }
            packets.push(tile);
        }
        let (found, behind) = compare(&src, &surface, &format!("{method:?} camera"), &packets);
        assert!(found > 1000, "{method:?}: only {found} camera rays hit");
        // The far side of the sphere behind the near one.
        assert!(
            behind > 500,
            "{method:?}: only {behind} camera rays hit behind"
        );
        // From the centre: finest-cell corners near the sphere, 64 at a time.
        let n = (1.0 / finest).round() as i64;
        let mut aimed = Vec::new();
        for iz in 0..=n {
            for iy in 0..=n {
                for ix in 0..=n {
                    let q = [ix, iy, iz].map(|i| i as f64 * finest);
                    let r = (0..3)
                        .map(|a| (q[a] - CENTRE[a]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    if (r - 0.31).abs() < 2.0 * finest && rng.f64() < 0.5 {
                        aimed.push((CENTRE, [0, 1, 2].map(|a| q[a] - CENTRE[a])));
                    }
                }
            }
        }
        let packets: Vec<Vec<_>> = aimed.chunks(64).map(|c| c.to_vec()).collect();
        let (found, _) = compare(&src, &surface, &format!("{method:?} corners"), &packets);
        assert!(found > 500, "{method:?}: only {found} aimed rays hit");
    }
}

/// A source's own any-hit test of candidate voxels ([`VoxelSource::with_occlusion_tests`]:
/// the octant method tests a voxel where its cache holds it) answers what the test by lookup
/// answers ([`occlusion_tests_by_lookup`]), one ray or a packet at a time, for voxels the cache
/// holds and voxels it does not, rays that cross a voxel's box and rays that miss it.
#[test]
fn a_sources_occlusion_test_answers_the_lookups() {
    let file = half_refined_sphere();
    for method in ALL_METHODS {
        let src = FieldSource::new(&file, 0, method).unwrap();
        let refs = src.extract(0.0).unwrap().refs;
        let mut rng = Rng(5);
        let (mut occluded, mut open) = (0, 0);
        for &r in refs.iter().cycle().take(3 * refs.len()) {
            let (lo, hi) = src.voxel_box(r);
            // Four rays from around the box through points in or near it (some miss it).
            let rays: Vec<GridRay> = (0..4)
                .map(|_| {
                    let at = [0, 1, 2].map(|a| lo[a] + (1.4 * rng.f64() - 0.2) * (hi[a] - lo[a]));
                    let d = [0, 1, 2].map(|_| rng.f64() - 0.5);
                    let o = [0, 1, 2].map(|a| at[a] - 2.0 * d[a] * (hi[a] - lo[a]));
                    GridRay { o, d }
                })
                .collect();
            let recips: Vec<[f64; 3]> = rays.iter().map(GridRay::recip).collect();
            let tmin: Vec<f64> = (0..4).map(|k| if k == 1 { 1.9 } else { 0.0 }).collect();
            let tmax: Vec<f64> = (0..4)
                .map(|k| if k == 2 { 2.1 } else { f64::INFINITY })
                .collect();
            let ask = |own: bool, query: AnyHitQuery<'_>| {
                let mut got = 0;
                let mut f =
                    |test: &mut amr_render::trace::source::OcclusionTest<'_>| got = test(r, query);
                if own {
                    src.with_occlusion_tests(0.0, &mut f);
                } else {
                    occlusion_tests_by_lookup(&src, 0.0, &mut f);
                }
                got
            };
            for k in 0..4 {
                let clip = BoxClip {
                    ray: &rays[k],
                    recip: &recips[k],
                    tmin: tmin[k],
                    tmax: tmax[k],
                };
                // Asked first of the source (the voxel perhaps not cached yet), then by
                // lookup, then of the source again.
                let first = ask(true, AnyHitQuery::One(&clip));
                assert_eq!(
                    first,
                    ask(false, AnyHitQuery::One(&clip)),
                    "{method:?} {r:#x} {k}"
                );
                assert_eq!(
                    first,
                    ask(true, AnyHitQuery::One(&clip)),
                    "{method:?} {r:#x} {k}"
                );
                if first != 0 {
                    occluded += 1;
                } else {
                    open += 1;
                }
            }
            let packet = AnyHitQuery::Packet {
                rays: &rays,
                recips: &recips,
                m: 0b1011,
                tmin: &tmin,
                tmax: &tmax,
            };
            let want = ask(false, packet);
            assert_eq!(ask(true, packet), want, "{method:?} {r:#x} packet");
        }
        assert!(
            occluded > 1000 && open > 1000,
            "{method:?}: {occluded} occluded, {open} open"
        );
    }
}

/// The layers of tiles of camera rays through three nested spheres (two transparent, the inner
/// one opaque) found together ([`TileLayers`]: continuations as packets) are, ray by ray, the
/// layers found ray by ray ([`ray_layers`]) from the same first hits; with the key light's
/// shadows of all layers traced as packets ([`KeyShadow`]) each ray shades to the sample it
/// gives with its shadow rays traced one by one.
#[test]
fn tile_layers_are_the_single_ray_layers() {
    let file = half_refined_sphere();
    let isos = [0.08f32, 0.0, -0.08];
    for method in [Reconstruction::Octant, Reconstruction::Nearest] {
        let src = FieldSource::new(&file, 0, method).unwrap();
        let surfaces = surfaces_at(&src, &isos[..]);
        let tracer = HybridTracer {
            src: &src,
            surfaces: &surfaces,
            sources: &[],
            smooth_normals: false,
        };
        let light = lighting(vec![0.3, 0.5, 1.0], true);
        let frame = src.frame();
        let mut rng = Rng(5);
        let mut hint = SearchHint::default();
        let mut tile = TileHits::new(surfaces.len());
        let mut layers = TileLayers::default();
        let mut shadows = KeyShadow::default();
        let (mut deep, mut rays_seen, mut deep_shadows, mut dimmed) = (0, 0, 0, 0);
        for t in 0..30u32 {
            let eye = eye_of(t);
            let look = [0, 1, 2].map(|a| CENTRE[a] + 0.5 * (rng.f64() - 0.5) - eye[a]);
            let pitch = if t % 3 == 0 { 0.04 } else { 0.003 };
            let (w, h) = if t % 7 == 3 { (6, 5) } else { (8, 8) };
            let (mut rays, mut dirs) = (Vec::new(), Vec::new());
            for y in 0..h {
                for x in 0..w {
                    let (u, v) = (x as f64 - 3.5, y as f64 - 3.5);
                    let d = [look[0] + pitch * u, look[1] + pitch * v, look[2]];
                    let len = d.iter().map(|x| x * x).sum::<f64>().sqrt();
                    let d = d.map(|x| x / len);
                    rays.push(GridRay::from_world(&frame, eye, d));
                    dirs.push(d);
                }
            }
            let wants = packet_layers_match(
                (&tracer, &light),
                &rays,
                (&mut hint, &mut tile, &mut layers),
                &format!("{method:?}: tile {t}"),
            );
            deep += wants.iter().filter(|w| w.len() >= 3).count();
            rays_seen += wants.len();
            shadows.trace(&tracer, &light, &dirs, &mut layers);
            for (k, &d) in dirs.iter().enumerate() {
                let traced = layers.of(k);
                deep_shadows += traced.iter().skip(1).filter(|l| l.shadow.is_some()).count();
                dimmed += traced
                    .iter()
                    .filter(|l| l.shadow.is_some_and(|s| s < 1.0))
                    .count();
                let single: Vec<_> = traced
                    .iter()
                    .map(|&l| Layer { shadow: None, ..l })
                    .collect();
                let sample = |layers: &[Layer]| {
                    let mut rng = PixelRng::for_pixel(k as u32, t, 0);
                    shade_hits(
                        &tracer,
                        &frame,
                        &light,
                        (eye_of(t), d),
                        layers,
                        &mut rng,
                        None,
                    )
                };
                // Compared as printed (shortest round-trip digits): equal values, NaN (no
                // painted value) included.
                let (a, b) = (sample(traced), sample(&single));
                assert_eq!(
                    format!("{a:?}"),
                    format!("{b:?}"),
                    "{method:?}: tile {t}, ray {k}"
                );
            }
        }
        assert!(
            deep > rays_seen / 4,
            "{method:?}: only {deep} of {rays_seen} rays have three layers or more"
        );
        assert!(
            deep_shadows > rays_seen / 4,
            "{method:?}: only {deep_shadows} shadow rays behind a first layer"
        );
        // The outer shells shade the inner ones.
        assert!(
            dimmed > rays_seen / 4,
            "{method:?}: only {dimmed} layers in a shell's shadow"
        );
    }
}

/// A tile of opaque surfaces (all three shells, and the middle one alone) takes each ray's
/// nearest first hit as its one layer: the layers `ray_layers` finds ray by ray.
#[test]
fn opaque_tile_layers_are_the_single_ray_layers() {
    let file = half_refined_sphere();
    let src = FieldSource::new(&file, 0, Reconstruction::Octant).unwrap();
    for isos in [&[0.08f32, 0.0, -0.08][..], &[0.0][..]] {
        let surfaces = surfaces_at(&src, isos);
        let tracer = HybridTracer {
            src: &src,
            surfaces: &surfaces,
            sources: &[],
            smooth_normals: false,
        };
        let light = lighting(vec![1.0; isos.len()], false);
        let frame = src.frame();
        let mut rng = Rng(7);
        let mut hint = SearchHint::default();
        let mut tile = TileHits::new(surfaces.len());
        let mut layers = TileLayers::default();
        let mut hits = 0;
        for t in 0..12u32 {
            let eye = eye_of(t);
            let look = [0, 1, 2].map(|a| CENTRE[a] + 0.5 * (rng.f64() - 0.5) - eye[a]);
            let rays: Vec<GridRay> = (0..64)
                .map(|k| {
                    let (u, v) = ((k % 8) as f64 - 3.5, (k / 8) as f64 - 3.5);
                    let d = [look[0] + 0.03 * u, look[1] + 0.03 * v, look[2]];
                    let len = d.iter().map(|x| x * x).sum::<f64>().sqrt();
                    GridRay::from_world(&frame, eye, d.map(|x| x / len))
                })
                .collect();
            let wants = packet_layers_match(
                (&tracer, &light),
                &rays,
                (&mut hint, &mut tile, &mut layers),
                &format!("{isos:?}: tile {t}"),
            );
            assert!(wants.iter().all(|w| w.len() <= 1));
            hits += wants.iter().map(Vec::len).sum::<usize>();
        }
        assert!(hits > 12 * 64 / 4, "{isos:?}: only {hits} rays hit");
    }
}

/// One surface per isovalue of `src`, each with its own BVH.
fn surfaces_at<D: AsRef<[u8]> + Sync>(src: &FieldSource<D>, isos: &[f32]) -> Vec<Surface> {
    isos.iter()
        .map(|&iso| {
            let refs = src.extract(iso).unwrap().refs;
            Surface::build(src, iso, &refs, &mut BvhBuilder::new())
        })
        .collect()
}

/// White surfaces of the given opacities lit from +z, without AO.
fn lighting(opacity: Vec<f32>, shadows: bool) -> Lighting {
    Lighting {
        colors: vec![[1.0; 3]; opacity.len()],
        opacity,
        key_dir: [0.0, 0.0, 1.0],
        shadows,
        ao_rays: 0,
        ao_distance: 0.1,
        ao_filter: false,
    }
}

/// Traces `rays` as one tile (first hits, then the layers behind them) and asserts that every
/// ray's layers are the ones [`ray_layers`] finds for it alone from the same first hits;
/// returns those layers, ray by ray.
fn packet_layers_match(
    (tracer, light): (&HybridTracer<'_, FieldSource<Vec<u8>>>, &Lighting),
    rays: &[GridRay],
    (hint, tile, layers): (&mut SearchHint, &mut TileHits, &mut TileLayers),
    label: &str,
) -> Vec<Vec<Layer>> {
    tile.trace(tracer, light, rays, hint);
    let firsts: Vec<Vec<_>> = (0..rays.len())
        .map(|k| tile.hits_of(k).copied().collect())
        .collect();
    layers.trace(tracer, light, rays, tile);
    rays.iter()
        .enumerate()
        .map(|(k, ray)| {
            let mut want = Vec::new();
            ray_layers(tracer, light, ray, &mut firsts[k].clone(), &mut want);
            assert_eq!(layers.of(k), &want[..], "{label}, ray {k}");
            want
        })
        .collect()
}

/// The camera position of tile `t` in [`tile_layers_are_the_single_ray_layers`].
fn eye_of(t: u32) -> [f64; 3] {
    [1.5 - 0.03 * f64::from(t), 0.25 + 0.02 * f64::from(t), 1.4]
}
