//! The frames of one run: each frame's file, camera and isosurfaces from the animation, one scene
//! kept while its file is rendered (so a camera path or an unchanged isovalue costs frames only),
//! dropped before the next file is opened (so a time series' memory stays flat), numbered
//! outputs written while the next frame renders, one progress bar over all frames and, when
//! asked, a movie.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use amr_render::field_stats::format_isovalue;
use amr_render::mapping::open_mapped;
use amr_render::output::header::frame_header;
use amr_render::output::legend::Legend;
use amr_render::scene::{field_named, TraceMethod};
use amr_render::shade::IsoSpec;
use amr_render::{render, render_reusing, ColorBy, ColorScale, Scene, View};
use anyhow::bail;
use serde::Serialize;

use crate::animation::SweptSurface;
use crate::frame_warnings::{
    note_no_room_for_legend, warn_empty, warn_enclosed, warn_isos_outside, warn_slices_outside,
};
use crate::frame_writer::{FrameJob, FrameWriter};
use crate::heap;
use crate::movie;
use crate::outputs::{self, FrameFiles, ProcessMemory, RunStats};
use crate::progress;
use crate::render::{request_isos, swept_surface};
use crate::render_args::RenderRequest;
use amr_render::system_memory::peak_rss_bytes;

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
    outputs::check_distinct(&files, &request.outputs)?;
    if request.files.len() > 1 {
        check_series(request)?;
    }
    let (bar, advance_frames) = progress::bar(u64::from(n), "frames");
    let quiet = |_: u64| {};

    let mut base_view = request.view.clone();
    if request.series_color_range {
        let ranges = series_ranges(request)?;
        match ranges.as_slice() {
            [(_, one)] if base_view.field_scales.is_empty() => {
                base_view.color_scale.range = Some(*one);
            }
            // A field's own range stays; the others take theirs over the series.
            _ => {
                for (name, range) in ranges {
                    let scales = &mut base_view.field_scales;
                    match scales.iter_mut().find(|(n, _)| *n == name) {
                        Some((_, own)) => {
                            own.range.get_or_insert(range);
                        }
                        None => {
                            let scale = ColorScale {
                                range: Some(range),
                                ..base_view.color_scale
                            };
                            scales.push((name, scale));
                        }
                    }
                }
            }
        }
    }
    // The open file's index, its scene, its isosurfaces and its swept surface (a default
    // isovalue or a percentile reads the field's cells, so it is found once per file, not once
    // per frame).
    let mut scene: Option<(usize, Scene, Vec<IsoSpec>, Option<SweptSurface>)> = None;
    let mut cameras = Vec::new();
    let mut records = Vec::new();
    let mut writer = FrameWriter::start()?;
    let mut warned_enclosed = false;
    let mut noted_legend = false;
    let start = Instant::now();
    for k in 0..n {
        let index = if anim.series { k as usize } else { 0 };
        if scene.as_ref().is_none_or(|(i, ..)| *i != index) {
            // The previous file's map and surfaces go before the next file is opened.
            if scene.take().is_some() {
                heap::return_freed();
            }
            let _stage = (n == 1).then(|| progress::stage("opening the file"));
            let opened = open_scene(request, index)?;
            let isos = request_isos(request, &opened)?;
            // One surface and nothing else: a frame without it gets `warn_empty`'s message.
            let alone = isos.len() == 1 && request.slices.is_empty() && anim.sweep.is_none();
            if !alone {
                warn_isos_outside(&opened, &isos);
            }
            let swept = swept_surface(request, &opened)?;
            scene = Some((index, opened, isos, swept));
        }
        let Some((_, scene, base_isos, swept)) = scene.as_mut() else {
            unreachable!("a scene was opened above");
        };
        let isos = anim.isos(base_isos, k, swept.as_ref());
        // In view: the first extraction of a file is limited to its frame's view; a later frame
        // extracts the new isovalues in the previous view, then everything again if the camera
        // moved (the statistics then report that last extraction).
        let in_view = match request.extract_in_view {
            true => {
                if cameras.is_empty() {
                    let start = request.view.camera(&scene.grid_frame())?;
                    base_view.keep_height_of(&start);
                    cameras = anim.cameras(&start)?;
                }
                Some(View {
                    camera: Some(cameras[k as usize]),
                    ..base_view.clone()
                })
            }
            false => None,
        };
        let stage = (n == 1).then(|| progress::stage("extracting and building the isosurfaces"));
        if scene.extract_view().is_none() {
            scene.set_extract_view(in_view.as_ref())?;
        }
        scene.set_isosurfaces(&isos)?;
        scene.set_extract_view(in_view.as_ref())?;
        scene.set_color_by(&painting(request, isos.len()))?;
        if cameras.is_empty() {
            let view = match request.frame_domain {
                true => request.view.clone(),
                false => framed_view(&request.view, scene)?,
            };
            let start = view.camera(&scene.grid_frame())?;
            base_view.keep_height_of(&start);
            cameras = anim.cameras(&start)?;
        }
        let view = View {
            camera: Some(cameras[k as usize]),
            ..base_view.clone()
        };
        if k == 0 && !anim.series && anim.sweep.is_none() {
            // One file's frames repeat their allocations: freed blocks are kept for the next.
            // A series keeps its memory at that of its largest step instead, and a sweep at
            // that of its largest extraction: kept frame blocks would sit beside each new
            // isovalue's refs, BVH and build scratch.
            heap::keep_freed_for_frames();
        }
        drop(stage);
        // One frame's rows are a bar of their own, from when they start.
        let (row_bar, advance_rows) = progress::bar(u64::from(view.size.1), "rows");
        let rows: &(dyn Fn(u64) + Sync) = if n == 1 { &advance_rows } else { &quiet };
        let rendered = match writer.written_planes() {
            Some(planes) => render_reusing(scene, &view, rows, planes)?,
            None => render(scene, &view, rows)?,
        };
        row_bar.finish_and_clear();
        if rendered.stats.covered_pixels == 0 {
            warn_empty(scene, &rendered.camera, view.size);
        }
        let every_pixel = u64::from(view.size.0) * u64::from(view.size.1);
        if rendered.stats.covered_pixels == every_pixel && !warned_enclosed {
            // Once a run: a camera path may stay inside for many frames.
            warned_enclosed = warn_enclosed(scene, &view, &rendered.camera)?;
        }
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
        if let [one] = rendered.color_ranges.as_slice() {
            let c = &one.scale;
            extra.push((
                "colormap",
                format!("{}{}", c.colormap, if c.log { " log" } else { "" }),
            ));
        }
        let header = frame_header(scene, &rendered, &extra);
        let legend = match request.outputs.legend {
            true => Some(Legend::of_frame(scene, &view, &rendered)),
            false => None,
        };
        if let (Some(legend), Some(png), true) = (
            &legend,
            files[k as usize].picture(),
            request.outputs.summary && !noted_legend,
        ) {
            // Once a run: the frames of a run share their size.
            noted_legend = note_no_room_for_legend(png, legend, view.size);
        }
        let stats = rendered.stats.clone();
        writer.write(FrameJob {
            files: files[k as usize].clone(),
            rendered,
            header,
            legend,
        })?;
        records.push(FrameRecord {
            frame: k,
            file: request.files[index].clone(),
            simulation_time: time,
            simulation_step: step,
            stats: RunStats::new(scene, stats, ProcessMemory::of(scene)),
        });
        advance_frames(1);
    }
    writer.finish()?;
    if let Some(last) = records.last_mut() {
        // The last write is part of the run's peak.
        last.stats.peak_rss_bytes = peak_rss_bytes();
    }
    if let (1, true, Some((index, scene, ..))) = (n, request.outputs.summary, &scene) {
        let took = start.elapsed();
        eprintln!(
            "{}",
            summary(&request.files[*index], scene, &files[0], took)
        );
    }
    drop(scene);
    bar.finish_and_clear();
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
        if request.outputs.summary {
            eprintln!(
                "wrote {n} frames, {} to {}, in {seconds:.2} s",
                files[0].exr.display(),
                files[n as usize - 1].exr.display()
            );
        }
    }
    if let Some((path, fps)) = &request.outputs.movie {
        let pngs: Vec<&Path> = files.iter().filter_map(|f| f.preview.as_deref()).collect();
        movie::encode(&pngs, *fps, path)?;
    }
    Ok(())
}

