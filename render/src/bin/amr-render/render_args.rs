//! The render command's arguments and their validation into a library request before any work
//! starts.

use std::path::PathBuf;

use amr_render::camera::ViewFrom;
use amr_render::camera_path::CameraKey;
use amr_render::output::exr_file::ExrCompression;
use amr_render::output::Background;
use amr_render::{
    CameraPlacement, ClipBox, ColorBy, ColorScale, Colormap, Outline, Reconstruction, SceneOptions,
    Slice, TraceMethod, View,
};
use anyhow::bail;
use clap::Args;

use crate::animation::{Animation, IsoSweep};
use crate::field_scale_arg::FieldScaleArg;
use crate::surface_arg::SurfaceArg;

/// Most worker threads `--threads` may ask for.
pub const MAX_THREADS: usize = 256;

/// Arguments of the render command.
#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// The .amrk file; several render a time series, one frame per file in the order given.
    /// A `.toml` scene file (see --write-scene) stands for the arguments it holds.
    #[arg(required = true, num_args = 1.., value_name = "FILE.amrk")]
    pub files: Vec<PathBuf>,
    /// Field to render (default: the file's first field).
    #[arg(long)]
    pub field: Option<String>,
    /// An isosurface: value, optional colour (name or #rrggbb) and opacity; repeat for several
    /// (default: the median of the field's cell values). The value is a number, or pQ: the
    /// field's Q-th percentile over every cell (--iso p99:red), found in each file. Negative
    /// values as typed: --iso -60:red. A surface of another field than --field: its name and
    /// `=` first, --iso temp=1500:red. `--iso none` draws no isosurface: slices alone.
    #[arg(
        long = "iso",
        value_name = "[FIELD=]V[:COLOR[:OPACITY]]",
        allow_hyphen_values = true,
        value_parser = parse_iso
    )]
    pub iso: Vec<Option<SurfaceArg>>,
    /// Output file: OpenEXR with every channel (.exr, or no extension), or a PNG picture with
    /// its legend when the name ends in .png (other extensions are refused); with several
    /// frames, OUT_0000.exr, OUT_0001.exr, ...
    #[arg(short = 'o', long = "output", value_name = "OUT.exr|OUT.png")]
    pub output: PathBuf,
    /// Paint isosurfaces by a field of the file (sampled at each hit), by the length of a vector
    /// of fields written between bars ('|x-velocity,y-velocity,z-velocity|') or by `level`;
    /// repeat to pair with the --iso values in order (`none` leaves one unpainted); one value
    /// paints all.
    #[arg(long = "color-by", value_name = "FIELD|level|none", value_parser = parse_color_by)]
    pub color_by: Vec<Option<ColorBy>>,
    /// Colormap of painted surfaces and slices [default: viridis].
    #[arg(long, value_name = "NAME")]
    pub colormap: Option<Colormap>,
    /// Values at the colormap's ends (default: 1st..99th percentile of the values in view);
    /// `auto-series`: each painting field's range over every file of a time series, the same
    /// for every frame.
    #[arg(long, value_name = "LO:HI|auto-series", value_parser = parse_color_range, allow_hyphen_values = true)]
    pub color_range: Option<ColorRange>,
    /// Map the logarithm of the values.
    #[arg(long)]
    pub color_log: bool,
    /// A field painted with a scale of its own: colormap, `log` or `linear`, range, each else
    /// the frame's (--colormap, --color-log, its values in view); repeat for several fields:
    /// --color-scale 'Y(OH)=magma:log'.
    #[arg(
        long = "color-scale",
        value_name = "FIELD=[COLORMAP][:log][:LO:HI]",
        allow_hyphen_values = true
    )]
    pub field_scale: Vec<FieldScaleArg>,
    /// A slice across an axis: x=0.5, with an optional opacity (z=0.008:0.6); repeatable.
    #[arg(long, value_name = "AXIS=VALUE[:OPACITY]", value_parser = Slice::parse_axis, allow_hyphen_values = true)]
    pub slice: Vec<Slice>,
    /// A slice through point P with normal N; repeatable.
    #[arg(long, value_name = "PX,PY,PZ,NX,NY,NZ[:OPACITY]", value_parser = Slice::parse_plane, allow_hyphen_values = true)]
    pub slice_plane: Vec<Slice>,
    /// The field that paints slices, or a magnitude '|A,B,C|' (default: the first --color-by
    /// field, else the rendered one).
    #[arg(long, value_name = "FIELD|level")]
    pub slice_field: Option<ColorBy>,
    /// Lines drawn for context: none, domain (its bounding box) or boxes (every level's boxes as
    /// the file stores them: large boxes split at amr-convert's --brick, small ones joined unless
    /// converted with --keep-boxes).
    #[arg(long, value_name = "WHAT", default_value = "domain")]
    pub outline: Outline,
    /// Frame the whole domain instead of the isosurfaces when no camera is given.
    #[arg(long)]
    pub frame_domain: bool,
    /// Print nothing but errors and warnings.
    #[arg(short, long)]
    pub quiet: bool,
    /// Frames on a circle around the point looked at (about the up vector), starting at the
    /// given or automatic camera.
    #[arg(long, value_name = "N")]
    pub orbit: Option<u32>,
    /// Degrees the orbit turns in all [default: 360].
    #[arg(long, value_name = "D", allow_hyphen_values = true)]
    pub orbit_degrees: Option<f64>,
    /// N frames with one more isosurface whose value goes from A to B (colour, opacity and
    /// another field than --field as for --iso: temp=800:1600:24).
    #[arg(
        long,
        value_name = "[FIELD=]A:B:N[:COLOR[:OPACITY]]",
        allow_hyphen_values = true
    )]
    pub iso_sweep: Option<IsoSweep>,
    /// A camera at one frame of an animation, the cameras between keyframes interpolated;
    /// repeat for several.
    #[arg(long, value_name = "FRAME:X,Y,Z:LX,LY,LZ[:UX,UY,UZ]", allow_hyphen_values = true, value_parser = parse_keyframe)]
    pub keyframe: Vec<CameraKey>,
    /// Encodes the frames' PNG previews into a movie with ffmpeg (when it is installed).
    #[arg(long, value_name = "OUT.mp4")]
    pub movie: Option<PathBuf>,
    /// Frames per second of --movie [default: 24].
    #[arg(long, value_name = "N")]
    pub fps: Option<u32>,
    /// Writes these arguments as a TOML scene file that `amr-render FILE.toml` renders again,
    /// once the command has succeeded.
    #[arg(long, value_name = "SCENE.toml")]
    pub write_scene: Option<PathBuf>,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "1024x768", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Camera position, world coordinates (default: framed automatically).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub camera_pos: Option<[f64; 3]>,
    /// Point the camera looks at (default: the domain's centre).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_at: Option<[f64; 3]>,
    /// Camera up vector (default: z, or y for a view along z).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<[f64; 3]>,
    /// Where the automatic camera looks from: an axis (+z looks down on the x-y plane, -x, y,
    /// ...) or a direction X,Y,Z from the centre of what it frames, which then fills the
    /// picture (an orbit keeps the distance at which every frame holds it)
    #[arg(long, value_name = "AXIS|X,Y,Z", value_parser = parse_view_from, allow_hyphen_values = true)]
    pub view_from: Option<[f64; 3]>,
    /// Cut the isosurfaces to this box (world coordinates, like --camera-pos) for a cut-away:
    /// only voxels that meet it are extracted, and the surfaces behind the cut show through
    /// the opening. Slices are not cut.
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    pub clip: Option<String>,
    /// Extract only the leaves the camera's view frustum may see (again for each camera of an
    /// animation). The frame is the same as the whole extraction's with --no-shadows --ao 0;
    /// otherwise surfaces out of view cast no shadows or occlusion into it. Without
    /// --camera-pos the camera frames the domain.
    #[arg(long)]
    pub extract_in_view: bool,
    /// Vertical field of view, degrees.
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 40.0,
        allow_hyphen_values = true
    )]
    pub fov: f64,
    /// Orthographic projection: parallel rays, so that a length looks as long at every depth,
    /// as in a slice plot. The picture is --view-height tall, else as tall as the perspective
    /// picture at the point looked at (the automatic camera: what it frames)
    #[arg(long)]
    pub ortho: bool,
    /// The orthographic picture's height, world units (with --ortho)
    #[arg(long, value_name = "H", requires = "ortho", allow_hyphen_values = true)]
    pub view_height: Option<f64>,
    /// The colour PNG pictures show where no surface is (a CSS name, #rrggbb, rgb(r,g,b)):
    /// `--background white` for a figure on a page; lines and labels turn dark on a light one
    /// [default: the neutral grey]
    #[arg(long, value_name = "COLOR")]
    pub background: Option<Background>,
    /// Reconstruction method: octant, current or nearest.
    #[arg(long, default_value_t = Reconstruction::Octant)]
    pub reconstruction: Reconstruction,
    /// Intersection method: hybrid (BVH and exact intersection) or sample (ray marching).
    #[arg(long, default_value_t = TraceMethod::Hybrid)]
    pub method: TraceMethod,
    /// Step of the sample method, world units (default: half a cell of the level each sample lands in).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub step: Option<f64>,
    /// Samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub spp: u32,
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Also write a tone-mapped PNG preview with its legend.
    #[arg(long, value_name = "OUT.png")]
    pub preview: Option<PathBuf>,
    /// PNG pictures without the legend (isovalues, colour bars, axis triad), as for a figure
    /// composed elsewhere; the legend is also left out of a picture too small to hold it.
    #[arg(long)]
    pub no_legend: bool,
    /// Lossless compression of EXR frames: piz (default; smaller and faster than zip), zip, rle
    /// (fastest, largest files) or none.
    #[arg(long, value_name = "KIND")]
    pub exr_compression: Option<ExrCompression>,
    /// Print statistics to stderr.
    #[arg(long)]
    pub stats: bool,
    /// Write statistics as JSON (`-`: to standard output)
    #[arg(long, value_name = "PATH")]
    pub stats_json: Option<PathBuf>,
    /// Ambient-occlusion rays per hit (0 disables); filtered across pixels, one ray per hit
    /// is less noisy than four unfiltered ones.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub ao: u32,
    /// Do not filter the ambient occlusion across neighbouring pixels (noisier; the filter
    /// applies to frames of one sample per pixel).
    #[arg(long)]
    pub no_ao_filter: bool,
    /// Do not cast shadow rays.
    #[arg(long)]
    pub no_shadows: bool,
    /// Shade with each voxel's own trilinear gradient instead of normals continuous across voxels.
    #[arg(long)]
    pub flat_normals: bool,
    /// Under `mpirun` (a build with the `mpi` feature): every rank holds the whole scene and
    /// renders tiles (replicated, the default), or each holds a part of it and the frames are
    /// composited (partitioned; no shadows or ambient occlusion).
    #[arg(long, value_name = "MODE")]
    pub mpi_mode: Option<String>,
}

