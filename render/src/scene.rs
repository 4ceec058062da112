//! A scene: one field of an open `.amrk` file, its reconstruction and its isosurfaces (the active
//! voxels and a BVH over them), kept alive between frames. The scene owns the mapped file;
//! changing the isovalues re-extracts only the surfaces that changed, and rendering never
//! touches the extraction.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::bvh::BvhBuilder;
use crate::clip::ClipBox;
use crate::coloring::ColorBy;
use crate::error::{RenderError, Result};
use crate::extract::{Extractor, Region};
use crate::frustum::Frustum;
use crate::mapping::{open_mapped, MappedFile, PageRelease, WatchedMap};
use crate::reconstruct::Reconstruction;
use crate::shade::IsoSpec;
use crate::slice::Slice;
use crate::stats::per_octant;
use crate::system_memory::{self, describe_bytes, Available};
use crate::trace::{FieldSource, GridFrame, Surface, VoxelSource};
use crate::view::View;

/// Ranges narrower than this are round-off, not data, when choosing the default field.
pub const DEGENERATE_WIDTH: f64 = 1e-12;

/// The voxel source of a mapped file.
pub type MappedSource<'f> = FieldSource<'f, WatchedMap>;

/// The voxel sources of a scene: the scene's field's, and those of the other fields that have
/// isosurfaces or paint surfaces and slices.
pub struct SceneSources<'f> {
    main: MappedSource<'f>,
    /// `(field index, source)`, one per other field opened.
    others: Vec<(usize, MappedSource<'f>)>,
}

self_cell::self_cell!(
    /// A mapped file and the voxel sources that read it.
    struct SourceCell {
        owner: MappedFile,
        #[covariant]
        dependent: SceneSources,
    }
);

/// How rays find an isosurface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum TraceMethod {
    /// A BVH over the active voxels and the exact ray-voxel intersection.
    #[default]
    Hybrid,
    /// Fixed-step marching through the reconstruction with bisection (the paper's baseline):
    /// nothing is extracted.
    Sample,
}

impl TraceMethod {
    /// The name used on command lines and in file headers.
    pub fn name(self) -> &'static str {
        match self {
            TraceMethod::Hybrid => "hybrid",
            TraceMethod::Sample => "sample",
        }
    }
}

impl std::fmt::Display for TraceMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for TraceMethod {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "hybrid" => Ok(TraceMethod::Hybrid),
            "sample" => Ok(TraceMethod::Sample),
            _ => Err(format!("unknown method '{s}' (hybrid, sample)")),
        }
    }
}

/// What a scene is made of, besides its isosurfaces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneOptions {
    /// The field (default: the file's first).
    pub field: Option<String>,
    /// The reconstruction.
    pub reconstruction: Reconstruction,
    /// How rays find the surfaces.
    pub method: TraceMethod,
    /// Keep the file's pages out of the resident set between the stages of extraction, build
    /// and rendering (they stay in the page cache): the map's share of the peak memory is what
    /// one stage touches, not the file.
    pub release_pages: bool,
}

/// What the last change of a scene's isosurfaces cost and what the scene holds.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SceneStats {
    /// Active voxels over all isosurfaces.
    pub active_octants: u64,
    /// Resident bytes of the refs.
    pub refs_bytes: u64,
    /// Resident bytes of the BVH nodes.
    pub bvh_bytes: u64,
    /// BVH nodes.
    pub bvh_nodes: u64,
    /// Refs and BVH bytes per active voxel.
    #[serde(serialize_with = "crate::stats::two_decimals")]
    pub resident_bytes_per_octant: f64,
    /// Largest build scratch held at once (boxes, PLOC buffers, binary BVH).
    pub build_scratch_bytes: u64,
    /// Leaves visited by the extraction of the surfaces that changed (octant method).
    pub leaves_visited: u64,
    /// Bytes of the file's map the extraction of the surfaces that changed touched, when pages
    /// are released (octant method; see [`crate::extract::ExtractStats::resident_bytes`]).
    pub extract_touched_bytes: Option<u64>,
    /// Extraction time of the surfaces that changed.
    #[serde(rename = "extract_ms", serialize_with = "crate::stats::millis")]
    pub extract: Duration,
    /// BVH build time of the surfaces that changed.
    #[serde(rename = "bvh_ms", serialize_with = "crate::stats::millis")]
    pub bvh: Duration,
    /// Surfaces extracted and built by the last change (the others were kept).
    #[serde(skip)]
    pub surfaces_built: usize,
}

