//! Shared helpers for the format tests: random nested hierarchies and an analytic field.

#![allow(dead_code)]

use amr_format::raw::Footer;
use amr_format::{AmrkFile, AmrkWriter, BrickSpec, HierarchySpec, IBox, LevelSpec, WriterOptions};
use std::path::Path;
use zerocopy::FromBytes;

/// A small deterministic generator (SplitMix64), so every failure names its seed.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
    pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
        lo + self.below((hi - lo).max(1) as u64) as i64
    }
    pub fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A random properly nested hierarchy: level 0 covers a domain at a random offset; each finer
/// level refines a few random boxes inside the previous level's bricks; boxes are split into
/// bricks of at most `brick` cells.
pub fn random_hierarchy(rng: &mut Rng, levels: usize, ratio: u32, brick: i64) -> HierarchySpec {
    let base = [rng.range(2, 9), rng.range(2, 9), rng.range(2, 9)];
    let off = [rng.range(-5, 5), rng.range(-5, 5), rng.range(-5, 5)];
    let dx0 = 0.5f64.powi(rng.range(0, 20) as i32) * (1.0 + rng.unit());
    let origin = [rng.unit() * 1e3, -rng.unit(), 0.0];
    let mut specs = Vec::new();
    let mut domain = IBox::new(off, [0, 1, 2].map(|a| off[a] + base[a]));
    let mut bricks: Vec<BrickSpec> = domain
        .split([brick; 3])
        .into_iter()
        .map(|c| BrickSpec { level: 0, cells: c })
        .collect();
    let mut dx = dx0;
    for l in 0..levels {
        specs.push(LevelSpec {
            cell_size: [dx; 3],
            origin,
            ratio_to_next: if l + 1 < levels { [ratio; 3] } else { [1; 3] },
            domain,
        });
        if l + 1 == levels {
            break;
        }
        let r = [ratio as i64; 3];
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
        dx /= ratio as f64;
    }
    HierarchySpec {
        levels: specs,
        fields: vec!["f".into(), "g".into()],
        bricks,
    }
}

/// Value of the test fields at cell `p` of `level`: a smooth function of the cell centre.
pub fn field_value(spec: &HierarchySpec, field: usize, level: usize, p: [i64; 3]) -> f32 {
    let lev = &spec.levels[level];
    let x = [0, 1, 2].map(|a| lev.origin[a] + (p[a] as f64 + 0.5) * lev.cell_size[a]);
    let s = (x[0] * 1.3).sin() + (x[1] * 0.7).cos() * 2.0 + x[2] * 0.1;
    if field == 0 {
        s as f32
    } else {
        (s * s - 1.0) as f32
    }
}

/// Values of one brick of one field.
pub fn brick_values(spec: &HierarchySpec, field: usize, b: &BrickSpec) -> Vec<f32> {
    let c = b.cells;
    let mut out = Vec::with_capacity(c.num_cells().unwrap() as usize);
    for z in c.lo[2]..c.hi[2] {
        for y in c.lo[1]..c.hi[1] {
            for x in c.lo[0]..c.hi[0] {
                out.push(field_value(spec, field, b.level as usize, [x, y, z]));
            }
        }
    }
    out
}

/// Writes `spec` with the test fields to `path`, bricks in reverse order to exercise
/// positioned writes.
pub fn write_file(
    spec: &HierarchySpec,
    path: &Path,
    opts: WriterOptions,
) -> amr_format::WriteSummary {
    let mut w = AmrkWriter::create(path, spec.clone(), opts).unwrap();
    for (i, b) in spec.bricks.iter().enumerate().rev() {
        for f in 0..spec.fields.len() {
            w.write_brick(i, f, &brick_values(spec, f, b)).unwrap();
        }
    }
    w.finish().unwrap()
}

/// The bytes of a valid three-level file made from `seed`.
pub fn valid_file(seed: u64) -> Vec<u8> {
    let mut rng = Rng(seed);
    let spec = random_hierarchy(&mut rng, 3, 2, 3);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.amrk");
    write_file(&spec, &path, WriterOptions::default());
    std::fs::read(&path).unwrap()
}

/// The footer of the file in `bytes`.
pub fn footer_of(bytes: &[u8]) -> Footer {
    Footer::read_from_bytes(&bytes[bytes.len() - size_of::<Footer>()..]).unwrap()
}

/// The message of the error opening `bytes`; panics when they open.
pub fn open_err(bytes: Vec<u8>) -> String {
    match AmrkFile::open(bytes) {
        Ok(_) => panic!("a damaged file opened"),
        Err(e) => e.to_string(),
    }
}
