//! Ray tracing isosurfaces of block-structured AMR data stored in `.amrk` files, as a library.
//!
//! Open a [`Scene`] (a mapped file, one field, a reconstruction), give it isosurfaces with
//! [`Scene::set_isosurfaces`] (only the ones that changed are extracted and built), and
//! [`render()`] it through any number of [`View`]s: a camera change costs one frame.
//!
//! ```no_run
//! use amr_render::{render, Scene, SceneOptions, View, IsoSpec};
//! # fn main() -> amr_render::Result<()> {
//! let mut scene = Scene::open("blobs.amrk".as_ref(), &SceneOptions::default())?;
//! scene.set_isosurfaces(&[IsoSpec::new(10.0)])?;
//! let frame = render(&scene, &View::default(), &|_rows| {})?;
//! amr_render::output::exr_file::write_exr("blobs.exr".as_ref(), &frame.frame, &[])?;
//! # Ok(())
//! # }
//! ```
//!
//! The layers underneath: [`mapping`] (the one memory map), [`reconstruct`] (the octant
//! method and the others), [`extract`] (active voxels), [`bvh`], [`trace`] (rays and exact
//! intersection), [`shade`] (lighting and the frame loop), [`output`] (EXR and PNG).
#![warn(missing_docs)]

pub mod bvh;
pub mod camera;
pub mod camera_path;
pub mod clip;
pub mod coloring;
pub mod colormap;
pub mod dump_hint;
pub mod error;
pub mod extract;
pub mod field_stats;
pub mod frustum;
pub mod info;
pub mod mapping;
pub mod outline;
pub mod output;
pub mod paint;
pub mod reconstruct;
pub mod render;
pub mod sample_mode;
pub mod scene;
pub mod shade;
pub mod sigbus;
pub mod slice;
pub mod stats;
pub mod system_memory;
pub mod trace;
pub mod view;
pub mod voxel;

pub use clip::ClipBox;
pub use coloring::{ColorBy, ColorScale};
pub use colormap::Colormap;
pub use error::{RenderError, Result};
pub use frustum::Frustum;
pub use outline::Outline;
pub use reconstruct::Reconstruction;
pub use render::{
    enclosing_surface, frame_painting, render, render_region, render_reusing, FramePainting,
    PaintedRange, Rect, RegionPixels, Rendered,
};
pub use scene::{Scene, SceneOptions, SceneStats, TraceMethod};
pub use shade::IsoSpec;
pub use slice::Slice;
pub use stats::FrameStats;
pub use view::{CameraPlacement, View};
