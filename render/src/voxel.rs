//! The one voxel type: a box in grid coordinates (doubled finest-level cells) with eight corner
//! values, interpolated trilinearly inside.

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
        // Plain comparisons (one instruction each) rather than `f32::min`/`max`, whose NaN
        // handling costs more; for finite values (all a converter writes) both agree. A NaN in a
        // damaged file reaches the voxel's cubic either way, which then has no root.
        let [v0, rest @ ..] = self.values;
        rest.iter().fold((v0, v0), |(lo, hi), &v| {
            (if v < lo { v } else { lo }, if v > hi { v } else { hi })
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
        // Written out: as `map`, its call was not inlined into the tracer's per-hit loop in
        // some builds (a call per hit on the close-up frame).
        let v = &self.values;
        let c = [
            f64::from(v[0]),
            f64::from(v[1]),
            f64::from(v[2]),
            f64::from(v[3]),
            f64::from(v[4]),
            f64::from(v[5]),
            f64::from(v[6]),
            f64::from(v[7]),
        ];
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let dx = |j: usize| c[j + 1] - c[j];
        let gx = lerp(lerp(dx(0), dx(2), u[1]), lerp(dx(4), dx(6), u[1]), u[2]);
        let dy = |j: usize| c[j + 2] - c[j];
        let gy = lerp(lerp(dy(0), dy(1), u[0]), lerp(dy(4), dy(5), u[0]), u[2]);
        let dz = |j: usize| c[j + 4] - c[j];
        let gz = lerp(lerp(dz(0), dz(1), u[0]), lerp(dz(2), dz(3), u[0]), u[1]);
        [gx, gy, gz]
    }

    /// Gradient of the trilinear interpolant at local coordinates `u`, per grid unit.
    #[inline]
    pub fn grad_grid(&self, u: [f64; 3]) -> [f64; 3] {
        let g = self.grad_local(u);
        let per_grid = |a: usize| g[a] / (self.hi[a] - self.lo[a]);
        [per_grid(0), per_grid(1), per_grid(2)]
    }

    /// Lower corner in doubled finest-level coordinates (grid coordinates are integers there).
    pub fn lo_doubled(&self) -> [i64; 3] {
        self.lo.map(|x| x as i64)
    }

    /// Upper corner in doubled finest-level coordinates.
    pub fn hi_doubled(&self) -> [i64; 3] {
        self.hi.map(|x| x as i64)
    }

    /// The voxel of a reference that names none: an empty box with no values, which no ray hits.
    pub const EMPTY: Voxel = Voxel {
        lo: [0.0; 3],
        hi: [0.0; 3],
        values: [f32::NAN; 8],
        level: 0,
    };

    /// Local coordinates of the grid point `p`.
    pub fn to_local(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| (p[a] - self.lo[a]) / (self.hi[a] - self.lo[a]))
    }
}