/// The scene of the request's `index`-th file, with its slices.
fn open_scene(request: &RenderRequest, index: usize) -> anyhow::Result<Scene> {
    let mut scene = Scene::open(&request.files[index], &request.scene)?;
    scene.set_clip(request.clip)?;
    if !request.slices.is_empty() {
        scene.set_slices(&request.slices, request.slice_field.clone())?;
        warn_slices_outside(&scene);
    }
    Ok(scene)
}

/// What paints each of `n` isosurfaces: one `--color-by` paints all, several pair in order.
pub(crate) fn painting(request: &RenderRequest, n: usize) -> Vec<Option<ColorBy>> {
    match request.color_by.as_slice() {
        [one] => vec![one.clone(); n],
        many => many.to_vec(),
    }
}

/// Opens every file of a series and finds in each the fields the request names (the field of
/// the surfaces and those that paint), so that a file missing or without one of them stops the
/// run before its first frame rather than at that file's.
fn check_series(request: &RenderRequest) -> anyhow::Result<()> {
    let painting = request.color_by.iter().chain([&request.slice_field]);
    let names: Vec<&str> = request
        .scene
        .field
        .iter()
        .map(String::as_str)
        .chain(painting.flatten().flat_map(ColorBy::fields))
        .chain(request.isos.iter().filter_map(|s| s.field.as_deref()))
        .chain(
            request
                .animation
                .sweep
                .iter()
                .filter_map(|s| s.field.as_deref()),
        )
        .collect();
    for path in &request.files {
        let file = open_mapped(path)?;
        for name in &names {
            field_named(&file, name).map_err(|e| e.in_file(path))?;
        }
    }
    Ok(())
}

