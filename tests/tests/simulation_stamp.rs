//! The simulation time and step of real dumps reach the `.amrk` footer: the values are those
//! the codes wrote (DD0010's parameter file says `InitialTime = 0.81751317119117` and
//! `InitialCycleNumber = 10`; the PeleLM plotfile's Header gives time 1.3924182125972017e-08 and
//! level steps starting at 20).

use amr_format::AmrkFile;

use crate::support::amrex::{convert, shared_data};

fn stamp_of(input: &std::path::Path) -> (Option<f64>, Option<i64>) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.amrk");
    convert(input, &out, &[], 16).unwrap();
    let file = AmrkFile::open(std::fs::read(&out).unwrap()).unwrap();
    (file.simulation_time(), file.simulation_step())
}

#[test]
fn enzo_and_amrex_dumps_record_their_time_and_step() {
    if let Some(dir) = shared_data("simulation_stamp", "enzo/DD0010", "moving7_0010.hierarchy") {
        assert_eq!(
            stamp_of(&dir.join("moving7_0010")),
            (Some(0.81751317119117), Some(10))
        );
    }
    if let Some(dir) = shared_data("simulation_stamp", "amrex/example_plt_3d", "Header") {
        assert_eq!(stamp_of(&dir), (Some(1.3924182125972017e-08), Some(20)));
    }
}
