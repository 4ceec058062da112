//! Pieces every suite section uses: the machine description, a seeded generator, statistics,
//! a point-sampling voxel source for any reconstruction, and writing analytic datasets.

use std::fmt;
use std::path::Path;

use amr_format::progress::NoProgress;
use amr_format::{HierarchySpec, WriterOptions};
use amr_render::reconstruct::Sampler;
use amr_render::trace::{GridFrame, Voxel, VoxelSource};
use amr_render::Reconstruction;
use amr_synth::{write_spec, AnalyticField};

/// CPU model, core count and memory, from `/proc`.
#[derive(Clone, Debug)]
pub struct Machine {
    /// `model name` from `/proc/cpuinfo`.
    pub cpu: String,
    /// Logical cores available to this process.
    pub cores: usize,
    /// `MemTotal` in bytes.
    pub mem_bytes: u64,
}

impl Machine {
    /// Reads the running machine's description (unknown parts stay empty or zero).
    pub fn read() -> Machine {
        let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let cpu = cpuinfo
            .lines()
            .find(|l| l.starts_with("model name"))
            .and_then(|l| l.split_once(':'))
            .map_or("unknown CPU".into(), |(_, v)| v.trim().to_owned());
        let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap_or_default();
        let mem_bytes = meminfo
            .lines()
            .find(|l| l.starts_with("MemTotal:"))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|kb| kb.parse::<u64>().ok())
            .map_or(0, |kb| kb * 1024);
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Machine {
            cpu,
            cores,
            mem_bytes,
        }
    }
}

impl fmt::Display for Machine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}, {} cores (nproc), {:.1} GiB RAM",
            self.cpu,
            self.cores,
            self.mem_bytes as f64 / (1u64 << 30) as f64
        )
    }
}

/// SplitMix64: small, seeded, reproducible on every platform.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }

    /// A uniformly distributed unit vector.
    pub fn unit_vector(&mut self) -> [f64; 3] {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    }
}

/// A stateless hash of `(seed, x)`, for refinement decisions that must not depend on order.
pub fn hash2(seed: u64, x: u64) -> u64 {
    let mut r = Rng::new(seed ^ x.wrapping_mul(0xD6E8_FEB8_6659_FD93));
    r.next_u64()
}

/// The `q`-quantile (0..=1) of `v` (which it sorts); NaN when empty.
pub fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_unstable_by(f64::total_cmp);
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    v[i.min(v.len() - 1)]
}

/// The median of `v` (which it sorts).
pub fn median(v: &mut [f64]) -> f64 {
    quantile(v, 0.5)
}

/// Root mean square of `v`; NaN when empty.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Writes `spec` with every field taking `field`'s values; errors name the file.
pub fn write_dataset<F: AnalyticField + Sync>(
    path: &Path,
    spec: HierarchySpec,
    field: &F,
) -> anyhow::Result<()> {
    write_spec(path, spec, field, WriterOptions::default(), &NoProgress)
        .map_err(|e| e.in_file(path))?;
    Ok(())
}

/// Point samples of any reconstruction, `finest` included, for sample mode (it has no voxels:
/// [`VoxelSource::voxel`] returns an empty voxel, so it must not be given to the hybrid tracer).
pub struct SampledSource<'f, D> {
    /// The sampler.
    pub sampler: Sampler<'f, D>,
    /// The reconstruction.
    pub method: Reconstruction,
    /// Its frame.
    pub frame: GridFrame,
}

impl<'f, D: AsRef<[u8]> + Sync> SampledSource<'f, D> {
    /// A source sampling `sampler` with `method`.
    pub fn new(sampler: Sampler<'f, D>, method: Reconstruction) -> Self {
        let frame = GridFrame::of_grid(sampler.grid());
        SampledSource {
            sampler,
            method,
            frame,
        }
    }
}

impl<D: AsRef<[u8]> + Sync> VoxelSource for SampledSource<'_, D> {
    fn frame(&self) -> GridFrame {
        self.frame
    }

    fn voxel(&self, _r: u64) -> Voxel {
        Voxel::EMPTY
    }

    fn sample(&self, p: [f64; 3]) -> Option<(f32, u32)> {
        let v = self.sampler.sample(p, self.method).ok().flatten()?;
        Some((v, 0))
    }
}

/// Total cells in all bricks of `file`.
pub fn total_cells<D: AsRef<[u8]>>(file: &amr_format::AmrkFile<D>) -> u64 {
    (0..file.num_bricks())
        .map(|i| file.brick(i).cells.num_cells().unwrap_or(0))
        .sum()
}
