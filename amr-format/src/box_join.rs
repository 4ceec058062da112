//! Joining small boxes into bricks: boxes of one level that come close together in the order
//! their data arrives and together fill a box of at most a brick's extent become one brick, so
//! that a level cut into many small boxes is stored, and its kd-tree built, as if it had been cut
//! into few.
//!
//! A writer streaming the data keeps a joined brick until the last of its boxes has come, so
//! which boxes may join is bounded by their positions in the stream: a run either holds
//! consecutive boxes (any number: a box cut into pieces, streamed piece by piece) or spans at
//! most [`WINDOW`] positions (neighbours a few boxes apart, as a space-filling curve or a row
//! order leaves them). At most `WINDOW + 1` joined bricks are then unfinished at any point of
//! the stream (see [`join_runs`]). Joining never moves a cell between levels and never changes a
//! value: the same cells are stored in fewer, larger bricks.

use crate::geometry::IBox;
use crate::hierarchy::BrickSpec;

/// Positions in the stream a run that is not consecutive may span, at most.
pub const WINDOW: usize = 16;

/// Passes over the runs; each pass joins runs found in the passes before, so a few suffice to
/// rebuild rows, then layers, then whole boxes from a box cut into pieces. The cap bounds the
/// work on sequences where every pass joins only one pair.
const MAX_PASSES: usize = 24;

/// One brick made of a run of boxes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JoinedBox {
    /// The level of every box of the run.
    pub level: u32,
    /// The run's cells: exactly the union of its boxes.
    pub cells: IBox,
    /// The run's positions in the sequence handed to [`join_runs`], ascending.
    pub members: Vec<usize>,
}

/// Joins `boxes` (level, cells), taken in the order given, into runs whose union is one box of
/// at most `max_extent` cells per axis, each run consecutive in the order or spanning at most
/// [`WINDOW`] positions. Boxes larger than that, and boxes no neighbour fits, stay runs of one.
/// Every position belongs to exactly one run; runs come in the order of their first box.
///
/// At any position `p` of the sequence, at most `WINDOW + 1` runs have boxes both before and
/// after `p`: one consecutive run holding `p`, and runs spanning at most `WINDOW` positions,
/// each with a box among the `WINDOW` positions up to `p`, which no two share.
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
            members: vec![i],
        })
        .collect();
    for _ in 0..MAX_PASSES {
        let before = runs.len();
        let mut joined: Vec<JoinedBox> = Vec::with_capacity(runs.len());
        for run in runs {
            // The runs kept last, most recent first: a partner within the window starts at
            // most WINDOW positions before this run's end, and consecutive ones end just
            // before it starts.
            let first = joined.len().saturating_sub(WINDOW);
            let partner = (first..joined.len())
                .rev()
                .find(|&k| joinable(&joined[k], &run, max_extent));
            match partner {
                Some(k) => {
                    let into = &mut joined[k];
                    into.cells = into.cells.union(&run.cells);
                    into.members.extend_from_slice(&run.members);
                    into.members.sort_unstable();
                }
                None => joined.push(run),
            }
        }
        joined.sort_by_key(|r| r.members[0]);
        runs = joined;
        if runs.len() == before {
            break;
        }
    }
    runs
}

/// `bricks` with runs of them joined as [`join_runs`] joins them, in their order: for writers
/// that lay out their bricks themselves (the synthetic generators).
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

/// True when `a` and `b` (each exactly the box `cells`) lie on one level, share no cell, fill
/// their bounding box, which fits in `max_extent` cells per axis, and together are consecutive
/// in the stream or span at most [`WINDOW`] positions.
fn joinable(a: &JoinedBox, b: &JoinedBox, max_extent: i64) -> bool {
    if a.level != b.level || a.cells.overlaps(&b.cells) {
        return false;
    }
    let hull = a.cells.union(&b.cells);
    if hull.extent().iter().any(|&e| e > max_extent) {
        return false;
    }
    let cells = |b: &IBox| b.num_cells().map(u128::from);
    let fills = match (cells(&a.cells), cells(&b.cells), cells(&hull)) {
        (Some(x), Some(y), Some(h)) => x + y == h,
        _ => false,
    };
    if !fills {
        return false;
    }
    let lo = a.members[0].min(b.members[0]);
    let hi = a.members[a.members.len() - 1].max(b.members[b.members.len() - 1]);
    let span = hi - lo + 1;
    span == a.members.len() + b.members.len() || span <= WINDOW
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
                members: (0..64).collect()
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
        assert_eq!(members, vec![vec![0, 1], vec![2], vec![3], vec![4]]);
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

    #[test]
    fn neighbours_a_few_positions_apart_join() {
        // Boxes of 8^3 filling 32x16x16, streamed as two layers of two rows of four: a brick of
        // 16^3 takes the first two boxes of each row, which are not consecutive.
        let mut boxes = Vec::new();
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..4 {
                    boxes.push((2, cube([8 * x, 8 * y, 8 * z], 8)));
                }
            }
        }
        let runs = join_runs(&boxes, 16);
        let cells: Vec<IBox> = runs.iter().map(|r| r.cells).collect();
        assert_eq!(
            cells,
            vec![
                IBox::new([0, 0, 0], [16, 16, 16]),
                IBox::new([16, 0, 0], [32, 16, 16])
            ]
        );
        assert_eq!(runs[0].members, vec![0, 1, 4, 5, 8, 9, 12, 13]);
    }

    #[test]
    fn few_runs_are_unfinished_at_any_point_of_the_stream() {
        // Boxes of 2 to 3 cells filling 48^2 x 6 in a shuffled but local order.
        let mut boxes = Vec::new();
        let mut state = 7u64;
        let mut next = |n: u64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) % n
        };
        let spans = |next: &mut dyn FnMut(u64) -> u64| {
            let mut at = 0;
            let mut out = Vec::new();
            while at < 48 {
                let end = (at + 2 + next(2) as i64).min(48);
                out.push((at, end));
                at = end;
            }
            out
        };
        let (xs, ys) = (spans(&mut next), spans(&mut next));
        for &(z0, z1) in &[(0, 3), (3, 6)] {
            for &(y0, y1) in &ys {
                for &(x0, x1) in &xs {
                    boxes.push((0, IBox::new([x0, y0, z0], [x1, y1, z1])));
                }
            }
        }
        for i in (0..boxes.len() - 1).step_by(3) {
            if next(2) == 0 {
                boxes.swap(i, i + 1);
            }
        }
        let runs = join_runs(&boxes, 16);
        assert!(runs.len() < boxes.len() / 4, "{} runs", runs.len());
        let mut seen = vec![false; boxes.len()];
        for r in &runs {
            let cells: u64 = r
                .members
                .iter()
                .map(|&m| boxes[m].1.num_cells().unwrap())
                .sum();
            assert_eq!(cells, r.cells.num_cells().unwrap());
            for &m in &r.members {
                assert!(!seen[m]);
                seen[m] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
        for p in 0..boxes.len() {
            let open = runs
                .iter()
                .filter(|r| r.members[0] <= p && p < r.members[r.members.len() - 1])
                .count();
            assert!(open <= WINDOW + 1, "{open} runs unfinished at {p}");
        }
    }
}
