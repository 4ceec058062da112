//! Smooth normals through the file pipeline: along a fine sweep of rays across a sphere whose
//! surface crosses voxel faces and a level boundary, the octant method's smooth normals turn
//! steadily within a level (where the voxels' own trilinear gradients jump by degrees at
//! faces), change only slightly where the level changes, and stay within a degree of the
//! sphere's normal.

use amr_format::AmrkFile;
use amr_render::bvh::BvhBuilder;
use amr_render::trace::{FieldSource, GridRay, HybridTracer, Surface, Tracer, VoxelSource};
use amr_render::Reconstruction;
use amr_synth::{AnalyticField, Case};

use crate::support::half_refined::write_half_refined_sphere;

const CENTRE: [f64; 3] = [0.47, 0.52, 0.5];

/// Angle between unit vectors, degrees.
fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = (0..3).map(|i| a[i] * b[i]).sum::<f64>().clamp(-1.0, 1.0);
    d.acos().to_degrees()
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (0..3).map(|i| v[i] * v[i]).sum::<f64>().sqrt();
    v.map(|x| x / n)
}

/// What a sweep of rays saw: the largest angle between the normals of neighbouring rays hitting
/// the same level and hitting different levels, the largest angle to the exact normal, and the
/// levels hit.
#[derive(Debug)]
struct Sweep {
    max_step: f64,
    max_step_across_levels: f64,
    max_error: f64,
    levels: Vec<u32>,
}

fn sweep(path: &std::path::Path, reconstruction: Reconstruction, smooth: bool) -> Sweep {
    let file = AmrkFile::open(std::fs::read(path).unwrap()).unwrap();
    let src = FieldSource::new(&file, 0, reconstruction).unwrap();
    let iso = Case::Sphere.default_iso() as f32;
    let refs = src.extract(iso).unwrap().refs;
    let surfaces = [Surface::build(&src, iso, &refs, &mut BvhBuilder::new())];
    let tracer = HybridTracer {
        src: &src,
        surfaces: &surfaces,
        smooth_normals: smooth,
    };
    let frame = src.frame();
    // Directions from the centre across the plane x = 0.5 (where level 1 begins) at a tilt, so
    // the hits cross voxel faces of both levels and the level boundary.
    let n = 6000;
    let (from, to) = (70f64.to_radians(), 100f64.to_radians());
    let tilt = 0.3f64;
    let mut normals = Vec::with_capacity(n);
    let mut max_error = 0f64;
    let mut levels = Vec::new();
    for i in 0..n {
        let th = from + (to - from) * i as f64 / (n - 1) as f64;
        let d = [th.cos(), th.sin() * tilt.cos(), th.sin() * tilt.sin()];
        let ray = GridRay::from_world(&frame, CENTRE, d);
        let hit = tracer
            .next_hit(0, &ray, 0.0, f64::INFINITY)
            .expect("every ray from inside hits the sphere");
        let g = unit([0, 1, 2].map(|a| hit.grad[a] / frame.unit[a]));
        let p = frame.to_world(hit.pos);
        let exact = unit([0, 1, 2].map(|a| p[a] - CENTRE[a]));
        max_error = max_error.max(angle(g, exact));
        normals.push((g, hit.level));
        if !levels.contains(&hit.level) {
            levels.push(hit.level);
        }
    }
    let (mut max_step, mut max_step_across_levels) = (0f64, 0f64);
    for w in normals.windows(2) {
        let step = angle(w[0].0, w[1].0);
        if w[0].1 == w[1].1 {
            max_step = max_step.max(step);
        } else {
            max_step_across_levels = max_step_across_levels.max(step);
        }
    }
    Sweep {
        max_step,
        max_step_across_levels,
        max_error,
        levels,
    }
}

#[test]
fn smooth_normals_turn_steadily_across_voxel_faces_and_level_boundaries() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.amrk");
    // The sweep crosses the boundary between levels 0 and 2 (level 1 only where x >= 0.5,
    // level 2 also only where y >= 0.5).
    write_half_refined_sphere(&path, 3, 2, 16);

    // The sweep turns the exact normal by 30 degrees over 6000 rays: 0.005 degrees a step.
    let flat = sweep(&path, Reconstruction::Octant, false);
    let smooth = sweep(&path, Reconstruction::Octant, true);
    eprintln!("octant, flat normals: {flat:?}");
    eprintln!("octant, smooth normals: {smooth:?}");
    assert!(
        flat.levels.len() >= 2 && smooth.levels.len() >= 2,
        "the sweep should cross a level boundary: {smooth:?}"
    );
    // Within a level the step of the differences is fixed and the field continuous: the
    // normals turn by about the sweep's own step, where the voxels' gradients jump by degrees.
    assert!(
        smooth.max_step < 0.02 && flat.max_step > 1.0,
        "smooth normals jump between neighbouring rays on one level: {smooth:?} {flat:?}"
    );
    // Where the level, and with it the step, changes, they change by a small fraction of what
    // the voxels' gradients do.
    assert!(
        smooth.max_step_across_levels < 0.1 * flat.max_step_across_levels,
        "smooth normals jump at the level boundary: {smooth:?} {flat:?}"
    );
    assert!(
        smooth.max_error < 1.0,
        "smooth normals are {} degrees off the sphere's",
        smooth.max_error
    );

    // `current` is discontinuous at level boundaries by construction (its surface cracks
    // there); its smooth normals are still closer to the sphere's than its voxels' gradients.
    let flat = sweep(&path, Reconstruction::Current, false);
    let smooth = sweep(&path, Reconstruction::Current, true);
    eprintln!("current, flat normals: {flat:?}");
    eprintln!("current, smooth normals: {smooth:?}");
    assert!(
        smooth.max_error < flat.max_error,
        "current: {smooth:?} {flat:?}"
    );
}