/// An open file's field, reconstructed, with its isosurfaces ready to render.
pub struct Scene {
    path: PathBuf,
    cell: SourceCell,
    field: usize,
    /// [`SceneOptions::release_pages`], for the sources of other fields.
    release_pages: bool,
    method: TraceMethod,
    isos: Vec<IsoSpec>,
    /// One per isosurface: the BVH over its active voxels (empty for the sample method).
    surfaces: Vec<Surface>,
    stats: SceneStats,
    /// What paints each isosurface, in order (shorter than `isos`: the rest are not painted).
    color_by: Vec<Option<ColorBy>>,
    /// Slices and what paints them.
    slices: Vec<(Slice, ColorBy)>,
    /// What the caller asked to paint the slices by (`None`: the default, resolved again
    /// whenever the surfaces' painters change).
    slice_by: Option<ColorBy>,
    /// The box the surfaces are cut to.
    clip: Option<ClipBox>,
    /// The frustum the extraction is limited to.
    extract_view: Option<Frustum>,
}

impl Scene {
    /// Maps and validates `path` and prepares the field `options` names; no isosurface yet.
    /// Errors name the file.
    pub fn open(path: &Path, options: &SceneOptions) -> Result<Scene> {
        let file = open_mapped(path).map_err(|e| RenderError::from(e).in_file(path))?;
        let field = resolve_field(&file, options.field.as_deref()).map_err(|e| e.in_file(path))?;
        let cell = SourceCell::try_new(file, |file| -> Result<SceneSources<'_>> {
            let source = scene_source(file, field, options)?;
            Ok(SceneSources {
                main: source,
                others: Vec::new(),
            })
        })
        .map_err(|e| e.in_file(path))?;
        Ok(Scene {
            path: path.to_path_buf(),
            cell,
            field,
            release_pages: options.release_pages,
            method: options.method,
            isos: Vec::new(),
            surfaces: Vec::new(),
            stats: SceneStats::default(),
            color_by: Vec::new(),
            slices: Vec::new(),
            slice_by: None,
            clip: None,
            extract_view: None,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The open file.
    pub fn file(&self) -> &MappedFile {
        self.cell.borrow_owner()
    }

    /// The voxel source of the field.
    pub fn source(&self) -> &MappedSource<'_> {
        &self.cell.borrow_dependent().main
    }

    /// The voxel source of field `field` opened by [`Self::set_color_by`] or
    /// [`Self::set_slices`].
    pub fn color_source(&self, field: usize) -> Option<&MappedSource<'_>> {
        let sources = self.cell.borrow_dependent();
        sources
            .others
            .iter()
            .find(|(f, _)| *f == field)
            .map(|(_, s)| s)
    }

