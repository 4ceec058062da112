//! Run time against error on the `sphere` case, whose true surface is known exactly: the hybrid
//! tracer with the octant, current and nearest reconstructions, each against sample mode on the
//! same reconstruction with steps from one finest cell down to 1/64 of one.
//!
//! Per setting: primary-ray frame time (median of several runs), hit-position error (distance
//! of the hit to the true sphere, in finest-cell widths), tracing error (distance along the ray to
//! the exact hit of the same reconstruction, the hybrid's) and image error of a Lambert-shaded
//! frame against the analytic frame (ray-sphere intersection, exact normals).

use std::fmt::Write as _;
use std::time::Instant;

use amr_render::bvh::BvhBuilder;
use amr_render::camera::Camera;
use amr_render::mapping::open_mapped;
use amr_render::sample_mode::{SampleStep, SampleTracer};
use amr_render::trace::{
    FieldSource, GridFrame, GridRay, HybridTracer, Surface, SurfaceHit, Tracer, VoxelSource,
};
use amr_render::Reconstruction;
use amr_synth::fields::{SPHERE_CENTRE, SPHERE_RADIUS};
use amr_synth::{build_hierarchy, Case, SynthParams};
use rayon::prelude::*;

use super::common::{quantile, write_dataset};
use super::plot::{loglog, Series};
use super::{img_link, Ctx};

/// Light direction (towards the light) for the shaded frames.
const LIGHT: [f64; 3] = [0.41, -0.57, 0.71];

/// A pixel's hit: world position, world normal and ray parameter.
type PixelHit = ([f64; 3], [f64; 3], f64);

/// One traced frame: per pixel the hit (world position, world normal), and the time taken.
struct Frame {
    hits: Vec<Option<PixelHit>>,
    secs: f64,
}

