//! One MPI rank's run of the render command: set-up on every rank, the mode's frame, and on
//! rank 0 the EXR, the preview and the statistics of every rank.

use std::time::Instant;

use ::mpi::collective::SystemOperation;
use ::mpi::topology::SimpleCommunicator;
use ::mpi::traits::*;
use ::mpi::Threading;
use anyhow::{anyhow, bail};

use super::stats::{cpu_seconds, table, RankStats};
use super::{partitioned, replicated, MpiMode};
use crate::mapping::open_mapped;
use crate::render_cmd::{
    build_surfaces, header_meta, peak_rss_bytes, progress_bar, sample_step, scene_setup,
    stats_rows, write_outputs, ActiveSource, Method, RenderArgs, RenderConfig, RenderReport,
};
use crate::sample_mode::SampleTracer;
use crate::shade::RenderSettings;
use crate::trace::amr_source::{resolve_field, AmrSource};
use crate::trace::{HybridTracer, VoxelSource};

/// Renders the file named in `args` with every rank of `mpirun`; rank 0 writes the outputs.
pub fn render_file(args: &RenderArgs, cfg: RenderConfig) -> anyhow::Result<()> {
    let (universe, threading) = ::mpi::initialize_with_threading(Threading::Multiple)
        .ok_or_else(|| anyhow!("MPI is already initialized in this process"))?;
    let world = universe.world();
    let mode = args.mpi_mode.unwrap_or(MpiMode::Replicated);
    if mode == MpiMode::Replicated && world.size() > 1 && threading < Threading::Serialized {
        bail!(
            "the MPI library provides only {threading:?} threading; the replicated mode needs \
             MPI_THREAD_SERIALIZED (use --mpi-mode partitioned or another MPI build)"
        );
    }
    match run_rank(&world, mode, args, cfg) {
        Ok(()) => Ok(()),
        // Every rank failed the same way (on a shared file system); rank 0 says why.
        Err(Failure::Agreed(e)) if world.rank() == 0 => Err(e),
        Err(Failure::Agreed(_)) => Ok(()),
        Err(Failure::Local(e)) if world.size() > 1 => {
            // Other ranks may wait in a collective for this one: end the whole job.
            eprintln!("Error (MPI rank {}): {e:#}", world.rank());
            world.abort(1)
        }
        Err(Failure::Local(e)) => Err(e),
    }
}

/// Why a rank's run failed.
enum Failure {
    /// Every rank failed during set-up (checked together).
    Agreed(anyhow::Error),
    /// This rank failed on its own.
    Local(anyhow::Error),
}

impl From<anyhow::Error> for Failure {
    fn from(e: anyhow::Error) -> Failure {
        Failure::Local(e)
    }
}

/// True on every rank when `ok` is true on every rank.
fn all_ok(world: &SimpleCommunicator, ok: bool) -> bool {
    let mut all = 0i32;
    world.all_reduce_into(&i32::from(ok), &mut all, SystemOperation::min());
    all == 1
}

fn run_rank(
    world: &SimpleCommunicator,
    mode: MpiMode,
    args: &RenderArgs,
    mut cfg: RenderConfig,
) -> Result<(), Failure> {
    let start = Instant::now();
    let rank = world.rank();
    let mut setup = || -> anyhow::Result<_> {
        crate::output::check_outputs(
            &args.file,
            &[Some(&args.output), args.preview.as_deref(), args.stats_json.as_deref()],
        )?;
        let file = open_mapped(&args.file)?;
        let field = resolve_field(&file, args, &mut cfg)?;
        Ok((file, field))
    };
    let setup = setup();
    if !all_ok(world, setup.is_ok()) {
        return Err(Failure::Agreed(match setup {
            Err(e) => e,
            Ok(_) => anyhow!("another MPI rank could not open {}", args.file.display()),
        }));
    }
    let (file, field) = setup?;
    let src = AmrSource::new(&file, field, args.reconstruction)?;
    let (camera, mut light) = scene_setup(&src, &cfg)?;
    if mode == MpiMode::Partitioned && (light.shadows || light.ao_rays > 0) {
        if rank == 0 {
            eprintln!(
                "note: --mpi-mode partitioned renders without shadows and ambient occlusion \
                 (they need the whole scene); --no-shadows --ao 0 silences this"
            );
        }
        light.shadows = false;
        light.ao_rays = 0;
    }
    let mut report = RenderReport {
        camera: Some(camera),
        ..Default::default()
    };
    let mut stats = RankStats::default();
    let settings = RenderSettings {
        width: cfg.size.0,
        height: cfg.size.1,
        spp: cfg.spp,
    };
    let tiles = replicated::Tiles::new(cfg.size.0, cfg.size.1);
    let bar_len = match mode {
        MpiMode::Replicated => u64::from(tiles.count()),
        MpiMode::Partitioned => u64::from(cfg.size.1),
    };
    let (bar, progress) = progress_bar(bar_len);
    let quiet = |_: u64| {};
    let progress: &(dyn Fn(u64) + Sync) = if rank == 0 { &progress } else { &quiet };
    let origin = src.frame().origin;
    let cpu0 = cpu_seconds();
    let frame = match (mode, cfg.method) {
        (MpiMode::Partitioned, _) => partitioned::render(
            world,
            &src,
            &cfg,
            &camera,
            &light,
            &mut report,
            &mut stats,
            progress,
        )?,
        (MpiMode::Replicated, Method::Hybrid) => {
            let surfaces = build_surfaces(&src, &cfg, |iso| src.extract(iso), &mut report)?;
            stats.cpu_scene = cpu_seconds();
            let tracer = HybridTracer {
                src: &src,
                surfaces: &surfaces,
                smooth_normals: cfg.smooth_normals,
            };
            let job = replicated::Job {
                tracer: &tracer,
                camera: &camera,
                light: &light,
                settings,
                tiles,
            };
            replicated::render(world, &job, origin, &mut stats, progress)?
        }
        (MpiMode::Replicated, Method::Sample) => {
            stats.cpu_scene = cpu_seconds();
            let tracer = SampleTracer {
                src: &src,
                isos: cfg.isos.iter().map(|s| s.value).collect(),
                step: sample_step(&src.frame(), &cfg)?,
            };
            let job = replicated::Job {
                tracer: &tracer,
                camera: &camera,
                light: &light,
                settings,
                tiles,
            };
            replicated::render(world, &job, origin, &mut stats, progress)?
        }
    };
    bar.finish_and_clear();
    let frame_time = start.elapsed();
    // The modes left the processor time at the start of rendering.
    stats.cpu_scene -= cpu0;
    if mode == MpiMode::Partitioned {
        stats.rays = report.rays as f64;
        stats.render = report.render.as_secs_f64();
    }
    stats.extract = report.extract.as_secs_f64();
    stats.bvh = report.bvh.as_secs_f64();
    stats.active_octants = report.active_octants as f64;
    stats.refs_bytes = report.refs_bytes as f64;
    stats.bvh_bytes = report.bvh_bytes as f64;
    stats.build_scratch = report.build_scratch_bytes as f64;
    stats.peak_rss = peak_rss_bytes().unwrap_or(0) as f64;
    let Some(ranks) = stats.gather(world) else {
        return Ok(());
    };
    let frame = frame.ok_or_else(|| anyhow!("rank 0 holds no frame"))?;
    Ok(write_rank0(
        args, &cfg, mode, report, frame, &ranks, frame_time, &file, field,
    )?)
}

