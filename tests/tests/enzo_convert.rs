//! Enzo datasets in: the real `DD0010` (shared data, not in the repository) against yt's
//! figures and an independent reading of its HDF5 file, and datasets written by the tests in
//! Enzo's layouts (packed and one file per grid, ghost zones, doubles), cell by cell; broken
//! ones must fail with a message naming the file and the grid, leaving nothing behind.

use std::path::Path;

use crate::support::amrex::check::check_cells;
use crate::support::amrex::{assert_fails, convert, shared_data};
use crate::support::enzo::value;
use crate::support::enzo::writer::{self, Desc, GridDesc};
use amr_format::AmrkFile;
use amr_render::field_stats::FieldPercentiles;
use amr_render::{Scene, SceneOptions};

/// yt 4.4.3 on DD0010 (`docs/enzo.md`): per field, the minimum and maximum over every grid's
/// active cells, `g[("enzo", field)]`.
const YT_RANGES: [(&str, f64, f64); 7] = [
    ("Dark_Matter_Density", 0.0, 2673962.0),
    ("Density", 0.09875256568193436, 256954.46875),
    ("Temperature", 1.0, 16697.09765625),
    ("TotalEnergy", 1.190296643471811e-07, 0.0020184072200208902),
    ("x-velocity", 0.5722823739051819, 1.020929217338562),
    ("y-velocity", 0.11771322041749954, 0.6384459733963013),
    ("z-velocity", 0.15302400290966034, 0.6125621199607849),
];

#[test]
fn dd0010_matches_yt() {
    let Some(dir) = shared_data("dd0010_matches_yt", "enzo/DD0010", "moving7_0010.hierarchy")
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    for (input, brick) in [(dir.join("moving7_0010"), 32), (dir.clone(), 4)] {
        let out = tmp.path().join(format!("b{brick}.amrk"));
        let s = convert(&input, &out, &[], brick).unwrap();
        assert_eq!(s.cells, 30_360);
        let file = AmrkFile::open(std::fs::read(&out).unwrap()).unwrap();
        file.verify().unwrap();
        assert_eq!(file.levels().len(), 8);
        assert!(file.levels()[..7].iter().all(|l| l.ratio_to_next == [2; 3]));
        for ((name, lo, hi), f) in YT_RANGES.iter().zip(file.fields()) {
            assert_eq!(f.name, *name);
            assert_eq!((f.min, f.max), (*lo as f32, *hi as f32), "{name}");
        }
        let sums = independent_sums(&dir.join("moving7_0010.cpu0000"));
        for (f, (name, want)) in sums.iter().enumerate() {
            let got: f64 = (0..file.num_bricks())
                .flat_map(|b| file.brick_values(f, b).unwrap().to_vec())
                .map(f64::from)
                .sum();
            assert_eq!(got, *want, "sum of {name}");
        }
    }
    // The velocity's components are offered as a vector to paint by its length.
    let mapped = amr_render::mapping::open_mapped(&tmp.path().join("b4.amrk")).unwrap();
    assert_eq!(
        amr_render::info::summarize(&mapped).vectors,
        ["|x-velocity,y-velocity,z-velocity|"]
    );
}