    /// The voxel source of the field an isosurface of `spec` is of: the scene's, or the one
    /// [`Self::set_isosurfaces`] opened for it.
    fn surface_source(&self, spec: &IsoSpec) -> &MappedSource<'_> {
        match spec.field {
            Some(f) if f != self.field => self.color_source(f).unwrap_or(self.source()),
            _ => self.source(),
        }
    }

    /// The voxel source of each isosurface, in order (the scene's source for those of its
    /// field).
    pub fn surface_sources(&self) -> Vec<&MappedSource<'_>> {
        self.isos.iter().map(|s| self.surface_source(s)).collect()
    }

    /// The index of the field the isosurface `spec` is of.
    pub fn surface_field(&self, spec: &IsoSpec) -> usize {
        spec.field.unwrap_or(self.field)
    }

    /// The name of the field the isosurface `spec` is of.
    pub fn surface_field_name(&self, spec: &IsoSpec) -> &str {
        &self.file().fields()[self.surface_field(spec)].name
    }

    /// True when every isosurface is of the scene's field.
    pub fn one_field(&self) -> bool {
        self.isos
            .iter()
            .all(|s| self.surface_field(s) == self.field)
    }

    /// The octant method's extractor (`None` for the other reconstructions).
    pub fn extractor(&self) -> Option<&Extractor<'_, WatchedMap>> {
        self.source().extractor()
    }

    /// The extractor of the field each isosurface of `isos` is of, in order, opening the voxel
    /// source of each field that is not the scene's (as [`Self::set_isosurfaces`] would); `None`
    /// for a reconstruction without one (only the octant reconstruction extracts this way). For
    /// a process that extracts its part of a scene before [`Self::set_isosurfaces_from_refs`].
    pub fn surface_extractors(
        &mut self,
        isos: &[IsoSpec],
    ) -> Result<Vec<Option<&Extractor<'_, WatchedMap>>>> {
        self.open_surface_sources(isos)?;
        Ok(isos
            .iter()
            .map(|s| self.surface_source(s).extractor())
            .collect())
    }

    /// Opens the voxel source of each field of `isos` that is not the scene's; an error for a
    /// field the file does not hold.
    fn open_surface_sources(&mut self, isos: &[IsoSpec]) -> Result<()> {
        let fields = self.file().fields().len();
        if let Some(f) = isos.iter().filter_map(|s| s.field).find(|&f| f >= fields) {
            return Err(RenderError::Invalid(format!(
                "an isosurface of field {f}, but the file has {fields} fields"
            ))
            .in_file(&self.path));
        }
        for spec in isos {
            let field = self.surface_field(spec);
            if field != self.field {
                self.open_source(field)?;
            }
        }
        Ok(())
    }

    /// The field's index in the file.
    pub fn field(&self) -> usize {
        self.field
    }

    /// The field's name.
    pub fn field_name(&self) -> &str {
        &self.file().fields()[self.field].name
    }

    /// The reconstruction.
    pub fn reconstruction(&self) -> Reconstruction {
        self.source().reconstruction()
    }

    /// How rays find the surfaces.
    pub fn method(&self) -> TraceMethod {
        self.method
    }

    /// The grid-to-world map and the domain's extent.
    pub fn grid_frame(&self) -> GridFrame {
        self.source().frame()
    }

    /// The isosurfaces, in the order given.
    pub fn isosurfaces(&self) -> &[IsoSpec] {
        &self.isos
    }

    /// The surfaces' BVHs, one per isosurface (empty BVHs for the sample method).
    pub fn surfaces(&self) -> &[Surface] {
        &self.surfaces
    }

    /// What the last change of isosurfaces cost and what the scene holds.
    pub fn stats(&self) -> &SceneStats {
        &self.stats
    }

    /// The isovalue used when none is given: the median of the field's cell values; when the
    /// median sits on a floor or ceiling many cells share (a density floor, zero dark matter in
    /// voids), the median of the values off those plateaus; the middle of the range when
    /// nothing is off them (a field that is one value up to round-off). A median is rounded to
    /// the five significant digits [`crate::field_stats::format_value`] prints.
    pub fn default_isovalue(&self) -> f32 {
        let f = &self.file().fields()[self.field];
        let mid = 0.5 * (f.min + f.max);
        let file = self.file();
        let read_ahead = |r: &[(u64, u64)]| crate::mapping::read_ahead(file, r.iter().copied());
        let Ok(p) =
            crate::field_stats::FieldPercentiles::of_reading_ahead(file, self.field, read_ahead)
        else {
            return mid;
        };
        // The legend's five significant digits, so that the isovalue shown is the one drawn
        // and can be typed again; the median itself where rounding lands on a plateau.
        let shown = |m: f64| {
            let rounded = crate::field_stats::round_to_shown(m);
            match p.off_plateaus(f64::from(rounded)) {
                true => rounded,
                false => m as f32,
            }
        };
        let median = p.at(0.5);
        if p.off_plateaus(median) {
            return shown(median);
        }
        p.median_off_plateaus().map_or(mid, shown)
    }

    /// The box the surfaces are cut to, if any.
    pub fn clip(&self) -> Option<ClipBox> {
        self.clip
    }

    /// Cuts the surfaces to `clip` (`None`: not cut): only the voxels that meet the box are
    /// extracted, and rendering accepts surface hits only inside it, so the surfaces behind the
    /// cut show through the opening; shadow and ambient-occlusion rays see only the cut surfaces.
    /// Slices are not cut. The surfaces are extracted again when the box changes. An error when
    /// the box does not overlap the domain.
    pub fn set_clip(&mut self, clip: Option<ClipBox>) -> Result<&SceneStats> {
        if let Some(c) = &clip {
            c.check_overlaps(&self.grid_frame())
                .map_err(|e| e.in_file(&self.path))?;
        }
        if clip == self.clip {
            return Ok(&self.stats);
        }
        self.clip = clip;
        self.extract_again()
    }

    /// The frustum the extraction is limited to, if any.
    pub fn extract_view(&self) -> Option<&Frustum> {
        self.extract_view.as_ref()
    }

    /// Limits the extraction to the leaves and voxels that may meet the frustum of `view`
    /// (`None`: the whole domain), extracting the surfaces again when the frustum changes.
    ///
    /// The frame `view` gives is the same as with the whole extraction when it casts no shadow
    /// or ambient-occlusion rays; with them, surfaces outside the view no longer shadow or
    /// occlude what is in it. [`crate::render()`] refuses a view whose frustum is not this one.
    pub fn set_extract_view(&mut self, view: Option<&View>) -> Result<&SceneStats> {
        let frustum = match view {
            Some(v) => Some(v.frustum(&self.grid_frame())?),
            None => None,
        };
        if frustum == self.extract_view {
            return Ok(&self.stats);
        }
        self.extract_view = frustum;
        self.extract_again()
    }

    /// Fails when the extraction is limited to a frustum other than `view`'s.
    pub fn check_view(&self, view: &View) -> Result<()> {
        let Some(f) = &self.extract_view else {
            return Ok(());
        };
        if view.frustum(&self.grid_frame())? == *f {
            return Ok(());
        }
        Err(RenderError::Invalid(
            "the surfaces were extracted for the frustum of another view; \
             set the extraction's view to this one (Scene::set_extract_view) first"
                .into(),
        ))
    }

    /// What the extraction keeps: the clip box and the frustum, in grid coordinates.
    pub fn region(&self) -> Region {
        let frame = self.grid_frame();
        let largest = frame.extent.iter().fold(1.0f64, |m, &e| m.max(e));
        Region {
            bounds: self.clip.map(|c| c.to_grid(&frame)),
            half_spaces: self.extract_view.map_or(Vec::new(), |f| f.sides.to_vec()),
            slack: 1e-6 * largest,
        }
    }

    /// Extracts and builds every surface again (after the region changed).
    fn extract_again(&mut self) -> Result<&SceneStats> {
        let isos = self.isos.clone();
        self.surfaces.clear();
        self.replace_surfaces(&isos, None)
    }

    /// What paints each isosurface, in the order given.
    pub fn color_by(&self) -> &[Option<ColorBy>] {
        &self.color_by
    }

    /// The slices and what paints them.
    pub fn slices(&self) -> &[(Slice, ColorBy)] {
        &self.slices
    }

    /// Everything that paints: the painted isosurfaces' painters, then the slices'.
    pub fn painters(&self) -> impl Iterator<Item = &ColorBy> {
        let surfaces = self.color_by.iter().flatten();
        surfaces.chain(self.slices.iter().map(|s| &s.1))
    }

    /// Paints the isosurfaces by data: `per_surface[i]` paints the `i`-th (`None` keeps its
    /// colour; surfaces past the list keep theirs). Opens a source for each field named.
    pub fn set_color_by(&mut self, per_surface: &[Option<ColorBy>]) -> Result<()> {
        for by in per_surface.iter().flatten() {
            self.open_color_source(by)?;
        }
        self.color_by = per_surface.to_vec();
        if self.slice_by.is_none() && !self.slices.is_empty() {
            // Slices painted by default follow the surfaces' painters.
            let painter = self.default_slice_painter();
            self.open_color_source(&painter)?;
            for slice in &mut self.slices {
                slice.1 = painter.clone();
            }
        }
        Ok(())
    }

    /// Replaces the slices, each painted by `by` (default: the first field that paints a
    /// surface, else the rendered field; the default follows later [`Self::set_color_by`]
    /// calls, so the two may come in either order).
    pub fn set_slices(&mut self, slices: &[Slice], by: Option<ColorBy>) -> Result<()> {
        let painter = by.clone().unwrap_or_else(|| self.default_slice_painter());
        if !slices.is_empty() {
            self.open_color_source(&painter)?;
        }
        self.slice_by = by;
        self.slices = slices.iter().map(|s| (*s, painter.clone())).collect();
        Ok(())
    }

    /// What paints slices given no painter: the first field that paints a surface, else the
    /// rendered field.
    fn default_slice_painter(&self) -> ColorBy {
        self.color_by
            .iter()
            .flatten()
            .find(|b| b.painted_name().is_some())
            .cloned()
            .unwrap_or_else(|| ColorBy::Field(self.field_name().to_string()))
    }

    /// The sources of the fields `by` reads, opened by [`Self::set_color_by`] or
    /// [`Self::set_slices`] (none for the level; `None` when one is not open).
    pub fn color_sources(&self, by: &ColorBy) -> Option<Vec<&MappedSource<'_>>> {
        by.fields()
            .iter()
            .map(|name| {
                self.file()
                    .field_index(name)
                    .and_then(|f| self.color_source(f))
            })
            .collect()
    }

    /// Opens the sources of the fields `by` reads unless they are open.
    fn open_color_source(&mut self, by: &ColorBy) -> Result<()> {
        for name in by.fields() {
            let field =
                resolve_field(self.file(), Some(name)).map_err(|e| e.in_file(&self.path))?;
            self.open_source(field)?;
        }
        Ok(())
    }

    /// Opens the source of field `field` beside the scene's unless it is open.
    fn open_source(&mut self, field: usize) -> Result<()> {
        if self.color_source(field).is_some() {
            return Ok(());
        }
        let options = SceneOptions {
            reconstruction: self.reconstruction(),
            release_pages: self.release_pages,
            ..SceneOptions::default()
        };
        let path = self.path.clone();
        self.cell.with_dependent_mut(|file, sources| -> Result<()> {
            let source = scene_source(file, field, &options).map_err(|e| e.in_file(&path))?;
            sources.others.push((field, source));
            Ok(())
        })
    }

    /// The first error met by any source since the last call.
    pub fn take_failure(&self) -> Option<RenderError> {
        let sources = self.cell.borrow_dependent();
        std::iter::once(&sources.main)
            .chain(sources.others.iter().map(|(_, s)| s))
            .find_map(|s| s.take_failure())
            .map(|e| e.in_file(&self.path))
    }

    /// The world box of the isosurfaces' active voxels, `None` without any. The sample method
    /// keeps none: for it the active voxels are extracted here, boxed and dropped (an
    /// extraction, which the sampled frame costs many times over).
    pub fn surface_bounds(&self) -> Result<Option<([f64; 3], [f64; 3])>> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut grow = |(a, b): ([f64; 3], [f64; 3])| {
            for k in 0..3 {
                lo[k] = lo[k].min(a[k]);
                hi[k] = hi[k].max(b[k]);
            }
        };
        match self.method {
            // The BVH build kept the union of the boxes it decoded.
            TraceMethod::Hybrid => self
                .surfaces
                .iter()
                .filter_map(|s| s.bvh.voxel_bounds())
                .for_each(grow),
            TraceMethod::Sample => {
                let region = self.region();
                for spec in &self.isos {
                    let source = self.surface_source(spec);
                    let e = source
                        .extract_in(spec.value, &region)
                        .map_err(|e| e.in_file(&self.path))?;
                    e.refs.iter().for_each(|&r| grow(source.voxel_box(r)));
                    source.release_pages();
                }
                if let Some(e) = self.take_failure() {
                    return Err(e);
                }
            }
        }
        if !(0..3).all(|k| lo[k] <= hi[k]) {
            return Ok(None);
        }
        let frame = self.grid_frame();
        Ok(Some((frame.to_world(lo), frame.to_world(hi))))
    }

    /// Replaces the isosurfaces with `isos`: a surface whose isovalue is already in the scene is
    /// kept (with the new colour and opacity), the others are extracted and built. Returns what
    /// the change cost.
    pub fn set_isosurfaces(&mut self, isos: &[IsoSpec]) -> Result<&SceneStats> {
        self.replace_surfaces(isos, None)
    }

    /// Replaces the isosurfaces with `isos`, built from the given active voxels (one list per
    /// isosurface) instead of extracted: for a process that holds one part of a scene.
    pub fn set_isosurfaces_from_refs(
        &mut self,
        isos: &[IsoSpec],
        refs: Vec<Vec<u64>>,
    ) -> Result<&SceneStats> {
        if refs.len() != isos.len() {
            return Err(RenderError::Invalid(format!(
                "{} lists of voxels for {} isosurfaces",
                refs.len(),
                isos.len()
            )));
        }
        self.surfaces.clear();
        self.replace_surfaces(isos, Some(refs))
    }

    /// [`Self::set_isosurfaces`], with the active voxels of each new surface from `given` when
    /// it is set.
    fn replace_surfaces(
        &mut self,
        isos: &[IsoSpec],
        given: Option<Vec<Vec<u64>>>,
    ) -> Result<&SceneStats> {
        if let Some(bad) = isos.iter().find(|s| !s.value.is_finite()) {
            return Err(RenderError::Invalid(format!(
                "isovalue {} is not a finite number",
                bad.value
            )));
        }
        self.open_surface_sources(isos)?;
        let mut given = given.map(Vec::into_iter);
        let mut old: Vec<Option<Surface>> = self.surfaces.drain(..).map(Some).collect();
        let mut stats = SceneStats::default();
        let mut builder = BvhBuilder::new();
        let mut surfaces = Vec::with_capacity(isos.len());
        for spec in isos {
            let field = self.surface_field(spec);
            let kept = old
                .iter_mut()
                .zip(&self.isos)
                .find(|(s, was)| {
                    s.as_ref().is_some_and(|s| {
                        s.iso.to_bits() == spec.value.to_bits() && self.surface_field(was) == field
                    })
                })
                .and_then(|(s, _)| s.take());
            let refs = given.as_mut().and_then(Iterator::next);
            let surface = match (kept, self.method) {
                (Some(s), _) => s,
                (None, TraceMethod::Sample) => Surface {
                    iso: spec.value,
                    ..Surface::default()
                },
                (None, TraceMethod::Hybrid) => {
                    stats.surfaces_built += 1;
                    let source = self.surface_source(spec);
                    self.build_surface(source, spec.value, refs, &mut builder, &mut stats)?
                }
            };
            surfaces.push(surface);
        }
        drop(old);
        builder.release();
        for spec in isos {
            self.surface_source(spec).release_pages();
        }
        self.source().release_pages();
        if let Some(e) = self.take_failure() {
            return Err(e);
        }
        for s in &surfaces {
            let bvh = &s.bvh;
            stats.active_octants += bvh.len() as u64;
            stats.refs_bytes += bvh.refs_bytes() as u64;
            stats.bvh_bytes += bvh.bvh_bytes() as u64;
            stats.bvh_nodes += bvh.num_nodes() as u64;
        }
        stats.resident_bytes_per_octant =
            per_octant(stats.refs_bytes + stats.bvh_bytes, stats.active_octants);
        self.isos = isos.to_vec();
        self.surfaces = surfaces;
        self.stats = stats;
        Ok(&self.stats)
    }

    /// Builds the surface `iso` of `source`'s field over `refs`, extracted when `None`, adding
    /// the times and scratch to `stats`.
    fn build_surface(
        &self,
        source: &MappedSource<'_>,
        iso: f32,
        refs: Option<Vec<u64>>,
        builder: &mut BvhBuilder,
        stats: &mut SceneStats,
    ) -> Result<Surface> {
        let region = self.region();
        let t = Instant::now();
        let refs = match refs {
            Some(mut refs) => {
                region
                    .retain_refs(&mut refs, |r| Ok(source.voxel_box(r)))
                    .map_err(|e| e.in_file(&self.path))?;
                refs
            }
            None => {
                let e = source
                    .extract_in(iso, &region)
                    .map_err(|e| e.in_file(&self.path))?;
                stats.leaves_visited += e.stats.leaves_visited;
                if let Some(b) = e.stats.resident_bytes {
                    stats.extract_touched_bytes =
                        Some(stats.extract_touched_bytes.unwrap_or(0) + b);
                }
                e.refs
            }
        };
        stats.extract += t.elapsed();
        source.release_pages();
        check_bvh_fits(iso, (refs.len(), Found::All), system_memory::available())
            .map_err(|e| e.in_file(&self.path))?;
        let t = Instant::now();
        let surface = Surface::build_owned(source, iso, refs, builder);
        stats.bvh += t.elapsed();
        stats.build_scratch_bytes = stats
            .build_scratch_bytes
            .max(builder.last_scratch_bytes as u64);
        Ok(surface)
    }
}

