//! Small analytic `.amrk` files written with the converter's own synthetic writer.

use std::path::{Path, PathBuf};

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_synth::{build_hierarchy, write_fields, write_synth, AnalyticField, Case, SynthParams};

/// `case` on two levels (ratio 2, base 16, bricks of 8) in the unit cube, written to
/// `dir/CASE.amrk`.
pub fn two_level(dir: &Path, case: Case) -> PathBuf {
    let path = dir.join(format!("{case}.amrk"));
    let params = SynthParams::unit_cube(2, 2, 16, 8);
    write_synth(&path, case, &params, WriterOptions::default(), &NoProgress).unwrap();
    path
}

/// A file of two fields on `params`' hierarchy refined around the sphere: `sphere` (the
/// sphere case's signed distance) and `ramp`, written to `dir/two.amrk`.
pub fn sphere_and_ramp(
    dir: &Path,
    params: &SynthParams,
    ramp: &(dyn Fn([f64; 3]) -> f64 + Sync),
) -> PathBuf {
    let path = dir.join("two.amrk");
    let mut spec = build_hierarchy(&Case::Sphere, "sphere", params).unwrap();
    spec.fields = vec!["sphere".into(), "ramp".into()];
    let sphere = |p: [f64; 3]| Case::Sphere.value(p);
    write_fields(&path, spec, &[&sphere, ramp], WriterOptions::default()).unwrap();
    path
}