fn trace_frame<T: Tracer + Sync>(t: &T, frame: &GridFrame, cam: &Camera, n: u32) -> Frame {
    let start = Instant::now();
    let hits = (0..n * n)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % n, i / n);
            let (o, d) = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5, n, n);
            let ray = GridRay::from_world(frame, o, d);
            t.next_hit(0, &ray, 0.0, f64::INFINITY)
                .map(|h: SurfaceHit| {
                    let g = [0, 1, 2].map(|a| h.grad[a] / frame.unit[a]);
                    (frame.to_world(h.pos), normalize(g), h.t)
                })
        })
        .collect();
    Frame {
        hits,
        secs: start.elapsed().as_secs_f64(),
    }
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if l > 0.0 {
        v.map(|x| x / l)
    } else {
        [0.0; 3]
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The analytic frame: the first intersection with the true sphere and its normal.
fn analytic(cam: &Camera, n: u32) -> Vec<Option<f64>> {
    let l = normalize(LIGHT);
    (0..n * n)
        .map(|i| {
            let (o, d) = cam.ray(f64::from(i % n) + 0.5, f64::from(i / n) + 0.5, n, n);
            let oc = [0, 1, 2].map(|a| o[a] - SPHERE_CENTRE[a]);
            let b = dot(oc, d);
            let c = dot(oc, oc) - SPHERE_RADIUS * SPHERE_RADIUS;
            let disc = b * b - c;
            (disc >= 0.0).then(|| {
                let t = -b - disc.sqrt();
                let p = [0, 1, 2].map(|a| o[a] + t * d[a] - SPHERE_CENTRE[a]);
                dot(normalize(p), l).max(0.0)
            })
        })
        .collect()
}

/// A row of the table.
struct Row {
    label: String,
    runs: usize,
    secs: f64,
    hit_med: f64,
    hit_p99: f64,
    hit_max: f64,
    trace_max: f64,
    image_rms: f64,
    hits: usize,
}

/// Runs the section.
pub fn run(ctx: &Ctx) -> anyhow::Result<String> {
    let quick = ctx.cfg.quick;
    // The reconstruction section's levels and sizes, with bricks of 16.
    let p = SynthParams {
        brick: 16,
        ..super::recon::params(quick)
    };
    let path = ctx.scratch.join("sphere.amrk");
    let field = Case::Sphere;
    write_dataset(&path, build_hierarchy(&field, "sphere", &p)?, &field)?;
    let file = open_mapped(&path)?;
    let nlev = file.levels().len() as u32;
    let finest = 1.0 / p.cells_per_axis(nlev - 1).unwrap_or(1) as f64;
    let n: u32 = if quick { 32 } else { 96 };
    let steps: Vec<u32> = if quick {
        vec![1, 4, 16]
    } else {
        vec![1, 2, 4, 8, 16, 32, 64]
    };
    // The camera frames the sphere tightly, so nearly every ray hits it.
    let cam = Camera::new(
        [
            SPHERE_CENTRE[0] + 0.62,
            SPHERE_CENTRE[1] - 0.85,
            SPHERE_CENTRE[2] + 0.5,
        ],
        SPHERE_CENTRE,
        [0.0, 0.0, 1.0],
        36.0,
    )?;
    let reference = analytic(&cam, n);

    let runs_fast = if quick { 3 } else { 7 };
    let ctx_run = RunCtx {
        cam: &cam,
        n,
        steps: &steps,
        quick,
        runs_fast,
        reference: &reference,
        finest,
    };
    let recons = measure_all(&file, &ctx_run)?;
    let rows: Vec<&Row> = recons.iter().flat_map(|r| r.rows.iter()).collect();

    let png = "tradeoff.png";
    let png_image = "tradeoff-image.png";
    // Per reconstruction, the hybrid's point and the sample-mode line of one error measure
    // against frame time (ms).
    let series_of = |error: fn(&Row) -> f64| -> Vec<Series> {
        let point = |x: &Row| (x.secs * 1e3, error(x));
        recons
            .iter()
            .flat_map(|r| {
                let finest_step = steps[steps.len() - 1];
                [
                    Series {
                        label: format!("hybrid ({})", r.name),
                        points: vec![point(&r.rows[0])],
                    },
                    Series {
                        label: format!("sample mode ({}), step 1..1/{finest_step}", r.name),
                        points: r.rows[1..].iter().map(point).collect(),
                    },
                ]
            })
            .collect()
    };
    let hit_series = series_of(|x| x.hit_p99);
    let image_series = series_of(|x| x.image_rms);
    loglog(
        &ctx.img.join(png),
        &format!("sphere, {n}x{n} primary rays: p99 hit error against frame time"),
        "frame time (ms, median)",
        "hit error p99 (finest cells)",
        &hit_series,
    )?;
    loglog(
        &ctx.img.join(png_image),
        &format!("sphere, {n}x{n} primary rays: image error against frame time"),
        "frame time (ms, median)",
        "image RMS error (shade units)",
        &image_series,
    )?;

    let mut s = String::new();
    writeln!(s, "## Run time against error\n")?;
    s.push_str(&ctx.provenance());
    writeln!(
        s,
        "\nDataset: the `sphere` case, {nlev} levels, base {}, ratio 2, bricks of 16, refined \
         around the surface ({} cells; finest cell {finest:.3e}). {n}x{n} primary rays from a \
         camera framing the sphere; threads: {}. Each reconstruction is traced by its hybrid \
         (active voxels, BVH, exact ray-voxel intersection) and by sample mode, which marches the \
         same reconstruction with the given step (in finest cells) and bisects the first sign \
         change. Hybrid voxels: *octant*, the crack-free octants and merged dual cells; \
         *current*, the level dual cells clipped to each kd-tree leaf (trilinear, cubic \
         intersection; the field jumps at level boundaries, so the surface has cracks there); \
         *nearest*, the cell faces between a cell below and one at or above the isovalue \
         (`docs/rendering.md`). Extraction and BVH build are not in the frame time: {}. \
         Normals: central differences of the reconstruction for octant and current (the \
         renderer's default) and for every sample-mode row, face normals for the nearest hybrid. \
         *Hit error*: distance from the hit to the true sphere in finest-cell widths, over the \
         pixels that hit. *Trace error*: largest distance along the ray from the hybrid's hit of \
         the same reconstruction, finest cells; a pixel that hits in one and not the other is not \
         counted here but is in the image error. *Image error*: RMS over pixels of the Lambert \
         shade against the analytic frame (ray-sphere intersection, exact normals; a pixel that \
         hits in only one counts 1). Where sample mode hits fewer pixels than the hybrid (the \
         *hits* column: a coarse step skips thin parts of the surface), its hit-error quantiles \
         are over fewer, easier pixels. Sample mode's normals are central differences half a \
         step apart: on the piecewise-constant nearest field a coarse step smooths the faces' \
         normals, so its image error there is lower than with the faces' own normals and rises \
         toward the hybrid's as the step shrinks.\n",
        p.base,
        super::common::total_cells(&file),
        rayon::current_num_threads(),
        build_costs(&recons)
    )?;
    table_rows(&mut s, &rows)?;
    writeln!(
        s,
        "\nGoal (hybrid reaches lower error than the best sample setting in at least ten times \
         less time), per reconstruction, against sample mode on the same reconstruction:\n"
    )?;
    for r in &recons {
        writeln!(s, "- {}", goal_line(r))?;
    }
    let octant_hybrid = &recons[0].rows[0];
    let all_samples: Vec<&Row> = recons.iter().flat_map(|r| r.rows[1..].iter()).collect();
    let best_any = all_samples
        .iter()
        .min_by(|a, b| a.hit_p99.total_cmp(&b.hit_p99))
        .expect("steps");
    writeln!(
        s,
        "- Across reconstructions, the lowest p99 hit error of any sample setting is `{}` \
         ({:.4}, {:.1} ms); the octant hybrid has {:.4} in {:.2} ms ({:.1}x less time).\n",
        best_any.label,
        best_any.hit_p99,
        best_any.secs * 1e3,
        octant_hybrid.hit_p99,
        octant_hybrid.secs * 1e3,
        best_any.secs / octant_hybrid.secs
    )?;
    writeln!(s, "![p99 hit error against time]({})\n", img_link(ctx, png))?;
    writeln!(
        s,
        "![image error against time]({})\n",
        img_link(ctx, png_image)
    )?;

    // The same camera on the partially refined sphere of the reconstruction section, where the
    // surface crosses level boundaries: octant and current differ there.
    let pp = super::recon::params(quick);
    let ppath = ctx.scratch.join("tradeoff-partial.amrk");
    super::recon::write_partial_sphere(&ppath, &pp)?;
    let pfile = open_mapped(&ppath)?;
    let plev = pfile.levels().len() as u32;
    let psteps: Vec<u32> = if quick { vec![1] } else { vec![1, 4] };
    let pctx = RunCtx {
        steps: &psteps,
        finest: 1.0 / pp.cells_per_axis(plev - 1).unwrap_or(1) as f64,
        ..ctx_run
    };
    let partial = measure_all(&pfile, &pctx)?;
    writeln!(s, "### Across level boundaries\n")?;
    writeln!(
        s,
        "The same camera and measures on the partially refined sphere of the reconstruction \
         section ({} levels, base {}, bricks of 8, a seeded third of the candidate bricks left \
         unrefined, {} cells), so the surface crosses level boundaries; sample mode at steps \
         {} (finest cells) only. Not in the plots. Extraction and BVH build: {}.\n",
        plev,
        pp.base,
        super::common::total_cells(&pfile),
        psteps
            .iter()
            .map(|k| format!("1/{k}"))
            .collect::<Vec<_>>()
            .join(", "),
        build_costs(&partial)
    )?;
    let prow: Vec<&Row> = partial.iter().flat_map(|r| r.rows.iter()).collect();
    table_rows(&mut s, &prow)?;
    writeln!(s)?;
    Ok(s)
}

/// Extraction, BVH build and voxel count per reconstruction, for the text.
fn build_costs(recons: &[Recon]) -> String {
    recons
        .iter()
        .map(|r| {
            format!(
                "{} {} voxels, {:.1} ms + {:.1} ms",
                r.name,
                r.active,
                r.t_extract * 1e3,
                r.t_bvh * 1e3
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// The results table.
fn table_rows(s: &mut String, rows: &[&Row]) -> anyhow::Result<()> {
    writeln!(
        s,
        "| tracer | runs | frame ms (median) | hits | hit err median | hit err p99 | hit err max | trace err max | image RMS |"
    )?;
    writeln!(s, "|---|---|---|---|---|---|---|---|---|")?;
    for r in rows {
        writeln!(
            s,
            "| {} | {} | {:.2} | {} | {:.4} | {:.4} | {:.4} | {:.2e} | {:.4} |",
            r.label,
            r.runs,
            r.secs * 1e3,
            r.hits,
            r.hit_med,
            r.hit_p99,
            r.hit_max,
            r.trace_max,
            r.image_rms
        )?;
    }
    Ok(())
}

/// The hybrid and sample mode of the octant, current and nearest reconstructions, one
/// [`FieldSource`] each, in that order. Normals: continuous across voxels (the renderer's
/// default) for the octant and current hybrids; face normals for nearest, whose field is
/// piecewise constant (as `render` does).
fn measure_all<D: AsRef<[u8]> + Sync>(
    file: &amr_format::AmrkFile<D>,
    c: &RunCtx<'_>,
) -> anyhow::Result<Vec<Recon>> {
    let mut recons = Vec::new();
    for r in [
        Reconstruction::Octant,
        Reconstruction::Current,
        Reconstruction::Nearest,
    ] {
        let src = FieldSource::new(file, 0, r)?;
        recons.push(measure(&src, r != Reconstruction::Nearest, c)?);
    }
    Ok(recons)
}

/// One reconstruction's hybrid row, then its sample-mode rows, and what building the hybrid cost.
struct Recon {
    name: &'static str,
    rows: Vec<Row>,
    active: usize,
    t_extract: f64,
    t_bvh: f64,
}

/// What every reconstruction is measured with.
#[derive(Clone, Copy)]
struct RunCtx<'a> {
    cam: &'a Camera,
    n: u32,
    steps: &'a [u32],
    quick: bool,
    runs_fast: usize,
    reference: &'a [Option<f64>],
    finest: f64,
}

/// The hybrid and the sample settings of one reconstruction.
fn measure<D: AsRef<[u8]> + Sync>(
    src: &FieldSource<'_, D>,
    smooth_normals: bool,
    c: &RunCtx<'_>,
) -> anyhow::Result<Recon> {
    let name = src.reconstruction().name();
    let frame = src.frame();
    let t = Instant::now();
    let refs = src.extract(0.0)?.refs;
    let t_extract = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut b = BvhBuilder::new();
    let surf = [Surface::build(src, 0.0, &refs, &mut b)];
    let t_bvh = t.elapsed().as_secs_f64();
    let hybrid = HybridTracer {
        src,
        surfaces: &surf,
        sources: &[],
        smooth_normals,
    };
    let mut last: Option<Frame> = None;
    let mut times = Vec::new();
    for _ in 0..c.runs_fast {
        let f = trace_frame(&hybrid, &frame, c.cam, c.n);
        times.push(f.secs);
        last = Some(f);
    }
    let exact = last.expect("at least one run");
    let mut rows = vec![row(
        &format!("hybrid ({name})"),
        &exact,
        &mut times,
        &exact,
        c.reference,
        c.finest,
    )];
    for &k in c.steps {
        let step = c.finest / f64::from(k);
        let tracer = SampleTracer {
            src,
            sources: &[],
            isos: vec![0.0],
            step: SampleStep::Fixed(step),
        };
        // Fine steps are slow: fewer runs for them.
        let runs = if c.quick {
            1
        } else if k <= 8 {
            5
        } else if k <= 16 {
            3
        } else {
            1
        };
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..runs {
            let f = trace_frame(&tracer, &frame, c.cam, c.n);
            times.push(f.secs);
            last = Some(f);
        }
        let f = last.expect("at least one run");
        rows.push(row(
            &format!("sample ({name}), step 1/{k}"),
            &f,
            &mut times,
            &exact,
            c.reference,
            c.finest,
        ));
    }
    Ok(Recon {
        name,
        rows,
        active: refs.len(),
        t_extract,
        t_bvh,
    })
}

/// The goal's verdict for one reconstruction.
fn goal_line(r: &Recon) -> String {
    let h = &r.rows[0];
    let samples = &r.rows[1..];
    let best = samples
        .iter()
        .min_by(|a, b| a.hit_p99.total_cmp(&b.hit_p99))
        .expect("steps");
    let better: Vec<&str> = samples
        .iter()
        .filter(|x| x.hit_p99 <= h.hit_p99 && x.image_rms <= h.image_rms)
        .map(|x| x.label.as_str())
        .collect();
    format!(
        "{}: the best sample setting by p99 hit error is `{}` ({:.4} finest cells, image RMS \
         {:.4}, {:.1} ms); the hybrid has {:.4} and {:.4} in {:.2} ms, {:.1}x less time. Goal {}. \
         Sample settings at least as accurate as the hybrid on both measures: {}.",
        r.name,
        best.label,
        best.hit_p99,
        best.image_rms,
        best.secs * 1e3,
        h.hit_p99,
        h.image_rms,
        h.secs * 1e3,
        best.secs / h.secs,
        if h.hit_p99 <= best.hit_p99 && best.secs >= 10.0 * h.secs {
            "met"
        } else {
            "NOT met"
        },
        if better.is_empty() {
            "none".to_owned()
        } else {
            better.join(", ")
        }
    )
}

fn row(
    label: &str,
    f: &Frame,
    times: &mut [f64],
    exact: &Frame,
    reference: &[Option<f64>],
    finest: f64,
) -> Row {
    let l = normalize(LIGHT);
    let mut hit_err = Vec::new();
    let mut trace_max = 0.0f64;
    let mut sq = 0.0;
    for (i, h) in f.hits.iter().enumerate() {
        if let Some((x, nrm, t)) = h {
            let r = (0..3)
                .map(|a| (x[a] - SPHERE_CENTRE[a]).powi(2))
                .sum::<f64>()
                .sqrt();
            hit_err.push((r - SPHERE_RADIUS).abs() / finest);
            if let Some((_, _, te)) = exact.hits[i] {
                trace_max = trace_max.max((t - te).abs() / finest);
            }
            let shade = dot(*nrm, l).max(0.0);
            sq += match reference[i] {
                Some(r) => (shade - r).powi(2),
                None => 1.0,
            };
        } else if reference[i].is_some() {
            sq += 1.0;
        }
    }
    let hits = hit_err.len();
    Row {
        label: label.to_owned(),
        runs: times.len(),
        secs: quantile(times, 0.5),
        hit_med: quantile(&mut hit_err, 0.5),
        hit_p99: quantile(&mut hit_err, 0.99),
        hit_max: hit_err.iter().copied().fold(0.0, f64::max),
        trace_max,
        image_rms: (sq / reference.len() as f64).sqrt(),
        hits,
    }
}
