//! Shared fixtures of the renderer tests: seeded random numbers and analytic multi-level grids.

pub use super::block_grid::BlockGrid;
pub use super::rng::Rng;
use amr_render::bvh::BvhBuilder;
use amr_render::render::{render_sampled, render_surfaces};
use amr_render::shade::IsoSpec;
use amr_render::trace::Surface;
use amr_render::{Rendered, Scene, SceneOptions, View};
use amr_synth::Case;

/// Centre of the sphere fixtures, a corner shared by 8 blocks of a 4^3 grid.
pub const CENTRE: [f64; 3] = [2.0, 2.0, 2.0];

/// Closed surfaces around [`CENTRE`] for the fixtures, each `f = norm(p - CENTRE) - radius`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// Euclidean norm: a sphere.
    Sphere,
    /// Max norm: a cube whose faces lie on voxel faces when the radius is a lattice coordinate.
    Cube,
    /// Sum norm: an octahedron through voxel edges and corners.
    Octahedron,
}

/// The field of `shape` with `radius`.
pub fn shape_field(shape: Shape, radius: f64) -> impl Fn([f64; 3]) -> f64 {
    move |p: [f64; 3]| {
        let d = [0, 1, 2].map(|a| (p[a] - CENTRE[a]).abs());
        let n = match shape {
            Shape::Sphere => (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt(),
            Shape::Cube => d[0].max(d[1]).max(d[2]),
            Shape::Octahedron => d[0] + d[1] + d[2],
        };
        n - radius
    }
}

/// A `4^3`-block grid, random levels in `0..levels` per block (seeded), with the signed distance
/// to a sphere of `radius` around [`CENTRE`].
pub fn sphere_grid(
    seed: u64,
    levels: u8,
    ratio: u32,
    radius: f64,
    origin: [f64; 3],
    unit: f64,
) -> BlockGrid {
    shape_grid(seed, levels, ratio, Shape::Sphere, radius, origin, unit)
}

/// Like [`sphere_grid`] for any [`Shape`].
pub fn shape_grid(
    seed: u64,
    levels: u8,
    ratio: u32,
    shape: Shape,
    radius: f64,
    origin: [f64; 3],
    unit: f64,
) -> BlockGrid {
    let f = shape_field(shape, radius);
    let level = move |b: [usize; 3]| {
        let mut r =
            Rng(seed ^ ((b[0] + 4 * b[1] + 16 * b[2]) as u64).wrapping_mul(0x2545_f491_4f6c_dd1d));
        (r.next_u64() % u64::from(levels)) as u8
    };
    BlockGrid::new(4, ratio, level, f, origin, unit)
}

/// One surface per isovalue over `grid`'s active voxels.
/// Renders `isos` of `grid` through `view` with the hybrid method, each surface built over the
/// grid's active voxels as a scene builds them (one builder, the refs handed over).
pub fn render_grid(grid: &BlockGrid, isos: &[IsoSpec], view: &View) -> Rendered {
    let mut b = BvhBuilder::new();
    let surfaces: Vec<Surface> = isos
        .iter()
        .map(|s| Surface::build_owned(grid, s.value, grid.active(s.value), &mut b))
        .collect();
    render_surfaces(grid, &surfaces, isos, view, &|_| {}).unwrap()
}

/// Renders `isos` of `grid` through `view` with the sample method.
pub fn render_grid_sampled(grid: &BlockGrid, isos: &[IsoSpec], view: &View) -> Rendered {
    render_sampled(grid, isos, view, &|_| {}).unwrap()
}

/// The surfaces of `isos`, built over the grid's active voxels.
pub fn surfaces(grid: &BlockGrid, isos: &[f32]) -> Vec<Surface> {
    let mut b = BvhBuilder::new();
    isos.iter()
        .map(|&iso| Surface::build(grid, iso, &grid.active(iso), &mut b))
        .collect()
}

/// `f()` run on a pool of `threads` threads (frames must not depend on the count).
pub fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(f)
}

/// The bits of a frame's colour, normals, alpha and depth, for bit-for-bit comparisons.
pub fn frame_bits(f: &amr_render::output::frame::FrameBuffer) -> Vec<u32> {
    let channels = f.rgb.iter().chain(&f.n).chain([&f.alpha, &f.z]);
    channels.flatten().map(|x| x.to_bits()).collect()
}

/// The demo's two blobs on two levels in `dir`, an opaque and a transparent surface.
pub fn blobs_scene(dir: &std::path::Path) -> Scene {
    let path = super::synth_file::two_level(dir, Case::Blobs);
    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    let isos: Vec<IsoSpec> = ["10:#d99e59", "6:#598cd9:0.3"]
        .iter()
        .map(|s| s.parse().unwrap())
        .collect();
    scene.set_isosurfaces(&isos).unwrap();
    scene
}