/// A validated render request: what the library needs and where the results go.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    /// The files, one per frame of a time series.
    pub files: Vec<PathBuf>,
    /// The scene's field, reconstruction and method.
    pub scene: SceneOptions,
    /// Isosurfaces (empty: the median of the field's values, unless `no_isosurface`).
    pub isos: Vec<SurfaceArg>,
    /// `--iso none`: no isosurface, not even the default one.
    pub no_isosurface: bool,
    /// Camera, size, sampling and lighting.
    pub view: View,
    /// Output files and reports.
    pub outputs: Outputs,
    /// Worker threads.
    pub threads: Option<usize>,
    /// What paints each isosurface (one entry paints all).
    pub color_by: Vec<Option<ColorBy>>,
    /// Slices.
    pub slices: Vec<Slice>,
    /// What paints the slices (`None`: the default).
    pub slice_field: Option<ColorBy>,
    /// The automatic camera frames the domain, not the isosurfaces.
    pub frame_domain: bool,
    /// One colour range for a whole series: the painting field's range over its files.
    pub series_color_range: bool,
    /// Frames after the first: a camera path, an isovalue sweep, a time series.
    pub animation: Animation,
    /// The box the surfaces are cut to.
    pub clip: Option<ClipBox>,
    /// Extraction limited to each frame's view frustum.
    pub extract_in_view: bool,
}

