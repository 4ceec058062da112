//! The converter on plotfiles this suite writes itself, for what the shared ones lack:
//! float32, big-endian, partial refinement, ratio 4 and anisotropic ratios, negative origin and
//! indices, ghost cells, `Cell_H` versions 2 to 4, offsets above 4 GiB, 2D, bad values.

use std::path::Path;

use crate::support::amrex::check::check_conversion;
use crate::support::amrex::writer::{write_plotfile, Bx, PlotSpec, Real};
use crate::support::amrex::{assert_fails, convert};
use amr_format::AmrkFile;

/// A smooth field that differs per level and component and is not exactly representable.
fn analytic(level: usize, comp: usize, p: [i64; 3]) -> f64 {
    let s = (p[0] as f64 * 0.37 + p[1] as f64 * 1.13 - p[2] as f64 * 0.71).sin();
    1.0 / 3.0 + s * 1e3 + level as f64 * 1e4 - comp as f64 * 7.0
}

/// Level 0 `[-8, 8)^3` on `[-2, 1.2]^3`, level 1 (ratio 4) covering part of it, level 2
/// (ratio 2) covering part of that; boxes of uneven sizes.
fn three_levels() -> PlotSpec {
    let b = |lo: [i64; 3], hi: [i64; 3]| -> Bx { (lo, hi) };
    PlotSpec {
        fields: vec![
            "density".into(),
            "Y(CH2(S)) [mass fraction]".into(),
            "temp".into(),
        ],
        prob_lo: [-2.0, -2.0, -2.0],
        prob_hi: [1.2, 1.2, 1.2],
        domain: ([-8; 3], [7; 3]),
        ratios: vec![[4, 4, 4], [2, 2, 2]],
        boxes: vec![
            vec![b([-8, -8, -8], [-1, 7, 7]), b([0, -8, -8], [7, 7, 7])],
            vec![
                b([-16, -16, -16], [3, 11, 7]),
                b([4, -16, -16], [15, 11, 7]),
            ],
            vec![
                b([-20, -20, -20], [-1, -3, 3]),
                b([0, -20, -20], [13, -3, 3]),
            ],
        ],
        ..PlotSpec::single(16)
    }
}

fn roundtrip(spec: &PlotSpec, brick: u32, fields: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let plt = dir.path().join("plt00010");
    write_plotfile(&plt, spec, &analytic, f64::NAN);
    let target = dir.path().join("out.amrk");
    convert(&plt, &target, fields, brick).unwrap();
    let checked = check_conversion(&plt, &target, fields);
    assert!(checked.values > 0);
    check_geometry(spec, &target);
}

fn check_geometry(spec: &PlotSpec, amrk: &Path) {
    let file = AmrkFile::open(std::fs::read(amrk).unwrap()).unwrap();
    for (l, info) in file.levels().iter().enumerate() {
        let (lo, hi) = spec.level_domain(l);
        let dx = spec.cell_size(l);
        assert_eq!(info.domain.lo, lo, "level {l} domain");
        assert_eq!(info.domain.hi, hi.map(|h| h + 1), "level {l} domain");
        for a in 0..3 {
            let origin = spec.prob_lo[a] - lo[a] as f64 * dx[a];
            assert!(
                (info.origin[a] - origin).abs() < 1e-12,
                "level {l} origin {:?}",
                info.origin
            );
            assert!(
                (info.cell_size[a] - dx[a]).abs() < 1e-15,
                "level {l} cell size {:?}",
                info.cell_size
            );
        }
        if l + 1 < spec.boxes.len() {
            assert_eq!(
                info.ratio_to_next.map(i64::from),
                spec.ratios[l],
                "level {l} ratio"
            );
        }
    }
}

#[test]
fn float64_little_endian_partial_refinement_ratio_4() {
    roundtrip(&three_levels(), 32, &[]);
}

#[test]
fn float32_big_endian_with_ghosts_and_small_bricks() {
    let spec = PlotSpec {
        real: Real::F32Be,
        nghost: [2; 3],
        boxes_per_file: 1,
        ..three_levels()
    };
    roundtrip(&spec, 5, &[]);
}

