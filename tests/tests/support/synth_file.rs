//! Small analytic `.amrk` files written with the converter's own synthetic writer.

use std::path::{Path, PathBuf};

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_synth::{write_synth, Case, SynthParams};

/// `case` on two levels (ratio 2, base 16, bricks of 8) in the unit cube, written to
/// `dir/CASE.amrk`.
pub fn two_level(dir: &Path, case: Case) -> PathBuf {
    let path = dir.join(format!("{case}.amrk"));
    let params = SynthParams::unit_cube(2, 2, 16, 8);
    write_synth(&path, case, &params, WriterOptions::default(), &NoProgress).unwrap();
    path
}