/// Where a frame and its statistics go.
#[derive(Clone, Debug)]
pub struct Outputs {
    /// The EXR frame.
    pub exr: PathBuf,
    /// A PNG preview.
    pub preview: Option<PathBuf>,
    /// Whether PNG pictures get their legend.
    pub legend: bool,
    /// How EXR frames are compressed.
    pub exr_compression: ExrCompression,
    /// Print statistics to stderr.
    pub print_stats: bool,
    /// Statistics as JSON.
    pub stats_json: Option<PathBuf>,
    /// Print the one-line summary.
    pub summary: bool,
    /// A movie of the frames' previews, and its frame rate.
    pub movie: Option<(PathBuf, u32)>,
}

impl RenderArgs {
    /// True when a slice is given (`--slice` or `--slice-plane`).
    fn has_slices(&self) -> bool {
        !(self.slice.is_empty() && self.slice_plane.is_empty())
    }

    /// The fields named to paint surfaces (`--color-by`) or slices (`--slice-field`), in the
    /// order they first do.
    fn painting_fields(&self) -> Vec<&str> {
        let painters = self.color_by.iter().chain([&self.slice_field]).flatten();
        amr_render::coloring::painting_fields(painters)
    }

    /// An error when `--color-range` would be the range of several painting fields (those
    /// without a range of their own), or a `--color-scale` names a field that paints nothing.
    fn check_field_scales(&self) -> anyhow::Result<()> {
        let fields = self.painting_fields();
        // The fields that would take `--color-range`: those without a range of their own.
        let own_range = |f: &str| {
            self.field_scale
                .iter()
                .any(|s| s.field == f && s.range.is_some())
        };
        let shared: Vec<&str> = fields.iter().copied().filter(|f| !own_range(f)).collect();
        // `auto-series` is a range per field: each field's over the series.
        if let (Some(ColorRange::Fixed(..)), true) = (&self.color_range, shared.len() > 1) {
            bail!(
                "--color-range gives one range, but {} fields paint ({}): each takes the 1st to \
                 99th percentile of its own values in view, on its own colour bar (or give a \
                 field its range: --color-scale FIELD=:LO:HI)",
                shared.len(),
                shared.join(", ")
            );
        }
        // A slice left to its default painter with no field painting surfaces takes the
        // scene's field, named or not: the renderer checks a scale against it.
        if self.has_slices() && self.slice_field.is_none() && fields.is_empty() {
            return Ok(());
        }
        match self
            .field_scale
            .iter()
            .find(|s| !fields.contains(&s.field.as_str()))
        {
            Some(s) => bail!(
                "--color-scale {}=...: {} paints nothing in this frame{}",
                s.field,
                s.field,
                match fields.is_empty() {
                    true => String::new(),
                    false => format!(" (painting: {})", fields.join(", ")),
                }
            ),
            None => Ok(()),
        }
    }

