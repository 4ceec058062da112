//! Reconstruction error against the analytic field on partially refined data, near and away from
//! level boundaries, and rays leaking through a closed surface, for every reconstruction.
//!
//! The dataset is the `sphere` case (a signed distance, so a value error is a distance error),
//! refined around the surface except on a seeded third of the candidate bricks, so that the
//! surface crosses level boundaries.

use std::fmt::Write as _;
use std::time::Instant;

use amr_synth::fields::{SPHERE_CENTRE, SPHERE_RADIUS};
use amr_synth::{build_hierarchy_by, near_surface, AnalyticField, Case, SynthParams};
use rayon::prelude::*;

use amr_render::bvh::BvhBuilder;
use amr_render::mapping::open_mapped;
use amr_render::reconstruct::Sampler;
use amr_render::sample_mode::{SampleStep, SampleTracer};
use amr_render::trace::{
    FieldSource, GridFrame, GridRay, HybridTracer, Surface, Tracer, VoxelSource,
};
use amr_render::Reconstruction;

use super::common::{hash2, rms, write_dataset, Rng, SampledSource};
use super::Ctx;

/// Seed of the refinement pattern, points and directions.
const SEED: u64 = 0x5EC7_1011;

/// The partially refined sphere dataset's parameters for this run.
pub fn params(quick: bool) -> SynthParams {
    SynthParams {
        levels: 3,
        ratio: 2,
        base: if quick { 16 } else { 32 },
        brick: 8,
        origin: [0.0; 3],
        size: 1.0,
    }
}

/// Writes the partially refined sphere to `path`.
pub fn write_partial_sphere(path: &std::path::Path, p: &SynthParams) -> anyhow::Result<()> {
    let field = Case::Sphere;
    let spec = build_hierarchy_by(p, vec!["sphere".into()], |b| {
        let key =
            (b.cells.lo[0] as u64) << 42 ^ (b.cells.lo[1] as u64) << 21 ^ b.cells.lo[2] as u64;
        near_surface(&field, 0.0, b) && !hash2(SEED + u64::from(b.level), key).is_multiple_of(3)
    })?;
    write_dataset(path, spec, &field)
}

struct ErrStats {
    near: Vec<f64>,
    away: Vec<f64>,
}

