//! Bad Chombo files: each gives an error that says what is wrong and where, never a panic,
//! and never an output file (nor a temporary left beside it).

use std::path::Path;

use crate::support::chombo::{writer, Desc};
use amr_convert::chombo::{self, ConvertOptions};
use amr_format::progress::NoProgress;
use amr_format::Compression;

/// Writes `d`, converts it, and returns the error's full chain; checks nothing was written.
fn fails(d: &Desc) -> String {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("plt.3d.hdf5");
    writer::write(&input, d).unwrap();
    fails_at(dir.path(), &input, &[])
}

fn fails_at(dir: &Path, input: &Path, fields: &[&str]) -> String {
    let output = dir.join("out.amrk");
    let opts = ConvertOptions {
        fields: fields.iter().map(|s| s.to_string()).collect(),
        brick: 8,
        compression: Compression::None,
        join: true,
        ..ConvertOptions::default()
    };
    let err =
        chombo::convert(input, &output, &opts, &NoProgress).expect_err("conversion should fail");
    let mut msg = err.to_string();
    let mut src = std::error::Error::source(&err);
    while let Some(c) = src {
        msg.push_str(": ");
        msg.push_str(&c.to_string());
        src = c.source();
    }
    assert!(!output.exists(), "an output was written despite: {msg}");
    let left: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 1, "files left behind: {left:?} ({msg})");
    msg
}

fn assert_has(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} does not mention {p:?}");
    }
}

#[test]
fn a_file_of_boxes_only_says_it_has_no_data() {
    let mut d = Desc::three_levels(true);
    d.boxes_only = true;
    assert_has(
        &fails(&d),
        &[
            "plt.3d.hdf5",
            "no data to convert",
            "no num_levels",
            "meshRefineTest",
        ],
    );
}

#[test]
fn a_2d_file_is_refused_clearly() {
    let mut d = Desc::three_levels(true);
    d.space_dim = 2;
    assert_has(&fails(&d), &["not supported", "2D", "SpaceDim"]);
}

#[test]
fn missing_root_attribute() {
    let mut d = Desc::three_levels(true);
    d.omit_root = vec!["num_levels".into()];
    assert_has(
        &fails(&d),
        &["plt.3d.hdf5", "root: missing attribute 'num_levels'"],
    );
}

#[test]
fn missing_component_name() {
    let mut d = Desc::three_levels(false);
    d.omit_root = vec!["component_2".into()];
    assert_has(&fails(&d), &["missing attribute 'component_2'"]);
}

#[test]
fn missing_level_attributes_name_the_level() {
    for (l, attr, want) in [
        (1, "dx", "level_1: missing attribute 'dx'"),
        (0, "ref_ratio", "level_0: missing attribute 'ref_ratio'"),
        (2, "prob_domain", "level_2: missing attribute 'prob_domain'"),
        (
            1,
            "outputGhost",
            "level_1/data_attributes: missing attribute 'outputGhost'",
        ),
        (2, "boxes", "level_2: missing dataset 'boxes'"),
        (
            0,
            "data:offsets=0",
            "level_0: missing dataset 'data:offsets=0'",
        ),
        (
            1,
            "data:datatype=0",
            "level_1: missing dataset 'data:datatype=0'",
        ),
    ] {
        let mut d = Desc::three_levels(true);
        d.omit_level = vec![(l, attr.to_string())];
        assert_has(&fails(&d), &[want]);
    }
}

#[test]
fn offsets_beyond_the_data() {
    let mut d = Desc::three_levels(true);
    d.truncate_data = Some((2, 10));
    assert_has(
        &fails(&d),
        &["level_2", "beyond the end of data:datatype=0"],
    );
}

#[test]
fn a_huge_box_count_is_refused_before_allocating() {
    let mut d = Desc::three_levels(true);
    d.huge_boxes = Some(1);
    assert_has(&fails(&d), &["level_1", "claims 8589934592 boxes"]);
}

#[test]
fn data_declared_but_never_written() {
    let mut d = Desc::three_levels(true);
    d.unwritten_data = Some(2);
    assert_has(
        &fails(&d),
        &["level_2", "data:datatype=0 stores 0 bytes", "never written"],
    );
}

