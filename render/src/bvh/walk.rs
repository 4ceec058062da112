//! The walk down one CWBVH8 with one ray: a depth-first walk with the node test passed in and
//! one stack shared by the top level and the chunk it enters.
//!
//! A node's hit children, leaves and inner nodes alike, are taken nearest-first by the ray
//! octant's slot order (slot `i ^ oct` for `i` from 7 down), a leaf's primitives from the
//! highest down. obvhs's own walk visits all the leaves of a node first, their primitives from
//! the highest bit of the node's mask down whatever the ray's direction, then the inner
//! children: a far leaf's voxels are then decoded before a near child's hit lowers `tmax`. Both
//! walks visit the same primitives when `tmax` is not lowered.

use std::mem::MaybeUninit;

use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray;

/// Stack entries: a walk holds at most seven entries per level of its path, and the wide
/// builder keeps a BVH's depth below 32 (obvhs's own stack size), so the top level and a chunk
/// fit together.
const STACK: usize = 512;

/// A stack entry's flag for a leaf, whose primitive count is in the two bits below the flag
/// and its first primitive in the low 32 bits; an entry without it is an inner node's index.
const LEAF_ENTRY: u64 = 1 << 63;

/// The stack entry of the hit child in slot `s` of `node`, whose inner children are `imask`.
#[inline(always)]
pub fn child_entry(node: &CwBvhNode, s: u32, imask: u32) -> u64 {
    if imask >> s & 1 != 0 {
        u64::from(node.child_base_idx + (imask & !(u32::MAX << s)).count_ones())
    } else {
        let meta = node.child_meta[s as usize];
        let first = node.primitive_base_idx + u32::from(meta & 0x1f);
        LEAF_ENTRY | u64::from((meta >> 5).count_ones()) << 61 | u64::from(first)
    }
}

/// The primitives of a leaf's stack entry ([`child_entry`]), or `None` for an inner node's.
#[inline(always)]
pub fn leaf_prims(entry: u64) -> Option<std::ops::Range<u32>> {
    (entry & LEAF_ENTRY != 0).then(|| {
        let first = entry as u32;
        first..first + (entry >> 61 & 3) as u32
    })
}

/// Nodes and leaves still to visit, for one ray. Its entries are not initialized until pushed
/// (zeroing them cost about 50 instructions per ray, 1 % of a primary ray).
pub struct Stack {
    entries: MaybeUninit<[u64; STACK]>,
    len: usize,
}

impl Stack {
    /// An empty stack.
    #[inline(always)]
    pub fn new() -> Self {
        // Built field by field: a struct literal with an uninitialized field is still zeroed
        // whole (one `memset`).
        let mut stack = MaybeUninit::<Self>::uninit();
        // SAFETY: `len` is written; `entries` may stay uninitialized (it is a `MaybeUninit`).
        unsafe {
            std::ptr::addr_of_mut!((*stack.as_mut_ptr()).len).write(0);
            stack.assume_init()
        }
    }

    /// True when no entry is left.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Pushes an entry; when full, the last entry is overwritten (obvhs's `StackStack` does the
    /// same; the depth bound above keeps it from happening).
    #[inline(always)]
    pub fn push(&mut self, entry: u64) {
        // SAFETY: the index is below `STACK`; writing through the pointer reads nothing.
        unsafe {
            self.entries
                .as_mut_ptr()
                .cast::<u64>()
                .add(self.len % STACK)
                .write(entry)
        };
        self.len = (self.len + 1).min(STACK - 1);
    }

    /// Pops the last entry pushed; the stack must not be empty.
    #[inline(always)]
    pub fn pop(&mut self) -> u64 {
        self.len -= 1;
        // SAFETY: every entry below `len` was written by `push` (`len` grows only there, by at
        // most one past the entry written).
        unsafe {
            self.entries
                .as_ptr()
                .cast::<u64>()
                .add(self.len % STACK)
                .read()
        }
    }
}

/// The slots of `node`'s children that `mask` (the node test's, obvhs's layout: an inner child
/// as bit `24 + (s ^ oct)`, a leaf as its primitives' bits) has hit, slot `s` as bit `s ^ oct`:
/// the highest bit nearest.
#[inline(always)]
fn hit_children(node: &CwBvhNode, mask: u32, oct: u32) -> u32 {
    let mut order = mask >> 24;
    for (s, &meta) in node.child_meta.iter().enumerate() {
        let leaf = meta != 0 && meta & 0x18 != 0x18;
        if leaf && mask >> (meta & 0x1f) & 1 != 0 {
            order |= 1 << (s as u32 ^ oct);
        }
    }
    order
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
    stack.push(0);
    while stack.len > floor {
        let entry = stack.pop();
        if let Some(prims) = leaf_prims(entry) {
            for i in prims.rev() {
                if leaf(i, ray, stack) {
                    stack.len = floor;
                    return true;
                }
            }
            continue;
        }
        let node = &nodes[entry as usize];
        let mask = test(node, ray, oct_inv4);
        // Pushed farthest first, so that the nearest is taken first.
        let imask = u32::from(node.imask);
        let mut order = hit_children(node, mask, oct);
        while order != 0 {
            let i = order.trailing_zeros();
            order &= order - 1;
            stack.push(child_entry(node, i ^ oct, imask));
        }
    }
    false
}