/// Runs the section.
pub fn run(ctx: &Ctx) -> anyhow::Result<String> {
    let quick = ctx.cfg.quick;
    let p = params(quick);
    let path = ctx.scratch.join("partial-sphere.amrk");
    write_partial_sphere(&path, &p)?;
    let file = open_mapped(&path)?;
    let levels = file.levels().len();
    let finest_cell = 1.0 / p.cells_per_axis(levels as u32 - 1).unwrap_or(1) as f64;
    let sampler = Sampler::new(&file, 0, 64 << 20)?;
    let frame = GridFrame::of_grid(sampler.grid());
    let npoints: usize = if quick { 40_000 } else { 1_000_000 };

    // Points uniform in a shell of +-3 coarse cells around the sphere, where refinement and level
    // boundaries are; a point is "near" a level boundary when a probe one cell of its own level
    // away along some axis lands on another level.
    let coarse = 1.0 / f64::from(p.base);
    let pts: Vec<([f64; 3], bool)> = (0..npoints)
        .into_par_iter()
        .map(|i| {
            let mut r = Rng::new(SEED ^ (i as u64).wrapping_mul(0x1000_0001));
            let d = r.unit_vector();
            let rad = SPHERE_RADIUS + r.range(-3.0, 3.0) * coarse;
            let x = [0, 1, 2].map(|a| SPHERE_CENTRE[a] + rad * d[a]);
            let g = frame.to_grid(x);
            let level = |q: [f64; 3]| -> Option<u32> {
                let ext = sampler.grid().extent();
                let f = [0, 1, 2].map(|a| ((q[a] * 0.5).floor() as i64).clamp(0, ext[a] - 1));
                sampler.locate(f).ok().flatten().map(|c| c.level)
            };
            let own = level(g).unwrap_or(0);
            let s = sampler.grid().scale(own);
            let near = (0..3).any(|a| {
                [-1.0, 1.0].iter().any(|&sg| {
                    let mut q = g;
                    q[a] += sg * 2.0 * s[a] as f64;
                    level(q).is_some_and(|l| l != own)
                })
            });
            (g, near)
        })
        .collect();
    let field = Case::Sphere;
    let mut rows = Vec::new();
    for m in Reconstruction::ALL {
        let errs: Vec<(f64, bool)> = pts
            .par_iter()
            .filter_map(|&(g, near)| {
                let v = sampler.sample(g, m).ok().flatten()?;
                let truth = field.value(frame.to_world(g));
                Some(((f64::from(v) - truth).abs() / finest_cell, near))
            })
            .collect();
        let st = ErrStats {
            near: errs.iter().filter(|e| e.1).map(|e| e.0).collect(),
            away: errs.iter().filter(|e| !e.1).map(|e| e.0).collect(),
        };
        rows.push((m, st));
    }

    // Leaks: rays from the sphere's centre, which is inside the closed surface value 0.
    let nrays: usize = if quick { 20_000 } else { 1_000_000 };
    let nrays_sample: usize = if quick { 5_000 } else { 100_000 };
    let centre = frame.to_grid(SPHERE_CENTRE);
    let dirs = |n: usize| -> Vec<[f64; 3]> {
        let mut r = Rng::new(SEED ^ 0xD1);
        (0..n).map(|_| r.unit_vector()).collect()
    };
    let mut leaks = Vec::new();
    let d = dirs(nrays);
    for m in [
        Reconstruction::Octant,
        Reconstruction::Current,
        Reconstruction::Nearest,
    ] {
        let src = FieldSource::new(&file, 0, m)?;
        leaks.push(hybrid_leaks(&src, centre, &d)?);
    }
    for m in Reconstruction::ALL {
        let src = SampledSource::new(Sampler::new(&file, 0, 64 << 20)?, m);
        let step = 0.25 * 2.0; // a quarter of a finest cell, in grid units
        let tracer = SampleTracer {
            src: &src,
            sources: &[],
            isos: vec![0.0],
            step: SampleStep::Fixed(step * frame.unit[0]),
        };
        let d = dirs(nrays_sample);
        let t = Instant::now();
        let miss = count_misses(&tracer, &src, centre, &d);
        leaks.push((
            "sample, step 1/4 finest cell",
            m,
            nrays_sample,
            miss,
            t.elapsed().as_secs_f64(),
        ));
    }

    let mut s = String::new();
    writeln!(
        s,
        "## Reconstruction error and leaks on partially refined data\n"
    )?;
    s.push_str(&ctx.provenance());
    writeln!(
        s,
        "\nDataset: the `sphere` case (signed distance, radius {SPHERE_RADIUS}) with {levels} \
         levels, base {}, ratio 2, bricks of 8, refined around the surface except on a seeded \
         third of the candidate bricks, so the surface crosses level boundaries ({} cells). \
         Errors are |reconstruction - analytic| in finest-cell widths at {npoints} seeded points \
         uniform in a shell of +-3 coarse cells around the surface; a point is *near* a level \
         boundary when a probe one of its own cells away along an axis lands on another level.\n",
        p.base,
        super::common::total_cells(&file)
    )?;
    writeln!(
        s,
        "| method | points near | max near | RMS near | points away | max away | RMS away |"
    )?;
    writeln!(s, "|---|---|---|---|---|---|---|")?;
    for (m, st) in &rows {
        let mx = |v: &[f64]| v.iter().copied().fold(0.0f64, f64::max);
        writeln!(
            s,
            "| {} | {} | {:.4} | {:.4} | {} | {:.4} | {:.4} |",
            m.name(),
            st.near.len(),
            mx(&st.near),
            rms(&st.near),
            st.away.len(),
            mx(&st.away),
            rms(&st.away)
        )?;
    }
    writeln!(
        s,
        "\nLeaks: rays cast from the sphere's centre (inside the closed surface) in seeded uniform \
         directions; a leak is a ray that leaves the domain without a hit. Each is traced: the \
         hybrid (active voxels, BVH, exact intersection) for `octant`, `current` (level dual \
         cells clipped to each kd-tree leaf) and `nearest` (cell faces), and sample mode for all \
         four. The `current` field jumps where levels meet, so its isosurface has cracks along \
         the level boundaries it crosses: a hybrid ray through a crack finds no voxel crossing \
         and leaks, which is what its count measures (the surface's holes, not a tracing \
         fault). Sample mode cannot leak on this test: a ray from inside to outside always \
         sees a change of sign, at a jump if not at a surface, and reports a hit there. \
         `finest` has no hybrid here.\n"
    )?;
    writeln!(s, "| tracer | method | rays | leaks | seconds |")?;
    writeln!(s, "|---|---|---|---|---|")?;
    for (tr, m, n, miss, secs) in &leaks {
        writeln!(s, "| {tr} | {} | {n} | {miss} | {secs:.2} |", m.name())?;
    }
    Ok(s)
}

/// Traces `dirs` from `centre` with the hybrid over `src`'s voxels for isovalue 0: the leaks row.
fn hybrid_leaks<D: AsRef<[u8]> + Sync>(
    src: &FieldSource<'_, D>,
    centre: [f64; 3],
    dirs: &[[f64; 3]],
) -> anyhow::Result<(&'static str, Reconstruction, usize, usize, f64)> {
    let refs = src.extract(0.0)?.refs;
    let mut b = BvhBuilder::new();
    let surf = [Surface::build(src, 0.0, &refs, &mut b)];
    let tracer = HybridTracer {
        src,
        surfaces: &surf,
        sources: &[],
        smooth_normals: false,
    };
    let t = Instant::now();
    let miss = count_misses(&tracer, src, centre, dirs);
    Ok((
        "hybrid",
        src.reconstruction(),
        dirs.len(),
        miss,
        t.elapsed().as_secs_f64(),
    ))
}

fn count_misses<T: Tracer + Sync, S: VoxelSource + ?Sized>(
    tracer: &T,
    src: &S,
    origin_grid: [f64; 3],
    dirs: &[[f64; 3]],
) -> usize {
    let frame = src.frame();
    let origin = frame.to_world(origin_grid);
    dirs.par_iter()
        .filter(|d| {
            let ray = GridRay::from_world(&frame, origin, **d);
            tracer.next_hit(0, &ray, 0.0, f64::INFINITY).is_none()
        })
        .count()
}
