//! Accuracy of the hybrid method: a thin feature the sample method misses at a coarse step, and
//! a domain far from the origin with tiny cells rendering like the unit cube.

use crate::support::block_grid::BlockGrid;
use crate::support::render::{render_grid, sphere_grid, surfaces, Rng};
use amr_render::sample_mode::{SampleStep, SampleTracer};
use amr_render::shade::IsoSpec;
use amr_render::trace::{GridRay, HybridTracer, Tracer};
use amr_render::View;

fn hit_fraction(tracer: &dyn Tracer, rays: &[GridRay]) -> f64 {
    let hits = rays
        .iter()
        .filter(|r| tracer.next_hit(0, r, 0.0, f64::INFINITY).is_some())
        .count();
    hits as f64 / rays.len() as f64
}

#[test]
fn thin_sheet_missed_by_coarse_marching_is_found_exactly() {
    let seed = 7;
    // |x - 2.03| on voxels 0.25 wide: the region below 0.05 is a sheet ~0.046 thick.
    let grid = BlockGrid::new(4, 4, |_| 1, |p| (p[0] - 2.03).abs(), [0.0; 3], 1.0);
    let iso = 0.05;
    let surf = surfaces(&grid, &[iso]);
    let mut rng = Rng(seed);
    let rays: Vec<GridRay> = (0..2000)
        .map(|_| {
            let o = [
                0.05 + 0.2 * rng.f64(),
                0.5 + 3.0 * rng.f64(),
                0.5 + 3.0 * rng.f64(),
            ];
            let d = [1.0, 0.2 * rng.f64() - 0.1, 0.2 * rng.f64() - 0.1];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            GridRay {
                o,
                d: d.map(|x| x / l),
            }
        })
        .collect();
    let hybrid = HybridTracer {
        src: &grid,
        surfaces: &surf,
        sources: &[],
        smooth_normals: false,
    };
    let coarse = SampleTracer {
        src: &grid,
        sources: &[],
        isos: vec![iso],
        step: SampleStep::Fixed(0.2),
    };
    let fine = SampleTracer {
        src: &grid,
        sources: &[],
        isos: vec![iso],
        step: SampleStep::Fixed(0.01),
    };
    let (h, c, f) = (
        hit_fraction(&hybrid, &rays),
        hit_fraction(&coarse, &rays),
        hit_fraction(&fine, &rays),
    );
    eprintln!("seed {seed}: hit fractions: hybrid {h}, sample step 0.2 {c}, sample step 0.01 {f}");
    assert_eq!(h, 1.0, "seed {seed}: the hybrid method missed the sheet");
    assert!(
        c < 0.5,
        "seed {seed}: coarse marching found the sheet {c} of the time"
    );
    assert_eq!(f, 1.0, "seed {seed}: fine marching missed the sheet");
    for r in &rays[..200] {
        let a = hybrid.next_hit(0, r, 0.0, f64::INFINITY).unwrap();
        let b = fine.next_hit(0, r, 0.0, f64::INFINITY).unwrap();
        assert!(
            (a.t - b.t).abs() < 0.01,
            "seed {seed}: hybrid t {} vs fine marching t {}",
            a.t,
            b.t
        );
    }
}

fn view() -> View {
    View {
        size: (64, 48),
        ao_rays: 2,
        ..View::default()
    }
}

