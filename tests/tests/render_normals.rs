//! Smooth normals through the file pipeline: along a fine sweep of rays across a sphere whose
//! surface crosses voxel faces and a level boundary, the octant method's smooth normals turn
//! steadily within a level (where the voxels' own trilinear gradients jump by degrees at
//! faces) and as steadily where the level changes, and stay within a degree of the sphere's
//! normal. The normals read from blocks of cell values inside one level
//! (`VoxelSource::level_gradient`) are compared ray by ray with the six point samples they
//! replace, which the sweep also traces (also where the block gives only some components and
//! the others are sampled, and near the level boundary, where both take the same blend of two
//! levels' differences), also on a ratio-3 file whose kd-tree leaves cut coarse cells; the
//! blend's weights from a thread's memo equal the kd-tree walk's; and frames with smooth
//! normals are the same on 1, 2 and 3 threads.

use amr_format::AmrkFile;
use amr_render::bvh::BvhBuilder;
use amr_render::reconstruct::level_blend::{LevelWeights, NearLevels};
use amr_render::shade::IsoSpec;
use amr_render::trace::octant::VoxelHit;
use amr_render::trace::{
    FieldSource, GridFrame, GridRay, HybridTracer, Surface, Tracer, Voxel, VoxelSource,
};
use amr_render::{render, CameraPlacement, Reconstruction, Scene, SceneOptions, View};
use amr_synth::{AnalyticField, Case};

use crate::support::half_refined::write_half_refined_sphere;
use crate::support::render::{frame_bits, on_threads};

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

/// A source tracing like `S` whose smooth normals always take six point samples per level
/// weighed (the trait's default `level_gradient`, with `S`'s blend weights), never the blocks
/// of cell values.
struct Sampled<'a, S>(&'a S);

impl<S: VoxelSource> VoxelSource for Sampled<'_, S> {
    fn frame(&self) -> GridFrame {
        self.0.frame()
    }
    fn voxel(&self, r: u64) -> Voxel {
        self.0.voxel(r)
    }
    fn sample(&self, p: [f64; 3]) -> Option<(f32, u32)> {
        self.0.sample(p)
    }
    fn gradient(&self, p: [f64; 3], h: [f64; 3]) -> Option<[f64; 3]> {
        self.0.gradient(p, h)
    }
    fn cell_size(&self, level: u32) -> Option<[f64; 3]> {
        self.0.cell_size(level)
    }
    fn level_weights(&self, p: [f64; 3], level: u32) -> LevelWeights {
        self.0.level_weights(p, level)
    }
    fn intersect(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
    ) -> Option<VoxelHit> {
        self.0.intersect(voxel, iso, ray, tmin, tmax)
    }
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
    /// The largest angle between a ray's normal and the six-sample normal at the same hit.
    max_to_sampled: f64,
    /// Hits whose level's block of cell values gives the gradient (`Sampler::level_gradient`).
    from_blocks: usize,
    /// Hits where the block gives some components but not all
    /// (`Sampler::level_gradient_axes`): the others are sampled.
    from_some_axes: usize,
}

/// Which normals a sweep takes.
#[derive(Clone, Copy, PartialEq)]
enum Normals {
    /// Each voxel's own trilinear gradient.
    Flat,
    /// The source's smooth normals.
    Smooth,
    /// Smooth normals from six point samples at every hit.
    Sampled,
}

