//! The walk down one CWBVH8: obvhs's `traverse!` loop, with the node test passed in and one
//! stack shared by the top level and the chunk it enters.
//!
//! The order is obvhs's: a node's hit inner children are taken nearest-first by the ray octant's
//! slot order, the rest of the group goes on the stack, and a leaf's primitives are visited from
//! the highest bit of its mask down.

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
    let mut group = UVec2::new(0, 0x8000_0000);
    let mut prims = UVec2::ZERO;
    loop {
        while prims.y != 0 {
            let k = high_bit(prims.y);
            prims.y &= !(1 << k);
            if leaf(prims.x + k, ray, stack) {
                stack.len = floor;
                return true;
            }
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
            prims = UVec2::new(node.primitive_base_idx, mask & 0x00ff_ffff);
        } else {
            group = UVec2::ZERO;
        }
        if prims.y == 0 && group.y & 0xff00_0000 == 0 {
            if stack.len == floor {
                return false;
            }
            group = stack.pop();
        }
    }
}