    /// An error when the options of the colour scale (`--colormap`, `--color-range`,
    /// `--color-log`, `--color-scale`) are given but no field paints a surface or a slice: they
    /// would change nothing, and the user who gave them expected colour.
    fn check_color_scale_applies(&self) -> anyhow::Result<()> {
        let paints_field = !self.painting_fields().is_empty()
            || (self.has_slices() && self.slice_field != Some(ColorBy::Level));
        let given: Vec<&str> = [
            (self.colormap.is_some(), "--colormap"),
            (self.color_range.is_some(), "--color-range"),
            (self.color_log, "--color-log"),
            (!self.field_scale.is_empty(), "--color-scale"),
        ]
        .into_iter()
        .filter_map(|(on, name)| on.then_some(name))
        .collect();
        if paints_field || given.is_empty() {
            return Ok(());
        }
        let by_level = self
            .color_by
            .iter()
            .chain([&self.slice_field])
            .any(|c| *c == Some(ColorBy::Level));
        bail!(
            "{} colours a field's values, but nothing is painted by a field{}: add {}",
            given.join(", "),
            if by_level {
                " (painting by level gives each level its own colour)"
            } else {
                ""
            },
            if self.has_slices() {
                "--color-by FIELD or --slice-field FIELD"
            } else {
                "--color-by FIELD or a --slice"
            }
        )
    }

    /// An error for an option that the rest of the command makes void: one that only qualifies
    /// another option left out (`--fps` without `--movie`), or one that another overrides
    /// (`--camera-pos` beside `--keyframe`). Ignored, it would leave the user believing it
    /// took effect.
    fn check_options_apply(&self) -> anyhow::Result<()> {
        let needs = [
            (
                self.orbit_degrees.is_some(),
                self.orbit.is_some(),
                "--orbit-degrees",
                "--orbit N",
            ),
            (
                self.fps.is_some(),
                self.movie.is_some(),
                "--fps",
                "--movie OUT.mp4",
            ),
            (
                self.step.is_some(),
                self.method == TraceMethod::Sample,
                "--step",
                "--method sample",
            ),
            (
                self.slice_field.is_some(),
                self.has_slices(),
                "--slice-field",
                "--slice or --slice-plane",
            ),
        ];
        for (given, parent, option, what) in needs {
            if given && !parent {
                bail!("{option} applies to {what}, which is not given");
            }
        }
        let writes_exr = self
            .output
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if self.exr_compression.is_some() && !writes_exr {
            bail!(
                "--exr-compression applies to EXR output, and -o {} writes none",
                self.output.display()
            );
        }
        if self.frame_domain && !self.keyframe.is_empty() {
            bail!("--keyframe places the camera of every frame: leave out --frame-domain");
        }
        if self.view_from.is_some() && self.camera_pos.is_some() {
            bail!("--camera-pos places the camera and --view-from the automatic one: give one of them");
        }
        let placed = [
            (self.camera_pos.is_some(), "--camera-pos"),
            (self.look_at.is_some(), "--look-at"),
            (self.up.is_some(), "--up"),
            (self.view_from.is_some(), "--view-from"),
        ];
        if let Some((_, option)) = placed.iter().find(|(given, _)| *given) {
            if !self.keyframe.is_empty() {
                bail!("--keyframe places the camera of every frame: leave out {option}");
            }
            // --view-from (and its --up) turns the automatic camera, which may frame the domain.
            if self.frame_domain && self.view_from.is_none() {
                bail!("--frame-domain frames the automatic camera: leave it out with {option}");
            }
        }
        Ok(())
    }

