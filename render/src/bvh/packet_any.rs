//! The any-hit walk down one CWBVH8 with a packet of rays: [`walk_packet`]'s
//! walk, in which a ray leaves the walk as soon as a primitive ends it.
//!
//! A ray ended by a hit is dropped from every entry popped after it, so the nodes left on the
//! stack are tested for the rays still live only, an entry none of them entered is popped
//! without a test, and the walk stops when no ray is live. A node's hit children are taken
//! farthest first (slot `i ^ oct` for `i` from 0 up) and a leaf's primitives lowest first, the
//! reverse of the closest-hit walks: an occluder is rarely among the nearest voxels, those of
//! the surface the rays leave. Until it is ended, a ray visits the primitives
//! [`super::packet::walk_packet`] gives it, in another order: a ray's entries do not depend on
//! the other rays of the packet, and with `tmax` never lowered, the order does not change which
//! primitives a ray reaches.

use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray;

use super::packet::{walk_packet, xor_slots, Mask, PacketStack};
use super::walk::{child_entry, leaf_prims};

/// Walks `nodes` (empty, or a CWBVH8 whose root is node 0) with the rays of `active`, children
/// taken farthest first in the order of direction octant code `oct_inv4`: `test(node, rays, m,
/// entered)` is
/// [`super::packet::walk_packet`]'s node test, and `leaf(i, m, rays, stack)` is called for
/// every primitive `i` of the leaves hit with the rays `m` that hit it and are still live, and
/// returns the rays of `m` it ends (none of them visits anything more). Returns the rays of
/// `active` ended. The entries the walk pushes on `stack` are gone when it returns.
#[inline(always)]
pub fn walk_packet_any(
    nodes: &[CwBvhNode],
    rays: &mut [Ray],
    active: Mask,
    oct_inv4: u32,
    stack: &mut PacketStack,
    test: impl Fn(&CwBvhNode, &[Ray], Mask, &mut [Mask; 8]) -> u32,
    mut leaf: impl FnMut(u32, Mask, &mut [Ray], &mut PacketStack) -> Mask,
) -> Mask {
    if nodes.is_empty() || active == 0 {
        return 0;
    }
    let floor = stack.len();
    // Pushed nearest first, so that the farthest is taken first.
    let far = !oct_inv4 & 7;
    let mut live = active;
    stack.push((0, active));
    while stack.len() > floor {
        let Some((entry, m)) = stack.pop() else { break };
        let m = m & live;
        if m == 0 {
            continue;
        }
        if let Some(prims) = leaf_prims(entry) {
            for i in prims {
                let m = m & live;
                if m == 0 {
                    break;
                }
                live &= !leaf(i, m, rays, stack);
            }
            if live == 0 {
                break;
            }
            continue;
        }
        let node = &nodes[entry as usize];
        let mut entered = [0; 8];
        let hit = test(node, rays, m, &mut entered);
        let imask = u32::from(node.imask);
        let mut order = xor_slots(hit, far);
        while order != 0 {
            let s = order.trailing_zeros() ^ far;
            order &= order - 1;
            stack.push((child_entry(node, s, imask), entered[s as usize]));
        }
    }
    stack.truncate(floor);
    active & !live
}

/// [`walk_packet_any`] when `ANY`, else [`super::packet::walk_packet`], whose `leaf` ends no
/// ray (what it returns is ignored, and none are returned ended).
#[inline(always)]
pub fn walk_packet_of<const ANY: bool>(
    nodes: &[CwBvhNode],
    rays: &mut [Ray],
    active: Mask,
    oct_inv4: u32,
    stack: &mut PacketStack,
    test: impl Fn(&CwBvhNode, &[Ray], Mask, &mut [Mask; 8]) -> u32,
    mut leaf: impl FnMut(u32, Mask, &mut [Ray], &mut PacketStack) -> Mask,
) -> Mask {
    if ANY {
        return walk_packet_any(nodes, rays, active, oct_inv4, stack, test, leaf);
    }
    walk_packet(
        nodes,
        rays,
        active,
        oct_inv4,
        stack,
        test,
        |i, m, rays, stack| {
            leaf(i, m, rays, stack);
        },
    );
    0
}