fn sweep(path: &std::path::Path, reconstruction: Reconstruction, kind: Normals) -> Sweep {
    let file = AmrkFile::open(std::fs::read(path).unwrap()).unwrap();
    let src = FieldSource::new(&file, 0, reconstruction).unwrap();
    let iso = Case::Sphere.default_iso() as f32;
    let refs = src.extract(iso).unwrap().refs;
    let surfaces = [Surface::build(&src, iso, &refs, &mut BvhBuilder::new())];
    let sampled = Sampled(&src);
    let tracer = HybridTracer {
        src: &src,
        surfaces: &surfaces,
        sources: &[],
        smooth_normals: kind == Normals::Smooth,
    };
    let reference = HybridTracer {
        src: &sampled,
        surfaces: &surfaces,
        sources: &[],
        smooth_normals: true,
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
    let mut max_to_sampled = 0f64;
    let mut from_blocks = 0;
    let mut from_some_axes = 0;
    for i in 0..n {
        let th = from + (to - from) * i as f64 / (n - 1) as f64;
        let d = [th.cos(), th.sin() * tilt.cos(), th.sin() * tilt.sin()];
        let ray = GridRay::from_world(&frame, CENTRE, d);
        let trace = |t: &dyn Tracer| {
            t.next_hit(0, &ray, 0.0, f64::INFINITY)
                .expect("every ray from inside hits the sphere")
        };
        let world = |grad: [f64; 3]| unit([0, 1, 2].map(|a| grad[a] / frame.unit[a]));
        let sampled_hit = trace(&reference);
        let hit = match kind {
            Normals::Sampled => sampled_hit,
            _ => trace(&tracer),
        };
        let g = world(hit.grad);
        assert_eq!(hit.pos, sampled_hit.pos, "the normals change no hit");
        max_to_sampled = max_to_sampled.max(angle(g, world(sampled_hit.grad)));
        let block = src.sampler().level_gradient(hit.pos, hit.level).unwrap();
        from_blocks += usize::from(block.is_some());
        let by_axis = src
            .sampler()
            .level_gradient_axes(hit.pos, hit.level)
            .unwrap();
        let given = by_axis.iter().filter(|g| g.is_some()).count();
        from_some_axes += usize::from(given > 0 && given < 3);
        match block {
            Some(g) => assert_eq!(by_axis, g.map(Some), "the block's components, axis by axis"),
            None => assert!(given < 3, "a component the whole block lacks"),
        }
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
        max_to_sampled,
        from_blocks,
        from_some_axes,
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
    let flat = sweep(&path, Reconstruction::Octant, Normals::Flat);
    let smooth = sweep(&path, Reconstruction::Octant, Normals::Smooth);
    let sampled = sweep(&path, Reconstruction::Octant, Normals::Sampled);
    eprintln!("octant, flat normals: {flat:?}");
    eprintln!("octant, smooth normals: {smooth:?}");
    eprintln!("octant, smooth normals from six samples: {sampled:?}");
    // Inside one level the blocks give the samples' normal up to rounding, and most hits are
    // inside one level.
    assert!(
        smooth.from_blocks > 1500 && smooth.max_to_sampled < 1e-3,
        "block normals differ from the sampled ones: {smooth:?}"
    );
    // Next to the level boundary, some hits take some components from the block and sample
    // the others; the comparison above covers them too.
    assert!(
        smooth.from_some_axes > 10,
        "no hit takes part of its gradient from a block: {smooth:?}"
    );
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
    // Where the level, and with it the step, changes, the two levels' differences are
    // blended (`level_blend`): the normals turn there as steadily as within a level (without
    // the blend they jumped by 0.21 degrees, 27 times the sweep's step).
    assert!(
        smooth.max_step_across_levels < 0.02,
        "smooth normals jump at the level boundary: {smooth:?} {flat:?}"
    );
    assert!(
        smooth.max_error < 1.0,
        "smooth normals are {} degrees off the sphere's",
        smooth.max_error
    );

    // `current` is discontinuous at level boundaries by construction (its surface cracks
    // there); its smooth normals are still closer to the sphere's than its voxels' gradients.
    let flat = sweep(&path, Reconstruction::Current, Normals::Flat);
    let smooth = sweep(&path, Reconstruction::Current, Normals::Smooth);
    let sampled = sweep(&path, Reconstruction::Current, Normals::Sampled);
    eprintln!("current, flat normals: {flat:?}");
    eprintln!("current, smooth normals: {smooth:?}");
    eprintln!("current, smooth normals from six samples: {sampled:?}");
    assert!(
        smooth.from_blocks > 1500 && smooth.max_to_sampled < 1e-3,
        "current: block normals differ from the sampled ones: {smooth:?}"
    );
    assert!(
        smooth.max_error < flat.max_error,
        "current: {smooth:?} {flat:?}"
    );
}

/// With refinement ratio 3, where kd-tree leaf faces cut coarse cells, the blocks still give
/// the six samples' normals.
#[test]
fn block_normals_equal_the_sampled_ones_at_ratio_3() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere3.amrk");
    write_half_refined_sphere(&path, 2, 3, 12);
    for reconstruction in [Reconstruction::Octant, Reconstruction::Current] {
        let smooth = sweep(&path, reconstruction, Normals::Smooth);
        eprintln!("{reconstruction}, ratio 3, smooth normals: {smooth:?}");
        assert!(
            smooth.from_blocks > 1000 && smooth.max_to_sampled < 1e-3,
            "{reconstruction}, ratio 3: {smooth:?}"
        );
    }
}

/// The bits of the colour and normals of a frame of `path` with `reconstruction`, rendered on
/// `threads` threads.
fn smooth_frame_bits(
    path: &std::path::Path,
    reconstruction: Reconstruction,
    threads: usize,
) -> Vec<u32> {
    on_threads(threads, || {
        let options = SceneOptions {
            reconstruction,
            ..SceneOptions::default()
        };
        let mut scene = Scene::open(path, &options).unwrap();
        let iso = Case::Sphere.default_iso();
        scene.set_isosurfaces(&[IsoSpec::new(iso as f32)]).unwrap();
        let view = View {
            camera: Some(CameraPlacement {
                pos: [1.6, 1.3, 1.1],
                look_at: Some(CENTRE),
                up: None,
            }),
            size: (96, 72),
            ao_rays: 1,
            ..View::default()
        };
        let f = render(&scene, &view, &|_| {}).unwrap().frame;
        assert!(f.covered() > 1000, "the sphere fills the frame");
        frame_bits(&f)
    })
}

/// The per-thread memo of cell blocks holds values that depend on the block alone, so a frame
/// does not depend on which thread met a block first.
#[test]
fn smooth_normals_are_the_same_on_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.amrk");
    write_half_refined_sphere(&path, 3, 2, 16);
    for reconstruction in [Reconstruction::Octant, Reconstruction::Current] {
        let one = smooth_frame_bits(&path, reconstruction, 1);
        for threads in [2, 3] {
            assert!(
                smooth_frame_bits(&path, reconstruction, threads) == one,
                "{reconstruction}: other pixels on {threads} threads"
            );
        }
    }
}

