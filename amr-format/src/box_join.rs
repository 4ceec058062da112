//! Joining small boxes into bricks: runs of boxes that follow one another in the order their
//! data arrives, lie on one level and together fill a box of at most a brick's extent become one
//! brick, so that a level cut into many small boxes is stored, and its kd-tree built, as if it had
//! been cut into few.
//!
//! A run joins only boxes that arrive one after another, so a writer streaming the data holds at
//! most one unfinished joined brick at a time (per field). Joining never moves a cell between
//! levels and never changes a value: the same cells are stored in fewer, larger bricks.

use std::ops::Range;

use crate::geometry::IBox;
use crate::hierarchy::BrickSpec;

/// Passes over the runs; each pass joins neighbouring runs, so a few suffice to rebuild rows,
/// then layers, then whole boxes from a box cut into pieces. The cap bounds the work on
/// sequences where every pass joins only one pair.
const MAX_PASSES: usize = 24;

/// One brick made of a run of boxes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JoinedBox {
    /// The level of every box of the run.
    pub level: u32,
    /// The run's cells: exactly the union of its boxes.
    pub cells: IBox,
    /// The run's positions in the sequence handed to [`join_runs`].
    pub members: Range<usize>,
}

/// Joins `boxes` (level, cells), taken in the order given, into runs whose union is one box of
/// at most `max_extent` cells per axis. Boxes larger than that, and boxes no neighbour fits,
/// stay runs of one. The runs partition `0..boxes.len()` in order.
///
/// Two runs join only when their boxes share no cell and their bounding box holds exactly their
/// cells, so overlapping input boxes (a malformed dump) are never joined and are still found
/// where the kd-tree is built.
pub fn join_runs(boxes: &[(u32, IBox)], max_extent: i64) -> Vec<JoinedBox> {
    let mut runs: Vec<JoinedBox> = boxes
        .iter()
        .enumerate()
        .map(|(i, &(level, cells))| JoinedBox {
            level,
            cells,
            members: i..i + 1,
        })
        .collect();
    for _ in 0..MAX_PASSES {
        let before = runs.len();
        let mut joined: Vec<JoinedBox> = Vec::with_capacity(runs.len());
        for run in runs {
            match joined.last_mut() {
                Some(last) if joinable(last, &run, max_extent) => {
                    last.cells = last.cells.union(&run.cells);
                    last.members.end = run.members.end;
                }
                _ => joined.push(run),
            }
        }
        runs = joined;
        if runs.len() == before {
            break;
        }
    }
    runs
}

/// `bricks` with runs of consecutive ones joined as [`join_runs`] joins them: for writers that
/// lay out their bricks themselves (the synthetic generators).
pub fn join_bricks(bricks: &[BrickSpec], max_extent: i64) -> Vec<BrickSpec> {
    let sequence: Vec<_> = bricks.iter().map(|b| (b.level, b.cells)).collect();
    join_runs(&sequence, max_extent)
        .into_iter()
        .map(|run| BrickSpec {
            level: run.level,
            cells: run.cells,
        })
        .collect()
}

/// True when `a` and `b` (each exactly the box `cells`) lie on one level, share no cell, and
/// fill their bounding box, which fits in `max_extent` cells per axis.
fn joinable(a: &JoinedBox, b: &JoinedBox, max_extent: i64) -> bool {
    if a.level != b.level || a.cells.overlaps(&b.cells) {
        return false;
    }
    let hull = a.cells.union(&b.cells);
    if hull.extent().iter().any(|&e| e > max_extent) {
        return false;
    }
    let cells = |b: &IBox| b.num_cells().map(u128::from);
    match (cells(&a.cells), cells(&b.cells), cells(&hull)) {
        (Some(x), Some(y), Some(h)) => x + y == h,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(lo: [i64; 3], n: i64) -> IBox {
        IBox::new(lo, lo.map(|v| v + n))
    }

    #[test]
    fn pieces_of_a_box_in_x_fastest_order_rejoin_into_it() {
        // A 16^3 box cut into 4^3 pieces, x fastest, as a reader would stream them.
        let mut boxes = Vec::new();
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    boxes.push((1, cube([4 * x, 4 * y, 4 * z], 4)));
                }
            }
        }
        let runs = join_runs(&boxes, 16);
        assert_eq!(
            runs,
            vec![JoinedBox {
                level: 1,
                cells: cube([0; 3], 16),
                members: 0..64
            }]
        );
    }

    #[test]
    fn runs_stop_at_the_extent_the_level_and_holes() {
        let boxes = [
            (0, cube([0, 0, 0], 8)),
            (0, cube([8, 0, 0], 8)),
            // Fits beside the first two but would make a run 24 wide.
            (0, cube([16, 0, 0], 8)),
            // Another level.
            (1, cube([24, 0, 0], 8)),
            // Touches the previous box only along an edge: the hull has holes.
            (1, cube([32, 8, 0], 8)),
        ];
        let runs = join_runs(&boxes, 16);
        let members: Vec<_> = runs.iter().map(|r| r.members.clone()).collect();
        assert_eq!(members, vec![0..2, 2..3, 3..4, 4..5]);
        assert_eq!(runs[0].cells, IBox::new([0, 0, 0], [16, 8, 8]));
    }

    #[test]
    fn overlapping_boxes_are_not_joined() {
        // Their hull's volume equals the sum of theirs, yet they share a cell and leave a hole.
        let a = IBox::new([0, 0, 0], [2, 1, 1]);
        let b = IBox::new([1, 0, 0], [2, 2, 1]);
        let runs = join_runs(&[(0, a), (0, b)], 16);
        assert_eq!(runs.len(), 2);
    }

    #[test]
    fn boxes_larger_than_the_extent_stay_alone() {
        let runs = join_runs(&[(0, cube([0; 3], 32)), (0, cube([32, 0, 0], 32))], 16);
        assert_eq!(runs.len(), 2);
    }
}
