//! Extraction limited to a region (issue 17, goal 4), on seeded random hierarchies: the refs an
//! extraction keeps inside a clip box are exactly the whole extraction's refs whose closed voxel
//! box meets the box (brute force over every ref, with the integer boxes the refs name), for the
//! octant, `current` and `nearest` reconstructions; inside a view frustum they are a subset of
//! the whole extraction that holds every voxel whose centre the frustum holds.

use crate::support::hierarchy::{build, standard_cases, Rng};
use amr_format::AmrkFile;
use amr_render::camera::Camera;
use amr_render::extract::Region;
use amr_render::reconstruct::Reconstruction;
use amr_render::trace::{FieldSource, GridFrame, VoxelSource};
use amr_render::Frustum;

/// Isovalues spread over field `field`'s range.
fn isovalues(file: &AmrkFile<Vec<u8>>, field: usize, rng: &mut Rng) -> Vec<f32> {
    let f = &file.fields()[field];
    (0..3)
        .map(|_| f.min + (f.max - f.min) * (0.2 + 0.6 * rng.f64() as f32))
        .collect()
}

/// A random box in grid coordinates that reaches past the domain `[0, e]` at times, with
/// coordinates off the grid's integers.
fn random_box(rng: &mut Rng, e: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for a in 0..3 {
        let x = (rng.f64() * 1.2 - 0.1) * e[a] + 0.37;
        let y = (rng.f64() * 1.2 - 0.1) * e[a] + 0.37;
        (lo[a], hi[a]) = (x.min(y), x.max(y) + 0.5);
    }
    (lo, hi)
}

/// Whether the closed integer box `[lo, hi]` meets the closed box `[blo, bhi]`.
fn meets(lo: [f64; 3], hi: [f64; 3], (blo, bhi): ([f64; 3], [f64; 3])) -> bool {
    (0..3).all(|a| lo[a] <= bhi[a] && hi[a] >= blo[a])
}

#[test]
fn clipped_extraction_equals_the_whole_one_filtered_by_the_box() {
    let (mut kept, mut dropped, mut empty) = (0u64, 0u64, 0u64);
    for case in standard_cases(2) {
        let (_, file) = build(&case);
        let mut rng = Rng(case.seed ^ 0xc11b);
        for reconstruction in [
            Reconstruction::Octant,
            Reconstruction::Current,
            Reconstruction::Nearest,
        ] {
            for field in 0..file.fields().len() {
                let src = FieldSource::new(&file, field, reconstruction).unwrap();
                let frame = src.frame();
                for iso in isovalues(&file, field, &mut rng) {
                    let all = src.extract(iso).unwrap().refs;
                    for _ in 0..3 {
                        let bounds = random_box(&mut rng, frame.extent);
                        let region = Region {
                            bounds: Some(bounds),
                            ..Region::default()
                        };
                        let ctx = format!(
                            "seed {} {reconstruction} field {field} iso {iso} box {bounds:?}",
                            case.seed
                        );
                        let got = src.extract_in(iso, &region).unwrap();
                        let want: Vec<u64> = all
                            .iter()
                            .copied()
                            .filter(|&r| {
                                let (lo, hi) = src.voxel_box(r);
                                meets(lo, hi, bounds)
                            })
                            .collect();
                        assert_eq!(got.refs, want, "{ctx}");
                        assert_eq!(got.stats.active, want.len() as u64, "{ctx}");
                        kept += want.len() as u64;
                        dropped += (all.len() - want.len()) as u64;
                        empty += u64::from(want.is_empty() && !all.is_empty());
                    }
                }
            }
        }
    }
    assert!(
        kept > 1000 && dropped > 1000 && empty > 0,
        "kept {kept}, dropped {dropped}, {empty} boxes empty: the boxes do not exercise the filter"
    );
}

#[test]
fn frustum_extraction_keeps_every_voxel_the_view_holds() {
    let (mut inside, mut dropped) = (0u64, 0u64);
    for case in standard_cases(1) {
        let (_, file) = build(&case);
        let mut rng = Rng(case.seed ^ 0xf00);
        let src = FieldSource::new(&file, 0, Reconstruction::Octant).unwrap();
        let frame: GridFrame = src.frame();
        let (lo, hi) = frame.world_bounds();
        let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
        let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        for iso in isovalues(&file, 0, &mut rng) {
            let all = src.extract(iso).unwrap().refs;
            for _ in 0..3 {
                let d = rng.dir();
                let pos = [0, 1, 2].map(|a| centre[a] + 0.9 * size * d[a]);
                let look = [0, 1, 2].map(|a| lo[a] + rng.f64() * (hi[a] - lo[a]));
                let Ok(camera) = Camera::new(pos, look, [0.0, 0.0, 1.0], 25.0) else {
                    continue;
                };
                let frustum = Frustum::of_camera(&camera, (64, 48), &frame);
                let region = Region {
                    half_spaces: frustum.sides.to_vec(),
                    ..Region::default()
                };
                let ctx = format!("seed {} iso {iso} camera {camera:?}", case.seed);
                let got = src.extract_in(iso, &region).unwrap().refs;
                let mut at = 0;
                for &r in &all {
                    let (lo, hi) = src.voxel_box(r);
                    let c = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
                    let holds = frustum.sides.iter().all(|s| s.may_overlap(c, c, 0.0));
                    let kept = got.get(at) == Some(&r);
                    at += usize::from(kept);
                    assert!(!holds || kept, "{ctx}: voxel {r:#x} in view was dropped");
                    inside += u64::from(holds);
                    dropped += u64::from(!kept);
                }
                assert_eq!(
                    at,
                    got.len(),
                    "{ctx}: kept refs are not a subsequence of all"
                );
            }
        }
    }
    assert!(
        inside > 100 && dropped > 100,
        "in view {inside}, dropped {dropped}"
    );
}
