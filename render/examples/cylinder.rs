//! A synthetic stand-in for an embedded-boundary run: a cylinder across a channel (the unit cube,
//! flow along x, the cylinder's axis along y), written as a three-level `.amrk` file refined
//! around the cylinder, with two fields: `distance` (signed distance to the cylinder's wall,
//! negative inside the solid, like an EB level set) and `speed` (potential flow past the
//! cylinder, zero inside it). `docs/pictures.md` renders it.
//!
//! ```text
//! cargo run --release -p amr-render --example cylinder -- /tmp/cylinder.amrk
//! ```

use amr_format::WriterOptions;
use amr_synth::{build_hierarchy, write_fields, AnalyticField, SynthParams};

/// The cylinder's axis crosses the x-z plane here.
const AXIS: [f64; 2] = [0.3, 0.5];
/// Its radius.
const RADIUS: f64 = 0.12;
/// Free-stream speed.
const U: f64 = 1.0;

/// The signed distance to the cylinder's wall.
struct Cylinder;

impl AnalyticField for Cylinder {
    fn value(&self, p: [f64; 3]) -> f64 {
        let (dx, dz) = (p[0] - AXIS[0], p[2] - AXIS[1]);
        (dx * dx + dz * dz).sqrt() - RADIUS
    }
    fn gradient(&self, p: [f64; 3]) -> [f64; 3] {
        let (dx, dz) = (p[0] - AXIS[0], p[2] - AXIS[1]);
        let r = (dx * dx + dz * dz).sqrt().max(1e-12);
        [dx / r, 0.0, dz / r]
    }
    fn default_iso(&self) -> f64 {
        0.0
    }
    fn distance_to_surface(&self, p: [f64; 3], iso: f64) -> Option<f64> {
        Some((self.value(p) - iso).abs())
    }
    fn distance_lower_bound(&self, p: [f64; 3], iso: f64) -> f64 {
        (self.value(p) - iso).abs()
    }
}

/// Speed of the potential flow past the cylinder, `|U (1 - R^2 / z^2)|` with `z = dx + i dz`.
fn speed(p: [f64; 3]) -> f64 {
    let (dx, dz) = (p[0] - AXIS[0], p[2] - AXIS[1]);
    let r2 = dx * dx + dz * dz;
    if r2 < RADIUS * RADIUS {
        return 0.0;
    }
    let k = RADIUS * RADIUS / (r2 * r2);
    let u = U * (1.0 - k * (dx * dx - dz * dz));
    let w = -U * k * 2.0 * dx * dz;
    (u * u + w * w).sqrt()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: cylinder OUT.amrk")?;
    let mut spec = build_hierarchy(&Cylinder, "distance", &SynthParams::unit_cube(3, 2, 16, 8))?;
    spec.fields = vec!["distance".into(), "speed".into()];
    let distance = |p: [f64; 3]| Cylinder.value(p);
    let summary = write_fields(
        path.as_ref(),
        spec,
        &[&distance, &speed],
        WriterOptions::default(),
    )?;
    println!("wrote {path}: {summary:?}");
    Ok(())
}
