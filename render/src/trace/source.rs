//! What the tracer needs from a volume: active voxels decoded from 64-bit refs, and point samples.

use crate::trace::octant::{intersect_voxel, VoxelHit};
use crate::trace::ray::GridRay;

/// One trilinear voxel (an octant or a merged dual cell) in grid coordinates.
///
/// Corner `i` sits at `lo` on the axes whose bit of `i` is 0 and at `hi` where it is 1 (bit 0 = x,
/// bit 1 = y, bit 2 = z); inside, the field is the trilinear interpolant of the corner values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Voxel {
    /// Lower corner, in grid coordinates.
    pub lo: [f64; 3],
    /// Upper corner, in grid coordinates.
    pub hi: [f64; 3],
    /// Corner values, x fastest.
    pub values: [f32; 8],
    /// AMR level the voxel belongs to.
    pub level: u32,
}

impl Voxel {
    /// Smallest and largest corner value.
    pub fn range(&self) -> (f32, f32) {
        self.values
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            })
    }

    /// The trilinear interpolant at local coordinates `u` (`[0, 1]^3` inside the voxel).
    pub fn eval_local(&self, u: [f64; 3]) -> f64 {
        let c = self.values.map(f64::from);
        let lx = |i: usize| c[i] + (c[i + 1] - c[i]) * u[0];
        let (e00, e10, e01, e11) = (lx(0), lx(2), lx(4), lx(6));
        let f0 = e00 + (e10 - e00) * u[1];
        let f1 = e01 + (e11 - e01) * u[1];
        f0 + (f1 - f0) * u[2]
    }

    /// Gradient of the trilinear interpolant with respect to local coordinates at `u`.
    pub fn grad_local(&self, u: [f64; 3]) -> [f64; 3] {
        let c = self.values.map(f64::from);
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let dx = |j: usize| c[j + 1] - c[j];
        let gx = lerp(lerp(dx(0), dx(2), u[1]), lerp(dx(4), dx(6), u[1]), u[2]);
        let dy = |j: usize| c[j + 2] - c[j];
        let gy = lerp(lerp(dy(0), dy(1), u[0]), lerp(dy(4), dy(5), u[0]), u[2]);
        let dz = |j: usize| c[j + 4] - c[j];
        let gz = lerp(lerp(dz(0), dz(1), u[0]), lerp(dz(2), dz(3), u[0]), u[1]);
        [gx, gy, gz]
    }

    /// Local coordinates of the grid point `p`.
    pub fn to_local(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| (p[a] - self.lo[a]) / (self.hi[a] - self.lo[a]))
    }
}

/// The affine map from grid coordinates to world coordinates, and the grid's extent.
///
/// Tracing happens in grid coordinates (relative to the domain's lower corner, in units of a
/// cell of some level), so a domain far from the world origin with tiny cells is traced with the
/// same precision as the unit cube.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridFrame {
    /// World position of grid point `(0, 0, 0)`: the domain's lower corner.
    pub origin: [f64; 3],
    /// World size of one grid unit on each axis.
    pub unit: [f64; 3],
    /// The domain is `[0, extent]` in grid coordinates.
    pub extent: [f64; 3],
}

impl GridFrame {
    /// World position of grid point `g`.
    pub fn to_world(&self, g: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.origin[a] + g[a] * self.unit[a])
    }

    /// Grid position of world point `w`.
    pub fn to_grid(&self, w: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| (w[a] - self.origin[a]) / self.unit[a])
    }

    /// World-space lower and upper corners of the domain.
    pub fn world_bounds(&self) -> ([f64; 3], [f64; 3]) {
        (self.origin, self.to_world(self.extent))
    }
}

/// A volume seen as a source of trilinear voxels, each named by a 64-bit ref (the paper's
/// *VoxelSource*, section 4.1.1), plus point sampling of the same reconstruction.
pub trait VoxelSource: Sync {
    /// The grid-to-world map and the domain's extent.
    fn frame(&self) -> GridFrame;

    /// The voxel named by `r`; `r` must come from this source's extraction.
    fn voxel(&self, r: u64) -> Voxel;

    /// The box `(lo, hi)` of the voxel named by `r`: by default [`Self::voxel`]'s; sources that
    /// can tell it from the reference alone skip reading its values.
    fn voxel_box(&self, r: u64) -> ([f64; 3], [f64; 3]) {
        let v = self.voxel(r);
        (v.lo, v.hi)
    }

    /// The reconstructed field and the AMR level at grid point `p`, or `None` outside the data.
    fn sample(&self, p: [f64; 3]) -> Option<(f32, u32)>;

    /// Drops pages of the underlying file from the resident set, between stages that touch it;
    /// a no-op for sources that hold no file.
    fn release_pages(&self) {}

    /// The first hit of `ray` with the surface `iso` inside `voxel` with `t` in `[tmin, tmax]`:
    /// by default the exact intersection with the voxel's trilinear interpolant.
    #[inline]
    fn intersect(
        &self,
        voxel: &Voxel,
        iso: f32,
        ray: &GridRay,
        tmin: f64,
        tmax: f64,
    ) -> Option<VoxelHit> {
        intersect_voxel(voxel, iso, ray, tmin, tmax)
    }
}
