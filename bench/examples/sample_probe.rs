//! A probe of the octant sampler at `amr-bench sample`'s random points: which kind of octant
//! each point falls in, what each kind costs, and a hash of every sample's bits that proves a
//! change left the values alone.
//!
//! ```text
//! sample_probe classify FILE [POINTS]            points per class
//! sample_probe counts FILE [POINTS] [RUNS]       ns per sample per class, fresh and scratch
//! sample_probe hash FILE [POINTS]                hash of every sample's bits, per method and path
//! sample_probe loop FILE KIND POINTS fresh|scratch [CLASS]
//! ```
//!
//! `loop` runs one pass of octant samples inside `probe_fresh` or `probe_scratch`, for
//! `valgrind --tool=callgrind --toggle-collect='*probe_fresh*'`; KIND is `near` or `away`.
//!
//! The class of a point is decided from the public API alone (so the probe builds against older
//! sampler code): the eight leaf cells around its octant's outer corner (the corner of the leaf
//! cell on the octant's side) are all of the cell's level (`one-level`), include a coarser one
//! (`coarser`: some vertex is stitched to a coarse octant), or only finer ones (`finer`).

use std::time::Instant;

use amr_bench::sample::draw_points;
use amr_render::mapping::open_mapped;
use amr_render::reconstruct::{Reconstruction, SampleScratch, Sampler};

/// The classes of [`class_of`], in print order.
const CLASSES: [&str; 4] = ["one-level", "finer", "coarser", "edge"];

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    let num = |i: usize, d: usize| arg(i).map_or(Ok(d), str::parse);
    let (Some(mode), Some(path)) = (arg(0), arg(1)) else {
        anyhow::bail!("usage: sample_probe classify|counts|hash|loop FILE ...");
    };
    let file = open_mapped(std::path::Path::new(path))?;
    let sampler = Sampler::new(&file, 0, 256 << 20)?;
    match mode {
        "classify" => {
            let points = draw_points(&sampler, num(2, 20_000)?, 1)?;
            for (kind, pts) in [("near", &points.near), ("away", &points.away)] {
                let mut n = [0usize; CLASSES.len()];
                for &p in pts {
                    n[class_of(&sampler, p)?] += 1;
                }
                let row: Vec<String> = CLASSES
                    .iter()
                    .zip(n)
                    .map(|(c, k)| format!("{c} {k}"))
                    .collect();
                println!("{kind}: {}", row.join(", "));
            }
        }
        "counts" => {
            let points = draw_points(&sampler, num(2, 20_000)?, 1)?;
            let runs = num(3, 5)?;
            println!("| points | class | count | ns fresh | ns scratch |");
            println!("|---|---|---|---|---|");
            for (kind, pts) in [("near", &points.near), ("away", &points.away)] {
                let mut by_class = vec![Vec::new(); CLASSES.len()];
                for &p in pts {
                    by_class[class_of(&sampler, p)?].push(p);
                }
                by_class.push(pts.clone());
                for (i, pts) in by_class.iter().enumerate() {
                    if pts.is_empty() {
                        continue;
                    }
                    let mut fresh = Vec::new();
                    let mut kept = Vec::new();
                    for _ in 0..runs.max(1) {
                        let t = Instant::now();
                        probe_fresh(&sampler, pts)?;
                        fresh.push(t.elapsed().as_secs_f64() * 1e9 / pts.len() as f64);
                        let t = Instant::now();
                        probe_scratch(&sampler, pts)?;
                        kept.push(t.elapsed().as_secs_f64() * 1e9 / pts.len() as f64);
                    }
                    println!(
                        "| {kind} | {} | {} | {:.0} | {:.0} |",
                        CLASSES.get(i).copied().unwrap_or("all"),
                        pts.len(),
                        median(&mut fresh),
                        median(&mut kept)
                    );
                }
            }
        }
        "hash" => {
            let points = draw_points(&sampler, num(2, 20_000)?, 1)?;
            let general = Sampler::new(&file, 0, 256 << 20)?.with_shortcuts(false);
            let mut all = Fnv::default();
            for method in Reconstruction::ALL {
                for (kind, pts) in [("near", &points.near), ("away", &points.away)] {
                    let mut h = [Fnv::default(), Fnv::default(), Fnv::default()];
                    let mut scratch = SampleScratch::default();
                    for &p in pts {
                        let fresh = sampler.sample(p, method)?;
                        let kept = sampler.sample_with(p, method, &mut scratch)?.map(|s| s.0);
                        let slow = general.sample(p, method)?;
                        for (h, x) in h.iter_mut().zip([fresh, kept, slow]) {
                            h.add(x.map_or(u64::MAX, |x| u64::from(x.to_bits())));
                        }
                    }
                    let [f, k, s] = h.map(|h| h.0);
                    println!("{method} {kind}: fresh {f:016x} scratch {k:016x} general {s:016x}");
                    for x in [f, k, s] {
                        all.add(x);
                    }
                }
            }
            println!("all: {:016x}", all.0);
        }
        "loop" => {
            let kind = arg(2).unwrap_or("near");
            let points = draw_points(&sampler, num(3, 2_000)?, 1)?;
            let pts = if kind == "away" {
                points.away
            } else {
                points.near
            };
            let pts = match arg(5) {
                Some(class) => {
                    let want = CLASSES.iter().position(|c| *c == class);
                    let mut kept = Vec::new();
                    for p in pts {
                        if Some(class_of(&sampler, p)?) == want {
                            kept.push(p);
                        }
                    }
                    kept
                }
                None => pts,
            };
            match arg(4).unwrap_or("fresh") {
                "scratch" => probe_scratch(&sampler, &pts)?,
                _ => probe_fresh(&sampler, &pts)?,
            }
            println!("{} points", pts.len());
        }
        _ => anyhow::bail!("unknown mode {mode}"),
    }
    Ok(())
}