#[test]
fn a_box_outside_the_domain() {
    let mut d = Desc::three_levels(false);
    d.levels[1].boxes[1] = [14, 6, 2, 21, 13, 16];
    assert_has(
        &fails(&d),
        &["level_1", "box 1", "lies outside the problem domain"],
    );
}

#[test]
fn levels_that_do_not_refine_each_other() {
    let mut d = Desc::three_levels(true);
    d.levels[1].domain = [0, 0, 0, 31, 23, 14];
    d.levels[1].boxes[0] = [4, 4, 2, 13, 11, 9];
    assert_has(
        &fails(&d),
        &[
            "level_1",
            "is not level_0 prob_domain",
            "refined by ref_ratio",
        ],
    );
    let mut d = Desc::three_levels(true);
    d.levels[2].dx = 0.1;
    assert_has(&fails(&d), &["level_2", "dx"]);
}

#[test]
fn non_finite_and_out_of_range_values_name_level_box_and_field() {
    for (value, why, f64) in [
        (f64::NAN, "NaN", false),
        (f64::INFINITY, "infinite", false),
        (f64::NEG_INFINITY, "infinite", true),
        (1.0e39, "outside the f32 range", true),
    ] {
        let mut d = Desc::three_levels(f64);
        d.poison = Some((1, 1, 2, [15, 7, 3], value));
        let msg = fails(&d);
        assert_has(
            &msg,
            &["level 1", "box 1", "field 'chi'", "[15, 7, 3]", why],
        );
    }
}

#[test]
fn a_nan_in_a_ghost_cell_is_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let mut d = Desc::three_levels(true);
    // Cell (-1, 0, 0) of box 0 on level 0 lies in its ghost layers (2 wide in x): it is
    // stored in the file but never read into the output.
    d.poison = Some((0, 0, 0, [-1, 0, 0], f64::NAN));
    let input = dir.path().join("plt.hdf5");
    writer::write(&input, &d).unwrap();
    let opts = ConvertOptions {
        fields: vec![],
        brick: 8,
        compression: Compression::None,
        join: true,
        ..ConvertOptions::default()
    };
    chombo::convert(&input, &dir.path().join("out.amrk"), &opts, &NoProgress).unwrap();
}

#[test]
fn an_unknown_field_lists_the_available_ones() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("plt.hdf5");
    writer::write(&input, &Desc::three_levels(true)).unwrap();
    assert_has(
        &fails_at(dir.path(), &input, &["rho"]),
        &["no field named 'rho'", "density, phi, chi"],
    );
}

#[test]
fn a_file_that_is_not_hdf5() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("plt.h5");
    std::fs::write(&input, b"this is not an HDF5 file").unwrap();
    assert_has(
        &fails_at(dir.path(), &input, &[]),
        &["plt.h5", "cannot open as an HDF5 file"],
    );
}

#[test]
fn a_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("nothing.hdf5");
    let opts = ConvertOptions {
        fields: vec![],
        brick: 8,
        compression: Compression::None,
        join: true,
        ..ConvertOptions::default()
    };
    let err =
        chombo::convert(&input, &dir.path().join("out.amrk"), &opts, &NoProgress).unwrap_err();
    let msg = format!("{err}: {}", std::error::Error::source(&err).unwrap());
    assert_has(&msg, &["cannot open", "nothing.hdf5", "No such file"]);
}

#[test]
fn run_convert_reports_the_chombo_error_with_context() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("chk.3d.hdf5");
    let mut d = Desc::per_variable_checkpoint();
    d.omit_level = vec![(1, "mom:offsets=0".into())];
    writer::write(&input, &d).unwrap();
    let out = dir.path().join("out.amrk");
    let err =
        crate::support::amrex::run_convert(&input, &out, &[], 8, Compression::None).unwrap_err();
    assert_has(
        &format!("{err:#}"),
        &[
            "converting HDF5 file (Chombo layout)",
            "chk.3d.hdf5",
            "level_1: missing dataset 'mom:offsets=0'",
        ],
    );
    assert!(!out.exists());
}