#[test]
fn far_from_the_origin_with_tiny_cells_renders_like_the_unit_cube() {
    let seed = 21;
    let unit = sphere_grid(seed, 3, 2, 1.3, [0.0; 3], 1.0);
    let far = sphere_grid(seed, 3, 2, 1.3, [1e6, -2e6, 5e5], 1e-6);
    let isos = ["0".parse::<IsoSpec>().unwrap()];
    let a = render_grid(&unit, &isos, &view()).frame;
    let b = render_grid(&far, &isos, &view()).frame;
    assert!(
        a.covered() > a.len() / 20,
        "seed {seed}: the sphere covers only {} pixels",
        a.covered()
    );
    let mut bad = 0;
    for i in 0..a.len() {
        let d = (0..3)
            .map(|c| (a.rgb[c][i] - b.rgb[c][i]).abs())
            .fold(0.0f32, f32::max);
        if d > 0.02 || (a.alpha[i] - b.alpha[i]).abs() > 0.02 {
            bad += 1;
        }
        if a.alpha[i] > 0.0 && b.alpha[i] > 0.0 {
            let rel = (a.z[i] - b.z[i] * 1e6).abs() / a.z[i];
            assert!(
                rel < 1e-4,
                "seed {seed}: pixel {i}: depth {} vs {} (scaled)",
                a.z[i],
                b.z[i] * 1e6
            );
        }
    }
    assert!(
        bad <= a.len() / 200,
        "seed {seed}: {bad} of {} pixels differ",
        a.len()
    );
}

/// The sample method's default step is half a cell of the level each sample lands in: on a
/// five-level file it steps by each level's own half cell, and its frame finds the surface where
/// the hybrid method does (a fixed step fine enough for the finest level took 98 times as long
/// on the Enzo dataset's 8 levels).
#[test]
fn the_sample_method_steps_by_the_level_it_samples() {
    use amr_format::progress::NoProgress;
    use amr_format::WriterOptions;
    use amr_render::{Scene, SceneOptions, TraceMethod};
    use amr_synth::{write_synth, Case, SynthParams};

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("deep.amrk");
    let params = SynthParams::unit_cube(5, 2, 8, 8);
    write_synth(
        &path,
        Case::Sphere,
        &params,
        WriterOptions::default(),
        &NoProgress,
    )
    .unwrap();
    let open = |method| {
        let options = SceneOptions {
            method,
            ..SceneOptions::default()
        };
        let mut scene = Scene::open(&path, &options).unwrap();
        scene.set_isosurfaces(&[IsoSpec::new(0.0)]).unwrap();
        scene
    };
    let (hybrid, sampled) = (open(TraceMethod::Hybrid), open(TraceMethod::Sample));
    let view = View {
        size: (64, 48),
        shadows: false,
        ao_rays: 0,
        camera: Some(amr_render::CameraPlacement {
            pos: [1.3, 0.9, 1.1],
            look_at: Some([0.47, 0.52, 0.5]),
            up: None,
        }),
        ..View::default()
    };
    // Level `l` of the unit cube has 8 * 2^l cells a side: half a cell is 1 / (16 * 2^l).
    let want: Vec<f64> = (0..5).map(|l| 1.0 / (16.0 * f64::from(1 << l))).collect();
    match view.sample_step(sampled.source()).unwrap() {
        SampleStep::PerLevel(steps) => {
            assert_eq!(steps.len(), 5);
            for (s, w) in steps.iter().zip(&want) {
                assert!((s - w).abs() < 1e-12 * w, "{steps:?} against {want:?}");
            }
        }
        other => panic!("a fixed default step {other:?}"),
    }
    let a = amr_render::render(&hybrid, &view, &|_| {}).unwrap().frame;
    let b = amr_render::render(&sampled, &view, &|_| {}).unwrap().frame;
    assert!(
        a.covered() > a.len() / 10,
        "the sphere covers {} pixels",
        a.covered()
    );
    let mut disagree = 0;
    let mut off = Vec::new();
    for i in 0..a.len() {
        match (a.z[i].is_finite(), b.z[i].is_finite()) {
            (true, true) => off.push((a.z[i] - b.z[i]).abs()),
            (x, y) if x != y => disagree += 1,
            _ => {}
        }
    }
    off.sort_by(f32::total_cmp);
    let finest = want[4] as f32;
    assert!(
        disagree <= a.len() / 100,
        "{disagree} pixels hit by one method only"
    );
    assert!(
        off[off.len() / 2] < 1e-3 * finest && off[off.len() * 99 / 100] < 0.1 * finest,
        "depths apart: median {}, 99th percentile {}",
        off[off.len() / 2],
        off[off.len() * 99 / 100]
    );
}
