//! Rendering a frame of a [`Scene`] seen through a [`View`]: the whole frame, or a rectangle of
//! it (tiles for several processes), pixel for pixel the same. Nothing here extracts or builds.

use std::time::Instant;

use crate::camera::Camera;
use crate::clip::ClipBox;
use crate::coloring::{painting_fields, ColorBy, ColorScale};
use crate::error::{RenderError, Result};
use crate::outline;
use crate::output::background::Background;
use crate::output::frame::{FrameBuffer, PixelSample, FRAME_PLANES};
use crate::paint::{GridSlice, PaintedTracer, Painter};
use crate::reconstruct::Reconstruction;
use crate::sample_mode::SampleTracer;
use crate::scene::{Scene, TraceMethod};
use crate::shade::{
    render_frame, render_in_planes, render_rect, IsoSpec, Lighting, RenderSettings,
};
use crate::stats::FrameStats;
use crate::system_memory::{self, describe_bytes, Available};
use crate::trace::ray::GridRay;
use crate::trace::{ClippedTracer, HybridTracer, Surface, Tracer, VoxelSource};
use crate::view::View;

/// A rendered frame.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// The image and its per-pixel channels.
    pub frame: FrameBuffer,
    /// The camera it was seen from.
    pub camera: Camera,
    /// What it cost.
    pub stats: FrameStats,
    /// The colour range of each field that painted surfaces or slices (and was seen), in the
    /// order the fields first paint: surfaces, then slices.
    pub color_ranges: Vec<PaintedRange>,
    /// The AMR levels painted into pixels by surfaces or slices painted by level, ascending
    /// (empty when none paints by level); `None` when not recorded (frames composited from
    /// the parts of several processes, which paint nothing).
    pub painted_levels: Option<Vec<u32>>,
    /// The background its picture is composited over ([`View::background`]).
    pub background: Background,
}

/// What painting by data gave a frame, beside its pixels.
#[derive(Default)]
struct Painting {
    /// [`Rendered::color_ranges`].
    color_ranges: Vec<PaintedRange>,
    /// The range each painting field paints with, in the order of
    /// [`painting_fields`] (`(0, 1)` for a field not seen).
    per_field: Vec<(f64, f64)>,
    /// [`Rendered::painted_levels`].
    levels: Vec<u32>,
}

/// The colour ranges a frame of a scene paints with, found by the pre-pass over its primary
/// rays (every fourth pixel each way) before any pixel is traced: found once per frame
/// ([`frame_painting`]) and handed to each of its regions ([`render_region`]), so that every
/// region paints as the whole frame does.
#[derive(Clone, Debug, Default)]
pub struct FramePainting {
    /// The ranges, as [`Rendered::color_ranges`] reports them (empty when nothing paints).
    pub color_ranges: Vec<PaintedRange>,
    per_field: Vec<(f64, f64)>,
}

/// The colour range one field painted a frame with.
#[derive(Clone, Debug, PartialEq)]
pub struct PaintedRange {
    /// The field's name.
    pub field: String,
    /// Its scale: [`View::color_scale`], or its own from [`View::field_scales`].
    pub scale: ColorScale,
    /// The values at the colormap's ends.
    pub range: (f64, f64),
    /// Whether values of the field that the colour-range pre-pass met (every fourth pixel on
    /// each axis) lie below the low end and above the high end.
    pub beyond: (bool, bool),
}

/// A rectangle of a frame: lower corner `x0, y0` (pixels from the top left) and size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

/// The pixels of a rectangle of a frame and the ray queries they took.
#[derive(Clone, Debug)]
pub struct RegionPixels {
    /// Row-major pixels, each equal to the same pixel of the whole frame.
    pub pixels: Vec<PixelSample>,
    /// Ray queries, those of the margin the filter of the ambient occlusion reads included.
    pub rays: u64,
    /// The AMR levels painted by level into its pixels, ascending, as
    /// [`Rendered::painted_levels`] lists them for a frame.
    pub painted_levels: Vec<u32>,
}

