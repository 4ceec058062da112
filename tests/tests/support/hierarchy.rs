//! Shared helpers for the reconstruction and extraction tests: seeded random nested hierarchies
//! written with `AmrkWriter` and read back into memory.

pub use super::rng::Rng;
use amr_format::{
    AmrkFile, AmrkWriter, BrickSpec, Compression, HierarchySpec, IBox, LevelSpec, WriterOptions,
};

/// What a random test file is made of.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    pub seed: u64,
    pub levels: usize,
    pub ratio: u32,
    pub brick: i64,
    /// World origin magnitude (up to 1e6) and finest cell size (down to 1e-6).
    pub far: bool,
    pub zstd: bool,
    /// The file stores tight leaf ranges (layout version 3) computed by the renderer.
    pub tight: bool,
}

impl Case {
    pub fn new(seed: u64, levels: usize, ratio: u32) -> Self {
        Self {
            seed,
            levels,
            ratio,
            brick: 4,
            far: seed % 2 == 1,
            zstd: false,
            // Two cases in three store tight leaf ranges; the others leave them to the extraction.
            tight: !seed.is_multiple_of(3),
        }
    }
}

/// A random properly nested hierarchy: level 0 covers a domain at a random offset; each finer
/// level refines one to three random boxes inside the previous level's bricks (boxes of level
/// `l + 1` are unions of refined level-`l` cells); boxes are split into bricks of at most
/// `brick` cells per axis.
pub fn random_hierarchy(case: &Case) -> HierarchySpec {
    let mut rng = Rng(case.seed);
    let base = [rng.range(2, 7), rng.range(2, 7), rng.range(2, 7)];
    let off = [rng.range(-5, 5), rng.range(-5, 5), rng.range(-5, 5)];
    let total_ratio = (case.ratio as f64).powi(case.levels as i32 - 1);
    let (origin, dx0) = if case.far {
        let finest = 1e-6 * (1.0 + rng.f64());
        (
            [
                1e6 * (1.0 - 2.0 * rng.f64()),
                -1e6 * rng.f64(),
                1e5 * rng.f64(),
            ],
            finest * total_ratio,
        )
    } else {
        (
            [rng.f64(), -rng.f64(), 0.0],
            0.5f64.powi(rng.range(0, 6) as i32),
        )
    };
    let mut specs = Vec::new();
    let mut domain = IBox::new(off, [0, 1, 2].map(|a| off[a] + base[a]));
    let brick = case.brick;
    let mut bricks: Vec<BrickSpec> = domain
        .split([brick; 3])
        .into_iter()
        .map(|c| BrickSpec { level: 0, cells: c })
        .collect();
    let mut dx = dx0;
    for l in 0..case.levels {
        specs.push(LevelSpec {
            cell_size: [dx; 3],
            origin,
            ratio_to_next: if l + 1 < case.levels {
                [case.ratio; 3]
            } else {
                [1; 3]
            },
            domain,
        });
        if l + 1 == case.levels {
            break;
        }
        let r = [case.ratio as i64; 3];
        let parents: Vec<IBox> = bricks
            .iter()
            .filter(|b| b.level as usize == l)
            .map(|b| b.cells)
            .collect();
        let mut chosen: Vec<IBox> = Vec::new();
        for _ in 0..rng.range(1, 4) {
            let p = parents[rng.below(parents.len() as u64) as usize];
            let e = p.extent();
            let lo = [0, 1, 2].map(|a| p.lo[a] + rng.range(0, e[a]));
            let hi = [0, 1, 2].map(|a| lo[a] + 1 + rng.range(0, p.hi[a] - lo[a]));
            let b = IBox::new(lo, hi).refine(r).unwrap();
            if chosen.iter().all(|c| !c.overlaps(&b)) {
                chosen.push(b);
            }
        }
        for c in &chosen {
            for piece in c.split([brick; 3]) {
                bricks.push(BrickSpec {
                    level: l as u32 + 1,
                    cells: piece,
                });
            }
        }
        domain = domain.refine(r).unwrap();
        dx /= case.ratio as f64;
    }
    HierarchySpec {
        levels: specs,
        fields: vec!["smooth".into(), "rough".into()],
        bricks,
    }
}

/// Field 0 is smooth in the cell centre's position relative to the domain; field 1 is a hash of
/// the cell, quantised to multiples of 1/8 in [-1, 1] so that values repeat and isovalues equal
/// to cell values are common.
pub fn cell_value(spec: &HierarchySpec, field: usize, level: usize, p: [i64; 3]) -> f32 {
    let lev = &spec.levels[level];
    if field == 0 {
        let d = &spec.levels[0].domain;
        let s = spec.finest_scale(level);
        let f0 = spec.finest_scale(0);
        let x = [0, 1, 2].map(|a| {
            ((p[a] as f64 + 0.5) * s[a] as f64 / f0[a] as f64 - d.lo[a] as f64)
                / d.extent()[a] as f64
        });
        ((x[0] * 5.1).sin() + (x[1] * 3.7).cos() * 0.8 + x[2] * x[0] * 1.3) as f32
    } else {
        let mut h = Rng((level as u64) << 48
            ^ (p[0] as u64).wrapping_mul(0x9E37)
            ^ (p[1] as u64) << 20
            ^ (p[2] as u64) << 34);
        let _ = lev;
        (h.range(-8, 9) as f32) / 8.0
    }
}

fn brick_values(spec: &HierarchySpec, field: usize, b: &BrickSpec) -> Vec<f32> {
    let c = b.cells;
    let mut out = Vec::with_capacity(c.num_cells().unwrap() as usize);
    for z in c.lo[2]..c.hi[2] {
        for y in c.lo[1]..c.hi[1] {
            for x in c.lo[0]..c.hi[0] {
                out.push(cell_value(spec, field, b.level as usize, [x, y, z]));
            }
        }
    }
    out
}

/// Writes the case's file and reads it back into memory.
pub fn build(case: &Case) -> (HierarchySpec, AmrkFile<Vec<u8>>) {
    let spec = random_hierarchy(case);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("case.amrk");
    let compression = if case.zstd {
        Compression::Zstd { level: 3 }
    } else {
        Compression::None
    };
    let mut w = AmrkWriter::create(
        &path,
        spec.clone(),
        WriterOptions {
            compression,
            tight: case.tight.then_some(amr_render::extract::tight_tables_of),
        },
    )
    .unwrap_or_else(|e| panic!("{case:?}: {e}"));
    for (i, b) in spec.bricks.iter().enumerate() {
        for f in 0..spec.fields.len() {
            w.write_brick(i, f, &brick_values(&spec, f, b)).unwrap();
        }
    }
    w.finish().unwrap_or_else(|e| panic!("{case:?}: {e}"));
    let bytes = std::fs::read(&path).unwrap();
    let file = AmrkFile::open(bytes).unwrap_or_else(|e| panic!("{case:?}: {e}"));
    (spec, file)
}

/// The cases most tests run: two and three levels with ratio 2 and 4, and nine levels.
pub fn standard_cases(seeds: u64) -> Vec<Case> {
    let mut out = Vec::new();
    for seed in 0..seeds {
        for (levels, ratio) in [(2, 2), (3, 2), (2, 4), (3, 4), (9, 2), (9, 4)] {
            out.push(Case::new(
                seed * 1000 + levels as u64 * 10 + ratio as u64,
                levels,
                ratio,
            ));
        }
    }
    out
}