/// The blend weights a thread takes from its memo of other-level leaves around dual cells are
/// those of the kd-tree walk at each point, on files whose levels meet at ratio 2 and at ratio
/// 3 (where leaf faces cut coarse cells), along a random walk that revisits dual cells and
/// crosses level boundaries.
#[test]
fn blend_weights_from_the_memo_equal_the_walked_ones() {
    let dir = tempfile::tempdir().unwrap();
    for (name, levels, ratio, base) in [("r2.amrk", 3, 2, 16), ("r3.amrk", 2, 3, 12)] {
        let path = dir.path().join(name);
        write_half_refined_sphere(&path, levels, ratio, base);
        let file = AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
        let src = FieldSource::new(&file, 0, Reconstruction::Octant).unwrap();
        let sampler = src.sampler();
        let extent = src.frame().extent;
        let mut memo = NearLevels::default();
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut blended, mut p) = (0, [0.5 * extent[0], 0.5 * extent[1], 0.5 * extent[2]]);
        for i in 0..60_000 {
            if i % 500 == 0 {
                p = [0, 1, 2].map(|a| next() * extent[a]);
            } else {
                p = [0, 1, 2].map(|a| (p[a] + (next() - 0.5) * 0.6).clamp(0.0, extent[a]));
            }
            let Some((_, level)) = src.sample(p) else {
                continue;
            };
            let walked = sampler.level_weights(p, level);
            let memoized = sampler.level_weights_near(p, level, &mut memo);
            assert_eq!(
                memoized, walked,
                "{name}: weights at {p:?} on level {level}"
            );
            blended += usize::from(walked.single().is_none());
        }
        eprintln!("{name}: {blended} of 60000 points blend two levels");
        assert!(
            blended > 200,
            "{name}: the walk should cross level boundaries"
        );
    }
}