    /// Checks everything that can be checked before opening the file.
    pub fn request(&self) -> anyhow::Result<RenderRequest> {
        let camera = match (self.camera_pos, self.look_at) {
            (Some(pos), look_at) => Some(CameraPlacement {
                pos,
                look_at,
                up: self.up,
            }),
            (None, Some(_)) => bail!("--look-at needs --camera-pos"),
            (None, None) if self.up.is_some() && self.view_from.is_none() => {
                bail!("--up needs --camera-pos or --view-from")
            }
            (None, None) => None,
        };
        match self.threads {
            Some(n) if n == 0 || n > MAX_THREADS => {
                bail!("--threads {n} must be between 1 and {MAX_THREADS}")
            }
            _ => {}
        }
        if self.mpi_mode.is_some() && !cfg!(feature = "mpi") {
            bail!("--mpi-mode needs a build with `--features mpi` and a start with mpirun");
        }
        let color_scale = ColorScale {
            colormap: self.colormap.unwrap_or_default(),
            range: match self.color_range {
                Some(ColorRange::Fixed(lo, hi)) => Some((lo, hi)),
                _ => None,
            },
            log: self.color_log,
        };
        let view = View {
            camera,
            view_from: self.view_from.map(|dir| ViewFrom {
                dir,
                up: self.up,
                tight: self.orbit.is_none(),
            }),
            fov_deg: self.fov,
            orthographic: self.ortho,
            view_height: self.view_height,
            size: self.size,
            spp: self.spp,
            shadows: !self.no_shadows,
            ao_rays: self.ao,
            ao_filter: !self.no_ao_filter,
            smooth_normals: !self.flat_normals,
            sample_step: self.step,
            color_scale,
            field_scales: self
                .field_scale
                .iter()
                .map(|s| (s.field.clone(), s.scale(&color_scale)))
                .collect(),
            outline: self.outline,
            background: self.background.unwrap_or_default(),
        };
        let no_isosurface = self.iso.iter().any(Option::is_none);
        if no_isosurface && self.iso.len() > 1 {
            bail!("--iso none draws no isosurface: leave out the other --iso values, or it");
        }
        if no_isosurface && !self.has_slices() && self.iso_sweep.is_none() {
            bail!(
                "--iso none draws no isosurface, and nothing else is asked for: add a --slice \
                 (x=0.5) or a --slice-plane"
            );
        }
        let isos: Vec<SurfaceArg> = self.iso.iter().flatten().cloned().collect();
        if self.color_by.len() > 1 && self.color_by.len() > isos.len() {
            bail!(
                "{} --color-by values for {} --iso values: give one (for all) or one per isosurface",
                self.color_by.len(),
                isos.len()
            );
        }
        view.validate()?;
        self.check_field_scales()?;
        self.check_color_scale_applies()?;
        self.check_options_apply()?;
        let clip = match &self.clip {
            Some(text) => Some(
                text.parse::<ClipBox>()
                    .map_err(|e| anyhow::anyhow!("--clip: {e}"))?,
            ),
            None => None,
        };
        let fps = self.fps.unwrap_or(24);
        if fps == 0 || fps > 240 {
            bail!("--fps {fps} must be between 1 and 240");
        }
        let animation = Animation::new(
            self.files.len(),
            self.orbit.map(|n| (n, self.orbit_degrees.unwrap_or(360.0))),
            self.iso_sweep.clone(),
            self.keyframe.clone(),
        )?;
        Ok(RenderRequest {
            files: self.files.clone(),
            scene: SceneOptions {
                field: self.field.clone(),
                reconstruction: self.reconstruction,
                method: self.method,
                release_pages: true,
            },
            isos,
            no_isosurface,
            view,
            outputs: Outputs {
                exr: self.output.clone(),
                preview: self.preview.clone(),
                legend: !self.no_legend,
                exr_compression: self.exr_compression.unwrap_or_default(),
                print_stats: self.stats,
                stats_json: self.stats_json.clone(),
                summary: !self.quiet,
                movie: self.movie.clone().map(|m| (m, fps)),
            },
            threads: self.threads,
            animation,
            color_by: self.color_by.clone(),
            slices: self
                .slice
                .iter()
                .chain(&self.slice_plane)
                .copied()
                .collect(),
            slice_field: self.slice_field.clone(),
            series_color_range: self.color_range == Some(ColorRange::AutoSeries),
            frame_domain: self.frame_domain,
            clip,
            extract_in_view: self.extract_in_view,
        })
    }
}

