//! Chombo plotfiles written through HDF5 by the test itself, converted, and read back cell by
//! cell: every value equals the source rounded to f32, every valid cell is covered once.

use crate::support::chombo::check::{check, roundtrip};
use crate::support::chombo::{writer, Desc};
use amr_format::Compression;

#[test]
fn float64_three_levels_every_value_is_the_source_rounded_to_f32() {
    roundtrip(&Desc::three_levels(true), &[], 8, Compression::None);
}

#[test]
fn float32_three_levels_every_value_survives() {
    roundtrip(&Desc::three_levels(false), &[], 5, Compression::None);
}

#[test]
fn selected_fields_keep_their_order() {
    roundtrip(
        &Desc::three_levels(true),
        &["chi", "density"],
        16,
        Compression::None,
    );
}

/// Level 0's two boxes of `8 x 12 x 8` cells share a face: with bricks of 16 they are joined
/// into one, and every value is still where it was.
#[test]
fn boxes_sharing_a_face_join_into_one_brick() {
    let d = Desc::three_levels(false);
    let stats = roundtrip(&d, &[], 16, Compression::None);
    assert_eq!(stats.boxes, 6);
    // Level 0 joined into one brick, level 1's two boxes apart, level 2's boxes of up to 24
    // cells per axis split into 2 x 1 x 2 and 1 x 1 x 1 bricks.
    assert_eq!(stats.bricks, 1 + 2 + 4 + 1);
}

#[test]
fn compressed_output_holds_the_same_values() {
    roundtrip(
        &Desc::three_levels(false),
        &["phi"],
        7,
        Compression::Zstd { level: 3 },
    );
}

#[test]
fn one_cell_bricks_and_no_ghosts() {
    let mut d = Desc::three_levels(true);
    d.ghost = [0, 0, 0];
    d.levels.truncate(2);
    d.levels[1].ref_ratio = 1;
    d.levels[1].boxes.truncate(1);
    roundtrip(&d, &["phi"], 1, Compression::None);
}

#[test]
fn amr_convert_detects_a_chombo_file_by_its_extension() {
    let dir = tempfile::tempdir().unwrap();
    let d = Desc::three_levels(true);
    for name in ["plt.h5", "plt.3d.hdf5"] {
        let input = dir.path().join(name);
        let output = dir.path().join(format!("{name}.amrk"));
        writer::write(&input, &d).unwrap();
        let s = crate::support::amrex::run_convert(&input, &output, &[], 8, Compression::None)
            .unwrap_or_else(|e| panic!("{e:#}"));
        assert!(s.cells > 0 && s.bricks > 0);
        check(&output, &d, &["density", "phi", "chi"], 8);
    }
}
