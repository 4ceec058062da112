//! Joining small boxes into bricks: boxes of one level that together fill a box of at most a
//! brick's extent, and whose data arrives close enough together, become one brick, so that a
//! level cut into many small boxes is stored, and its kd-tree built, as if it had been cut into
//! few.
//!
//! A writer streaming the data keeps a joined brick until the last of its boxes has come, so the
//! joins are bounded by the stream: at no position of it may more than `max_open` joined bricks
//! have boxes both before and after that position ([`join_runs`]). The writer then holds at most
//! `max_open + 1` unfinished bricks per field, whatever the size of the dump. Joining never
//! moves a cell between levels and never changes a value: the same cells are stored in fewer,
//! larger bricks.

use std::collections::hash_map::Entry;

use foldhash::{HashMap, HashMapExt};

use crate::geometry::IBox;
use crate::hierarchy::BrickSpec;

/// Passes over the runs. A pass joins each run with the neighbours sharing a whole face with it
/// as long as it can, so one pass rebuilds most boxes cut into pieces; later passes pick up
/// joins that became possible only after others.
const MAX_PASSES: usize = 8;

/// Bytes of unfinished joined bricks a streaming writer may hold, about: [`max_open`] turns it
/// into the bound [`join_runs`] keeps.
pub const PENDING_BYTES: u64 = 64 << 20;

/// The most runs [`join_runs`] may leave open at a position of the stream so that the unfinished
/// bricks of `fields` fields, each of at most `max_extent` cells per axis in `f32`, stay within
/// [`PENDING_BYTES`]; at least 16.
pub fn max_open(max_extent: i64, fields: usize) -> usize {
    let cells = u64::try_from(max_extent.max(1)).unwrap_or(u64::MAX);
    let brick = cells.saturating_pow(3).saturating_mul(4);
    let per_run = brick.saturating_mul(fields.max(1) as u64);
    usize::try_from(PENDING_BYTES / per_run)
        .unwrap_or(usize::MAX)
        .max(16)
}

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

/// Joins `boxes` (level, cells), taken in the order their data will arrive, into runs whose
/// union is one box of at most `max_extent` cells per axis. Two runs join when they lie on one
/// level and share a whole face (so their union is a box and they share no cell), and when the
/// joined run keeps the stream's bound: at every position `p`, at most `max_open` runs have
/// boxes both before and after `p` (a run counts at the positions from its first box up to, not
/// including, its last). Boxes larger than `max_extent`, and boxes no neighbour fits, stay runs of
/// one. Every position belongs to exactly one run; runs come in the order of their first box.
///
/// Two runs join only when they share no cell, so the overlapping boxes of a malformed dump are
/// never joined and are still found where the kd-tree is built.
pub fn join_runs(boxes: &[(u32, IBox)], max_extent: i64, max_open: usize) -> Vec<JoinedBox> {
    let mut runs = consecutive_runs(boxes, max_extent);
    let mut faces = Faces::with_capacity(runs.len());
    let mut open = OpenCounts::new(boxes.len());
    for (id, run) in runs.iter().enumerate() {
        faces.insert(run, id);
        open.add(run.first, run.last, 1);
    }
    // Aligned first: runs inside one block of the grid of `max_extent` cells, so that the
    // greedy joins do not cut across each other's blocks; then whatever else still fits.
    for aligned in [true, false] {
        for _ in 0..MAX_PASSES {
            let mut joins = 0;
            for id in 0..runs.len() {
                while runs[id].alive {
                    let Some(other) = faces.partner(&runs, id, max_extent, |a, b| {
                        (!aligned || in_one_block(&a.cells.union(&b.cells), max_extent))
                            && open.fits(a.first.min(b.first), a.last.max(b.last), max_open, [a, b])
                    }) else {
                        break;
                    };
                    faces.remove(&runs[id], id);
                    faces.remove(&runs[other], other);
                    open.add(runs[id].first, runs[id].last, -1);
                    open.add(runs[other].first, runs[other].last, -1);
                    let absorbed = std::mem::replace(&mut runs[other], Run::joined());
                    runs[id].absorb(absorbed);
                    open.add(runs[id].first, runs[id].last, 1);
                    faces.insert(&runs[id], id);
                    joins += 1;
                }
            }
            if joins == 0 {
                break;
            }
        }
    }
    let mut out: Vec<JoinedBox> = runs
        .into_iter()
        .filter(|r| r.alive)
        .map(|mut r| {
            r.members.sort_unstable();
            JoinedBox {
                level: r.level,
                cells: r.cells,
                members: r.members,
            }
        })
        .collect();
    out.sort_by_key(|r| r.members[0]);
    out
}

