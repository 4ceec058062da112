//! Watertightness of the whole file pipeline: a synthetic `.amrk` file (sphere distance field,
//! refined near the surface, 2 to 4 levels, ratio 2 and 4), octant extraction, BVH, exact
//! intersection. From the sphere's centre every ray must hit the closed isosurface: random
//! directions, the axes and diagonals, and rays aimed exactly at finest-cell corners near the
//! surface, many of which lie on the level-boundary faces, edges and corners the surface crosses.

use amr_format::AmrkFile;
use amr_render::bvh::BvhBuilder;
use amr_render::trace::traverse::Surface;
use amr_render::trace::FieldSource;
use amr_render::trace::{GridRay, VoxelSource};
use amr_render::Reconstruction;
use rayon::prelude::*;

use crate::support::half_refined::write_half_refined_sphere;
use crate::support::rng::Rng;

const CENTRE: [f64; 3] = [0.47, 0.52, 0.5];
const RADIUS: f64 = 0.31;

fn check(seed: u64, levels: u32, ratio: u32, base: u32, random: usize) -> usize {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.amrk");
    write_half_refined_sphere(&path, levels, ratio, base);
    let file = AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
    assert_eq!(
        file.levels().len() as u32,
        levels,
        "seed {seed}: levels dropped"
    );
    let src = FieldSource::new(&file, 0, Reconstruction::Octant).unwrap();
    let refs = src.extract(0.0).unwrap().refs;
    let surface = Surface::build(&src, 0.0, &refs, &mut BvhBuilder::new());
    let frame = src.frame();

    let mut rng = Rng(seed);
    let mut dirs: Vec<[f64; 3]> = (0..random).map(|_| rng.dir()).collect();
    for a in 0..3 {
        for s in [-1.0, 1.0] {
            let mut d = [0.0; 3];
            d[a] = s;
            dirs.push(d);
        }
    }
    for k in 0..8 {
        dirs.push([0, 1, 2].map(|a| if k >> a & 1 == 1 { 1.0 } else { -1.0 }));
    }
    // Finest-cell corners within two finest cells of the sphere.
    let finest = file.levels().last().unwrap().cell_size[0];
    let n = (1.0 / finest).round() as i64;
    let mut aimed = 0;
    for iz in 0..=n {
        for iy in 0..=n {
            for ix in 0..=n {
                let q = [ix, iy, iz].map(|i| i as f64 * finest);
                let r = (0..3)
                    .map(|a| (q[a] - CENTRE[a]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                if (r - RADIUS).abs() < 2.0 * finest && rng.f64() < 0.25 {
                    dirs.push([0, 1, 2].map(|a| q[a] - CENTRE[a]));
                    aimed += 1;
                }
            }
        }
    }
    // Each ray: None if it escaped, else |F(hit) - iso| relative to the voxel's value scale.
    let results: Vec<Option<f64>> = dirs
        .par_iter()
        .map(|d| {
            let ray = GridRay::from_world(&frame, CENTRE, *d);
            let hit = surface.closest_hit(&src, &ray, 0.0, f64::INFINITY)?;
            // The any-hit query (shadows, ambient occlusion) must agree with closest-hit.
            assert!(
                surface.any_hit(&src, &ray, 0.0, f64::INFINITY),
                "seed {seed}: closest-hit finds the surface along {d:?}, any-hit does not"
            );
            let scale = hit
                .voxel
                .values
                .iter()
                .fold(0f64, |m, &c| m.max(f64::from(c).abs()));
            Some(hit.voxel.eval_local(hit.local).abs() / scale.max(f64::MIN_POSITIVE))
        })
        .collect();
    let escaped: Vec<usize> = (0..results.len())
        .filter(|&i| results[i].is_none())
        .collect();
    assert!(
        escaped.is_empty(),
        "seed {seed}, {levels} levels, ratio {ratio}: {} of {} rays escaped, first direction {:?}",
        escaped.len(),
        dirs.len(),
        dirs[escaped[0]]
    );
    let worst = results.iter().flatten().fold(0f64, |m, &e| m.max(e));
    assert!(
        worst <= 1e-6,
        "seed {seed}: a hit is off the surface: |F - iso| / scale = {worst:e}"
    );
    let mut level_hits = vec![0usize; levels as usize];
    for d in dirs.iter().step_by(97) {
        let ray = GridRay::from_world(&frame, CENTRE, *d);
        let hit = surface.closest_hit(&src, &ray, 0.0, f64::INFINITY).unwrap();
        level_hits[hit.voxel.level as usize] += 1;
    }
    assert!(
        level_hits.iter().all(|&n| n > 0),
        "seed {seed}: the surface should be hit on every level, hits per level {level_hits:?}"
    );
    eprintln!("seed {seed}: hits per level (sampled) {level_hits:?}");
    eprintln!(
        "seed {seed}: {levels} levels, ratio {ratio}: {} active octants, {} rays ({aimed} aimed at finest corners), all hit, worst |F-iso|/scale {worst:e}",
        refs.len(),
        dirs.len()
    );
    dirs.len()
}

#[test]
fn every_ray_from_inside_the_sphere_hits_through_the_file_pipeline() {
    let configs = [
        (1, 2, 2, 32, 200_000),
        (2, 3, 2, 16, 200_000),
        (3, 4, 2, 16, 200_000),
        (4, 2, 4, 16, 200_000),
        (5, 3, 4, 8, 200_000),
    ];
    let total: usize = configs
        .iter()
        .map(|&(s, l, r, b, n)| check(s, l, r, b, n))
        .sum();
    assert!(total >= 1_000_000, "only {total} rays");
}