/// Bytes a surface's BVH takes per active voxel, rounded up (11.3 measured on the 1e8-cell
/// synthetic file at iso 10: `bvh_bytes` over `active_octants`); the build's scratch is bounded
/// apart from that (it builds in chunks).
const BVH_BYTES_PER_VOXEL: u64 = 12;

/// Whether an extraction has found all its active voxels or is part way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Found {
    /// Every active voxel of the isovalue.
    All,
    /// Those found before the extraction was stopped.
    SoFar,
}

/// The voxel source of field `field` of `file` as a scene reads it: with `options`'
/// reconstruction and page release, and the BVH's memory checked as the extraction finds voxels.
fn scene_source<'f>(
    file: &'f MappedFile,
    field: usize,
    options: &SceneOptions,
) -> Result<MappedSource<'f>> {
    let mut source = FieldSource::new(file, field, options.reconstruction)?;
    if options.release_pages {
        source.set_page_release(PageRelease::new(file));
    }
    source.set_refs_check(Box::new(|iso, voxels| {
        check_bvh_fits(iso, (voxels, Found::SoFar), system_memory::available())
    }));
    Ok(source)
}

/// Refuses to build the BVH of the `voxels` active voxels of isovalue `iso` (all of them, or
/// those an extraction has found so far, which stops it) when it needs, with a tenth to spare,
/// more than `available` bytes (the memory this process can still be given, when known): the
/// system would kill the process part way through the build, or through the extraction as its
/// refs grow, instead of it failing with a message.
fn check_bvh_fits(
    iso: f32,
    (voxels, found): (usize, Found),
    available: Option<Available>,
) -> Result<()> {
    let needed = (voxels as u64).saturating_mul(BVH_BYTES_PER_VOXEL);
    let found = match found {
        Found::All => "",
        Found::SoFar => " found so far (the extraction stopped there)",
    };
    match Available::short_of(needed, available) {
        Some(free) => Err(RenderError::Invalid(format!(
            "iso {iso}: the BVH of its {voxels} active voxels{found} needs about {} and {} {} \
             available: render a smaller region (a clip box, or the view's frustum alone) or \
             an isovalue with fewer active voxels",
            describe_bytes(needed),
            free.whose(),
            describe_bytes(free.bytes)
        ))),
        None => Ok(()),
    }
}