/// The boxes joined where each shares a whole face with the run of those just before it, inside
/// one block of the grid of `max_extent` cells: a cheap first step (one look at each box, no
/// lookups) that rebuilds the rows of boxes streamed row by row. A consecutive run is open only
/// at its own positions, where no other run is yet.
fn consecutive_runs(boxes: &[(u32, IBox)], max_extent: i64) -> Vec<Run> {
    let mut runs: Vec<Run> = Vec::with_capacity(boxes.len());
    for (i, &(level, cells)) in boxes.iter().enumerate() {
        if let Some(run) = runs.last_mut() {
            let hull = run.cells.union(&cells);
            let fits = hull.extent().iter().all(|&e| e <= max_extent);
            if run.level == level
                && shares_whole_face(&run.cells, &cells)
                && fits
                && in_one_block(&hull, max_extent)
            {
                run.cells = hull;
                run.members.push(i);
                run.last = i;
                continue;
            }
        }
        runs.push(Run {
            level,
            cells,
            members: vec![i],
            first: i,
            last: i,
            alive: true,
        });
    }
    runs
}

/// True when `a` and `b` share a whole face: adjacent along one axis, the same range on the two
/// others. Their union is then a box, and they share no cell.
fn shares_whole_face(a: &IBox, b: &IBox) -> bool {
    (0..3).any(|ax| {
        face(0, a, ax, a.hi[ax]) == face(0, b, ax, b.lo[ax])
            || face(0, a, ax, a.lo[ax]) == face(0, b, ax, b.hi[ax])
    })
}

/// True when `cells` lies inside one block of the grid of `size` cells per axis (blocks
/// `[k * size, (k + 1) * size)` of the level's index space).
fn in_one_block(cells: &IBox, size: i64) -> bool {
    let size = size.max(1);
    (0..3).all(|a| cells.lo[a].div_euclid(size) == (cells.hi[a] - 1).div_euclid(size))
}

/// `bricks` with runs of them joined as [`join_runs`] joins them, in their order: for writers
/// that lay out their bricks themselves (the synthetic generators).
pub fn join_bricks(bricks: &[BrickSpec], max_extent: i64, max_open: usize) -> Vec<BrickSpec> {
    let sequence: Vec<_> = bricks.iter().map(|b| (b.level, b.cells)).collect();
    join_runs(&sequence, max_extent, max_open)
        .into_iter()
        .map(|run| BrickSpec {
            level: run.level,
            cells: run.cells,
        })
        .collect()
}

/// A run while the passes join runs: its members in no particular order, its first and last
/// positions, and whether it still stands (a run joined into another no longer does).
struct Run {
    level: u32,
    cells: IBox,
    members: Vec<usize>,
    first: usize,
    last: usize,
    alive: bool,
}

impl Run {
    /// What is left of a run joined into another.
    fn joined() -> Self {
        Self {
            level: 0,
            cells: IBox::default(),
            members: Vec::new(),
            first: 0,
            last: 0,
            alive: false,
        }
    }

    /// Takes `other`'s boxes into this run.
    fn absorb(&mut self, other: Run) {
        self.cells = self.cells.union(&other.cells);
        self.first = self.first.min(other.first);
        self.last = self.last.max(other.last);
        self.members.extend(other.members);
    }
}

/// A whole face of a box: level, axis, the face's coordinate on that axis, the box's range on
/// the two other axes.
type FaceKey = (u32, usize, i64, [i64; 4]);

/// The face of `cells` at `coord` on `axis`.
fn face(level: u32, cells: &IBox, axis: usize, coord: i64) -> FaceKey {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    (
        level,
        axis,
        coord,
        [cells.lo[u], cells.hi[u], cells.lo[v], cells.hi[v]],
    )
}

/// The standing runs by their upper and lower faces.
struct Faces {
    upper: HashMap<FaceKey, usize>,
    lower: HashMap<FaceKey, usize>,
}

