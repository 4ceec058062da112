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
