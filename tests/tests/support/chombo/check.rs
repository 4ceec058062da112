//! Converting a written fixture and reading it back cell by cell: every value equals the
//! source rounded to f32, every valid cell is covered once.

use std::path::Path;

use amr_convert::chombo::{self, ConvertOptions, ConvertStats};
use amr_format::progress::NoProgress;
use amr_format::{AmrkFile, Compression, IBox};

use super::{value, writer, Desc};
use crate::support::amrex::check::check_cells;

/// Converts `input` with the Chombo reader, panicking with the error chain on failure.
pub fn convert(
    input: &Path,
    output: &Path,
    fields: &[&str],
    brick: u32,
    compression: Compression,
) -> ConvertStats {
    let opts = ConvertOptions {
        fields: fields.iter().map(|s| s.to_string()).collect(),
        brick,
        compression,
        join: true,
        ..ConvertOptions::default()
    };
    match chombo::convert(input, output, &opts, &NoProgress) {
        Ok(s) => s,
        Err(e) => panic!("conversion failed: {}", chain(&e)),
    }
}

/// An error and its sources, joined.
pub fn chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut src = e.source();
    while let Some(c) = src {
        s.push_str(": ");
        s.push_str(&c.to_string());
        src = c.source();
    }
    s
}

/// A box in Chombo's inclusive notation as a half-open box.
pub fn inclusive(b: [i32; 6]) -> IBox {
    IBox::new(
        [b[0], b[1], b[2]].map(i64::from),
        [b[3], b[4], b[5]].map(|h| i64::from(h) + 1),
    )
}

/// Checks `out` against `d`: geometry, coverage, and every value of every field in `fields`.
pub fn check(out: &Path, d: &Desc, fields: &[&str], brick: i64) {
    let file = AmrkFile::open(std::fs::read(out).unwrap()).unwrap();
    file.verify().unwrap();
    assert_eq!(file.levels().len(), d.levels.len());
    for (l, (got, want)) in file.levels().iter().zip(&d.levels).enumerate() {
        assert_eq!(got.cell_size, [want.dx; 3], "level {l} cell size");
        assert_eq!(got.origin, [0.0; 3], "level {l} origin");
        assert_eq!(got.domain, inclusive(want.domain), "level {l} domain");
    }
    let names: Vec<&str> = file.fields().iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, fields);
    // Coverage: every brick is no larger than `brick` and made of whole cells of the level's
    // boxes (one box's, part of one, or several joined); cells add up.
    let mut cells = vec![0u64; d.levels.len()];
    for i in 0..file.num_bricks() {
        let b = file.brick(i);
        let l = b.level as usize;
        assert!(
            b.cells.extent().iter().all(|&e| e <= brick),
            "brick {i} {:?} exceeds {brick}",
            b.cells
        );
        let in_boxes: u64 = d.levels[l]
            .boxes
            .iter()
            .map(|&sb| inclusive(sb).intersect(&b.cells).num_cells().unwrap())
            .sum();
        assert_eq!(
            in_boxes,
            b.cells.num_cells().unwrap(),
            "brick {i} {:?} is not made of level-{l} boxes' cells",
            b.cells
        );
        cells[l] += b.cells.num_cells().unwrap();
    }
    for (l, lev) in d.levels.iter().enumerate() {
        let want: u64 = lev
            .boxes
            .iter()
            .map(|&b| inclusive(b).num_cells().unwrap())
            .sum();
        assert_eq!(cells[l], want, "level {l} cell count");
    }
    let comp: Vec<usize> = fields
        .iter()
        .map(|name| d.comps.iter().position(|c| c == name).unwrap())
        .collect();
    check_cells(out, &|l, f, p| value(l, comp[f], p) as f32);
}

/// Writes `d`, converts `fields` of it (all when empty), and checks the output.
pub fn roundtrip(d: &Desc, fields: &[&str], brick: u32, compression: Compression) -> ConvertStats {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("plt.3d.hdf5");
    let output = dir.path().join("out.amrk");
    writer::write(&input, d).unwrap();
    let stats = convert(&input, &output, fields, brick, compression);
    let all: Vec<&str> = d.comps.iter().map(String::as_str).collect();
    let fields = if fields.is_empty() { &all[..] } else { fields };
    check(&output, d, fields, i64::from(brick));
    let cells: u64 = d
        .levels
        .iter()
        .flat_map(|l| &l.boxes)
        .map(|&b| inclusive(b).num_cells().unwrap())
        .sum();
    assert_eq!(stats.cells, cells);
    assert!(stats.bytes_read > 0);
    stats
}
