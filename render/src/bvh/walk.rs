//! The walk down one CWBVH8: obvhs's `traverse!` loop, with the node test passed in and one
//! stack shared by the top level and the chunk it enters.
//!
//! The order is obvhs's for the inner children: a node's hit inner children are taken
//! nearest-first by the ray octant's slot order, the rest of the group goes on the stack. A
//! node's hit leaves are visited before its inner children, as in obvhs, but nearest-first by the
//! same slot order (obvhs visits all their primitives from the highest bit of the node's mask
//! down, whatever the ray's direction), each leaf's primitives from the highest down: a closest
//! hit found in a near leaf then lowers `tmax` before the far leaves' voxels are decoded.

use std::mem::MaybeUninit;

use glam::UVec2;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray;

/// Stack entries: a walk holds at most one group per level of its path, and the wide builder
/// keeps a BVH's depth below 32 (obvhs's own stack size), so the top level and a chunk fit
/// together.
const STACK: usize = 64;

/// Groups of children still to visit, for one ray. Its entries are not initialized until pushed
/// (zeroing them cost about 50 instructions per ray, 1 % of a primary ray).
pub struct Stack {
    groups: MaybeUninit<[UVec2; STACK]>,
    len: usize,
}

impl Stack {
    /// An empty stack.
    #[inline(always)]
    pub fn new() -> Self {
        // Built field by field: a struct literal with an uninitialized field is still zeroed
        // whole (one `memset` of 520 bytes).
        let mut stack = MaybeUninit::<Self>::uninit();
        // SAFETY: `len` is written; `groups` may stay uninitialized (it is a `MaybeUninit`).
        unsafe {
            std::ptr::addr_of_mut!((*stack.as_mut_ptr()).len).write(0);
            stack.assume_init()
        }
    }

    /// Pushes a group; when full, the last entry is overwritten (obvhs's `StackStack` does the
    /// same; the depth bound above keeps it from happening).
    #[inline(always)]
    fn push(&mut self, g: UVec2) {
        // SAFETY: the index is below `STACK`; writing through the pointer reads nothing.
        unsafe {
            self.groups
                .as_mut_ptr()
                .cast::<UVec2>()
                .add(self.len % STACK)
                .write(g)
        };
        self.len = (self.len + 1).min(STACK - 1);
    }

    #[inline(always)]
    fn pop(&mut self) -> UVec2 {
        self.len -= 1;
        // SAFETY: every entry below `len` was written by `push` (`len` grows only there, by at
        // most one past the entry written).
        unsafe {
            self.groups
                .as_ptr()
                .cast::<UVec2>()
                .add(self.len % STACK)
                .read()
        }
    }
}

/// The index of the highest set bit of a non-zero `x`.
#[inline(always)]
fn high_bit(x: u32) -> u32 {
    31 - x.leading_zeros()
}

/// The slots of `node`'s leaves that `mask` (the node test's, obvhs's layout) has hit, slot `s`
/// as bit `s ^ oct`: highest bit nearest.
#[inline(always)]
pub fn hit_leaves(node: &CwBvhNode, mask: u32, oct: u32) -> u32 {
    let mut order = 0;
    for (s, &meta) in node.child_meta.iter().enumerate() {
        let leaf = meta != 0 && meta & 0x18 != 0x18;
        if leaf && mask >> (meta & 0x1f) & 1 != 0 {
            order |= 1 << (s as u32 ^ oct);
        }
    }
    order
}

/// Visits the primitives of the leaves `order` of `node` ([`hit_leaves`]), nearest leaf first,
/// each leaf's from the highest down: `leaf(i, s)` for each primitive `i`, `s` its leaf's slot,
/// until it returns true (then true).
#[inline(always)]
pub fn visit_leaves(
    node: &CwBvhNode,
    mut order: u32,
    oct: u32,
    mut leaf: impl FnMut(u32, usize) -> bool,
) -> bool {
    while order != 0 {
        let i = high_bit(order);
        order &= !(1 << i);
        let s = (i ^ oct) as usize;
        let meta = node.child_meta[s];
        let at = node.primitive_base_idx + u32::from(meta & 0x1f);
        for j in (at..at + (meta >> 5).count_ones()).rev() {
            if leaf(j, s) {
                return true;
            }
        }
    }
    false
}

/// Walks `nodes` (empty, or a CWBVH8 whose root is node 0) with `ray`: `test(node, ray,
/// oct_inv4)` gives a node's child hit mask, and `leaf(i, ray, stack)` is called for every
/// primitive `i` of the leaves hit, may lower `ray.tmax`, and returns true to stop the walk, which
/// then returns true. The entries the walk pushes on `stack` are gone when it returns.
#[inline(always)]
pub fn walk(
    nodes: &[CwBvhNode],
    ray: &mut Ray,
    oct_inv4: u32,
    stack: &mut Stack,
    test: impl Fn(&CwBvhNode, &Ray, u32) -> u32,
    mut leaf: impl FnMut(u32, &mut Ray, &mut Stack) -> bool,
) -> bool {
    if nodes.is_empty() {
        return false;
    }
    let floor = stack.len;
    let oct = oct_inv4 & 7;
    let mut group = UVec2::new(0, 0x8000_0000);
    // The node tested last and its hit leaves ([`hit_leaves`]).
    let (mut leaf_node, mut leaves) = (&nodes[0], 0);
    loop {
        if leaves != 0 {
            if visit_leaves(leaf_node, leaves, oct, |i, _| leaf(i, ray, stack)) {
                stack.len = floor;
                return true;
            }
            leaves = 0;
        }
        if group.y & 0xff00_0000 != 0 {
            let hits = group.y;
            let k = high_bit(hits);
            group.y &= !(1 << k);
            let base = group.x;
            if group.y & 0xff00_0000 != 0 {
                stack.push(group);
            }
            let slot = (k - 24) ^ (oct_inv4 & 0xff);
            let node = &nodes[(base + (hits & !(u32::MAX << slot)).count_ones()) as usize];
            let mask = test(node, ray, oct_inv4);
            group = UVec2::new(
                node.child_base_idx,
                (mask & 0xff00_0000) | node.imask as u32,
            );
            (leaf_node, leaves) = (node, hit_leaves(node, mask, oct));
        } else {
            group = UVec2::ZERO;
        }
        if leaves == 0 && group.y & 0xff00_0000 == 0 {
            if stack.len == floor {
                return false;
            }
            group = stack.pop();
        }
    }
}
