//! Primary rays traced as packets ([`Surface::closest_hits`]) find for every ray exactly the hit
//! the single-ray search finds ([`Surface::closest_hit_with`] without the last hit's memory):
//! tiles of camera rays over a multi-level sphere file, and rays from inside aimed at
//! finest-cell corners, which lie on faces, edges and corners shared by several voxels. Shadow
//! rays traced as packets ([`Surface::any_hits`]) answer for every ray what the single-ray
//! occlusion query ([`Surface::any_hit`]) answers, on the same rays.

use amr_format::AmrkFile;
use amr_render::bvh::BvhBuilder;
use amr_render::trace::traverse::Surface;
use amr_render::trace::FieldSource;
use amr_render::trace::{GridRay, VoxelSource};
use amr_render::Reconstruction;

use crate::support::half_refined::write_half_refined_sphere;
use crate::support::rng::Rng;

const CENTRE: [f64; 3] = [0.47, 0.52, 0.5];

/// Compares packet and single-ray hits, and packet and single-ray occlusion, for each packet of
/// `(origin, direction)` pairs; returns the hits found.
fn compare(
    src: &(impl VoxelSource + ?Sized),
    surface: &Surface,
    name: &str,
    packets: &[Vec<([f64; 3], [f64; 3])>],
) -> usize {
    let frame = src.frame();
    let mut found = 0;
    let (mut occluded_rays, mut open_rays) = (0, 0);
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
        surface.closest_hits(src, &rays, 0.0, &tmax, &mut hits);
        for (k, ray) in rays.iter().enumerate() {
            let want = surface.closest_hit_with(src, ray, 0.0, tmax[k], false);
            assert_eq!(hits[k], want, "{name}: packet {p}, ray {k}");
            found += usize::from(want.is_some());
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
    }
    assert!(
        occluded_rays > 100 && open_rays > 100,
        "{name}: {occluded_rays} rays occluded, {open_rays} open"
    );
    found
}

#[test]
fn packets_find_the_single_ray_hits() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.amrk");
    write_half_refined_sphere(&path, 3, 2, 8);
    let file = AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
    let finest = file.levels().last().unwrap().cell_size[0];
    for method in [
        Reconstruction::Octant,
        Reconstruction::Current,
        Reconstruction::Nearest,
    ] {
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
        let found = compare(&src, &surface, &format!("{method:?} camera"), &packets);
        assert!(found > 1000, "{method:?}: only {found} camera rays hit");
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
        let found = compare(&src, &surface, &format!("{method:?} corners"), &packets);
        assert!(found > 500, "{method:?}: only {found} aimed rays hit");
    }
}
