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
use super::walk::{child_entry, leaf_prims, Stack};

/// Walks `nodes` (empty, or a CWBVH8 whose root is node 0) with the rays of `active`, children
/// taken farthest first in the order of direction octant code `oct_inv4`: `test(node, rays, m,
/// entered)` is
/// [`super::packet::walk_packet`]'s node test, `test_one(node, ray)` the same test for a node
/// reached by one live ray `ray` (the slots it enters, no masks: every child is entered by that
/// ray alone), and `leaf(i, m, rays, stack)` is called for
/// every primitive `i` of the leaves hit with the rays `m` that hit it and are still live, and
/// returns the rays of `m` it ends (none of them visits anything more). Returns the rays of
/// `active` ended. The entries the walk pushes on `stack` are gone when it returns.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn walk_packet_any(
    nodes: &[CwBvhNode],
    rays: &mut [Ray],
    active: Mask,
    oct_inv4: u32,
    stack: &mut PacketStack,
    test: impl Fn(&CwBvhNode, &[Ray], Mask, &mut [Mask; 8]) -> u32,
    test_one: impl Fn(&CwBvhNode, &Ray) -> u32,
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
        if m & (m - 1) == 0 {
            if walk_lone(nodes, entry, m, far, rays, stack, &test_one, &mut leaf) {
                live &= !m;
                if live == 0 {
                    break;
                }
            }
            continue;
        }
        let node = &nodes[entry as usize];
        let imask = u32::from(node.imask);
        let mut entered = [0; 8];
        let hit = test(node, rays, m, &mut entered);
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

/// [`walk_packet_any`]'s walk below the inner node `entry` reached by the one live ray `m`: the
/// nodes and primitives the packet walk would take there, in the same order (the entries a node
/// pushes are popped before any entry below them, in both walks), on a stack of bare entries
/// (every one is the ray's alone). True when `leaf` ends the ray, which stops the walk.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn walk_lone(
    nodes: &[CwBvhNode],
    entry: u64,
    m: Mask,
    far: u32,
    rays: &mut [Ray],
    stack: &mut PacketStack,
    test_one: &impl Fn(&CwBvhNode, &Ray) -> u32,
    leaf: &mut impl FnMut(u32, Mask, &mut [Ray], &mut PacketStack) -> Mask,
) -> bool {
    let k = m.trailing_zeros() as usize;
    let mut lone = Stack::new();
    lone.push(entry);
    while !lone.is_empty() {
        let entry = lone.pop();
        if let Some(prims) = leaf_prims(entry) {
            for i in prims {
                if leaf(i, m, rays, stack) != 0 {
                    return true;
                }
            }
            continue;
        }
        let node = &nodes[entry as usize];
        let imask = u32::from(node.imask);
        let mut order = xor_slots(test_one(node, &rays[k]), far);
        while order != 0 {
            let s = order.trailing_zeros() ^ far;
            order &= order - 1;
            lone.push(child_entry(node, s, imask));
        }
    }
    false
}

/// [`walk_packet_any`] when `ANY`, else [`super::packet::walk_packet`] (which has no use for
/// `test_one`), whose `leaf` ends no ray (what it returns is ignored, and none are returned
/// ended).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn walk_packet_of<const ANY: bool>(
    nodes: &[CwBvhNode],
    rays: &mut [Ray],
    active: Mask,
    oct_inv4: u32,
    stack: &mut PacketStack,
    test: impl Fn(&CwBvhNode, &[Ray], Mask, &mut [Mask; 8]) -> u32,
    test_one: impl Fn(&CwBvhNode, &Ray) -> u32,
    mut leaf: impl FnMut(u32, Mask, &mut [Ray], &mut PacketStack) -> Mask,
) -> Mask {
    if ANY {
        return walk_packet_any(nodes, rays, active, oct_inv4, stack, test, test_one, leaf);
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

/// Below this many rays at a node, an any-hit packet of several direction octants tests the node
/// ray by ray for all its octants in one pass ([`children_of_octants`]); from it on, eight rays
/// at a time whatever their octants, after a cull by the rays' reach
/// ([`super::packet_mixed::MixedPacket`]). (callgrind, occlusion at 512x384 on the far 1e8-cell
/// view: 8, 16, 28, 40 and 52 rays tried, 40 least; before the mixed test, each octant's own
/// [`super::packet::Avx2Packet::children`] from 40 rays on, with the same threshold.)
#[cfg(target_arch = "x86_64")]
pub const OCTANTS_RAY_BY_RAY_BELOW: u32 = 40;

/// Sets bit `k` of `entered[s]` for each ray `k` of `m` (of `rays`, walked with positive zeros,
/// [`super::by_octant`], and whose direction octant's rays are `octants[o]`) that enters the
/// non-empty child in slot `s` of `node`, and returns the slots whose mask is then not empty:
/// [`super::packet::Avx2Packet::children`] of each octant's rays, ray by ray as it tests a few
/// rays, with the node's planes decoded once for all the octants. Each ray's
/// result is that test's, bit for bit: the same products, sums, `max` and `min`, in the same
/// operand order, of the same origin, inverse direction and `tmax`.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub fn children_of_octants(
    node: &CwBvhNode,
    rays: &[Ray],
    m: Mask,
    octants: &[Mask; 8],
    entered: &mut [Mask; 8],
) -> u32 {
    use std::arch::x86_64::*;
    let (lo, hi, used) = super::packet::child_planes(node);
    let extent = node.compute_extent();
    let e = [extent.x, extent.y, extent.z].map(|x| _mm256_set1_ps(x));
    let p = node.p;
    let p = [p.x, p.y, p.z].map(|x| _mm256_set1_ps(x));
    let mut any = 0;
    for (o, &of_o) in octants.iter().enumerate() {
        let m = m & of_o;
        if m == 0 {
            continue;
        }
        // The octant's near and far planes per axis (x, y, z): the high ones first along an
        // axis the rays go down.
        let planes = |a: usize, down: bool| if down { (hi[a], lo[a]) } else { (lo[a], hi[a]) };
        let near_far = [
            planes(0, o & 4 == 0),
            planes(1, o & 2 == 0),
            planes(2, o & 1 == 0),
        ];
        for k in super::packet::rays_of(m) {
            let r = &rays[k];
            let (o, inv) = (r.origin, r.inv_direction);
            let (o, inv) = ([o.x, o.y, o.z], [inv.x, inv.y, inv.z]);
            let axis = |a: usize| {
                let inv = _mm256_set1_ps(inv[a]);
                let scale = _mm256_mul_ps(e[a], inv);
                let offset = _mm256_mul_ps(_mm256_sub_ps(p[a], _mm256_set1_ps(o[a])), inv);
                let (near, far) = near_far[a];
                (
                    _mm256_add_ps(_mm256_mul_ps(near, scale), offset),
                    _mm256_add_ps(_mm256_mul_ps(far, scale), offset),
                )
            };
            let slabs = [axis(0), axis(1), axis(2)];
            any |= super::packet::enter_children(slabs, r.tmax, used, k, entered);
        }
    }
    any
}
