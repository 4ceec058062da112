//! Shared fixtures of the renderer tests: seeded random numbers and analytic multi-level grids.
#![allow(dead_code)]

use amr_render::bvh::BvhBuilder;
use amr_render::trace::synthetic::BlockGrid;
use amr_render::trace::Surface;

/// SplitMix64: small, seedable, and the same everywhere.
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform on the unit sphere.
    pub fn dir(&mut self) -> [f64; 3] {
        let z = 2.0 * self.f64() - 1.0;
        let phi = 2.0 * std::f64::consts::PI * self.f64();
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    }
}

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
pub fn surfaces(grid: &BlockGrid, isos: &[f32]) -> Vec<Surface> {
    let mut b = BvhBuilder::new();
    isos.iter()
        .map(|&iso| Surface::build(grid, iso, &grid.active(iso), &mut b))
        .collect()
}
