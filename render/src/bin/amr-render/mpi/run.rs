//! One MPI rank's run of the render command: the scene opened on every rank as a single process
//! opens it, the mode's frame, and on rank 0 the EXR, the preview and the statistics of every
//! rank.

use std::time::Instant;

use ::mpi::collective::SystemOperation;
use ::mpi::topology::SimpleCommunicator;
use ::mpi::traits::*;
use ::mpi::Threading;
use amr_render::outline;
use amr_render::output::header::frame_header;
use amr_render::shade::IsoSpec;
use amr_render::{frame_painting, FramePainting, FrameStats, Rendered, Scene, TraceMethod};
use anyhow::{anyhow, bail};
use serde::Serialize;

use super::pixels::RECORD;
use super::stats::{cpu_seconds, table, RankRecord, RankStats};
use super::{partitioned, replicated, MpiMode};
use crate::frame_warnings::{note_no_room_for_legend, warn_slices_outside};
use crate::frames::{framed_view, painting};
use crate::outputs::{self, FrameFiles, RunStats};
use crate::progress;
use crate::render::request_isos;
use crate::render_args::RenderRequest;
use amr_render::system_memory::peak_rss_bytes;

/// What an MPI run adds to the statistics of a render.
#[derive(Serialize)]
struct MpiTotals {
    mpi_mode: &'static str,
    mpi_ranks: usize,
    #[serde(serialize_with = "amr_render::stats::millis")]
    frame_ms: std::time::Duration,
    wait_ms: f64,
    composite_ms: f64,
    redistribute_ms: f64,
    bytes_sent: u64,
    cpu_scene_s: f64,
    cpu_render_s: f64,
    peak_rss_bytes_max_rank: u64,
    resident_bytes_max_rank: u64,
    per_rank: Vec<RankRecord>,
}