/// Renders `scene` as `view` asks; `progress(rows)` is called as rows finish.
pub fn render(scene: &Scene, view: &View, progress: &(dyn Fn(u64) + Sync)) -> Result<Rendered> {
    render_with(scene, view, progress, None)
}

/// [`render`] in the planes of `planes`, the frame of an earlier render that is no longer
/// needed: the same frame, written into memory already touched instead of fresh pages (a run of
/// frames hands each frame back once it is written).
pub fn render_reusing(
    scene: &Scene,
    view: &View,
    progress: &(dyn Fn(u64) + Sync),
    planes: FrameBuffer,
) -> Result<Rendered> {
    render_with(scene, view, progress, Some(planes))
}

/// [`render`], in `planes` when given.
fn render_with(
    scene: &Scene,
    view: &View,
    progress: &(dyn Fn(u64) + Sync),
    planes: Option<FrameBuffer>,
) -> Result<Rendered> {
    let (w, h) = view.size;
    if planes
        .as_ref()
        .is_none_or(|p| (p.width, p.height) != (w, h))
    {
        check_frame_fits(view.size, system_memory::available())?;
    }
    let (mut rendered, painting) =
        with_scene_tracer(scene, view, None, |tracer, camera, light| {
            trace_frame(tracer, *camera, light, view, progress, planes)
        })?;
    check_source(scene)?;
    rendered.color_ranges = painting.color_ranges;
    rendered.painted_levels = Some(painting.levels);
    let colors = outline::LevelColors::of_scene(scene, &view.background);
    let segments = outline::segments(
        view.outline,
        scene.file(),
        scene.grid_frame().world_bounds(),
        (&colors, view.background.outline()),
    );
    let width = outline::line_width(view.size.0, view.size.1);
    outline::draw(&mut rendered.frame, &rendered.camera, &segments, width);
    Ok(rendered)
}

/// Refuses a `w x h` frame whose planes, with a tenth to spare, need more than `available`
/// bytes (the memory this process can still be given, when known): the system would kill the
/// process part way through the frame instead of it failing with a message.
fn check_frame_fits((w, h): (u32, u32), available: Option<Available>) -> Result<()> {
    let needed = FrameBuffer::bytes_for(w, h);
    match Available::short_of(needed, available) {
        Some(free) => Err(RenderError::Invalid(format!(
            "a {w}x{h} frame needs {} for its {FRAME_PLANES} planes and {} {} available: \
             render a smaller frame",
            describe_bytes(needed),
            free.whose(),
            describe_bytes(free.bytes)
        ))),
        None => Ok(()),
    }
}

/// The colour ranges of the frame of `scene` that `view` sees, for [`render_region`]: the
/// pre-pass of a painted frame alone (nothing is traced when nothing paints).
pub fn frame_painting(scene: &Scene, view: &View) -> Result<FramePainting> {
    let ((), painting) = with_scene_tracer(scene, view, None, |_, _, _| ())?;
    check_source(scene)?;
    Ok(FramePainting {
        color_ranges: painting.color_ranges,
        per_field: painting.per_field,
    })
}

/// Renders the rectangle `rect` of the frame [`render`] would give, painted with `painting`,
/// that frame's [`frame_painting`].
pub fn render_region(
    scene: &Scene,
    view: &View,
    painting: &FramePainting,
    rect: Rect,
) -> Result<RegionPixels> {
    let (w, h) = view.size;
    if rect.x0.checked_add(rect.width).is_none_or(|x| x > w)
        || rect.y0.checked_add(rect.height).is_none_or(|y| y > h)
    {
        return Err(RenderError::Invalid(format!(
            "region {rect:?} is outside the {w}x{h} frame"
        )));
    }
    let ((pixels, rays), painted) =
        with_scene_tracer(scene, view, Some(painting), |tracer, camera, light| {
            render_rect(
                tracer,
                camera,
                light,
                view.settings(),
                (rect.x0, rect.y0, rect.width, rect.height),
            )
        })?;
    check_source(scene)?;
    Ok(RegionPixels {
        pixels,
        rays,
        painted_levels: painted.levels,
    })
}

