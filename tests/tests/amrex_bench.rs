//! Generates large plotfiles for the conversion benchmarks in `docs/benchmarks-amrex.md`.
//! Ignored by default; run with
//! `AMR_BENCH_OUT=DIR AMR_BENCH_MB=1000 cargo test --release -p amr-tests --test tests amrex_bench -- --ignored`
//! (`AMR_BENCH_EDGE=8` for boxes of `8^3` cells instead of `64^3`, the case where the converter
//! joins boxes into bricks).

use std::path::PathBuf;

use crate::support::amrex::writer::{write_plotfile, PlotSpec};

/// Box edge in cells by default; a box holds 4 float64 fields, 8 MiB.
const EDGE: i64 = 64;

#[test]
#[ignore = "writes a plotfile of AMR_BENCH_MB megabytes to AMR_BENCH_OUT"]
fn generate_bench_plotfile() {
    let out = PathBuf::from(std::env::var("AMR_BENCH_OUT").expect("set AMR_BENCH_OUT"));
    let mb: u64 = std::env::var("AMR_BENCH_MB")
        .expect("set AMR_BENCH_MB")
        .parse()
        .unwrap();
    let edge: i64 = std::env::var("AMR_BENCH_EDGE").map_or(EDGE, |e| e.parse().unwrap());
    let box_bytes = (edge * edge * edge * 4 * 8) as u64;
    let n = (mb * 1_000_000 / box_bytes).max(1) as i64;
    // Boxes along x, then y: a slab of n boxes, each file holding up to 16 of them.
    let (nx, ny) = if n >= 8 { (8, (n + 7) / 8) } else { (n, 1) };
    let mut boxes = Vec::new();
    for i in 0..n {
        let lo = [(i % nx) * edge, (i / nx) * edge, 0];
        boxes.push((lo, [lo[0] + edge - 1, lo[1] + edge - 1, edge - 1]));
    }
    let spec = PlotSpec {
        fields: vec![
            "density".into(),
            "temp".into(),
            "Y(H2)".into(),
            "x_velocity".into(),
        ],
        domain: ([0; 3], [nx * edge - 1, ny * edge - 1, edge - 1]),
        prob_hi: [nx as f64, ny as f64, 1.0],
        boxes: vec![boxes],
        boxes_per_file: 16,
        ..PlotSpec::single(edge)
    };
    let value =
        |_l: usize, c: usize, p: [i64; 3]| (p[0] + 3 * p[1] - 7 * p[2]) as f64 * 1e-3 + c as f64;
    write_plotfile(&out, &spec, &value, 0.0);
    eprintln!(
        "wrote {n} boxes of {edge}^3 x 4 float64 fields to {}",
        out.display()
    );
}
