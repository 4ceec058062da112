//! Enzo datasets written by the tests themselves, in the layout Enzo's own writers produce
//! (`WriteParameterFile.C`, `Group_WriteDataHierarchy.C`, `Grid_Group_WriteGrid.C`), plus where
//! the shared real dataset is and a cell-by-cell check of a converted file.
#![allow(dead_code)]

pub mod writer;

use std::path::{Path, PathBuf};

use amr_format::AmrkFile;

/// The shared Enzo dataset `DD0010`: `$AMR_TEST_DATA/enzo/DD0010`, else
/// `../shared/data/enzo/DD0010` from the workspace root. `None` (after saying so on stderr) when
/// absent, so the caller can skip.
pub fn shared_enzo(test: &str) -> Option<PathBuf> {
    let root = match std::env::var_os("AMR_TEST_DATA") {
        Some(p) => PathBuf::from(p),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"),
    };
    let dir = root.join("enzo/DD0010");
    if dir.join("moving7_0010.hierarchy").is_file() {
        Some(dir)
    } else {
        eprintln!(
            "skipped: {test}, because the shared Enzo dataset is not at {} (set AMR_TEST_DATA to the folder holding enzo/)",
            dir.display()
        );
        None
    }
}

/// The value the fixtures store at a valid cell of `level`: smooth, different per level and
/// field, and (as f64) not exactly an f32.
pub fn value(level: usize, field: usize, p: [i64; 3]) -> f64 {
    let [x, y, z] = p.map(|v| v as f64);
    (field as f64 + 1.0) * ((0.29 * x - 0.83 * y + 0.57 * z).cos() * 7.0 + level as f64 * 50.0)
        + 1.0 / 7.0
}

/// The value a fixture stores in a ghost zone: far from every valid value.
pub fn ghost_value() -> f64 {
    -9.0e6
}

/// Compares every cell of every brick of `amrk` with `expected(level, field, cell)`; returns
/// the number of values compared.
pub fn check_cells(amrk: &Path, expected: &dyn Fn(usize, usize, [i64; 3]) -> f32) -> u64 {
    let file = AmrkFile::open(std::fs::read(amrk).unwrap()).unwrap();
    file.verify().unwrap();
    let mut n = 0;
    for f in 0..file.fields().len() {
        for b in 0..file.num_bricks() {
            let info = file.brick(b);
            let vals = file.brick_values(f, b).unwrap();
            let c = info.cells;
            let mut i = 0;
            for z in c.lo[2]..c.hi[2] {
                for y in c.lo[1]..c.hi[1] {
                    for x in c.lo[0]..c.hi[0] {
                        let want = expected(info.level as usize, f, [x, y, z]);
                        assert_eq!(
                            vals[i].to_bits(),
                            want.to_bits(),
                            "field {f}, level {}, cell {:?}: {} != {want}",
                            info.level,
                            [x, y, z],
                            vals[i]
                        );
                        i += 1;
                        n += 1;
                    }
                }
            }
        }
    }
    n
}