/// Names of the field a scientist looks at first (compared ignoring case: Enzo's `Density`,
/// AMReX's and Chombo's `density`, FLASH's `dens`), preferred as the default field in this order.
const DENSITY_NAMES: [&str; 3] = ["density", "rho", "dens"];

/// The index of the field `name`; when `None`, the density (a field named as in
/// [`DENSITY_NAMES`]) if its range is not degenerate, else the first field whose range is not
/// degenerate (constant, or round-off around zero, like a velocity component that is zero
/// everywhere), or the first field when all are.
fn resolve_field(file: &MappedFile, name: Option<&str>) -> Result<usize> {
    let Some(name) = name else {
        let spread = |f: &amr_format::FieldInfo| {
            let width = f64::from(f.max) - f64::from(f.min);
            let size = f64::from(f.max.abs().max(f.min.abs()));
            width > DEGENERATE_WIDTH && width > 1e-6 * size
        };
        let fields = file.fields();
        let density = DENSITY_NAMES.iter().find_map(|want| {
            fields
                .iter()
                .position(|f| f.name.eq_ignore_ascii_case(want) && spread(f))
        });
        return Ok(density
            .or_else(|| fields.iter().position(spread))
            .unwrap_or(0));
    };
    field_named(file, name)
}

/// The index of the field `name` of `file`; an error listing the file's fields (and the one
/// that differs only in letter case, if any) when it has none of that name.
pub fn field_named<D: AsRef<[u8]>>(file: &amr_format::AmrkFile<D>, name: &str) -> Result<usize> {
    file.field_index(name).ok_or_else(|| RenderError::NoField {
        name: name.to_string(),
        available: file.fields().iter().map(|f| f.name.clone()).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A BVH larger than the memory left is refused, naming the isovalue, the voxels and what
    /// leaves the memory; one that fits, or whose memory is unknown, is not.
    #[test]
    fn a_bvh_larger_than_the_memory_left_is_refused() {
        let gib = 1u64 << 30;
        let limit = |bytes| {
            Some(Available {
                bytes,
                by_limit: true,
            })
        };
        // 100 M voxels: about 1.1 GiB of BVH.
        let all = (100_000_000, Found::All);
        assert!(check_bvh_fits(10.0, all, limit(2 * gib)).is_ok());
        assert!(check_bvh_fits(10.0, all, None).is_ok());
        let text = check_bvh_fits(10.0, all, limit(gib))
            .unwrap_err()
            .to_string();
        assert!(
            text.contains("iso 10")
                && text.contains("100000000 active voxels")
                && text.contains("1.1 GiB")
                && text.contains("memory limit")
                && !text.contains("so far"),
            "{text}"
        );
        let text = check_bvh_fits(10.0, (100_000_000, Found::SoFar), limit(gib))
            .unwrap_err()
            .to_string();
        assert!(text.contains("found so far"), "{text}");
    }
}
