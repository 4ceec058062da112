//! The integration tests, one binary; this file is their table of contents.
//!
//! Readers, on real files (`../shared/data`) and on files written after each code's own writer:
//! - [`amrex_real`]: PeleLM plotfiles and the bad plotfiles beside them.
//! - [`amrex_written`]: plotfiles this suite writes (float32 and float64, ghost cells, layouts).
//! - [`amrex_float32`]: FAB headers typed out from AMReX's own writer (float32 and float64).
//! - [`amrex_ratio_one`]: a ratio of 1 on an axis is refused with the reason.
//! - [`chombo_convert`] and [`chombo_errors`]: Chombo HDF5 files, good and bad.
//! - [`chombo_checkpoint`]: Chombo checkpoints in both layouts.
//! - [`amrex_hdf5`]: AMReX's HDF5 plotfiles, written as AMReX's HDF5 writer writes them.
//! - [`enzo_convert`]: the real Enzo dataset against yt, written Enzo datasets, bad ones.
//! - [`stream_order`]: every reader streams its boxes in the order it declares, which the
//!   converter's joining of small boxes relies on.
//! - [`amrex_bench`], [`chombo_bench`] and [`enzo_bench`]: large inputs for the conversion
//!   benchmarks (ignored).
//!
//! The file format:
//! - [`format_versions`]: a frozen small file of every layout version opens and renders alike.
//!
//! Reconstruction and extraction, on seeded random hierarchies:
//! - [`reconstruct_continuity`]: the octant method is continuous across level boundaries.
//! - [`extract_reference`]: extraction equals a brute-force reference.
//! - [`extract_region`]: extraction in a clip box or a view frustum equals the whole extraction
//!   filtered.
//! - [`hybrid_current_nearest`]: the `current` and `nearest` voxels.
//! - [`leaf_tree`]: the extraction's leaf tree finds what a scan of every leaf finds.
//! - [`decode_frame`]: the box of merged dual cells a decode keeps per leaf.
//! - [`sample_scratch`]: point samples through a per-thread scratch equal fresh samples.
//! - [`sample_shortcuts`]: the sampler's shortcuts give the general rules' answers bit for bit.
//!
//! Rendering:
//! - [`render_watertight`] and [`render_watertight_amrk`]: no ray leaks through a closed surface.
//! - [`render_accuracy`]: the hybrid method against the sample method.
//! - [`render_golden`]: a golden image.
//! - [`render_packets`]: packets of primary rays find each ray's single-ray hit.
//! - [`render_ao_packets`]: frames whose shadow and AO rays of every layer are traced as packets
//!   equal the single-ray shader's pixel for pixel.
//! - [`render_ao_filter`]: the ambient occlusion filtered across pixels: less noise, and tiles
//!   and bands of rows equal to the whole frame.
//! - [`render_shading`]: coarse real data under smooth normals: no black silhouette pixels, no
//!   self-shadow on a convex surface.
//! - [`render_normals`]: smooth normals turn steadily across voxel faces and level boundaries,
//!   equal the six-sample normals inside a level, and do not depend on the thread count.
//! - [`render_clip`]: a clip box cuts surfaces open; view-limited extraction renders the view
//!   bit for bit.
//! - [`scene_api`]: the library's scene, views and isovalue changes.
//! - [`pictures`]: surfaces painted by a second field, slices, outlines, default field and
//!   isovalue, against the analytic fields.
//! - [`bvh_threads`]: BVHs and frames are the same on any thread count.
//! - [`render_bench`]: measurements for docs/benchmarks-render.md (ignored).

mod support;

mod amrex_bench;
mod amrex_float32;
mod amrex_hdf5;
mod amrex_ratio_one;
mod amrex_real;
mod amrex_written;
mod bvh_threads;
mod chombo_bench;
mod chombo_checkpoint;
mod chombo_convert;
mod chombo_errors;
mod decode_frame;
mod enzo_bench;
mod enzo_convert;
mod extract_reference;
mod extract_region;
mod format_versions;
mod hybrid_current_nearest;
mod leaf_tree;
mod pictures;
mod reconstruct_continuity;
mod render_accuracy;
mod render_ao_filter;
mod render_ao_packets;
mod render_bench;
mod render_clip;
mod render_fields;
mod render_golden;
mod render_normals;
mod render_ortho;
mod render_packets;
mod render_shading;
mod render_watertight;
mod render_watertight_amrk;
mod sample_scratch;
mod sample_shortcuts;
mod scene_api;
mod simulation_stamp;
mod stream_order;