#[test]
fn float32_little_and_float64_big_endian() {
    roundtrip(
        &PlotSpec {
            real: Real::F32Le,
            ..three_levels()
        },
        7,
        &[],
    );
    roundtrip(
        &PlotSpec {
            real: Real::F64Be,
            nghost: [1; 3],
            ..three_levels()
        },
        16,
        &["temp", "density"],
    );
}

#[test]
fn cell_h_versions_without_fab_headers() {
    for (version, real) in [(2, Real::F64Le), (3, Real::F32Be), (4, Real::F64Be)] {
        let spec = PlotSpec {
            cell_h_version: version,
            real,
            nghost: [1; 3],
            ..three_levels()
        };
        roundtrip(&spec, 6, &[]);
    }
}

#[test]
fn anisotropic_ratio_and_ghost_vector() {
    let spec = PlotSpec {
        version: "CartGrid-V2.0".into(),
        domain: ([0; 3], [7, 7, 3]),
        prob_hi: [1.0, 1.0, 0.5],
        ratios: vec![[2, 4, 2]],
        boxes: vec![vec![([0; 3], [7, 7, 3])], vec![([4, 8, 0], [11, 23, 5])]],
        nghost: [1, 0, 2],
        cell_h_version: 2,
        ..PlotSpec::single(8)
    };
    roundtrip(&spec, 4, &[]);
}

#[test]
fn offsets_above_4_gib() {
    let dir = tempfile::tempdir().unwrap();
    let plt = dir.path().join("big");
    let spec = PlotSpec {
        first_offset: (4 << 30) + 12_345,
        boxes_per_file: 8,
        ..three_levels()
    };
    write_plotfile(&plt, &spec, &analytic, f64::NAN);
    let target = dir.path().join("big.amrk");
    let s = convert(&plt, &target, &[], 32).unwrap();
    assert!(
        s.bytes_read < 1 << 24,
        "the gap before the FAB is skipped, not read: {}",
        s.bytes_read
    );
    check_conversion(&plt, &target, &[]);
}

#[test]
fn two_dimensional_plotfile_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let plt = dir.path().join("plt2d");
    write_plotfile(
        &plt,
        &PlotSpec {
            dim: 2,
            ..PlotSpec::single(8)
        },
        &analytic,
        0.0,
    );
    assert_fails(&plt, &[], &["2D is not supported", "Header"]);
}

#[test]
fn nan_infinite_and_huge_values_are_refused() {
    for (bad, why) in [
        (f64::NAN, "NaN"),
        (f64::INFINITY, "infinite"),
        (1e39, "outside the f32 range"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let plt = dir.path().join("plt");
        let value = move |l: usize, c: usize, p: [i64; 3]| {
            if l == 1 && c == 2 && p == [5, 0, 1] {
                bad
            } else {
                analytic(l, c, p)
            }
        };
        write_plotfile(&plt, &three_levels(), &value, 0.0);
        let msg = assert_fails(
            &plt,
            &[],
            &[
                "level 1, box 1",
                "field 'temp'",
                why,
                "Level_1/Cell_D_00000",
            ],
        );
        assert!(msg.contains("(4,-16,-16)..=(15,11,7)"), "{msg}");
    }
}

#[test]
fn ghost_cells_are_never_read_as_values() {
    // Ghost cells hold NaN in every written plotfile; this one has wide, uneven ghosts.
    let spec = PlotSpec {
        nghost: [3, 1, 2],
        cell_h_version: 3,
        ..three_levels()
    };
    roundtrip(&spec, 32, &[]);
}

#[test]
fn truncated_and_inconsistent_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let plt = dir.path().join("plt");
    write_plotfile(
        &plt,
        &PlotSpec {
            boxes_per_file: 1,
            ..three_levels()
        },
        &analytic,
        0.0,
    );
    let data = plt.join("Level_2/Cell_D_00001");
    let len = std::fs::metadata(&data).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&data)
        .unwrap()
        .set_len(len - 3)
        .unwrap();
    assert_fails(
        &plt,
        &[],
        &["Level_2/Cell_D_00001", "truncated", "level 2, box 1"],
    );

    std::fs::remove_file(&data).unwrap();
    assert_fails(&plt, &[], &["Level_2/Cell_D_00001", "cannot open"]);

    let header = plt.join("Header");
    let text = std::fs::read_to_string(&header).unwrap();
    std::fs::write(&header, text.replacen("\n2 2 0.25\n", "\n2 3 0.25\n", 1)).unwrap();
    assert_fails(&plt, &[], &["Header", "grid 2 of level 2"]);
}

