//! A synthetic sphere file whose closed surface crosses level boundaries: each level refines
//! near the surface, but only on one side of a plane per level (x >= 0.5 for level 1, also
//! y >= 0.5 for level 2, also z >= 0.5 for level 3), so two or three levels meet along lines and
//! at points on the surface.

use std::path::Path;

use amr_format::progress::NoProgress;
use amr_format::WriterOptions;
use amr_synth::{build_hierarchy_by, near_surface, write_spec, AnalyticField, Case, SynthParams};

/// Writes the sphere distance field (`Case::Sphere`) of `levels` levels, refinement ratio
/// `ratio`, `base` cells per axis on level 0 and bricks of 8^3 cells over the unit cube to
/// `path`, refined as the module says.
pub fn write_half_refined_sphere(path: &Path, levels: u32, ratio: u32, base: u32) {
    let params = SynthParams {
        levels,
        ratio,
        base,
        brick: 8,
        origin: [0.0; 3],
        size: 1.0,
    };
    let field = Case::Sphere;
    let iso = field.default_iso();
    let spec = build_hierarchy_by(&params, vec!["sphere".into()], |b| {
        let half = (0..b.level as usize).all(|a| b.lo[a] >= 0.5);
        half && near_surface(&field, iso, b)
    })
    .unwrap();
    write_spec(path, spec, &field, WriterOptions::default(), &NoProgress).unwrap();
}