/// Any file of the dataset names it: its data file and its boundary files convert to the same
/// bytes as its parameter file.
#[test]
fn dd0010_converts_from_any_of_its_files() {
    let Some(dir) = shared_data(
        "dd0010_converts_from_any_of_its_files",
        "enzo/DD0010",
        "moving7_0010.hierarchy",
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let want = tmp.path().join("params.amrk");
    convert(&dir.join("moving7_0010"), &want, &[], 16).unwrap();
    for part in [
        "moving7_0010.cpu0000",
        "moving7_0010.boundary",
        "moving7_0010.boundary.hdf",
    ] {
        let out = tmp.path().join(format!("{part}.amrk"));
        convert(&dir.join(part), &out, &[], 16).unwrap();
        assert!(
            std::fs::read(&out).unwrap() == std::fs::read(&want).unwrap(),
            "{part} converts to other bytes than the parameter file"
        );
    }
}

/// Rendered without a field or an isovalue, DD0010 shows `Density` (not the first field in name
/// order, `Dark_Matter_Density`) at its median; `Dark_Matter_Density`, zero in over a quarter of
/// the cells, gets its median too, not the middle of its range.
#[test]
fn dd0010_defaults_to_density_at_its_median() {
    let Some(dir) = shared_data(
        "dd0010_defaults_to_density_at_its_median",
        "enzo/DD0010",
        "moving7_0010.hierarchy",
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("dd0010.amrk");
    convert(&dir.join("moving7_0010"), &out, &[], 32).unwrap();
    let scene = Scene::open(&out, &SceneOptions::default()).unwrap();
    assert_eq!(scene.field_name(), "Density");
    let file = AmrkFile::open(std::fs::read(&out).unwrap()).unwrap();
    for (field, name) in [(1, "Density"), (0, "Dark_Matter_Density")] {
        let median = FieldPercentiles::of(&file, field).unwrap().at(0.5);
        // Rounded to five significant digits, as the legend prints it.
        let median: f32 = format!("{median:.4e}").parse().unwrap();
        let options = SceneOptions {
            field: Some(name.into()),
            ..SceneOptions::default()
        };
        let scene = Scene::open(&out, &options).unwrap();
        assert_eq!(scene.default_isovalue(), median, "{name}");
        assert!(median > 1.0 && median < 10.0, "{name}: median {median}");
    }
}

/// Per field (in name order), the sum over every `GridNNNNNNNN` group's dataset, read straight
/// from the HDF5 file.
fn independent_sums(cpu: &Path) -> Vec<(String, f64)> {
    let f = hdf5_metno::File::open(cpu).unwrap();
    let mut sums: Vec<(String, f64)> = YT_RANGES.iter().map(|r| (r.0.to_string(), 0.0)).collect();
    for g in f.member_names().unwrap() {
        let group = f.group(&g).unwrap();
        for (name, sum) in sums.iter_mut() {
            let v: Vec<f32> = group.dataset(name).unwrap().read_raw().unwrap();
            *sum += v.iter().map(|&x| f64::from(x)).sum::<f64>();
        }
    }
    sums
}

fn expected(level: usize, field: usize, c: [i64; 3]) -> f32 {
    value(level, field, c) as f32
}

#[test]
fn written_datasets_convert_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let mut cases = Vec::new();
    let d = Desc::three_levels();
    cases.push(("ghosts_f64_packed", d.clone()));
    cases.push((
        "active_f32_per_grid",
        Desc {
            write_ghosts: false,
            f64: false,
            packed: false,
            ..d.clone()
        },
    ));
    for (name, d) in cases {
        let params = writer::write(&tmp.path().join(name), "DD0003", &d);
        for brick in [32, 3] {
            let out = tmp.path().join(format!("{name}{brick}.amrk"));
            let s = convert(&params, &out, &[], brick).unwrap();
            assert_eq!(
                s.cells,
                8 * 6 * 4 + 6 * 8 * 6 + 6 * 4 * 6 + 8 * 10 * 8,
                "{name}"
            );
            assert_eq!(check_cells(&out, &expected), s.cells * 3, "{name}");
            let file = AmrkFile::open(std::fs::read(&out).unwrap()).unwrap();
            assert_eq!(
                file.levels()[2].cell_size,
                [2.0 / 32.0, 1.5 / 24.0, 1.0 / 16.0]
            );
            assert_eq!(file.levels()[0].origin, [-1.0, 0.0, 2.0]);
        }
    }
    let params = writer::write(&tmp.path().join("sel"), "DD0003", &d);
    let out = tmp.path().join("sel.amrk");
    convert(
        &params.with_extension("hierarchy"),
        &out,
        &["x-velocity"],
        8,
    )
    .unwrap();
    check_cells(&out, &|l, _, c| expected(l, 2, c));
}

#[test]
fn misaligned_and_badly_nested_grids_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let shifted = Desc {
        shift: Some((3, 0.5)),
        ..Desc::three_levels()
    };
    let p = writer::write(&tmp.path().join("a"), "DD0003", &shifted);
    assert_fails(
        &p,
        &[],
        &[
            "DD0003.hierarchy",
            "grid 3",
            "cells off level 1's cell grid",
        ],
    );

    let mut outside = Desc::three_levels();
    outside.roots[0].children[1].children = vec![GridDesc {
        lo: [18, 0, 4],
        hi: [24, 4, 8],
        children: vec![],
    }];
    let p = writer::write(&tmp.path().join("b"), "DD0003", &outside);
    assert_fails(
        &p,
        &[],
        &["grid 4 (level 2", "not properly nested", "parent grid 3"],
    );

    let p = writer::write(
        &tmp.path().join("c"),
        "DD0003",
        &Desc {
            omit_refine_by: true,
            ..Desc::three_levels()
        },
    );
    assert_fails(&p, &[], &["DD0003", "no 'RefineBy' parameter"]);

    let p = writer::write(
        &tmp.path().join("d"),
        "DD0003",
        &Desc {
            rank: 2,
            ..Desc::three_levels()
        },
    );
    assert_fails(&p, &[], &["not supported", "2D dataset"]);

    let unwritten = Desc {
        unwritten: Some(4),
        ..Desc::three_levels()
    };
    let p = writer::write(&tmp.path().join("f"), "DD0003", &unwritten);
    assert_fails(
        &p,
        &[],
        &["DD0003.cpu0000", "grid 4's 'Density' stores 0 bytes"],
    );

    let p = writer::write(&tmp.path().join("e"), "DD0003", &Desc::three_levels());
    assert_fails(
        &p,
        &["Pressure"],
        &[
            "no field named 'Pressure'",
            "Density, Temperature, x-velocity",
        ],
    );
    assert_fails(
        &p,
        &["density"],
        &["no field named 'density' (did you mean 'Density'?)"],
    );
    std::fs::remove_file(tmp.path().join("e/DD0003.cpu0000")).unwrap();
    assert_fails(&p, &[], &["DD0003.cpu0000", "cannot open as an HDF5 file"]);
}

/// An output named like one of the dataset's grid data files (packed `.cpuNNNN` or one file
/// per grid) is refused before anything is read, and the file is left as it was.
#[test]
fn an_output_that_is_a_grid_file_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    for packed in [true, false] {
        let d = Desc {
            packed,
            ..Desc::three_levels()
        };
        let params = writer::write(&tmp.path().join(format!("p{packed}")), "DD0003", &d);
        let dir = params.parent().unwrap();
        let grid_files: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p != &params && p.extension().is_none_or(|e| e != "hierarchy"))
            .collect();
        assert!(!grid_files.is_empty(), "the writer wrote no grid file");
        for grid in grid_files {
            let before = std::fs::read(&grid).unwrap();
            let err = convert(&params, &grid, &[], 8).expect_err("a grid file is an input");
            let msg = err.to_string();
            assert!(
                msg.contains("refusing") && msg.contains(&*grid.to_string_lossy()),
                "{msg}"
            );
            assert_eq!(std::fs::read(&grid).unwrap(), before, "{}", grid.display());
        }
    }
}
