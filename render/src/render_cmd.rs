//! The `render` and `demo` commands: arguments, their validation into a [`RenderConfig`] before
//! any work starts, and the pipeline from an `.amrk` file to an EXR frame.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::bvh::BvhBuilder;
use crate::camera::Camera;
use crate::output::exr_file::write_exr;
use crate::output::frame::FrameBuffer;
use crate::output::png_preview::write_preview;
use crate::sample_mode::SampleTracer;
use crate::shade::{render_frame, IsoSpec, Lighting, RenderSettings};
use crate::trace::{GridFrame, HybridTracer, Surface, VoxelSource};

/// A camera given on the command line: position, look-at point and up vector.
pub type CameraSpec = ([f64; 3], Option<[f64; 3]>, Option<[f64; 3]>);

/// How cell values are reconstructed between cell centres.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Reconstruction {
    /// The octant method (continuous across level boundaries).
    Octant,
    /// Trilinear on the dual cell of the current level.
    Current,
    /// The value of the cell containing the point.
    Nearest,
}

/// How rays find the isosurface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// BVH over active octants with exact ray-voxel intersection.
    Hybrid,
    /// Fixed-step ray marching with bisection.
    Sample,
}

/// Arguments of the render command.
#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// The .amrk file.
    pub file: PathBuf,
    /// Field to render (default: the file's first field).
    #[arg(long)]
    pub field: Option<String>,
    /// An isosurface: value, optional colour (name or #rrggbb) and opacity; repeat for several
    /// (default: the middle of the field's range).
    #[arg(long = "iso", value_name = "V[:COLOR[:OPACITY]]")]
    pub iso: Vec<IsoSpec>,
    /// Output OpenEXR file.
    #[arg(short = 'o', long = "output", value_name = "OUT.exr")]
    pub output: PathBuf,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "1024x768", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Camera position, world coordinates (default: framed automatically).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub camera_pos: Option<[f64; 3]>,
    /// Point the camera looks at (default: the domain's centre).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_at: Option<[f64; 3]>,
    /// Camera up vector.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<[f64; 3]>,
    /// Vertical field of view, degrees.
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 40.0,
        allow_hyphen_values = true
    )]
    pub fov: f64,
    /// Reconstruction method.
    #[arg(long, value_enum, default_value_t = Reconstruction::Octant)]
    pub reconstruction: Reconstruction,
    /// Intersection method.
    #[arg(long, value_enum, default_value_t = Method::Hybrid)]
    pub method: Method,
    /// Step of the sample method, world units (default: half the finest cell).
    #[arg(long, value_name = "S")]
    pub step: Option<f64>,
    /// Samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub spp: u32,
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Also write a tone-mapped PNG preview.
    #[arg(long, value_name = "OUT.png")]
    pub preview: Option<PathBuf>,
    /// Print statistics to stderr.
    #[arg(long)]
    pub stats: bool,
    /// Write statistics as JSON.
    #[arg(long, value_name = "PATH")]
    pub stats_json: Option<PathBuf>,
    /// Ambient-occlusion rays per hit (0 disables).
    #[arg(long, value_name = "N", default_value_t = 4)]
    pub ao: u32,
    /// Do not cast shadow rays.
    #[arg(long)]
    pub no_shadows: bool,
    /// Shade with each voxel's own trilinear gradient instead of normals continuous across voxels.
    #[arg(long)]
    pub flat_normals: bool,
    /// Under `mpirun` (a build with the `mpi` feature): every rank holds the whole scene and
    /// renders tiles (replicated, the default), or each holds a part of it and the frames are
    /// composited (partitioned; no shadows or ambient occlusion).
    #[arg(long, value_enum, value_name = "MODE")]
    pub mpi_mode: Option<crate::mpi::MpiMode>,
}

/// Parses an image size `WxH` (at least 1x1, at most 2^28 pixels).
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size '{s}' is not WxH"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("size '{s}' is not WxH"))
    };
    let (w, h) = (p(w)?, p(h)?);
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > 1 << 28 {
        return Err(format!(
            "size {w}x{h} must be at least 1x1 and at most 2^28 pixels"
        ));
    }
    Ok((w, h))
}

fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<&str> = s.split(',').collect();
    if v.len() != 3 {
        return Err(format!("'{s}' is not X,Y,Z"));
    }
    let mut out = [0.0f64; 3];
    for (o, x) in out.iter_mut().zip(v) {
        *o = x
            .trim()
            .parse::<f64>()
            .map_err(|_| format!("'{x}' in '{s}' is not a number"))?;
        if !o.is_finite() {
            return Err(format!("'{x}' in '{s}' is not finite"));
        }
    }
    Ok(out)
}