impl Faces {
    fn with_capacity(n: usize) -> Self {
        Self {
            upper: HashMap::with_capacity(3 * n),
            lower: HashMap::with_capacity(3 * n),
        }
    }

    fn insert(&mut self, run: &Run, id: usize) {
        for a in 0..3 {
            self.upper
                .insert(face(run.level, &run.cells, a, run.cells.hi[a]), id);
            self.lower
                .insert(face(run.level, &run.cells, a, run.cells.lo[a]), id);
        }
    }

    fn remove(&mut self, run: &Run, id: usize) {
        for a in 0..3 {
            let up = face(run.level, &run.cells, a, run.cells.hi[a]);
            let low = face(run.level, &run.cells, a, run.cells.lo[a]);
            for (map, key) in [(&mut self.upper, up), (&mut self.lower, low)] {
                if let Entry::Occupied(e) = map.entry(key) {
                    if *e.get() == id {
                        e.remove();
                    }
                }
            }
        }
    }

    /// A standing run sharing a whole face with run `id`, x first, whose union with it fits in
    /// `max_extent` cells per axis and passes `bound`.
    fn partner(
        &self,
        runs: &[Run],
        id: usize,
        max_extent: i64,
        mut bound: impl FnMut(&Run, &Run) -> bool,
    ) -> Option<usize> {
        let run = &runs[id];
        let e = run.cells.extent();
        (0..3).find_map(|a| {
            let below = self
                .upper
                .get(&face(run.level, &run.cells, a, run.cells.lo[a]));
            let above = self
                .lower
                .get(&face(run.level, &run.cells, a, run.cells.hi[a]));
            [below, above].into_iter().flatten().copied().find(|&k| {
                let other = &runs[k];
                k != id
                    && other.alive
                    && e[a] + other.cells.extent()[a] <= max_extent
                    && bound(run, other)
            })
        })
    }
}

/// How many runs are open at each position of the stream (from their first box up to, not
/// including, their last): a segment tree with range additions and range maxima.
struct OpenCounts {
    size: usize,
    max: Vec<i64>,
    add: Vec<i64>,
}

impl OpenCounts {
    fn new(n: usize) -> Self {
        let size = n.max(1).next_power_of_two();
        Self {
            size,
            max: vec![0; 2 * size],
            add: vec![0; 2 * size],
        }
    }

    /// Adds `delta` to the positions `first..last`.
    fn add(&mut self, first: usize, last: usize, delta: i64) {
        if first < last {
            self.update(1, 0, self.size, first, last, delta);
        }
    }

    /// The largest count over `first..last` (0 when empty).
    fn max_in(&self, first: usize, last: usize) -> i64 {
        if first < last {
            self.query(1, 0, self.size, first, last)
        } else {
            0
        }
    }

    /// True when a run over `first..last` replacing the runs `parts` keeps every count within
    /// `max_open`.
    fn fits(&mut self, first: usize, last: usize, max_open: usize, parts: [&Run; 2]) -> bool {
        for p in parts {
            self.add(p.first, p.last, -1);
        }
        let ok = self.max_in(first, last) < max_open as i64;
        for p in parts {
            self.add(p.first, p.last, 1);
        }
        ok
    }

    fn update(&mut self, node: usize, lo: usize, hi: usize, a: usize, b: usize, delta: i64) {
        if b <= lo || hi <= a {
            return;
        }
        if a <= lo && hi <= b {
            self.max[node] += delta;
            self.add[node] += delta;
            return;
        }
        let mid = (lo + hi) / 2;
        self.update(2 * node, lo, mid, a, b, delta);
        self.update(2 * node + 1, mid, hi, a, b, delta);
        self.max[node] = self.add[node] + self.max[2 * node].max(self.max[2 * node + 1]);
    }