/// Renders `request` with every rank of `mpirun`; rank 0 writes the outputs.
pub fn run(request: &RenderRequest, mode: Option<&str>) -> anyhow::Result<()> {
    let mode = MpiMode::parse(mode)?;
    if request.animation.frames > 1 || request.files.len() > 1 {
        bail!(
            "under mpirun amr-render renders one frame of one file; run animations in one process"
        );
    }
    let (w, h) = request.view.size;
    // Pixel messages count `RECORD` `f32` per pixel in a C `int`.
    if u64::from(w) * u64::from(h) * RECORD as u64 > i32::MAX as u64 {
        bail!(
            "--size {w}x{h} is too large for MPI messages (at most {} M pixels)",
            i32::MAX as usize / RECORD / 1_000_000
        );
    }
    if mode == MpiMode::Partitioned && request.no_isosurface {
        bail!(
            "--mpi-mode partitioned draws no slices, and --iso none leaves it nothing to draw: \
             use the replicated mode (the default)"
        );
    }
    if mode == MpiMode::Partitioned && request.scene.method != TraceMethod::Hybrid {
        bail!("--mpi-mode partitioned needs --method hybrid (it partitions the active octants)");
    }
    let (universe, threading) = ::mpi::initialize_with_threading(Threading::Multiple)
        .ok_or_else(|| anyhow!("MPI is already initialized in this process"))?;
    let world = universe.world();
    if mode == MpiMode::Replicated && world.size() > 1 && threading < Threading::Serialized {
        bail!(
            "the MPI library provides only {threading:?} threading; the replicated mode needs \
             MPI_THREAD_SERIALIZED (use --mpi-mode partitioned or another MPI build)"
        );
    }
    match run_rank(&world, mode, request) {
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

impl<E: Into<anyhow::Error>> From<E> for Failure {
    fn from(e: E) -> Failure {
        Failure::Local(e.into())
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
    request: &RenderRequest,
) -> Result<(), Failure> {
    let start = Instant::now();
    let rank = world.rank();
    let painted = !request.color_by.is_empty() || !request.slices.is_empty();
    let setup = (|| -> anyhow::Result<(Scene, Vec<IsoSpec>)> {
        if rank == 0 {
            let files = FrameFiles::numbered(&request.outputs, 0, 1, false);
            outputs::check_frame(&files, &request.outputs, &[&request.files[0]])?;
            outputs::check_distinct(std::slice::from_ref(&files), &request.outputs)?;
        }
        let mut scene = Scene::open(&request.files[0], &request.scene)?;
        let isos = request_isos(request, &scene)?;
        if mode == MpiMode::Replicated && painted {
            scene.set_slices(&request.slices, request.slice_field.clone())?;
            scene.set_color_by(&painting(request, isos.len()))?;
            if rank == 0 {
                warn_slices_outside(&scene);
            }
        }
        Ok((scene, isos))
    })();
    if !all_ok(world, setup.is_ok()) {
        return Err(Failure::Agreed(match setup {
            Err(e) => e,
            Ok(_) => anyhow!(
                "another MPI rank could not open {}",
                request.files[0].display()
            ),
        }));
    }
    let (mut scene, isos) = setup?;
    let mut view = request.view.clone();
    if mode == MpiMode::Partitioned && (view.shadows || view.ao_rays > 0) {
        if rank == 0 {
            eprintln!(
                "note: --mpi-mode partitioned renders without shadows and ambient occlusion \
                 (they need the whole scene); --no-shadows --ao 0 silences this"
            );
        }
        view.shadows = false;
        view.ao_rays = 0;
    }
    if rank == 0 && mode == MpiMode::Partitioned && painted {
        eprintln!(
            "note: --mpi-mode partitioned draws no --color-by and no slices (each rank holds \
             only part of the surfaces); the replicated mode draws them"
        );
    }
    let mut stats = RankStats::default();
    let tiles = replicated::Tiles::new(view.size.0, view.size.1);
    let bar_len = match mode {
        MpiMode::Replicated => u64::from(tiles.count()),
        MpiMode::Partitioned => u64::from(view.size.1),
    };
    let (bar, progress) = progress::bar(bar_len, "tiles");
    let quiet = |_: u64| {};
    let progress: &(dyn Fn(u64) + Sync) = if rank == 0 { &progress } else { &quiet };
    let origin = scene.grid_frame().origin;
    let cpu0 = cpu_seconds();
    let mut painting = FramePainting::default();
    let frame = match mode {
        MpiMode::Partitioned => {
            let frame_surfaces = !request.frame_domain;
            partitioned::render_part(
                world,
                &mut scene,
                &isos,
                &mut view,
                frame_surfaces,
                &mut stats,
                progress,
            )?
            // Nothing is painted by level in this mode.
            .map(|frame| (frame, None))
        }
        MpiMode::Replicated => {
            scene.set_isosurfaces(&isos)?;
            stats.extract = scene.stats().extract.as_secs_f64();
            if !request.frame_domain {
                // Every rank holds the same scene, so every rank frames it alike.
                view = framed_view(&view, &scene)?;
            }
            stats.cpu_scene = cpu_seconds();
            // Every rank finds the same colour ranges, from the same pre-pass over the frame.
            painting = frame_painting(&scene, &view)?;
            let job = replicated::Job {
                scene: &scene,
                view: &view,
                painting: &painting,
                tiles,
            };
            replicated::render(world, &job, origin, &mut stats, progress)?
                .map(|g| (g.frame, Some(g.painted_levels)))
        }
    };
    bar.finish_and_clear();
    let camera = view.camera(&scene.grid_frame())?;
    let frame_time = start.elapsed();
    // The modes left the processor time at the start of rendering.
    stats.cpu_scene -= cpu0;
    let scene_stats = scene.stats();
    stats.bvh = scene_stats.bvh.as_secs_f64();
    stats.active_octants = scene_stats.active_octants as f64;
    stats.refs_bytes = scene_stats.refs_bytes as f64;
    stats.bvh_bytes = scene_stats.bvh_bytes as f64;
    stats.build_scratch = scene_stats.build_scratch_bytes as f64;
    stats.peak_rss = peak_rss_bytes().unwrap_or(0) as f64;
    let Some(ranks) = stats.gather(world) else {
        return Ok(());
    };
    let (mut frame, painted_levels) = frame.ok_or_else(|| anyhow!("rank 0 holds no frame"))?;
    let colors = outline::LevelColors::of_scene(&scene, &view.background);
    let segments = outline::segments(
        view.outline,
        scene.file(),
        scene.grid_frame().world_bounds(),
        (&colors, view.background.outline()),
    );
    outline::draw(
        &mut frame,
        &camera,
        &segments,
        outline::line_width(view.size.0, view.size.1),
    );
    let rendered = Rendered {
        frame,
        camera,
        stats: FrameStats::default(),
        color_ranges: painting.color_ranges,
        painted_levels,
        background: view.background,
    };
    write_rank0(request, &scene, mode, rendered, &ranks, frame_time)?;
    Ok(())
}

/// Rank 0's outputs: the frame, the preview and the statistics in total and per rank.
fn write_rank0(
    request: &RenderRequest,
    scene: &Scene,
    mode: MpiMode,
    mut rendered: Rendered,
    ranks: &[RankStats],
    frame_time: std::time::Duration,
) -> anyhow::Result<()> {
    let max = |f: fn(&RankStats) -> f64| ranks.iter().map(f).fold(0.0, f64::max);
    let sum = |f: fn(&RankStats) -> f64| ranks.iter().map(f).sum::<f64>();
    let secs = std::time::Duration::from_secs_f64;
    let frame = &rendered.frame;
    let frame_stats = FrameStats::new(
        secs(max(|r| r.render)),
        sum(|r| r.rays) as u64,
        (frame.width, frame.height),
        frame.covered() as u64,
    );
    rendered.stats = frame_stats.clone();
    let totals = MpiTotals {
        mpi_mode: mode.name(),
        mpi_ranks: ranks.len(),
        frame_ms: frame_time,
        wait_ms: max(|r| r.wait) * 1e3,
        composite_ms: max(|r| r.composite) * 1e3,
        redistribute_ms: max(|r| r.redistribute) * 1e3,
        bytes_sent: sum(|r| r.bytes_sent) as u64,
        cpu_scene_s: sum(|r| r.cpu_scene),
        cpu_render_s: sum(|r| r.cpu_render),
        peak_rss_bytes_max_rank: max(|r| r.peak_rss) as u64,
        resident_bytes_max_rank: max(|r| r.refs_bytes + r.bvh_bytes) as u64,
        per_rank: ranks.iter().enumerate().map(|(k, r)| r.record(k)).collect(),
    };
    let mut stats = RunStats::new(scene, frame_stats, totals);
    stats.scene.extract = secs(max(|r| r.extract));
    stats.scene.bvh = secs(max(|r| r.bvh));
    if mode == MpiMode::Partitioned {
        stats.scene.active_octants = sum(|r| r.active_octants) as u64;
        stats.scene.refs_bytes = sum(|r| r.refs_bytes) as u64;
        stats.scene.bvh_bytes = sum(|r| r.bvh_bytes) as u64;
        stats.scene.build_scratch_bytes = max(|r| r.build_scratch) as u64;
    }
    let header = frame_header(
        scene,
        &rendered,
        &[("mpi", format!("{} ranks, {}", ranks.len(), mode.name()))],
    );
    let work = match mode {
        MpiMode::Replicated => "tiles",
        MpiMode::Partitioned => "leaves",
    };
    let files = FrameFiles::numbered(&request.outputs, 0, 1, false);
    let legend = request
        .outputs
        .legend
        .then(|| amr_render::output::legend::Legend::of_frame(scene, &request.view, &rendered));
    if let (Some(legend), Some(png), true) = (&legend, files.picture(), request.outputs.summary) {
        note_no_room_for_legend(png, legend, request.view.size);
    }
    outputs::write_frame(&files, &rendered, &header, legend.as_ref())?;
    outputs::report(&request.outputs, &stats, &table(ranks, work))
}
