//! In-memory voxel sources built from analytic functions, for tests and benchmarks that must
//! not depend on a file: a grid of unit blocks, each refined to its own level, with vertex values
//! on level boundaries taken from the coarser side's interpolant so the field is continuous.

use amr_render::trace::{GridFrame, Voxel, VoxelSource};

/// A multi-level voxel grid over `[0, n]^3` blocks (grid units = level-0 cells).
///
/// Block `b` is split into `ratio^level(b)` voxels per axis. A vertex that is a lattice point of
/// the coarsest level touching it takes the analytic value; any other vertex on a level boundary
/// takes the trilinear value of that coarsest level's voxel (chosen by a fixed rule, so every
/// voxel sharing the vertex gets the same bits).
pub struct BlockGrid {
    n: usize,
    ratio: u32,
    levels: Vec<u8>,
    voxels: Vec<Voxel>,
    block_start: Vec<u32>,
    frame: GridFrame,
}

impl BlockGrid {
    /// Builds the grid: `n^3` blocks, refinement `ratio`, `level(block index)` per block,
    /// field `f` in grid coordinates, placed in the world by `origin` and `unit`.
    pub fn new(
        n: usize,
        ratio: u32,
        level: impl Fn([usize; 3]) -> u8,
        f: impl Fn([f64; 3]) -> f64,
        origin: [f64; 3],
        unit: f64,
    ) -> BlockGrid {
        let mut levels = Vec::with_capacity(n * n * n);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    levels.push(level([x, y, z]));
                }
            }
        }
        let mut g = BlockGrid {
            n,
            ratio,
            levels,
            voxels: Vec::new(),
            block_start: Vec::new(),
            frame: GridFrame {
                origin,
                unit: [unit; 3],
                extent: [n as f64; 3],
            },
        };
        let mut cache = std::collections::HashMap::new();
        for b in 0..n * n * n {
            g.block_start.push(g.voxels.len() as u32);
            let bi = [b % n, (b / n) % n, b / (n * n)];
            let k = g.per_axis(g.levels[b]);
            let w = 1.0 / k as f64;
            for iz in 0..k {
                for iy in 0..k {
                    for ix in 0..k {
                        let lo = [0, 1, 2].map(|a| bi[a] as f64 + [ix, iy, iz][a] as f64 * w);
                        let hi = lo.map(|x| x + w);
                        let mut values = [0f32; 8];
                        for (c, v) in values.iter_mut().enumerate() {
                            let p = [0, 1, 2].map(|a| if c >> a & 1 == 1 { hi[a] } else { lo[a] });
                            *v = g.vertex_value(p, &f, &mut cache);
                        }
                        g.voxels.push(Voxel {
                            lo,
                            hi,
                            values,
                            level: u32::from(g.levels[b]),
                        });
                    }
                }
            }
        }
        g
    }

    fn per_axis(&self, level: u8) -> usize {
        (self.ratio as usize).pow(u32::from(level))
    }

    /// The lowest level of the blocks whose closed box contains `p`.
    fn min_level_at(&self, p: [f64; 3]) -> u8 {
        let mut m = u8::MAX;
        let n = self.n as i64;
        let ranges = p.map(|x| {
            let f = x.floor() as i64;
            if x == f as f64 {
                (f - 1).max(0)..=f.min(n - 1)
            } else {
                f..=f
            }
        });
        for z in ranges[2].clone() {
            for y in ranges[1].clone() {
                for x in ranges[0].clone() {
                    m = m.min(self.levels[(x + n * (y + n * z)) as usize]);
                }
            }
        }
        m
    }

    fn vertex_value(
        &self,
        p: [f64; 3],
        f: &impl Fn([f64; 3]) -> f64,
        cache: &mut std::collections::HashMap<[u64; 3], f32>,
    ) -> f32 {
        let key = p.map(f64::to_bits);
        if let Some(&v) = cache.get(&key) {
            return v;
        }
        let m = self.min_level_at(p);
        let k = self.per_axis(m) as f64;
        let on_lattice = p.iter().all(|&x| (x * k).fract() == 0.0);
        let v = if on_lattice {
            f(p) as f32
        } else {
            let w = 1.0 / k;
            let top = self.n as f64 * k - 1.0;
            let lo = p.map(|x| (x * k).floor().min(top) * w);
            let mut c = [0f32; 8];
            for (i, v) in c.iter_mut().enumerate() {
                let q = [0, 1, 2].map(|a| if i >> a & 1 == 1 { lo[a] + w } else { lo[a] });
                *v = self.vertex_value(q, f, cache);
            }
            let vox = Voxel {
                lo,
                hi: lo.map(|x| x + w),
                values: c,
                level: u32::from(m),
            };
            vox.eval_local(vox.to_local(p)) as f32
        };
        cache.insert(key, v);
        v
    }

    /// All voxels.
    pub fn voxels(&self) -> &[Voxel] {
        &self.voxels
    }

    /// Refs of the voxels whose closed corner range contains `iso`, in order.
    pub fn active(&self, iso: f32) -> Vec<u64> {
        (0..self.voxels.len() as u64)
            .filter(|&r| {
                let (a, b) = self.voxels[r as usize].range();
                a <= iso && iso <= b
            })
            .collect()
    }

    /// The index of the voxel containing grid point `p` (clamped into the domain).
    fn locate(&self, p: [f64; 3]) -> Option<usize> {
        let n = self.n as f64;
        if p.iter().any(|&x| !(0.0..=n).contains(&x)) {
            return None;
        }
        let bi = p.map(|x| (x.floor() as usize).min(self.n - 1));
        let b = bi[0] + self.n * (bi[1] + self.n * bi[2]);
        let k = self.per_axis(self.levels[b]);
        let ii =
            [0, 1, 2].map(|a| (((p[a] - bi[a] as f64) * k as f64).floor() as usize).min(k - 1));
        Some(self.block_start[b] as usize + ii[0] + k * (ii[1] + k * ii[2]))
    }
}

impl VoxelSource for BlockGrid {
    fn frame(&self) -> GridFrame {
        self.frame
    }

    fn voxel(&self, r: u64) -> Voxel {
        self.voxels[r as usize]
    }

    fn sample(&self, p: [f64; 3]) -> Option<(f32, u32)> {
        let v = &self.voxels[self.locate(p)?];
        Some((v.eval_local(v.to_local(p)) as f32, v.level))
    }
}