/// Each painting field's range over every file of a time series (`--color-range auto-series`),
/// from the ranges the files store, so no data is read: the fields of `--color-by` and
/// `--slice-field`, in that order, or the scene's field (`--field`) when only slices paint with
/// it.
fn series_ranges(request: &RenderRequest) -> anyhow::Result<Vec<(String, (f64, f64))>> {
    // Each painter once, by name, with the fields it reads (a magnitude's components).
    let mut painters: Vec<(String, Vec<String>)> = Vec::new();
    let by = request
        .color_by
        .iter()
        .chain([&request.slice_field])
        .flatten();
    for by in by {
        if let Some(name) = by.painted_name() {
            if painters.iter().all(|(n, _)| n != name) {
                let read = by.fields().into_iter().map(String::from).collect();
                painters.push((name.to_string(), read));
            }
        }
    }
    if let (true, false, Some(field)) = (
        painters.is_empty(),
        request.slices.is_empty(),
        &request.scene.field,
    ) {
        painters.push((field.clone(), vec![field.clone()]));
    }
    if painters.is_empty() {
        bail!("--color-range auto-series needs a field to paint with (--color-by FIELD or --slice-field FIELD)");
    }
    let mut ranges: Vec<(f64, f64)> = vec![(f64::INFINITY, f64::NEG_INFINITY); painters.len()];
    for path in &request.files {
        let file = open_mapped(path)?;
        for ((_, read), (lo, hi)) in painters.iter().zip(&mut ranges) {
            let mut component_ranges = Vec::new();
            for field in read {
                let Some(i) = file.field_index(field) else {
                    bail!(
                        "{}: no field '{field}' to take the series' colour range from",
                        path.display()
                    );
                };
                let f = &file.fields()[i];
                component_ranges.push((f64::from(f.min), f64::from(f.max)));
            }
            let (file_lo, file_hi) = match component_ranges.as_slice() {
                [one] => *one,
                many => magnitude_bounds(many),
            };
            *lo = lo.min(file_lo);
            *hi = hi.max(file_hi);
        }
    }
    for ((name, _), (lo, hi)) in painters.iter().zip(&ranges) {
        if !(lo < hi) {
            bail!("field '{name}' is {lo} in every file of the series: no colour range to spread");
        }
    }
    Ok(painters.into_iter().map(|(n, _)| n).zip(ranges).collect())
}