    fn query(&self, node: usize, lo: usize, hi: usize, a: usize, b: usize) -> i64 {
        if b <= lo || hi <= a {
            return i64::MIN / 4;
        }
        if a <= lo && hi <= b {
            return self.max[node];
        }
        let mid = (lo + hi) / 2;
        self.add[node]
            + self
                .query(2 * node, lo, mid, a, b)
                .max(self.query(2 * node + 1, mid, hi, a, b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(lo: [i64; 3], n: i64) -> IBox {
        IBox::new(lo, lo.map(|v| v + n))
    }

    /// Cubes of `size` cells of `level` filling `counts` of them per axis, x fastest.
    fn cubes_in_row_order(level: u32, counts: [i64; 3], size: i64) -> Vec<(u32, IBox)> {
        let mut boxes = Vec::new();
        for z in 0..counts[2] {
            for y in 0..counts[1] {
                for x in 0..counts[0] {
                    boxes.push((level, cube([x, y, z].map(|v| v * size), size)));
                }
            }
        }
        boxes
    }

    #[test]
    fn pieces_of_a_box_in_x_fastest_order_rejoin_into_it() {
        // A 16^3 box cut into 4^3 pieces, x fastest, as a reader would stream them.
        let boxes = cubes_in_row_order(1, [4; 3], 4);
        let runs = join_runs(&boxes, 16, 16);
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
        let runs = join_runs(&boxes, 16, 16);
        let members: Vec<_> = runs.iter().map(|r| r.members.clone()).collect();
        assert_eq!(members, vec![vec![0, 1], vec![2], vec![3], vec![4]]);
        assert_eq!(runs[0].cells, IBox::new([0, 0, 0], [16, 8, 8]));
    }

    #[test]
    fn overlapping_boxes_are_not_joined() {
        // Their hull's volume equals the sum of theirs, yet they share a cell and leave a hole.
        let a = IBox::new([0, 0, 0], [2, 1, 1]);
        let b = IBox::new([1, 0, 0], [2, 2, 1]);
        let runs = join_runs(&[(0, a), (0, b)], 16, 16);
        assert_eq!(runs.len(), 2);
    }

    #[test]
    fn boxes_larger_than_the_extent_stay_alone() {
        let runs = join_runs(&[(0, cube([0; 3], 32)), (0, cube([32, 0, 0], 32))], 16, 16);
        assert_eq!(runs.len(), 2);
    }

    #[test]
    fn neighbours_a_few_positions_apart_join() {
        // Boxes of 8^3 filling 32x16x16, streamed as two layers of two rows of four: a brick of
        // 16^3 takes the first two boxes of each row, which are not consecutive.
        let boxes = cubes_in_row_order(2, [4, 2, 2], 8);
        let runs = join_runs(&boxes, 16, 16);
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
        let runs = join_runs(&boxes, 16, 16);
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
            assert!(open <= 16, "{open} runs unfinished at {p}");
        }
    }

    #[test]
    fn one_cell_boxes_in_row_order_rejoin_within_the_bound() {
        let boxes = cubes_in_row_order(0, [40; 3], 1);
        // 3 x 3 bricks of up to 16^3 open across a layer at once: 9 runs.
        for (max_open, want) in [(9, 27), (4, 0)] {
            let runs = join_runs(&boxes, 16, max_open);
            if want > 0 {
                assert_eq!(runs.len(), want);
            } else {
                assert!(runs.len() > 27, "{} runs", runs.len());
            }
            let mut open = vec![0usize; boxes.len()];
            for r in &runs {
                for o in &mut open[r.members[0]..r.members[r.members.len() - 1]] {
                    *o += 1;
                }
            }
            assert!(open.iter().all(|&o| o <= max_open), "bound {max_open}");
        }
    }

    #[test]
    fn the_bound_follows_the_fields() {
        assert_eq!(max_open(16, 1), 4096);
        assert_eq!(max_open(16, 38), 107);
        assert_eq!(max_open(1024, 1), 16);
    }

    #[test]
    fn boxes_streamed_by_data_file_rejoin_into_aligned_blocks() {
        // The PeleLM plotfile's finest level: 64 boxes of 8^3 listed x fastest, streamed by data
        // file (each holding two runs of eight of them): eight bricks of 16^3, one per block.
        let order: Vec<i64> = [40..48, 56..64, 0..8, 16..24, 8..16, 24..32, 32..40, 48..56]
            .into_iter()
            .flatten()
            .collect();
        let boxes: Vec<(u32, IBox)> = order
            .iter()
            .map(|&i| (2, cube([8 * (i % 4), 8 * (i / 4 % 4), 8 * (i / 16)], 8)))
            .collect();
        let runs = join_runs(&boxes, 16, 16);
        assert_eq!(runs.len(), 8);
        for r in &runs {
            assert_eq!(r.cells.extent(), [16; 3]);
            assert!(r.cells.lo.iter().all(|&v| v % 16 == 0), "{:?}", r.cells);
        }
    }
}