/// Parses an image size `WxH`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size '{s}' is not WxH"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("size '{s}' is not WxH"))
    };
    Ok((p(w)?, p(h)?))
}

/// Parses what paints a surface: a field name, `level`, or `none`.
/// Parses `--iso`: a surface, or `none` for none.
fn parse_iso(s: &str) -> Result<Option<SurfaceArg>, String> {
    match s.trim() {
        "none" => Ok(None),
        other => other.parse().map(Some),
    }
}

fn parse_color_by(s: &str) -> Result<Option<ColorBy>, String> {
    match s.trim() {
        "none" => Ok(None),
        other => other.parse().map(Some),
    }
}

/// What `--color-range` asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ColorRange {
    /// These values at the colormap's ends.
    Fixed(f64, f64),
    /// The painting field's range over every file of the series.
    AutoSeries,
}

/// Parses `LO:HI` or `auto-series`.
fn parse_color_range(s: &str) -> Result<ColorRange, String> {
    if s.trim() == "auto-series" {
        return Ok(ColorRange::AutoSeries);
    }
    parse_range(s).map(|(lo, hi)| ColorRange::Fixed(lo, hi))
}

/// Parses a range `LO:HI` of finite numbers with `LO < HI`.
pub fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (lo, hi) = s
        .split_once(':')
        .ok_or_else(|| format!("range '{s}' is not LO:HI"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("'{v}' in range '{s}' is not a finite number"))
    };
    let (lo, hi) = (p(lo)?, p(hi)?);
    if !(lo < hi) {
        return Err(format!("range '{s}' needs LO < HI"));
    }
    Ok((lo, hi))
}

/// Parses a keyframe `FRAME:X,Y,Z:LX,LY,LZ[:UX,UY,UZ]`.
fn parse_keyframe(s: &str) -> Result<CameraKey, String> {
    let parts: Vec<&str> = s.split(':').collect();
    if !(3..=4).contains(&parts.len()) {
        return Err(format!(
            "keyframe '{s}' is not FRAME:X,Y,Z:LX,LY,LZ[:UX,UY,UZ]"
        ));
    }
    let frame = parts[0]
        .trim()
        .parse::<u32>()
        .map_err(|_| format!("frame '{}' in '{s}' is not a frame number", parts[0]))?;
    Ok(CameraKey {
        frame,
        pos: parse_vec3(parts[1])?,
        look_at: parse_vec3(parts[2])?,
        up: match parts.get(3) {
            Some(u) => parse_vec3(u)?,
            None => [0.0, 0.0, 1.0],
        },
    })
}

/// Parses `--view-from`: an axis, `+x`, `x` (the same), `-x`, ..., or a vector `X,Y,Z` that is
/// not zero.
fn parse_view_from(s: &str) -> Result<[f64; 3], String> {
    let axis = s.trim().to_ascii_lowercase();
    let (sign, name) = match axis.strip_prefix('-') {
        Some(name) => (-1.0, name),
        None => (1.0, axis.strip_prefix('+').unwrap_or(&axis)),
    };
    if let Some(a) = ["x", "y", "z"].iter().position(|&n| n == name) {
        let mut dir = [0.0; 3];
        dir[a] = sign;
        return Ok(dir);
    }
    let dir = parse_vec3(s)
        .map_err(|_| format!("'{s}' is neither an axis (+x, -y, z, ...) nor X,Y,Z"))?;
    if dir.iter().all(|&x| x == 0.0) {
        return Err(format!(
            "'{s}' is the zero vector: it looks from no direction"
        ));
    }
    Ok(dir)
}

/// Parses a vector `X,Y,Z` of finite numbers.
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
