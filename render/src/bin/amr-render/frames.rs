//! The frames of one run: each frame's file, camera and isosurfaces from the animation, one scene
//! kept while its file is rendered (so a camera path or an unchanged isovalue costs frames only),
//! dropped before the next file is opened (so a time series' memory stays flat), numbered
//! outputs, one progress bar over all frames and, when asked, a movie.

use std::path::{Path, PathBuf};
use std::time::Instant;

use amr_render::output::header::frame_header;
use amr_render::{render, Scene, View};
use serde::Serialize;

use crate::heap;
use crate::movie;
use crate::outputs::{self, FrameFiles, ProcessMemory, RunStats};
use crate::progress;
use crate::render::request_isos;
use crate::render_args::RenderRequest;

/// The statistics of one frame of an animation.
#[derive(Serialize)]
struct FrameRecord {
    /// Frame number.
    frame: u32,
    /// The file rendered.
    file: PathBuf,
    /// Its simulation time and step, when recorded.
    simulation_time: Option<f64>,
    simulation_step: Option<i64>,
    #[serde(flatten)]
    stats: RunStats<ProcessMemory>,
}

/// Renders every frame of `request` and writes what it asks.
pub fn render_all(request: &RenderRequest) -> anyhow::Result<()> {
    let anim = &request.animation;
    let n = anim.frames;
    let want_png = request.outputs.movie.is_some();
    let files: Vec<FrameFiles> = (0..n)
        .map(|k| FrameFiles::numbered(&request.outputs, k, n, want_png))
        .collect();
    let inputs: Vec<&Path> = request.files.iter().map(PathBuf::as_path).collect();
    for f in &files {
        outputs::check_frame(f, &request.outputs, &inputs)?;
    }
    let (bar, advance_frames) = progress::bar(u64::from(n), "frames");
    let quiet = |_: u64| {};
    let (row_bar, advance_rows) = progress::bar(u64::from(request.view.size.1), "rows");
    let rows: &(dyn Fn(u64) + Sync) = if n == 1 { &advance_rows } else { &quiet };

    let mut scene: Option<(usize, Scene)> = None;
    let mut cameras = Vec::new();
    let mut records = Vec::new();
    let start = Instant::now();
    for k in 0..n {
        let index = if anim.series { k as usize } else { 0 };
        if scene.as_ref().is_none_or(|(i, _)| *i != index) {
            // The previous file's map and surfaces go before the next file is opened.
            if scene.take().is_some() {
                heap::return_freed();
            }
            scene = Some((index, Scene::open(&request.files[index], &request.scene)?));
        }
        let Some((_, scene)) = scene.as_mut() else {
            unreachable!("a scene was opened above");
        };
        if cameras.is_empty() {
            cameras = anim.cameras(&request.view.camera(&scene.grid_frame())?)?;
        }
        scene.set_isosurfaces(&anim.isos(&request_isos(request, scene), k))?;
        let view = View {
            camera: Some(cameras[k as usize]),
            ..request.view.clone()
        };
        let rendered = render(scene, &view, rows)?;
        let file = scene.file();
        let (time, step) = (file.simulation_time(), file.simulation_step());
        let mut extra = vec![];
        if n > 1 {
            extra.push(("frame", format!("{k} of {n}")));
        }
        if let Some(t) = time {
            extra.push(("simulation_time", t.to_string()));
        }
        if let Some(s) = step {
            extra.push(("simulation_step", s.to_string()));
        }
        let header = frame_header(scene, &rendered, &extra);
        outputs::write_frame(&files[k as usize], &rendered, &header)?;
        records.push(FrameRecord {
            frame: k,
            file: request.files[index].clone(),
            simulation_time: time,
            simulation_step: step,
            stats: RunStats::new(scene, rendered.stats.clone(), ProcessMemory::of(scene)),
        });
        advance_frames(1);
    }
    drop(scene);
    bar.finish_and_clear();
    row_bar.finish_and_clear();
    if n == 1 {
        let only = records.pop().map(|r| r.stats);
        outputs::report(&request.outputs, &only, "")?;
    } else {
        let seconds = start.elapsed().as_secs_f64();
        let per_frame = format!(
            "{n} frames in {seconds:.2} s ({:.3} s per frame)\n",
            seconds / f64::from(n)
        );
        outputs::report(&request.outputs, &records, &per_frame)?;
    }
    if let Some((path, fps)) = &request.outputs.movie {
        let pngs: Vec<&Path> = files.iter().filter_map(|f| f.preview.as_deref()).collect();
        movie::encode(&pngs, *fps, path)?;
    }
    Ok(())
}