/// Bounds of the length of a vector whose components lie in `ranges`: from the length of the
/// components nearest zero to that of those farthest from it.
fn magnitude_bounds(ranges: &[(f64, f64)]) -> (f64, f64) {
    let (mut near, mut far) = (0.0f64, 0.0f64);
    for &(lo, hi) in ranges {
        if lo > 0.0 || hi < 0.0 {
            near += lo.abs().min(hi.abs()).powi(2);
        }
        far += lo.abs().max(hi.abs()).powi(2);
    }
    (near.sqrt(), far.sqrt())
}

/// `view`, with a camera that frames the scene's isosurfaces when it has none and the frame has
/// no slices (which span the domain).
pub(crate) fn framed_view(view: &View, scene: &Scene) -> anyhow::Result<View> {
    if view.camera.is_none() && scene.slices().is_empty() {
        if let Some(bounds) = scene.surface_bounds()? {
            return Ok(view.framing(bounds)?);
        }
    }
    Ok(view.clone())
}

/// The one line that says what a single-frame render did.
fn summary(file: &Path, scene: &Scene, files: &FrameFiles, took: Duration) -> String {
    let isos: Vec<String> = scene
        .isosurfaces()
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let value = surface_value(scene, s);
            match scene.color_by().get(i).cloned().flatten() {
                Some(by) => format!("{value} (coloured by {by})"),
                None => value,
            }
        })
        .collect();
    let surfaces = match scene.method() {
        TraceMethod::Hybrid => format!("{} active voxels", scene.stats().active_octants),
        // Nothing is extracted: "0 active voxels" would read as an empty surface.
        TraceMethod::Sample => "sampled along rays".to_string(),
    };
    // The scene's field is named when some surface is of it (the others name their own).
    let of_scene_field = scene
        .isosurfaces()
        .iter()
        .any(|s| scene.surface_field(s) == scene.field());
    let mut out = match (isos.is_empty(), of_scene_field) {
        (true, _) => format!("{}: no isosurface", file.display()),
        (false, true) => format!(
            "{}: field {}, iso {}, {surfaces}",
            file.display(),
            scene.field_name(),
            isos.join(", "),
        ),
        (false, false) => format!("{}: iso {}, {surfaces}", file.display(), isos.join(", ")),
    };
    if !scene.slices().is_empty() {
        let n = scene.slices().len();
        out += &format!(", {n} slice{}", if n == 1 { "" } else { "s" });
    }
    let mut written = vec![files.exr.display().to_string()];
    written.extend(files.preview.iter().map(|p| p.display().to_string()));
    // A PNG output is its own preview: named once.
    written.dedup();
    out += &format!(
        ": wrote {} in {:.2} s",
        written.join(" and "),
        took.as_secs_f64()
    );
    out
}

/// An isovalue as the summary and warnings write it: `V`, or `FIELD=V` for a surface of
/// another field than the scene's (as `--iso` reads it).
pub(crate) fn surface_value(scene: &Scene, s: &IsoSpec) -> String {
    let value = format_isovalue(s.value);
    match scene.surface_field(s) == scene.field() {
        true => value,
        false => format!("{}={value}", scene.surface_field_name(s)),
    }
}
