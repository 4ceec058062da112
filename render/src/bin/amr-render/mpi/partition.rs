//! The partitioned mode's split of the scene: the kd-tree leaves in visibility order from the
//! camera, cut into contiguous runs balanced by active-octant count.
//!
//! Every ray from the eye meets the leaves in visibility order (at each split the eye's side
//! comes first), so runs of that order are front to back too: rank 0's part is in front of rank
//! 1's along every ray, and the partial frames composite in rank order. A run of a depth-first
//! order is a union of few subtrees, so the parts are spatially compact.

use amr_format::kdtree::TreeView;
use amr_render::camera::Camera;
use amr_render::trace::GridFrame;

/// The leaves of `tree` front to back along the primary rays of `camera` in a domain with grid
/// frame `frame`.
pub fn visibility_order(tree: &TreeView<'_>, camera: &Camera, frame: &GridFrame) -> Vec<u32> {
    tree.front_to_back(order_point(camera, frame))
}

/// The point (finest-level cell coordinates) the leaves are ordered from: the eye of a
/// perspective camera. An orthographic camera's rays are parallel: the point lies beyond the
/// domain, far back along the view on each axis it runs along, so that every split plane
/// across the rays is seen from the side they come from (from the camera's position, a plane
/// the camera stands over would be seen from the wrong side).
fn order_point(camera: &Camera, frame: &GridFrame) -> [f64; 3] {
    [0, 1, 2].map(|a| {
        let eye = 0.5 * (camera.pos[a] - frame.origin[a]) / frame.unit[a];
        let f = camera.forward()[a];
        match camera.is_orthographic() {
            true if f > 0.0 => -1e300,
            true if f < 0.0 => 1e300,
            _ => eye,
        }
    })
}

/// The part (`0..parts`) of each leaf, indexed by leaf: `order` cut into `parts` contiguous runs
/// whose sums of `weight[leaf]` are as even as whole leaves allow (a leaf goes to the part its
/// weight's midpoint falls in). With no weight at all, runs of equal leaf count.
pub fn balanced_runs(order: &[u32], weight: &[u64], parts: usize) -> Vec<u32> {
    let parts = parts.max(1);
    let mut owner = vec![0u32; weight.len()];
    let total: u64 = order.iter().map(|&l| weight[l as usize]).sum();
    let mut before = 0u64;
    for (k, &leaf) in order.iter().enumerate() {
        let w = weight[leaf as usize];
        let part = if total == 0 {
            k * parts / order.len().max(1)
        } else {
            let mid = 2 * u128::from(before) + u128::from(w);
            (mid * parts as u128 / (2 * u128::from(total))) as usize
        };
        owner[leaf as usize] = part.min(parts - 1) as u32;
        before += w;
    }
    owner
}

#[cfg(test)]
mod tests {
    use super::*;
    use amr_format::kdtree::{build, TreeBrick};
    use amr_format::IBox;

    /// A tree over a row of `n` unit bricks along x with `n` leaves.
    fn row(n: i64) -> amr_format::kdtree::KdTree {
        let bricks: Vec<TreeBrick> = (0..n)
            .map(|i| TreeBrick {
                level: 0,
                bounds: IBox::new([i, 0, 0], [i + 1, 1, 1]),
            })
            .collect();
        build(&bricks, IBox::new([0, 0, 0], [n, 1, 1])).unwrap()
    }

    fn view(t: &amr_format::kdtree::KdTree, n: i64) -> TreeView<'_> {
        TreeView {
            nodes: &t.nodes,
            leaves: &t.leaves,
            domain: IBox::new([0, 0, 0], [n, 1, 1]),
        }
    }

    /// The frame of a row of `n` cells along x: grid units of half a cell, as the order's
    /// point is computed.
    fn frame(n: f64) -> GridFrame {
        GridFrame {
            origin: [0.0; 3],
            unit: [0.5; 3],
            extent: [2.0 * n, 2.0, 2.0],
        }
    }

    fn camera(pos: [f64; 3], look_at: [f64; 3]) -> Camera {
        Camera::new(pos, look_at, [0.0, 0.0, 1.0], 40.0).unwrap()
    }

    #[test]
    fn visibility_order_runs_from_the_eye() {
        let tree = row(8);
        let view = view(&tree, 8);
        let centre = |l: u32| view.leaf_box(l).lo[0];
        let order = |c: Camera| -> Vec<i64> {
            visibility_order(&view, &c, &frame(8.0))
                .into_iter()
                .map(centre)
                .collect()
        };
        let from_left = order(camera([-1.0, 0.5, 0.5], [4.0, 0.5, 0.5]));
        assert_eq!(from_left, (0..8).collect::<Vec<_>>());
        let from_right = order(camera([9.0, 0.5, 0.5], [4.0, 0.5, 0.5]));
        assert_eq!(from_right, (0..8).rev().collect::<Vec<_>>());
        // An orthographic camera above cell 2 looking down and to the right: its rays cross
        // the cells from left to right, whichever cell the camera is above.
        let oblique = camera([2.5, 0.5, 3.0], [5.5, 0.5, 0.5]);
        let parallel = order(oblique.orthographic(Some(2.0)).unwrap());
        assert_eq!(parallel, (0..8).collect::<Vec<_>>());
        let inside = order(oblique);
        assert_eq!(inside[0], 2);
        // Along the row, every leaf comes after the leaves between it and the eye.
        for (k, &x) in inside.iter().enumerate() {
            for &y in &inside[k + 1..] {
                let between = (x < y && y < 2) || (2 < y && y < x);
                assert!(!between, "{inside:?}");
            }
        }
    }

    #[test]
    fn runs_are_contiguous_and_balanced() {
        let order: Vec<u32> = vec![3, 1, 0, 2, 5, 4];
        let weight = vec![10, 10, 10, 10, 10, 10];
        let owner = balanced_runs(&order, &weight, 3);
        let seq: Vec<u32> = order.iter().map(|&l| owner[l as usize]).collect();
        assert_eq!(seq, vec![0, 0, 1, 1, 2, 2]);
        let skew = vec![100, 1, 1, 1, 1, 1];
        let owner = balanced_runs(&[0, 1, 2, 3, 4, 5], &skew, 2);
        assert_eq!(owner[0], 0);
        assert!(owner[1..].iter().all(|&p| p == 1));
        let none = balanced_runs(&[0, 1, 2, 3], &[0; 4], 2);
        assert_eq!(none, vec![0, 0, 1, 1]);
        // More parts than leaves: some parts are empty.
        assert_eq!(balanced_runs(&[0, 1], &[5, 5], 4), vec![1, 3]);
    }
}
