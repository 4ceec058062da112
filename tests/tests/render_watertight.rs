//! Watertightness: from inside a closed isosurface that crosses level boundaries, every ray hits,
//! including rays aimed exactly at voxel faces, edges and corners and rays along the axes; every
//! hit lies on the reconstructed surface.

use crate::support::render::{shape_grid, surfaces, Rng, Shape, CENTRE};
use amr_render::trace::{GridRay, Surface, VoxelSource};

/// Rays of one configuration: random directions from several origins, directions to lattice
/// points near the surface, and axis and diagonal directions.
fn rays(
    seed: u64,
    ratio: u32,
    levels: u8,
    random: usize,
    near: &dyn Fn([f64; 3]) -> f64,
) -> Vec<GridRay> {
    let mut rng = Rng(seed);
    let origins = [
        CENTRE,
        [2.25, 2.125, 1.875],
        [1.5, 2.0, 2.5],
        [2.0 + 1.0 / 3.0, 1.9, 2.1],
    ];
    let mut out = Vec::new();
    for i in 0..random {
        out.push(GridRay {
            o: origins[i % origins.len()],
            d: rng.dir(),
        });
    }
    let finest = 1.0 / f64::from(ratio).powi(i32::from(levels) - 1);
    let steps = (4.0 / finest) as i64;
    for o in &origins[..2] {
        for iz in 0..=steps {
            for iy in 0..=steps {
                for ix in 0..=steps {
                    let q = [ix, iy, iz].map(|i| i as f64 * finest);
                    if near(q).abs() < 2.0 * finest.max(0.25) && rng.f64() < 0.5 {
                        out.push(GridRay {
                            o: *o,
                            d: [0, 1, 2].map(|a| q[a] - o[a]),
                        });
                    }
                }
            }
        }
        for a in 0..3 {
            for s in [-1.0, 1.0] {
                let mut d = [0.0; 3];
                d[a] = s;
                out.push(GridRay { o: *o, d });
            }
        }
        for k in 0..8 {
            let d = [0, 1, 2].map(|a| if k >> a & 1 == 1 { 1.0 } else { -1.0 });
            out.push(GridRay { o: *o, d });
        }
    }
    out
}

fn check(seed: u64, levels: u8, ratio: u32, shape: Shape, radius: f64, random: usize) -> usize {
    let grid = shape_grid(seed, levels, ratio, shape, radius, [0.0; 3], 1.0);
    let surface: Vec<Surface> = surfaces(&grid, &[0.0]);
    let field = crate::support::render::shape_field(shape, radius);
    let rays = rays(seed, ratio, levels, random, &field);
    let mut worst: f64 = 0.0;
    for (i, ray) in rays.iter().enumerate() {
        let hit = surface[0].closest_hit(&grid, ray, 0.0, f64::INFINITY);
        let Some(hit) = hit else {
            panic!("seed {seed}, {levels} levels, ratio {ratio}: ray {i} {ray:?} escaped");
        };
        let v = hit.voxel.eval_local(hit.local);
        let scale = hit
            .voxel
            .values
            .iter()
            .fold(0.0f64, |m, &c| m.max(f64::from(c).abs()));
        let err = v.abs() / scale.max(f64::MIN_POSITIVE);
        worst = worst.max(err);
        assert!(
            err <= 1e-6,
            "seed {seed}: ray {i} hit with F - iso = {v:e} (scale {scale:e}) at {:?}",
            hit.grid_pos()
        );
        let p = hit.grid_pos();
        let on_ray = ray.at(hit.t);
        let dist = (0..3)
            .map(|a| (p[a] - on_ray[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            dist < 1e-9,
            "seed {seed}: ray {i}: hit point {p:?} is {dist:e} off the ray"
        );
        let (f, _) = grid.sample(p).unwrap();
        assert!(
            f64::from(f).abs() < 1e-5,
            "seed {seed}: ray {i}: sampled F(p) = {f}"
        );
    }
    eprintln!(
        "seed {seed}: {shape:?} r={radius}, {levels} levels, ratio {ratio}: {} rays, all hit, worst |F-iso|/scale {worst:e}",
        rays.len()
    );
    rays.len()
}

#[test]
fn every_ray_from_inside_a_closed_surface_hits() {
    use Shape::*;
    let configs = [
        (11, 2, 2, Sphere, 1.3, 150_000),
        (12, 3, 2, Sphere, 1.3, 150_000),
        (13, 4, 2, Sphere, 1.3, 150_000),
        (14, 2, 4, Sphere, 1.3, 150_000),
        (15, 3, 4, Sphere, 1.3, 150_000),
        (16, 3, 2, Cube, 1.25, 60_000),
        (17, 4, 2, Cube, 1.5, 60_000),
        (18, 3, 4, Cube, 1.0625, 60_000),
        (19, 3, 2, Octahedron, 1.5, 60_000),
        (20, 3, 4, Octahedron, 1.75, 60_000),
    ];
    let total: usize = configs
        .iter()
        .map(|&(s, l, r, shape, rad, n)| check(s, l, r, shape, rad, n))
        .sum();
    assert!(total >= 1_000_000, "only {total} rays");
}
