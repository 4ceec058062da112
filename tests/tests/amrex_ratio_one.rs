//! A refinement ratio of 1 on an axis (quasi-2D runs refine `2 2 1`) is refused with a message
//! that says why and where to read more (`docs/format.md`), leaving nothing behind.

use crate::support::amrex::assert_fails;
use crate::support::amrex::writer::{write_plotfile, PlotSpec};

#[test]
fn ratio_one_on_an_axis_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let plt = dir.path().join("quasi2d");
    let spec = PlotSpec {
        domain: ([0; 3], [7, 7, 3]),
        prob_hi: [1.0, 1.0, 0.5],
        ratios: vec![[2, 2, 1]],
        boxes: vec![vec![([0; 3], [7, 7, 3])], vec![([4, 4, 0], [11, 11, 3])]],
        ..PlotSpec::single(8)
    };
    write_plotfile(
        &plt,
        &spec,
        &|_, c, p| (p[0] + p[1] + p[2]) as f64 + c as f64,
        0.0,
    );
    assert_fails(
        &plt,
        &[],
        &[
            "Header",
            "refinement ratio 1 on axis 2 from level 0 to 1",
            "at least 2 on every axis",
            "docs/format.md",
        ],
    );
}
