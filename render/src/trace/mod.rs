//! Ray tracing implicit isosurfaces: rays in grid coordinates, exact ray-voxel intersection,
//! and closest-hit and any-hit traversal of a BVH over active voxels.

pub mod clipped;
pub mod cubic;
pub mod face;
pub mod field_source;
#[cfg(target_arch = "x86_64")]
mod lanes;
mod last_hit;
pub mod octant;
pub mod ray;
pub mod source;
pub mod tracer;
pub mod traverse;

pub use clipped::ClippedTracer;
pub use field_source::FieldSource;
pub use ray::GridRay;
pub use source::{GridFrame, Voxel, VoxelLookup, VoxelSource};
pub use tracer::{HybridTracer, Paint, SurfaceHit, Tracer};
pub use traverse::{Hit, Surface};