#[test]
fn unrecognised_inputs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    assert_fails(dir.path(), &[], &["unrecognised input", "without a Header"]);
    std::fs::write(dir.path().join("Header"), "hello\n").unwrap();
    assert_fails(dir.path(), &[], &["unrecognised input", "'hello'"]);
    let h5 = dir.path().join("run.hdf5");
    std::fs::write(&h5, b"\x89HDF").unwrap();
    assert_fails(&h5, &[], &["run.hdf5"]);
}

/// Levels cut into many small boxes of random sizes, listed in a shuffled order and spread over
/// several data files, so that the converter joins boxes that arrive far apart and out of
/// order: every value of every field still comes back where it was, and fewer bricks than
/// boxes are written.
#[test]
fn small_boxes_in_shuffled_files_join_and_keep_every_value() {
    use crate::support::rng::Rng;
    for seed in 1..=4u64 {
        let mut rng = Rng(seed);
        // Cuts of `0..n` into spans of 1 to 5 cells.
        let mut spans = |lo: i64, n: i64| {
            let mut out = Vec::new();
            let mut at = lo;
            while at < lo + n {
                let end = (at + 1 + rng.below(5) as i64).min(lo + n);
                out.push((at, end));
                at = end;
            }
            out
        };
        let mut cut = |lo: [i64; 3], n: [i64; 3]| -> Vec<Bx> {
            let (xs, ys, zs) = (spans(lo[0], n[0]), spans(lo[1], n[1]), spans(lo[2], n[2]));
            let mut boxes = Vec::new();
            for &(z0, z1) in &zs {
                for &(y0, y1) in &ys {
                    for &(x0, x1) in &xs {
                        boxes.push(([x0, y0, z0], [x1 - 1, y1 - 1, z1 - 1]));
                    }
                }
            }
            boxes
        };
        let mut level0 = cut([0; 3], [20, 12, 10]);
        // Level 1 (ratio 2) over part of level 0, in boxes of 1 to 5 cells as well.
        let mut level1 = cut([4, 2, 2], [24, 14, 12]);
        let mut shuffle = |boxes: &mut Vec<Bx>| {
            for i in (1..boxes.len()).rev() {
                let j = rng.below(i as u64 + 1) as usize;
                boxes.swap(i, j);
            }
        };
        shuffle(&mut level0);
        shuffle(&mut level1);
        let spec = PlotSpec {
            fields: vec!["density".into(), "temp".into()],
            domain: ([0; 3], [19, 11, 9]),
            prob_hi: [2.0, 1.2, 1.0],
            ratios: vec![[2, 2, 2]],
            boxes: vec![level0, level1],
            boxes_per_file: 7,
            ..PlotSpec::single(20)
        };
        let dir = tempfile::tempdir().unwrap();
        let plt = dir.path().join("plt00000");
        write_plotfile(&plt, &spec, &analytic, 0.0);
        let target = dir.path().join("out.amrk");
        let s = convert(&plt, &target, &[], 16).unwrap();
        let boxes: u64 = spec.boxes.iter().map(|l| l.len() as u64).sum();
        assert_eq!(s.boxes, boxes);
        assert!(
            s.bricks < boxes / 2,
            "seed {seed}: {} bricks of {boxes} boxes",
            s.bricks
        );
        let checked = check_conversion(&plt, &target, &[]);
        assert_eq!(checked.values, s.cells * 2, "seed {seed}");
        check_geometry(&spec, &target);
    }
}
