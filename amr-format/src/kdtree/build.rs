//! Building the kd-tree: split on brick faces until one finest brick covers each leaf.

use crate::error::{FormatError, Result};
use crate::geometry::IBox;
use crate::raw::{KdLeaf, KdNode, KD_LEAF};

/// A brick as the tree builder sees it.
#[derive(Clone, Copy, Debug)]
pub struct TreeBrick {
    /// The brick's cells in finest-level cells relative to the domain's lower corner.
    pub bounds: IBox,
    /// The brick's level.
    pub level: u32,
}

/// A built tree, ready to be written.
#[derive(Clone, Debug, Default)]
pub struct KdTree {
    /// Nodes, depth first.
    pub nodes: Vec<KdNode>,
    /// Leaves, in the order the depth-first walk meets them.
    pub leaves: Vec<KdLeaf>,
    /// Per leaf: the finest covering brick, then every coarser brick overlapping the leaf.
    pub brick_list: Vec<u32>,
}

/// Builds the tree over `bricks` inside `domain` (`domain.lo` is the origin: all zeros).
///
/// A leaf is a region covered entirely by one brick of the finest level present there, or a
/// region no brick covers. Two bricks of one level that share a cell are an error.
pub fn build(bricks: &[TreeBrick], domain: IBox) -> Result<KdTree> {
    let mut tree = KdTree::default();
    let all: Vec<u32> = (0..bricks.len() as u32)
        .filter(|&i| bricks[i as usize].bounds.overlaps(&domain))
        .collect();
    let mut stack = vec![Task {
        region: domain,
        bricks: all,
        parent: None,
    }];
    while let Some(task) = stack.pop() {
        let index = tree.nodes.len();
        if let Some(parent) = task.parent {
            let node: &mut KdNode = &mut tree.nodes[parent];
            node.b = (node.b.get() | ((index as u32) << 2)).into();
        }
        if index >= (u32::MAX >> 2) as usize {
            return Err(FormatError::InvalidHierarchy(
                "kd-tree has too many nodes".into(),
            ));
        }
        match decide(bricks, &task)? {
            Decision::Leaf(list) => {
                let leaf = tree.leaves.len() as u32;
                let start = u32::try_from(tree.brick_list.len()).map_err(|_| {
                    FormatError::InvalidHierarchy("kd-tree brick list too long".into())
                })?;
                tree.brick_list.extend_from_slice(&list);
                tree.leaves.push(KdLeaf {
                    lo: task.region.lo.map(|v| (v as u32).into()),
                    hi: task.region.hi.map(|v| (v as u32).into()),
                    brick_start: start.into(),
                    brick_count: (list.len() as u32).into(),
                });
                tree.nodes.push(KdNode {
                    a: leaf.into(),
                    b: KD_LEAF.into(),
                });
            }
            Decision::Split { axis, at } => {
                tree.nodes.push(KdNode {
                    a: (at as u32).into(),
                    b: (axis as u32).into(),
                });
                let (mut left, mut right) = (task.region, task.region);
                left.hi[axis] = at;
                right.lo[axis] = at;
                let side = |r: &IBox| -> Vec<u32> {
                    task.bricks
                        .iter()
                        .copied()
                        .filter(|&b| bricks[b as usize].bounds.overlaps(r))
                        .collect()
                };
                let (lb, rb) = (side(&left), side(&right));
                // The second child is pushed first so that the first child is built next,
                // directly after its parent: depth-first order with an implicit first child.
                stack.push(Task {
                    region: right,
                    bricks: rb,
                    parent: Some(index),
                });
                stack.push(Task {
                    region: left,
                    bricks: lb,
                    parent: None,
                });
            }
        }
    }
    Ok(tree)
}

struct Task {
    region: IBox,
    bricks: Vec<u32>,
    /// Set for a second child: the node whose child index must point here.
    parent: Option<usize>,
}

enum Decision {
    Leaf(Vec<u32>),
    Split { axis: usize, at: i64 },
}

fn decide(bricks: &[TreeBrick], task: &Task) -> Result<Decision> {
    let Some(finest) = task.bricks.iter().map(|&b| bricks[b as usize].level).max() else {
        return Ok(Decision::Leaf(Vec::new()));
    };
    let top: Vec<u32> = task
        .bricks
        .iter()
        .copied()
        .filter(|&b| bricks[b as usize].level == finest)
        .collect();
    let covering = top
        .iter()
        .find(|&&b| bricks[b as usize].bounds.contains_box(&task.region));
    if let Some(&cover) = covering {
        if let Some(&other) = top.iter().find(|&&b| b != cover) {
            return Err(overlap(bricks, cover, other));
        }
        let mut list = task.bricks.clone();
        list.sort_by_key(|&b| (std::cmp::Reverse(bricks[b as usize].level), b));
        return Ok(Decision::Leaf(list));
    }
    let r = &task.region;
    // The plane nearest the middle of its axis wins (|2 at - lo - hi| / extent, in fixed point);
    // ties go to the longer axis, so regions stay compact.
    // (distance from the middle, longer axis first, axis, plane): smallest wins.
    type PlaneKey = (u128, std::cmp::Reverse<i64>, usize, i64);
    let mut best: Option<(PlaneKey, usize, i64)> = None;
    for &b in &top {
        let bb = &bricks[b as usize].bounds;
        for axis in 0..3 {
            for at in [bb.lo[axis], bb.hi[axis]] {
                if at <= r.lo[axis] || at >= r.hi[axis] {
                    continue;
                }
                let extent = r.hi[axis] - r.lo[axis];
                let off = (2 * at - r.lo[axis] - r.hi[axis]).unsigned_abs() as u128;
                let key = (
                    (off << 32) / extent as u128,
                    std::cmp::Reverse(extent),
                    axis,
                    at,
                );
                if best.as_ref().is_none_or(|(k, _, _)| key < *k) {
                    best = Some((key, axis, at));
                }
            }
        }
    }
    match best {
        Some((_, axis, at)) => Ok(Decision::Split { axis, at }),
        // No face of a finest brick inside the region, yet none covers it: two of them overlap.
        None => Err(overlap(bricks, top[0], *top.get(1).unwrap_or(&top[0]))),
    }
}

fn overlap(bricks: &[TreeBrick], a: u32, b: u32) -> FormatError {
    let (x, y) = (&bricks[a as usize], &bricks[b as usize]);
    FormatError::InvalidHierarchy(format!(
        "bricks {a} and {b} of level {} overlap (finest-level cells {:?}..{:?} and {:?}..{:?})",
        x.level, x.bounds.lo, x.bounds.hi, y.bounds.lo, y.bounds.hi
    ))
}