/// Rank 0's outputs: the frame, the preview and the statistics in total and per rank.
#[allow(clippy::too_many_arguments)]
fn write_rank0<D: AsRef<[u8]>>(
    args: &RenderArgs,
    cfg: &RenderConfig,
    mode: MpiMode,
    mut report: RenderReport,
    frame: crate::output::frame::FrameBuffer,
    ranks: &[RankStats],
    frame_time: std::time::Duration,
    file: &amr_format::AmrkFile<D>,
    field: usize,
) -> anyhow::Result<()> {
    let max = |f: fn(&RankStats) -> f64| ranks.iter().map(f).fold(0.0, f64::max);
    let sum = |f: fn(&RankStats) -> f64| ranks.iter().map(f).sum::<f64>();
    let secs = std::time::Duration::from_secs_f64;
    report.frame = frame;
    report.extract = secs(max(|r| r.extract));
    report.bvh = secs(max(|r| r.bvh));
    report.render = secs(max(|r| r.render));
    report.rays = sum(|r| r.rays) as u64;
    if mode == MpiMode::Partitioned {
        report.active_octants = sum(|r| r.active_octants) as u64;
        report.refs_bytes = sum(|r| r.refs_bytes) as u64;
        report.bvh_bytes = sum(|r| r.bvh_bytes) as u64;
        report.build_scratch_bytes = max(|r| r.build_scratch) as u64;
    }
    let per_rank: Vec<String> = ranks.iter().enumerate().map(|(k, r)| r.json(k)).collect();
    let extra = [
        ("field", format!("\"{}\"", file.fields()[field].name)),
        ("file_bytes", file.bytes().len().to_string()),
        ("mpi_mode", format!("\"{}\"", mode.name())),
        ("mpi_ranks", ranks.len().to_string()),
        ("frame_ms", format!("{:.3}", frame_time.as_secs_f64() * 1e3)),
        ("wait_ms", format!("{:.3}", max(|r| r.wait) * 1e3)),
        ("composite_ms", format!("{:.3}", max(|r| r.composite) * 1e3)),
        (
            "redistribute_ms",
            format!("{:.3}", max(|r| r.redistribute) * 1e3),
        ),
        ("bytes_sent", format!("{}", sum(|r| r.bytes_sent))),
        ("cpu_scene_s", format!("{:.2}", sum(|r| r.cpu_scene))),
        ("cpu_render_s", format!("{:.2}", sum(|r| r.cpu_render))),
        (
            "peak_rss_bytes_max_rank",
            format!("{}", max(|r| r.peak_rss)),
        ),
        (
            "resident_bytes_max_rank",
            format!("{}", max(|r| r.refs_bytes + r.bvh_bytes)),
        ),
    ];
    let meta = header_meta(
        cfg,
        &report,
        &[
            ("file", args.file.display().to_string()),
            ("mpi", format!("{} ranks, {}", ranks.len(), mode.name())),
        ],
    );
    let mut rows = stats_rows(&report, &extra);
    if args.stats {
        let width = rows.iter().map(|r| r.0.len()).max().unwrap_or(0);
        for (k, v) in &rows {
            eprintln!("{k:<width$}  {v}");
        }
        let work = match mode {
            MpiMode::Replicated => "tiles",
            MpiMode::Partitioned => "leaves",
        };
        eprint!("{}", table(ranks, work));
    }
    rows.push((
        "per_rank".into(),
        format!("[\n    {}\n  ]", per_rank.join(",\n    ")),
    ));
    write_outputs(
        &report,
        &meta,
        &args.output,
        args.preview.as_deref(),
        &rows,
        false,
        args.stats_json.as_deref(),
    )
}
