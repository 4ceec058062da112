//! Chombo checkpoints, in both layouts `AMRLevel::writeCheckpointLevel` implementations
//! produce (see `docs/chombo.md`): one `data` holding every component (GRChombo's
//! `GRAMRLevel`, Chombo's example `AMRLevel`s), and one `LevelData` per variable with vector
//! variables named `xNAME`, `yNAME`, `zNAME` at the root. Ghost layers are stripped; a
//! single-level checkpoint is a valid input.

use crate::support::chombo::check::roundtrip;
use crate::support::chombo::{writer, Desc};
use amr_format::Compression;

#[test]
fn one_data_for_every_component() {
    let mut d = Desc::three_levels(true);
    d.checkpoint_marker = true;
    roundtrip(&d, &[], 8, Compression::None);
}

#[test]
fn one_dataset_per_variable_with_a_vector() {
    roundtrip(&Desc::per_variable_checkpoint(), &[], 8, Compression::None);
    roundtrip(
        &Desc::per_variable_checkpoint(),
        &["zmom", "density"],
        5,
        Compression::None,
    );
}

#[test]
fn one_dataset_per_variable_single_level_float32() {
    let mut d = Desc::per_variable_checkpoint();
    d.f64 = false;
    d.levels.truncate(1);
    d.levels[0].ref_ratio = 1;
    roundtrip(&d, &[], 8, Compression::None);
}

#[test]
fn unlisted_vector_components_are_numbered() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("chk.hdf5");
    let mut d = Desc::per_variable_checkpoint();
    d.omit_root = vec!["num_components".into()];
    writer::write(&input, &d).unwrap();
    let pf = amr_convert::chombo::Plotfile::open(&input).unwrap();
    assert_eq!(pf.fields, ["density", "mom_0", "mom_1", "mom_2"]);
    assert_eq!(pf.vars, ["density", "mom"]);
}
