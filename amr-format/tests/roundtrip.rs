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
    let summary = write_file(
        &spec,
        &path,
        WriterOptions {
            compression,
            ..Default::default()
        },
    );
    let file = AmrkFile::open(std::fs::read(&path).unwrap())
        .unwrap_or_else(|e| panic!("seed {seed}: open failed: {e}"));
    assert_eq!(file.num_bricks(), spec.bricks.len(), "seed {seed}");
    assert_eq!(file.levels().len(), levels, "seed {seed}");
    assert_eq!(summary.file_bytes, std::fs::metadata(&path).unwrap().len());
    for (i, b) in spec.bricks.iter().enumerate() {
        assert_eq!(file.brick(i).cells, b.cells, "seed {seed} brick {i}");
        for f in 0..2 {
            let got = file.brick_values(f, i).unwrap();
            assert_eq!(
                &got[..],
                &brick_values(&spec, f, b)[..],
                "seed {seed} brick {i} field {f}"
            );
        }
    }
    for (l, lev) in spec.levels.iter().enumerate() {
        assert_eq!(file.levels()[l].cell_size, lev.cell_size);
        assert_eq!(file.levels()[l].origin, lev.origin);
        assert_eq!(file.levels()[l].domain, lev.domain);
    }
    let report = file
        .verify()
        .unwrap_or_else(|e| panic!("seed {seed}: verify failed: {e}"));
    assert_eq!(report.leaves as usize, file.num_leaves());
    // No file other than the target is left behind.
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "seed {seed}: temporary files left"
    );
}

#[test]
fn round_trip_ratio_2_and_4_raw_and_compressed() {
    for seed in 0..40 {
        let ratio = if seed % 2 == 0 { 2 } else { 4 };
        let levels = 1 + (seed as usize % 4);
        let compression = if seed % 3 == 0 {
            Compression::Zstd { level: 3 }
        } else {
            Compression::None
        };
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

fn one_level(
    domain: amr_format::IBox,
    bricks: Vec<amr_format::IBox>,
    levels: usize,
) -> amr_format::HierarchySpec {
    use amr_format::{BrickSpec, HierarchySpec, LevelSpec};
    let mut specs = Vec::new();
    let mut d = domain;
    for l in 0..levels {
        specs.push(LevelSpec {
            cell_size: [1.0 / (1 << l) as f64; 3],
            origin: [0.0; 3],
            ratio_to_next: if l + 1 < levels { [2; 3] } else { [1; 3] },
            domain: d,
        });
        d = d.refine([2; 3]).unwrap();
    }
    HierarchySpec {
        levels: specs,
        fields: vec!["f".into(), "g".into()],
        bricks: bricks
            .into_iter()
            .enumerate()
            .map(|(i, c)| BrickSpec {
                level: (i % levels) as u32,
                cells: c,
            })
            .collect(),
    }
}

#[test]
fn overlapping_bricks_of_one_level_are_refused_by_name() {
    use amr_format::IBox;
    let domain = IBox::new([0; 3], [8; 3]);
    let spec = one_level(
        domain,
        vec![IBox::new([0; 3], [5; 3]), IBox::new([4; 3], [8; 3])],
        1,
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("o.amrk");
    // Found from the boxes alone, before any data is read.
    let e = amr_format::AmrkWriter::create(&path, spec.clone(), WriterOptions::default())
        .err()
        .expect("overlap must be refused")
        .to_string();
    assert!(
        e.contains("bricks 0 and 1") || e.contains("bricks 1 and 0"),
        "{e}"
    );
    assert!(!path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "temporary files left behind"
    );
}

#[test]
fn holes_and_unnested_fine_bricks_still_tile() {
    use amr_format::IBox;
    // Level 0 covers only part of the domain; a level-1 brick sits partly over the hole.
    let domain = IBox::new([-4, 0, 2], [4, 6, 10]);
    let spec = one_level(
        domain,
        vec![
            IBox::new([-4, 0, 2], [0, 6, 10]),
            IBox::new([-2, 2, 6], [4, 8, 12]),
        ],
        2,
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.amrk");
    write_file(&spec, &path, WriterOptions::default());
    let file = AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
    let report = file.verify().unwrap();
    assert_eq!(report.covered_cells, 8 * 6 * 8 * 8);
    let empty = (0..file.num_leaves() as u32)
        .filter(|&l| file.leaf(l).bricks.is_empty())
        .count();
    assert!(empty > 0, "the hole is an empty leaf");
    let (lo, hi) = file.leaf_range(
        0,
        (0..file.num_leaves() as u32)
            .find(|&l| file.leaf(l).bricks.is_empty())
            .unwrap(),
    );
    assert!(lo > hi, "an empty leaf's range contains nothing");
}

#[test]
fn point_location_finds_the_finest_brick() {
    for seed in 300..320 {
        let mut rng = Rng(seed);
        let spec = random_hierarchy(&mut rng, 4, 2, 3);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.amrk");
        write_file(&spec, &path, WriterOptions::default());
        let file = AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
        let tree = file.tree();
        let origin = file.finest_domain().lo;
        for _ in 0..200 {
            let p = [0, 1, 2].map(|a| rng.range(0, tree.domain.hi[a]));
            let leaf = tree
                .find_leaf(p)
                .unwrap_or_else(|| panic!("seed {seed}: {p:?} not found"));
            assert!(file.leaf(leaf).bounds.contains_cell(p), "seed {seed}");
            let finest = (0..file.num_bricks())
                .filter(|&b| file.brick_finest_bounds(b, origin).contains_cell(p))
                .max_by_key(|&b| file.brick(b).level);
            assert_eq!(
                file.leaf(leaf).bricks.first().map(|b| b.get() as usize),
                finest,
                "seed {seed}: point {p:?}"
            );
        }
    }
}
