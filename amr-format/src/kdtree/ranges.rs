//! Conservative per-leaf value ranges for the octant reconstruction.
//!
//! The octant reconstruction inside a leaf of level L blends only leaf cells (the finest cell
//! at a point): cells within one level-L cell of the leaf, and, where it stitches to a coarser
//! level l, cells within two level-l cells. So the range of a leaf is the union of the value
//! ranges of the finest bricks of every leaf touching the leaf grown by two cells of the
//! coarsest level met, grown again until that level stops changing. `docs/format.md` has the
//! argument; the renderer's tests check it against the reconstruction itself.

use super::view::TreeView;

/// Computes each leaf's range for one field.
///
/// `leaf_level[i]` is the level of leaf `i`'s finest brick (`None` for a leaf without bricks),
/// `first_brick_range(i)` the value range of that brick, and `cell_scale[l]` the width of one
/// level-`l` cell in finest-level cells. A leaf without bricks gets `(+inf, -inf)`.
pub fn leaf_ranges(
    tree: &TreeView<'_>,
    leaf_level: &[Option<u32>],
    first_brick_range: impl Fn(u32) -> (f32, f32),
    cell_scale: &[[i64; 3]],
) -> Vec<(f32, f32)> {
    let mut out = Vec::with_capacity(leaf_level.len());
    let mut touching = Vec::new();
    for (leaf, level) in leaf_level.iter().enumerate() {
        let Some(mut coarsest) = *level else {
            out.push((f32::INFINITY, f32::NEG_INFINITY));
            continue;
        };
        let own = tree.leaf_box(leaf as u32);
        loop {
            let region = own.grow(cell_scale[coarsest as usize].map(|s| 2 * s));
            touching.clear();
            tree.for_each_leaf_touching(&region, |l| touching.push(l));
            let met = touching
                .iter()
                .filter_map(|&l| leaf_level[l as usize])
                .min()
                .unwrap_or(coarsest);
            if met >= coarsest {
                break;
            }
            coarsest = met;
        }
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for &l in &touching {
            if leaf_level[l as usize].is_some() {
                let (a, b) = first_brick_range(l);
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        out.push(widen_range(lo, hi));
    }
    out
}

/// Widens a range by a few units of round-off of its largest magnitude, so that averages and
/// trilinear interpolation evaluated in f32 can never fall outside it.
pub fn widen_range(lo: f32, hi: f32) -> (f32, f32) {
    let m = lo.abs().max(hi.abs());
    let slack = m * 4.0e-6;
    ((lo - slack).next_down(), (hi + slack).next_up())
}
