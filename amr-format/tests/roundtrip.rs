//! Write/read round trips and the tree invariants over random hierarchies.

mod common;

use amr_format::{AmrkFile, Compression, WriterOptions};
use common::*;

fn check_round_trip(seed: u64, levels: usize, ratio: u32, compression: Compression) {
    let mut rng = Rng(seed);
    let brick = rng.range(2, 6);
    let spec = random_hierarchy(&mut rng, levels, ratio, brick);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.amrk");
    let summary = write_file(&spec, &path, WriterOptions { compression });
    let file = AmrkFile::open(std::fs::read(&path).unwrap())
        .unwrap_or_else(|e| panic!("seed {seed}: open failed: {e}"));
    assert_eq!(file.num_bricks(), spec.bricks.len(), "seed {seed}");
    assert_eq!(file.levels().len(), levels, "seed {seed}");
    assert_eq!(summary.file_bytes, std::fs::metadata(&path).unwrap().len());
    for (i, b) in spec.bricks.iter().enumerate() {
        assert_eq!(file.brick(i).cells, b.cells, "seed {seed} brick {i}");
        for f in 0..2 {
            let got = file.brick_values(f, i).unwrap();
            assert_eq!(&got[..], &brick_values(&spec, f, b)[..], "seed {seed} brick {i} field {f}");
        }
    }
    for (l, lev) in spec.levels.iter().enumerate() {
        assert_eq!(file.levels()[l].cell_size, lev.cell_size);
        assert_eq!(file.levels()[l].origin, lev.origin);
        assert_eq!(file.levels()[l].domain, lev.domain);
    }
    let report = file.verify().unwrap_or_else(|e| panic!("seed {seed}: verify failed: {e}"));
    assert_eq!(report.leaves as usize, file.num_leaves());
    // No file other than the target is left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "seed {seed}: temporary files left");
}

#[test]
fn round_trip_ratio_2_and_4_raw_and_compressed() {
    for seed in 0..40 {
        let ratio = if seed % 2 == 0 { 2 } else { 4 };
        let levels = 1 + (seed as usize % 4);
        let compression = if seed % 3 == 0 { Compression::Zstd { level: 3 } } else { Compression::None };
        check_round_trip(seed, levels, ratio, compression);
    }
}

#[test]
fn nine_levels_ratio_2() {
    for seed in 100..110 {
        check_round_trip(seed, 9, 2, Compression::None);
    }
}

#[test]
fn six_levels_ratio_4() {
    for seed in 200..206 {
        check_round_trip(seed, 6, 4, Compression::None);
    }
}
