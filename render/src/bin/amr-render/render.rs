//! `amr-render FILE.amrk ...`: one frame of one file, in this process or with MPI ranks.

use std::time::{Duration, Instant};

use amr_render::field_stats::format_value;
use amr_render::output::header::frame_header;
use amr_render::output::legend::Legend;
use amr_render::shade::IsoSpec;
use amr_render::{render, Scene};
use anyhow::bail;

use crate::outputs::{self, ProcessMemory, RunStats};
use crate::progress;
use crate::render_args::{RenderArgs, RenderRequest};

/// Environment variables that MPI launchers set in every process they start (Open MPI, PMI as in
/// MPICH's Hydra, PMIx).
const LAUNCHER_VARS: [&str; 3] = ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"];

/// True when this process was started by `mpirun` (or another MPI launcher).
pub fn launched_by_mpirun() -> bool {
    LAUNCHER_VARS.iter().any(|v| std::env::var_os(v).is_some())
}

/// Runs the render command.
pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let request = args.request()?;
    let work = || -> anyhow::Result<()> {
        if launched_by_mpirun() {
            #[cfg(feature = "mpi")]
            return crate::mpi::run::run(&request, args.mpi_mode.as_deref());
            #[cfg(not(feature = "mpi"))]
            bail!(
                "started by mpirun, but this amr-render was built without MPI; \
                 rebuild with `cargo build --release -p amr-render --features mpi`"
            );
        }
        if args.mpi_mode.is_some() {
            bail!("--mpi-mode needs a start with mpirun (mpirun -n N amr-render ...)");
        }
        render_request(&request)
    };
    match request.threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()?
            .install(work),
        None => work(),
    }
}

/// Opens the scene, renders the frame and writes what the request asks.
pub fn render_request(request: &RenderRequest) -> anyhow::Result<()> {
    let start = Instant::now();
    outputs::check(&request.outputs, &[&request.file])?;
    let scene = open_scene(request)?;
    let mut view = request.view.clone();
    if view.camera.is_none() && scene.slices().is_empty() {
        if let Some(bounds) = scene.surface_bounds() {
            view.camera = Some(view.framing(bounds)?);
        }
    }
    let (bar, progress) = progress::bar(u64::from(view.size.1), "rows");
    let rendered = render(&scene, &view, &progress)?;
    bar.finish_and_clear();
    let stats = RunStats::new(&scene, rendered.stats.clone(), ProcessMemory::of(&scene));
    let mut extra = Vec::new();
    if rendered.color_range.is_some() {
        let s = &view.color_scale;
        extra.push(("colormap", format!("{}{}", s.colormap, if s.log { " log" } else { "" })));
    }
    let header = frame_header(&scene, &rendered, &extra);
    let legend = Legend::of_frame(&scene, &view, &rendered);
    outputs::write(&request.outputs, &rendered, &header, &stats, "", &legend)?;
    if rendered.stats.covered_pixels == 0 {
        warn_empty(&scene);
    }
    if request.outputs.summary {
        eprintln!("{}", summary(request, &scene, start.elapsed()));
    }
    Ok(())
}

/// The one line that says what a render did.
fn summary(request: &RenderRequest, scene: &Scene, took: Duration) -> String {
    let isos: Vec<String> = scene
        .isosurfaces()
        .iter()
        .enumerate()
        .map(|(i, s)| match scene.color_by().get(i).cloned().flatten() {
            Some(by) => format!("{} (coloured by {by})", format_value(f64::from(s.value))),
            None => format_value(f64::from(s.value)),
        })
        .collect();
    let mut out = format!(
        "{}: field {}, iso {}, {} active voxels",
        request.file.display(),
        scene.field_name(),
        isos.join(", "),
        scene.stats().active_octants
    );
    if !scene.slices().is_empty() {
        out += &format!(", {} slices", scene.slices().len());
    }
    let mut written = vec![request.outputs.exr.display().to_string()];
    written.extend(request.outputs.preview.iter().map(|p| p.display().to_string()));
    out += &format!(": wrote {} in {:.2} s", written.join(" and "), took.as_secs_f64());
    out
}

/// Warns that a frame shows nothing, with the field's range.
fn warn_empty(scene: &Scene) {
    let f = &scene.file().fields()[scene.field()];
    let isos: Vec<String> = scene
        .isosurfaces()
        .iter()
        .map(|s| format_value(f64::from(s.value)))
        .collect();
    eprintln!(
        "warning: the frame shows no surface: {} ranges over [{}, {}] and the isovalues are {} ({} active voxels)",
        f.name,
        format_value(f64::from(f.min)),
        format_value(f64::from(f.max)),
        isos.join(", "),
        scene.stats().active_octants
    );
}

/// The request's scene with its isosurfaces, their painting and the slices.
fn open_scene(request: &RenderRequest) -> anyhow::Result<Scene> {
    let mut scene = Scene::open(&request.file, &request.scene)?;
    let isos = request_isos(request, &scene);
    scene.set_isosurfaces(&isos)?;
    let color_by = match request.color_by.as_slice() {
        [one] => vec![one.clone(); isos.len()],
        many => many.to_vec(),
    };
    scene.set_color_by(&color_by)?;
    if !request.slices.is_empty() {
        scene.set_slices(&request.slices, request.slice_field.clone())?;
    }
    Ok(scene)
}

/// The request's isosurfaces (the median of the field's values when none given).
pub fn request_isos(request: &RenderRequest, scene: &Scene) -> Vec<IsoSpec> {
    match request.isos.is_empty() {
        true => vec![IsoSpec::new(scene.default_isovalue())],
        false => request.isos.clone(),
    }
}