/// One octant sample per point, a fresh sampler call each.
#[inline(never)]
fn probe_fresh<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, pts: &[[f64; 3]]) -> anyhow::Result<()> {
    for &p in pts {
        std::hint::black_box(sampler.sample(p, Reconstruction::Octant)?);
    }
    Ok(())
}

/// One octant sample per point through one scratch, new for the pass.
#[inline(never)]
fn probe_scratch<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, pts: &[[f64; 3]]) -> anyhow::Result<()> {
    let mut scratch = SampleScratch::default();
    for &p in pts {
        std::hint::black_box(sampler.sample_with(p, Reconstruction::Octant, &mut scratch)?);
    }
    Ok(())
}

/// The index in [`CLASSES`] of the octant holding doubled point `p`.
fn class_of<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, p: [f64; 3]) -> anyhow::Result<usize> {
    let grid = sampler.grid();
    let ext = grid.extent();
    let finest: [i64; 3] =
        std::array::from_fn(|a| ((p[a] * 0.5).floor() as i64).clamp(0, ext[a] - 1));
    let Some(c) = sampler.locate(finest)? else {
        return Ok(3);
    };
    let centre = grid.centre(c.level, c.cell);
    let s = grid.scale(c.level);
    let outer: [i64; 3] = std::array::from_fn(|a| {
        if p[a] >= centre[a] as f64 {
            centre[a] + s[a]
        } else {
            centre[a] - s[a]
        }
    });
    let Some(cells) = sampler.around(outer)? else {
        return Ok(3);
    };
    Ok(if cells.iter().any(|x| x.level < c.level) {
        2
    } else if cells.iter().any(|x| x.level > c.level) {
        1
    } else {
        0
    })
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// FNV-1a over 64-bit words.
struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    fn add(&mut self, x: u64) {
        for b in x.to_le_bytes() {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
        }
    }
}
