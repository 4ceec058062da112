//! Point-sampling cost: nanoseconds per sample of each reconstruction at random points near
//! level boundaries and away from them, with a fresh sampler call per point
//! ([`Sampler::sample`]) and through a per-thread [`SampleScratch`] kept across points
//! ([`Sampler::sample_with`], what the tracer's smooth normals and sample mode use).

use std::time::{Duration, Instant};

use amr_format::AmrkFile;
use amr_render::reconstruct::{Reconstruction, SampleScratch, Sampler};
use amr_render::shade::sampling::Rng;

/// Random points of one field, sorted by where they lie.
#[derive(Clone, Debug, Default)]
pub struct SamplePoints {
    /// Points whose neighbourhood (one cell of their own level on every side) holds leaf cells
    /// of another level: where the octant method stitches levels.
    pub near: Vec<[f64; 3]>,
    /// Points whose neighbourhood is all of their own level.
    pub away: Vec<[f64; 3]>,
}

/// One row of the result: a reconstruction, a kind of point, and the cost per sample.
#[derive(Clone, Debug)]
pub struct SampleCost {
    /// The reconstruction.
    pub method: Reconstruction,
    /// `"near"` or `"away"` (from level boundaries).
    pub points: &'static str,
    /// Median over the runs of the time per sample, one sampler call per point.
    pub fresh: Duration,
    /// The same with a scratch kept across the points.
    pub scratch: Duration,
}

/// Draws up to `n` points of each kind (uniform in the domain, in doubled coordinates, seeded by
/// `seed`), giving up after `50 n` draws.
pub fn draw_points<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    n: usize,
    seed: u32,
) -> amr_render::Result<SamplePoints> {
    let grid = sampler.grid();
    let ext = grid.extent();
    let mut rng = Rng::for_pixel(seed, 0, 0);
    let mut out = SamplePoints::default();
    for _ in 0..50 * n {
        if out.near.len() >= n && out.away.len() >= n {
            break;
        }
        let p = [0, 1, 2].map(|a| rng.next_f64() * 2.0 * ext[a] as f64);
        let finest =
            |q: [f64; 3]| [0, 1, 2].map(|a| ((q[a] * 0.5).floor() as i64).clamp(0, ext[a] - 1));
        let Some(c) = sampler.locate(finest(p))? else {
            continue;
        };
        if sampler.sample(p, Reconstruction::Octant)?.is_none() {
            continue;
        }
        let s = grid.scale(c.level);
        let mut mixed = false;
        for d in 0..27 {
            let off = [d % 3, d / 3 % 3, d / 9].map(|k| k as f64 - 1.0);
            let q = [0, 1, 2].map(|a| p[a] + 2.0 * off[a] * s[a] as f64);
            if let Some(o) = sampler.locate(finest(q))? {
                mixed |= o.level != c.level;
            }
        }
        let kind = if mixed { &mut out.near } else { &mut out.away };
        if kind.len() < n {
            kind.push(p);
        }
    }
    Ok(out)
}

/// The cost per sample of each of `methods` at `points`, median of `runs` passes, on the
/// calling thread.
pub fn sample_costs<D: AsRef<[u8]>>(
    file: &AmrkFile<D>,
    field: usize,
    points: &SamplePoints,
    methods: &[Reconstruction],
    runs: usize,
) -> amr_render::Result<Vec<SampleCost>> {
    let sampler = Sampler::new(file, field, 256 << 20)?;
    let mut rows = Vec::new();
    for &method in methods {
        for (kind, pts) in [("near", &points.near), ("away", &points.away)] {
            if pts.is_empty() {
                continue;
            }
            let per = |d: Duration| d / pts.len() as u32;
            let mut fresh = Vec::with_capacity(runs);
            let mut kept = Vec::with_capacity(runs);
            for _ in 0..runs.max(1) {
                let t = Instant::now();
                for &p in pts.iter() {
                    std::hint::black_box(sampler.sample(p, method)?);
                }
                fresh.push(per(t.elapsed()));
                // A new scratch per pass: what one pass over random points costs from cold.
                let mut scratch = SampleScratch::default();
                let t = Instant::now();
                for &p in pts.iter() {
                    std::hint::black_box(sampler.sample_with(p, method, &mut scratch)?);
                }
                kept.push(per(t.elapsed()));
            }
            rows.push(SampleCost {
                method,
                points: kind,
                fresh: crate::median(&mut fresh),
                scratch: crate::median(&mut kept),
            });
        }
    }
    Ok(rows)
}