/// A validated render request for any [`ActiveSource`].
#[derive(Clone, Debug)]
pub struct RenderConfig {
    /// Isosurfaces, in the order given.
    pub isos: Vec<IsoSpec>,
    /// Width and height.
    pub size: (u32, u32),
    /// Camera position, look-at point (default: the domain's centre) and up vector (default:
    /// z, or y when z is along the view); `None` frames the domain automatically.
    pub camera: Option<CameraSpec>,
    /// Field of view for automatic framing.
    pub fov: f64,
    /// Intersection method.
    pub method: Method,
    /// Step of the sample method (world units); `None` picks half the finest grid unit.
    pub step: Option<f64>,
    /// Samples per pixel.
    pub spp: u32,
    /// Shadow rays.
    pub shadows: bool,
    /// AO rays per hit.
    pub ao: u32,
    /// Normals continuous across voxels.
    pub smooth_normals: bool,
}

/// A volume that can list its active voxels for an isovalue.
pub trait ActiveSource: VoxelSource {
    /// Refs of the voxels whose corner range contains `iso`.
    fn extract(&self, iso: f32) -> anyhow::Result<Vec<u64>>;
}

/// What a render produced and what it cost.
#[derive(Clone, Debug, Default)]
pub struct RenderReport {
    /// The frame.
    pub frame: FrameBuffer,
    /// The camera used.
    pub camera: Option<Camera>,
    /// Active voxels over all isosurfaces.
    pub active_octants: u64,
    /// Resident bytes of the refs.
    pub refs_bytes: u64,
    /// Resident bytes of the BVH nodes.
    pub bvh_bytes: u64,
    /// BVH nodes.
    pub bvh_nodes: u64,
    /// Largest build scratch held at once (boxes, PLOC buffers, binary BVH).
    pub build_scratch_bytes: u64,
    /// Extraction time.
    pub extract: Duration,
    /// BVH build time.
    pub bvh: Duration,
    /// Frame time.
    pub render: Duration,
    /// Ray queries (one per ray and isosurface).
    pub rays: u64,
}

/// The camera and lighting of a render of `src`.
pub fn scene_setup<S: ActiveSource + ?Sized>(
    src: &S,
    cfg: &RenderConfig,
) -> anyhow::Result<(Camera, Lighting)> {
    let frame = src.frame();
    let (lo, hi) = frame.world_bounds();
    let (w, h) = cfg.size;
    let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
    let camera = match cfg.camera {
        Some((pos, look, up)) => make_camera(pos, look.unwrap_or(centre), up, cfg.fov)?,
        None => Camera::framing(lo, hi, cfg.fov, f64::from(w) / f64::from(h))?,
    };
    let diag = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
    let colors = cfg
        .isos
        .iter()
        .enumerate()
        .map(|(i, s)| s.color_or_palette(i))
        .collect();
    let opacity = cfg.isos.iter().map(|s| s.opacity).collect();
    let mut light = Lighting::for_camera(&camera, colors, opacity, 0.08 * diag);
    light.shadows = cfg.shadows;
    light.ao_rays = cfg.ao;
    Ok((camera, light))
}

/// Builds one surface per isovalue of `cfg` from the refs `refs(iso)` returns, adding the
/// extraction and build times and sizes to `report`.
pub fn build_surfaces<S: VoxelSource + ?Sized>(
    src: &S,
    cfg: &RenderConfig,
    mut refs: impl FnMut(f32) -> anyhow::Result<Vec<u64>>,
    report: &mut RenderReport,
) -> anyhow::Result<Vec<Surface>> {
    let mut builder = BvhBuilder::new();
    let mut surfaces = Vec::with_capacity(cfg.isos.len());
    for spec in &cfg.isos {
        let t = Instant::now();
        let refs = refs(spec.value)?;
        report.extract += t.elapsed();
        src.release_pages();
        let t = Instant::now();
        let s = Surface::build_owned(src, spec.value, refs, &mut builder);
        report.bvh += t.elapsed();
        report.build_scratch_bytes = report
            .build_scratch_bytes
            .max(builder.last_scratch_bytes as u64);
        report.active_octants += s.bvh.len() as u64;
        report.refs_bytes += s.bvh.refs_bytes() as u64;
        report.bvh_bytes += s.bvh.bvh_bytes() as u64;
        report.bvh_nodes += s.bvh.num_nodes() as u64;
        surfaces.push(s);
    }
    builder.release();
    src.release_pages();
    Ok(surfaces)
}

/// The step of the sample method: `cfg.step`, or half the finest grid unit.
pub fn sample_step(frame: &GridFrame, cfg: &RenderConfig) -> anyhow::Result<f64> {
    let unit = frame.unit.iter().fold(f64::INFINITY, |m, &u| m.min(u));
    let step = cfg.step.unwrap_or(0.5 * unit);
    if !(step > 0.0 && step.is_finite()) {
        bail!("--step {step} must be positive and finite");
    }
    Ok(step)
}

