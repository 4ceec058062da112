//! The merged dual cells deep inside a leaf, classified straight from its brick's values.
//!
//! A level-`L` cell `c` whose neighbours `c - 1 ..= c + 1` are all cells of the leaf (which has
//! one finest brick and nothing finer inside it) owns exactly one voxel: the merged dual cell
//! whose lowest cell is `c`, with the eight cells `c ..= c + 1` as corners. Every octant of `c`
//! belongs to a dual cell whose eight cells are leaf cells of level `L`, so none is a voxel of
//! its own. Such a dual cell is active when one of its cells is `>= iso` and another `< iso`
//! (a NaN is neither), which is what the neighbourhood's codes give it ([`super::leaf`]);
//! here no neighbourhood is filled: one byte code per cell of the box grown by one upwards, then
//! eight codes ORed per dual cell, row by row.

use amr_format::IBox;

use super::local::{ABOVE, BELOW};
use super::refs::{make_ref, LocalVoxel};

/// The cells of `leaf_cells` (level-`L` cells lying inside the leaf) that
/// [`extract_interior`] can take: those whose 26 neighbours lie in the leaf too.
pub fn interior_cells(leaf_cells: &IBox) -> IBox {
    leaf_cells.grow([-1; 3])
}

/// Appends to `out` the active merged dual cells of leaf `leaf` whose lowest cell lies in
/// `cells` (a box of [`interior_cells`], inside the brick's cells `bc` whose values are
/// `values`), referenced by their lowest cell's index in `refs`; returns how many dual cells
/// were evaluated (`cells`' count). `codes` and `row` are scratch.
#[allow(clippy::too_many_arguments)]
pub fn extract_interior(
    (values, bc): (&[f32], &IBox),
    cells: &IBox,
    (leaf, refs): (u32, &IBox),
    iso: f32,
    (codes, row): (&mut Vec<u8>, &mut Vec<u8>),
    out: &mut Vec<u64>,
) -> u64 {
    if cells.is_empty() {
        return 0;
    }
    let g = IBox::new(cells.lo, [0, 1, 2].map(|a| cells.hi[a] + 1));
    debug_assert!(bc.contains_box(&g));
    let ge = g.extent();
    let (gw, gh) = (ge[0] as usize, ge[1] as usize);
    codes.clear();
    codes.resize(gw * gh * ge[2] as usize, 0);
    for (z, slab) in codes.chunks_exact_mut(gw * gh).enumerate() {
        for (y, dst) in slab.chunks_exact_mut(gw).enumerate() {
            let src = bc.linear_index([g.lo[0], g.lo[1] + y as i64, g.lo[2] + z as i64]);
            for (d, &v) in dst.iter_mut().zip(&values[src..src + gw]) {
                *d = u8::from(v >= iso) | u8::from(v < iso) << 1;
            }
        }
    }
    let w = gw - 1;
    row.clear();
    row.resize(w, 0);
    let both = ABOVE | BELOW;
    let e = cells.extent();
    for z in 0..e[2] as usize {
        for y in 0..e[1] as usize {
            let r = |dy: usize, dz: usize| {
                let start = (z + dz) * gw * gh + (y + dy) * gw;
                &codes[start..start + gw]
            };
            let (a, b, c, d) = (r(0, 0), r(1, 0), r(0, 1), r(1, 1));
            // Whole-row ORs of equal-length slices, which the compiler vectorizes.
            row.copy_from_slice(&a[..w]);
            for src in [
                &a[1..],
                &b[..w],
                &b[1..],
                &c[..w],
                &c[1..],
                &d[..w],
                &d[1..],
            ] {
                for (m, &x) in row.iter_mut().zip(src) {
                    *m |= x;
                }
            }
            if row.iter().filter(|&&m| m == both).count() == 0 {
                continue;
            }
            let first =
                refs.linear_index([cells.lo[0], cells.lo[1] + y as i64, cells.lo[2] + z as i64]);
            for (k, &m) in row.iter().enumerate() {
                if m == both {
                    let cell = (first + k) as u32;
                    out.push(make_ref(leaf, LocalVoxel::Dual { cell }));
                }
            }
        }
    }
    cells.num_cells().unwrap_or(0)
}
