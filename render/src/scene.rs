//! A scene: one field of an open `.amrk` file, its reconstruction and its isosurfaces (the active
//! voxels and a BVH over them), kept alive between frames. The scene owns the mapped file;
//! changing the isovalues re-extracts only the surfaces that changed, and rendering never
//! touches the extraction.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::bvh::BvhBuilder;
use crate::error::{RenderError, Result};
use crate::extract::Extractor;
use crate::mapping::{open_mapped, MappedFile, PageRelease, WatchedMap};
use crate::reconstruct::Reconstruction;
use crate::shade::IsoSpec;
use crate::stats::per_octant;
use crate::trace::{FieldSource, GridFrame, Surface, VoxelSource};

/// The voxel source of a mapped file.
pub type MappedSource<'f> = FieldSource<'f, WatchedMap>;

self_cell::self_cell!(
    /// A mapped file and the voxel source that reads it.
    struct SourceCell {
        owner: MappedFile,
        #[covariant]
        dependent: MappedSource,
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
    method: TraceMethod,
    isos: Vec<IsoSpec>,
    /// One per isosurface: the BVH over its active voxels (empty for the sample method).
    surfaces: Vec<Surface>,
    stats: SceneStats,
}

impl Scene {
    /// Maps and validates `path` and prepares the field `options` names; no isosurface yet.
    /// Errors name the file.
    pub fn open(path: &Path, options: &SceneOptions) -> Result<Scene> {
        let file = open_mapped(path).map_err(|e| RenderError::from(e).in_file(path))?;
        let field = resolve_field(&file, options.field.as_deref()).map_err(|e| e.in_file(path))?;
        let cell = SourceCell::try_new(file, |file| -> Result<MappedSource<'_>> {
            let mut source = FieldSource::new(file, field, options.reconstruction)?;
            if options.release_pages {
                source.set_page_release(PageRelease::new(file));
            }
            Ok(source)
        })
        .map_err(|e| e.in_file(path))?;
        Ok(Scene {
            path: path.to_path_buf(),
            cell,
            field,
            method: options.method,
            isos: Vec::new(),
            surfaces: Vec::new(),
            stats: SceneStats::default(),
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
        self.cell.borrow_dependent()
    }

    /// The octant method's extractor (`None` for the other reconstructions).
    pub fn extractor(&self) -> Option<&Extractor<'_, WatchedMap>> {
        self.source().extractor()
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

    /// The middle of the field's range: the isovalue used when none is given.
    pub fn default_isovalue(&self) -> f32 {
        let f = &self.file().fields()[self.field];
        0.5 * (f.min + f.max)
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
        let mut given = given.map(Vec::into_iter);
        let mut old: Vec<Option<Surface>> = self.surfaces.drain(..).map(Some).collect();
        let mut stats = SceneStats::default();
        let mut builder = BvhBuilder::new();
        let mut surfaces = Vec::with_capacity(isos.len());
        for spec in isos {
            let kept = old
                .iter_mut()
                .find(|s| s.as_ref().is_some_and(|s| s.iso.to_bits() == spec.value.to_bits()))
                .and_then(Option::take);
            let refs = given.as_mut().and_then(Iterator::next);
            let surface = match (kept, self.method) {
                (Some(s), _) => s,
                (None, TraceMethod::Sample) => Surface {
                    iso: spec.value,
                    ..Surface::default()
                },
                (None, TraceMethod::Hybrid) => {
                    stats.surfaces_built += 1;
                    self.build_surface(spec.value, refs, &mut builder, &mut stats)?
                }
            };
            surfaces.push(surface);
        }
        drop(old);
        builder.release();
        let source = self.source();
        source.release_pages();
        if let Some(e) = source.take_failure() {
            return Err(e.in_file(&self.path));
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

    /// Builds the surface `iso` over `refs`, extracted when `None`, adding the times and
    /// scratch to `stats`.
    fn build_surface(
        &self,
        iso: f32,
        refs: Option<Vec<u64>>,
        builder: &mut BvhBuilder,
        stats: &mut SceneStats,
    ) -> Result<Surface> {
        let source = self.source();
        let t = Instant::now();
        let refs = match refs {
            Some(refs) => refs,
            None => source.extract(iso).map_err(|e| e.in_file(&self.path))?.refs,
        };
        stats.extract += t.elapsed();
        source.release_pages();
        let t = Instant::now();
        let surface = Surface::build_owned(source, iso, refs, builder);
        stats.bvh += t.elapsed();
        stats.build_scratch_bytes = stats
            .build_scratch_bytes
            .max(builder.last_scratch_bytes as u64);
        Ok(surface)
    }

}

/// The index of the field `name` (the first when `None`).
fn resolve_field(file: &MappedFile, name: Option<&str>) -> Result<usize> {
    let Some(name) = name else {
        return Ok(0);
    };
    file.field_index(name).ok_or_else(|| RenderError::NoField {
        name: name.to_string(),
        available: file.fields().iter().map(|f| f.name.clone()).collect(),
    })
}