/// Renders `src` as `cfg` asks; `progress(rows)` is called as rows finish.
pub fn render_source<S: ActiveSource + ?Sized>(
    src: &S,
    cfg: &RenderConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> anyhow::Result<RenderReport> {
    let (camera, light) = scene_setup(src, cfg)?;
    let mut report = RenderReport {
        camera: Some(camera),
        ..Default::default()
    };
    let (w, h) = cfg.size;
    let settings = RenderSettings {
        width: w,
        height: h,
        spp: cfg.spp,
    };
    let (fb, rays) = match cfg.method {
        Method::Hybrid => {
            let surfaces = build_surfaces(src, cfg, |iso| src.extract(iso), &mut report)?;
            let tracer = HybridTracer {
                src,
                surfaces: &surfaces,
                smooth_normals: cfg.smooth_normals,
            };
            let t = Instant::now();
            let out = render_frame(&tracer, &camera, &light, settings, progress);
            report.render = t.elapsed();
            out
        }
        Method::Sample => {
            let tracer = SampleTracer {
                src,
                isos: cfg.isos.iter().map(|s| s.value).collect(),
                step: sample_step(&src.frame(), cfg)?,
            };
            let t = Instant::now();
            let out = render_frame(&tracer, &camera, &light, settings, progress);
            report.render = t.elapsed();
            out
        }
    };
    report.frame = fb;
    report.rays = rays;
    Ok(report)
}

/// The EXR header's text attributes for a render.
pub fn header_meta(
    cfg: &RenderConfig,
    report: &RenderReport,
    extra: &[(&str, String)],
) -> Vec<(String, String)> {
    let mut m: Vec<(String, String)> = Vec::new();
    if let Some(c) = &report.camera {
        m.push((
            "camera".into(),
            format!(
                "pos={:?} look_at={:?} up={:?} fov_deg={}",
                c.pos, c.look_at, c.up, c.fov_deg
            ),
        ));
    }
    let isos: Vec<String> = cfg
        .isos
        .iter()
        .map(|s| format!("{}:{:?}:{}", s.value, s.color, s.opacity))
        .collect();
    m.push(("isovalues".into(), isos.join(" ")));
    m.push(("method".into(), format!("{:?}", cfg.method).to_lowercase()));
    m.push((
        "timings_ms".into(),
        format!(
            "extract={:.3} bvh={:.3} render={:.3}",
            ms(report.extract),
            ms(report.bvh),
            ms(report.render)
        ),
    ));
    m.push((
        "P_relative_to".into(),
        "P_origin_x/y/z (world position of the domain's lower corner)".into(),
    ));
    for (k, v) in extra {
        m.push(((*k).into(), v.clone()));
    }
    m
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Writes the frame, the preview and the statistics as the arguments ask.
pub fn write_outputs(
    report: &RenderReport,
    meta: &[(String, String)],
    output: &Path,
    preview: Option<&Path>,
    stats: &[(String, String)],
    print_stats: bool,
    stats_json: Option<&Path>,
) -> anyhow::Result<()> {
    write_exr(output, &report.frame, meta)?;
    if let Some(p) = preview {
        write_preview(p, &report.frame)?;
    }
    if print_stats {
        let rows = stats;
        let width = rows.iter().map(|r| r.0.len()).max().unwrap_or(0);
        for (k, v) in rows {
            eprintln!("{k:<width$}  {v}");
        }
    }
    if let Some(p) = stats_json {
        let body: Vec<String> = stats
            .iter()
            .map(|(k, v)| format!("  \"{k}\": {v}"))
            .collect();
        let tmp = crate::output::exr_file::temp_path(p);
        std::fs::write(&tmp, format!("{{\n{}\n}}\n", body.join(",\n")))
            .with_context(|| format!("cannot write {}", tmp.display()))?;
        std::fs::rename(&tmp, p).with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(())
}

/// The statistics rows (`key`, JSON value) of a render.
pub fn stats_rows(report: &RenderReport, extra: &[(&str, String)]) -> Vec<(String, String)> {
    let n = report.active_octants.max(1) as f64;
    let mut rows: Vec<(String, String)> = vec![
        ("active_octants".into(), report.active_octants.to_string()),
        ("refs_bytes".into(), report.refs_bytes.to_string()),
        ("bvh_bytes".into(), report.bvh_bytes.to_string()),
        ("bvh_nodes".into(), report.bvh_nodes.to_string()),
        (
            "resident_bytes_per_octant".into(),
            format!("{:.2}", (report.refs_bytes + report.bvh_bytes) as f64 / n),
        ),
        (
            "build_scratch_bytes".into(),
            report.build_scratch_bytes.to_string(),
        ),
        ("extract_ms".into(), format!("{:.3}", ms(report.extract))),
        ("bvh_ms".into(), format!("{:.3}", ms(report.bvh))),
        ("render_ms".into(), format!("{:.3}", ms(report.render))),
        ("rays".into(), report.rays.to_string()),
        (
            "rays_per_second".into(),
            format!(
                "{:.0}",
                report.rays as f64 / report.render.as_secs_f64().max(1e-9)
            ),
        ),
        ("width".into(), report.frame.width.to_string()),
        ("height".into(), report.frame.height.to_string()),
        ("covered_pixels".into(), report.frame.covered().to_string()),
        (
            "peak_rss_bytes".into(),
            peak_rss_bytes().map_or("null".into(), |b| b.to_string()),
        ),
    ];
    for (k, v) in extra {
        rows.push(((*k).into(), v.clone()));
    }
    rows
}

/// Peak resident set of this process (`VmHWM` in `/proc/self/status`).
pub fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line
        .trim_start_matches("VmHWM:")
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}

/// A progress callback that draws a bar on stderr once a frame has taken more than a second,
/// and only when stderr is a terminal.
pub fn progress_bar(rows: u64) -> (ProgressBar, impl Fn(u64) + Sync) {
    let bar = ProgressBar::with_draw_target(Some(rows), ProgressDrawTarget::hidden());
    if let Ok(style) =
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} rows ({eta})")
    {
        bar.set_style(style);
    }
    let start = Instant::now();
    let shown = AtomicBool::new(false);
    let terminal = std::io::stderr().is_terminal();
    let b = bar.clone();
    let cb = move |n: u64| {
        b.inc(n);
        if terminal && !shown.load(Ordering::Relaxed) && start.elapsed() > Duration::from_secs(1) {
            shown.store(true, Ordering::Relaxed);
            b.set_draw_target(ProgressDrawTarget::stderr());
        }
    };
    (bar, cb)
}

/// A camera from user input: `up` defaults to z, or y when the view is along z.
fn make_camera(
    pos: [f64; 3],
    look: [f64; 3],
    up: Option<[f64; 3]>,
    fov: f64,
) -> anyhow::Result<Camera> {
    let cam = match up {
        Some(up) => Camera::new(pos, look, up, fov),
        None => Camera::new(pos, look, [0.0, 0.0, 1.0], fov).or_else(|e| match e {
            crate::camera::CameraError::BadUp(_) => Camera::new(pos, look, [0.0, 1.0, 0.0], fov),
            e => Err(e),
        }),
    };
    Ok(cam?)
}

impl RenderArgs {
    /// Checks everything that can be checked before opening the file.
    pub fn config(&self) -> anyhow::Result<RenderConfig> {
        let camera = match (self.camera_pos, self.look_at) {
            (Some(pos), look) => Some((pos, look, self.up)),
            (None, Some(_)) => bail!("--look-at needs --camera-pos"),
            (None, None) if self.up.is_some() => bail!("--up needs --camera-pos"),
            (None, None) => None,
        };
        if let Some((pos, Some(look), up)) = camera {
            make_camera(pos, look, up, self.fov)?;
        }
        if !(self.fov > 0.0 && self.fov < 180.0) {
            bail!("--fov {} is outside (0, 180) degrees", self.fov);
        }
        if self.spp == 0 {
            bail!("--spp must be at least 1");
        }
        if let Some(s) = self.step {
            if !(s > 0.0 && s.is_finite()) {
                bail!("--step {s} must be positive and finite");
            }
        }
        if self.threads == Some(0) {
            bail!("--threads must be at least 1");
        }
        Ok(RenderConfig {
            isos: self.iso.clone(),
            size: self.size,
            camera,
            fov: self.fov,
            method: self.method,
            step: self.step,
            spp: self.spp,
            shadows: !self.no_shadows,
            ao: self.ao,
            smooth_normals: !self.flat_normals,
        })
    }
}

/// Runs `amr-render FILE.amrk ...`.
pub fn run_render(args: &RenderArgs) -> anyhow::Result<()> {
    let cfg = args.config()?;
    let run = || match crate::mpi::use_mpi(args)? {
        true => crate::mpi::render_file(args, cfg.clone()),
        false => crate::trace::amr_source::render_file(args, cfg.clone()),
    };
    match args.threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()?
            .install(run),
        None => run(),
    }
}

/// Runs `amr-render demo`: synthesizes a small multi-level dataset, converts it to a temporary
/// `.amrk` file and renders it to `out` (with a PNG preview beside it).
pub fn run_demo(out: &Path) -> anyhow::Result<()> {
    crate::trace::amr_source::demo(out)
}
