//! Compares a converted `.amrk` file cell by cell with an independent reading of its plotfile.

use std::path::Path;

use amr_format::AmrkFile;

use super::source::{read_plotfile, SrcPlotfile};

/// What [`check_conversion`] compared.
#[derive(Debug, Default)]
pub struct Checked {
    /// Cell values compared (cells times fields).
    pub values: u64,
    /// Per-box minima and maxima compared with `Cell_H`.
    pub min_max: u64,
}

/// Checks that `amrk` holds exactly the plotfile's valid cells for `fields` (all when empty):
/// every stored value equals the source value rounded to f32, the bricks of each level cover
/// exactly its boxes, and each box's stored min/max equal `Cell_H`'s rounded to f32.
pub fn check_conversion(plotfile: &Path, amrk: &Path, fields: &[&str]) -> Checked {
    let src = read_plotfile(plotfile);
    check_against(&src, amrk, fields)
}

/// [`check_conversion`] against an already-read plotfile.
pub fn check_against(src: &SrcPlotfile, amrk: &Path, fields: &[&str]) -> Checked {
    let file = AmrkFile::open(std::fs::read(amrk).unwrap()).unwrap();
    file.verify().unwrap();
    let names: Vec<String> = if fields.is_empty() {
        src.fields.clone()
    } else {
        fields.iter().map(|s| s.to_string()).collect()
    };
    let stored: Vec<String> = file.fields().iter().map(|f| f.name.clone()).collect();
    assert_eq!(stored, names, "field names and order");
    let comps: Vec<usize> = names
        .iter()
        .map(|n| src.fields.iter().position(|f| f == n).unwrap())
        .collect();
    assert_eq!(file.levels().len(), src.levels.len(), "level count");

    let mut checked = Checked::default();
    // Per level and box: cells covered by bricks, and min/max of the stored values per field.
    let mut covered: Vec<Vec<u64>> = src.levels.iter().map(|l| vec![0; l.len()]).collect();
    let mut mins: Vec<Vec<Vec<f32>>> = src
        .levels
        .iter()
        .map(|l| vec![vec![f32::INFINITY; comps.len()]; l.len()])
        .collect();
    let mut maxs: Vec<Vec<Vec<f32>>> = src
        .levels
        .iter()
        .map(|l| vec![vec![f32::NEG_INFINITY; comps.len()]; l.len()])
        .collect();
    for b in 0..file.num_bricks() {
        let info = file.brick(b);
        let level = info.level as usize;
        let (lo, hi) = (info.cells.lo, info.cells.hi);
        // A brick holds one source box's cells, part of them, or (joined) several boxes whole.
        let owners: Vec<usize> = (0..src.levels[level].len())
            .filter(|&i| {
                let s = &src.levels[level][i];
                (0..3).all(|a| s.lo[a] < hi[a] && lo[a] <= s.hi[a])
            })
            .collect();
        for (f, &c) in comps.iter().enumerate() {
            let vals = file.brick_values(f, b).unwrap();
            let mut i = 0;
            for z in lo[2]..hi[2] {
                for y in lo[1]..hi[1] {
                    for x in lo[0]..hi[0] {
                        let owner = *owners
                            .iter()
                            .find(|&&o| src.levels[level][o].contains([x, y, z]))
                            .unwrap_or_else(|| {
                                panic!("brick {b}'s cell ({x},{y},{z}) of level {level} lies in no source box")
                            });
                        let sb = &src.levels[level][owner];
                        if f == 0 {
                            covered[level][owner] += 1;
                        }
                        let want = sb.at(c, [x, y, z]) as f32;
                        let got = vals[i];
                        assert_eq!(
                            got.to_bits(),
                            want.to_bits(),
                            "level {level} cell ({x},{y},{z}) field {}: stored {got:e}, source rounds to {want:e}",
                            names[f]
                        );
                        mins[level][owner][f] = mins[level][owner][f].min(got);
                        maxs[level][owner][f] = maxs[level][owner][f].max(got);
                        i += 1;
                    }
                }
            }
            checked.values += i as u64;
        }
    }
    for (l, boxes) in src.levels.iter().enumerate() {
        for (i, sb) in boxes.iter().enumerate() {
            let n: i64 = (0..3).map(|a| sb.hi[a] - sb.lo[a] + 1).product();
            assert_eq!(
                covered[l][i], n as u64,
                "bricks cover level {l} box {i} exactly"
            );
            let (Some(min), Some(max)) = (&sb.min, &sb.max) else {
                continue;
            };
            for (f, &c) in comps.iter().enumerate() {
                assert_eq!(
                    mins[l][i][f], min[c] as f32,
                    "Cell_H minimum of level {l} box {i} field {}",
                    names[f]
                );
                assert_eq!(
                    maxs[l][i][f], max[c] as f32,
                    "Cell_H maximum of level {l} box {i} field {}",
                    names[f]
                );
                checked.min_max += 1;
            }
        }
    }
    checked
}

/// Compares every cell of every brick of `amrk` with `expected(level, field, cell)`; returns
/// the number of values compared.
pub fn check_cells(amrk: &Path, expected: &dyn Fn(usize, usize, [i64; 3]) -> f32) -> u64 {
    let file = AmrkFile::open(std::fs::read(amrk).unwrap()).unwrap();
    file.verify().unwrap();
    let mut n = 0;
    for f in 0..file.fields().len() {
        for b in 0..file.num_bricks() {
            let info = file.brick(b);
            let vals = file.brick_values(f, b).unwrap();
            let c = info.cells;
            let mut i = 0;
            for z in c.lo[2]..c.hi[2] {
                for y in c.lo[1]..c.hi[1] {
                    for x in c.lo[0]..c.hi[0] {
                        let want = expected(info.level as usize, f, [x, y, z]);
                        assert_eq!(
                            vals[i].to_bits(),
                            want.to_bits(),
                            "field {f}, level {}, cell {:?}: {} != {want}",
                            info.level,
                            [x, y, z],
                            vals[i]
                        );
                        i += 1;
                        n += 1;
                    }
                }
            }
        }
    }
    n
}