/// Renders the surfaces `surfaces` of `src` (one per entry of `isos`) with the hybrid method:
/// for sources that are not a scene's, such as in-memory test fields or one part of a scene.
pub fn render_surfaces<S: VoxelSource + ?Sized>(
    src: &S,
    surfaces: &[Surface],
    isos: &[IsoSpec],
    view: &View,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Rendered> {
    check_frame_fits(view.size, system_memory::available())?;
    let method = (TraceMethod::Hybrid, view.smooth_normals);
    with_tracer(
        (src, &[]),
        surfaces,
        isos,
        method,
        (view, None),
        |tracer, camera, light| trace_frame(tracer, *camera, light, view, progress, None),
    )
}

/// [`render_surfaces`] with the sample method: isovalues `isos`, no surfaces.
pub fn render_sampled<S: VoxelSource + ?Sized>(
    src: &S,
    isos: &[IsoSpec],
    view: &View,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Rendered> {
    let method = (TraceMethod::Sample, view.smooth_normals);
    with_tracer(
        (src, &[]),
        &[],
        isos,
        method,
        (view, None),
        |tracer, camera, light| trace_frame(tracer, *camera, light, view, progress, None),
    )
}

/// Directions of the rays [`enclosing_surface`] casts.
const ENCLOSURE_RAYS: usize = 64;

/// The first of the scene's isosurfaces that encloses world point `point`, as seen through
/// `view` (its clip box cuts surfaces open): the one that every one of [`ENCLOSURE_RAYS`] rays
/// from `point`, in directions spread evenly over the sphere, meets. A camera there sees only
/// the inside of that surface.
pub fn enclosing_surface(scene: &Scene, view: &View, point: [f64; 3]) -> Result<Option<usize>> {
    let found = with_surface_tracer(scene, view, |tracer, _, _| {
        let frame = tracer.frame();
        let n = ENCLOSURE_RAYS as f64;
        // A Fibonacci lattice: even spacing on the sphere without clusters at the poles.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let rays: Vec<GridRay> = (0..ENCLOSURE_RAYS)
            .map(|k| {
                let z = 1.0 - (2.0 * k as f64 + 1.0) / n;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * k as f64;
                GridRay::from_world(&frame, point, [r * phi.cos(), r * phi.sin(), z])
            })
            .collect();
        (0..scene.isosurfaces().len()).find(|&i| {
            rays.iter()
                .all(|ray| tracer.occluded(i, ray, 0.0, f64::INFINITY))
        })
    })?;
    check_source(scene)?;
    Ok(found)
}

/// [`with_tracer`] for a scene's surfaces, unpainted and without slices.
fn with_surface_tracer<R>(
    scene: &Scene,
    view: &View,
    run: impl FnOnce(&(dyn Tracer + Sync), &Camera, &Lighting) -> R,
) -> Result<R> {
    // A piecewise-constant field has no smooth normals: nearest shades with the faces' normals.
    let smooth = view.smooth_normals && scene.reconstruction() != Reconstruction::Nearest;
    let method = (scene.method(), smooth);
    scene.check_view(view)?;
    // Surfaces of other fields read their own sources; a scene of one field passes none.
    let sources = match scene.one_field() {
        true => Vec::new(),
        false => scene.surface_sources(),
    };
    with_tracer(
        (scene.source(), &sources),
        scene.surfaces(),
        scene.isosurfaces(),
        method,
        (view, scene.clip()),
        run,
    )
}

/// [`with_surface_tracer`] with the surfaces painted and the slices added when the scene has
/// any, with the colour ranges of `known` or else of the frame's pre-pass; also returns what
/// painting gave the frame beside its pixels.
fn with_scene_tracer<R>(
    scene: &Scene,
    view: &View,
    known: Option<&FramePainting>,
    run: impl FnOnce(&(dyn Tracer + Sync), &Camera, &Lighting) -> R,
) -> Result<(R, Painting)> {
    let isos = scene.isosurfaces();
    with_surface_tracer(scene, view, |tracer, camera, light| {
        let fields = painting_fields(scene.painters());
        if let Some((name, _)) = view
            .field_scales
            .iter()
            .find(|(n, _)| !fields.contains(&n.as_str()))
        {
            return Err(RenderError::Invalid(format!(
                "a colour scale for {name}, which paints nothing in this frame"
            )));
        }
        if scene.painters().next().is_none() {
            return Ok((run(tracer, camera, light), Painting::default()));
        }
        let own = |f: &str| view.field_scales.iter().find(|(n, _)| n == f).map(|s| s.1);
        let shared: Vec<&str> = fields
            .iter()
            .copied()
            .filter(|f| own(f).is_none())
            .collect();
        if let (Some((lo, hi)), true) = (view.color_scale.range, shared.len() > 1) {
            return Err(RenderError::Invalid(format!(
                "one colour range {lo}:{hi} for {} fields that paint ({}): each field \
                     takes the range of its own values in view, or the one its own scale gives",
                shared.len(),
                shared.join(", ")
            )));
        }
        let scales: Vec<ColorScale> = fields
            .iter()
            .map(|f| own(f).unwrap_or(view.color_scale))
            .collect();
        // The sources each painter reads, held here for the painters to borrow.
        let sources: Vec<(&ColorBy, Vec<&dyn VoxelSource>)> = scene
            .painters()
            .filter_map(|by| {
                let read = scene.color_sources(by)?;
                Some((
                    by,
                    read.into_iter().map(|s| s as &dyn VoxelSource).collect(),
                ))
            })
            .collect();
        let painter = |by: &ColorBy| {
            let k = by
                .painted_name()
                .and_then(|n| fields.iter().position(|f| *f == n));
            let read = sources
                .iter()
                .find(|(b, _)| *b == by)
                .map(|(_, s)| s.as_slice());
            match (by, read) {
                (ColorBy::Field(_), Some([src])) => Painter::Field(*src, k.unwrap_or(0)),
                (ColorBy::Magnitude { .. }, Some(srcs)) => Painter::Magnitude(srcs, k.unwrap_or(0)),
                _ => Painter::Level,
            }
        };
        let frame = tracer.frame();
        let mut painted = PaintedTracer {
            inner: tracer,
            surfaces: (0..isos.len())
                .map(|i| {
                    scene
                        .color_by()
                        .get(i)
                        .cloned()
                        .flatten()
                        .map(|b| painter(&b))
                })
                .collect(),
            slices: scene
                .slices()
                .iter()
                .map(|(s, by)| GridSlice::new(s, &frame, painter(by)))
                .collect(),
            levels: scene.source(),
            scales: scales.clone(),
            ranges: Vec::new(),
            painted_levels: Default::default(),
        };
        let mut light = light.clone();
        for (s, _) in scene.slices() {
            light.colors.push([1.0; 3]);
            light.opacity.push(s.opacity);
        }
        let ranges = match known {
            Some(k) if k.per_field.len() == fields.len() => {
                painted.ranges = k.per_field.clone();
                k.color_ranges.clone()
            }
            Some(_) => {
                return Err(RenderError::Invalid(
                    "a region painted with the colour ranges of another frame".into(),
                ))
            }
            None => {
                let seen = painted.visible_ranges(camera, view.size, &light.opacity);
                painted.ranges = seen
                    .iter()
                    .map(|r| r.map_or((0.0, 1.0), |r| r.range))
                    .collect();
                fields
                    .iter()
                    .zip(&seen)
                    .zip(&scales)
                    .filter_map(|((field, r), scale)| {
                        r.map(|r| PaintedRange {
                            field: field.to_string(),
                            scale: *scale,
                            range: r.range,
                            beyond: r.beyond,
                        })
                    })
                    .collect()
            }
        };
        let out = run(&painted, camera, &light);
        let painting = Painting {
            color_ranges: ranges,
            per_field: painted.ranges.clone(),
            levels: painted.levels_painted(),
        };
        Ok((out, painting))
    })?
}

/// The camera, lighting and tracer of a frame of `src.0` (surfaces `surfaces` of `isos`, those
/// of other fields read from `src.1` by their index as [`HybridTracer::sources`]; traced with
/// `method.0`, smooth normals when `method.1`, cut to the clip box `view.1` when set) seen
/// through `view.0`, handed to `run`.
fn with_tracer<S: VoxelSource + ?Sized, R>(
    (src, sources): (&S, &[&S]),
    surfaces: &[Surface],
    isos: &[IsoSpec],
    (method, smooth_normals): (TraceMethod, bool),
    (view, clip): (&View, Option<ClipBox>),
    run: impl FnOnce(&(dyn Tracer + Sync), &Camera, &Lighting) -> R,
) -> Result<R> {
    view.validate()?;
    let frame = src.frame();
    let camera = view.camera(&frame)?;
    let light = view.lighting(&camera, &frame, isos);
    let run_clipped = |tracer: &(dyn Tracer + Sync)| match clip {
        Some(c) => {
            let (lo, hi) = c.to_grid(&frame);
            run(
                &ClippedTracer {
                    inner: tracer,
                    lo,
                    hi,
                },
                &camera,
                &light,
            )
        }
        None => run(tracer, &camera, &light),
    };
    Ok(match method {
        TraceMethod::Hybrid => run_clipped(&HybridTracer {
            src,
            surfaces,
            sources,
            smooth_normals,
        }),
        TraceMethod::Sample => run_clipped(&SampleTracer {
            src,
            sources,
            isos: isos.iter().map(|s| s.value).collect(),
            step: view.sample_step(src)?,
        }),
    })
}

/// Traces a whole frame through `tracer`, in `planes` when given.
fn trace_frame<T: Tracer + Sync + ?Sized>(
    tracer: &T,
    camera: Camera,
    light: &Lighting,
    view: &View,
    progress: &(dyn Fn(u64) + Sync),
    planes: Option<FrameBuffer>,
) -> Rendered {
    let settings: RenderSettings = view.settings();
    let t = Instant::now();
    let (frame, rays) = match planes {
        None => render_frame(tracer, &camera, light, settings, progress),
        Some(p) => render_in_planes(tracer, &camera, light, settings, progress, p),
    };
    let stats = FrameStats::new(t.elapsed(), rays, view.size, frame.covered() as u64);
    Rendered {
        frame,
        camera,
        stats,
        color_ranges: Vec::new(),
        painted_levels: None,
        background: view.background,
    }
}

/// The first error the scene's sources met while the frame was traced.
fn check_source(scene: &Scene) -> Result<()> {
    match scene.take_failure() {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_larger_than_the_memory_left_is_refused() {
        let gib = 1u64 << 30;
        // 8192 x 8192 pixels of 13 planes: 3.25 GiB.
        let machine = |bytes| {
            Some(Available {
                bytes,
                by_limit: false,
            })
        };
        assert!(check_frame_fits((8192, 8192), machine(16 * gib)).is_ok());
        assert!(check_frame_fits((8192, 8192), None).is_ok());
        let err = check_frame_fits((8192, 8192), machine(3 * gib)).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("8192x8192")
                && text.contains("3.2 GiB")
                && text.contains("3.0 GiB")
                && text.contains("this machine"),
            "{text}"
        );
        // A tenth to spare: 3.5 GiB is too little for 3.25.
        assert!(check_frame_fits((8192, 8192), machine(3 * gib + gib / 2)).is_err());
        let limited = Available {
            bytes: 2 * gib,
            by_limit: true,
        };
        let text = check_frame_fits((8192, 8192), Some(limited))
            .unwrap_err()
            .to_string();
        assert!(
            text.contains("memory limit") && text.contains("2.0 GiB"),
            "{text}"
        );
    }
}
