//! The walk down one CWBVH8 with a packet of rays at once: a node is entered when any active ray
//! enters it, and each ray keeps the mask of the children it enters.
//!
//! Every ray of a packet has the same direction octant, so the children are taken in one order
//! for all of them: the order [`super::walk::walk`] gives each one. The walk is a depth-first
//! pre-order over the tree: at a node, the primitives of its hit leaves (highest primitive bit
//! first), then its hit inner children (nearest slot first), each with the rays that entered it.
//! A ray's node tests see its `tmax` as lowered by the primitives it visited before, and a ray
//! visits a node's children with the mask computed when the node was tested, as in the single-ray
//! walk. So each ray visits exactly the primitives, in exactly the order and under exactly the
//! `tmax`, that [`super::walk::walk`] gives it alone (`bvh::tests` compares them visit by visit).
//! What a packet shares is the node: its fetch, the decoding of its 48 plane bytes and its child
//! layout; each ray's test is then about 30 instructions instead of 85.

use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray;

/// Most rays in one packet: one bit each of a [`Mask`].
pub const PACKET: usize = 64;

/// A set of rays of a packet, bit `k` for ray `k`.
pub type Mask = u64;

/// The rays of `m`, lowest first.
#[inline(always)]
pub fn rays_of(mut m: Mask) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let k = m.trailing_zeros() as usize;
            m &= m - 1;
            k
        })
    })
}

/// Groups of children still to visit: a node and the rays that entered it.
pub type PacketStack = Vec<(u32, Mask)>;

/// True when a child's meta byte names an inner node (bits 3 and 4 set: its slot plus 24).
#[inline(always)]
fn is_inner(meta: u8) -> bool {
    meta & 0x18 == 0x18
}

/// Walks `nodes` (empty, or a CWBVH8 whose root is node 0) with the rays of `active`, all of
/// direction octant code `oct_inv4`: `test(node, rays, m, entered)` sets bit `k` of `entered[s]`
/// for each ray `k` of `m` that enters the child in slot `s` (a non-empty one), and
/// `leaf(i, m, rays)` is called for every primitive `i` of the leaves hit with the rays `m` that
/// hit it, and may lower their `tmax`. The entries the walk pushes on `stack` are gone when it
/// returns.
#[inline(always)]
pub fn walk_packet(
    nodes: &[CwBvhNode],
    rays: &mut [Ray],
    active: Mask,
    oct_inv4: u32,
    stack: &mut PacketStack,
    test: impl Fn(&CwBvhNode, &[Ray], Mask, &mut [Mask; 8]),
    mut leaf: impl FnMut(u32, Mask, &mut [Ray], &mut PacketStack),
) {
    if nodes.is_empty() || active == 0 {
        return;
    }
    let floor = stack.len();
    let oct = oct_inv4 & 7;
    stack.push((0, active));
    while stack.len() > floor {
        let Some((n, m)) = stack.pop() else { break };
        let node = &nodes[n as usize];
        let mut entered = [0; 8];
        test(node, rays, m, &mut entered);
        // The rays of each primitive bit, as the single-ray mask has them.
        let mut prim_rays = [0; 24];
        let mut prims = 0u32;
        for (s, &e) in entered.iter().enumerate() {
            let meta = node.child_meta[s];
            if e == 0 || is_inner(meta) {
                continue;
            }
            let at = u32::from(meta & 0x1f);
            let count = (meta >> 5).count_ones();
            for j in at..(at + count).min(24) {
                prim_rays[j as usize] = e;
            }
            prims |= u32::from(meta >> 5) << at;
        }
        while prims != 0 {
            let j = 31 - prims.leading_zeros();
            prims &= !(1 << j);
            leaf(
                node.primitive_base_idx + j,
                prim_rays[j as usize],
                rays,
                stack,
            );
        }
        // Inner children nearest first: pushed in the reverse order.
        let imask = u32::from(node.imask);
        for i in 0..8 {
            let s = i ^ oct;
            let e = entered[s as usize];
            if e != 0 && imask >> s & 1 != 0 {
                let child = node.child_base_idx + (imask & !(u32::MAX << s)).count_ones();
                stack.push((child, e));
            }
        }
    }
    stack.truncate(floor);
}

/// The packet node test on any CPU: obvhs's own test per ray, its mask read back per slot.
#[inline(always)]
pub fn children_portable(
    node: &CwBvhNode,
    rays: &[Ray],
    m: Mask,
    oct_inv4: u32,
    entered: &mut [Mask; 8],
) {
    // The bit of each non-empty child in obvhs's mask: any of a leaf's primitive bits (all set
    // or none), an inner child's slot bit.
    let mut bit = [0u32; 8];
    for (s, b) in bit.iter_mut().enumerate() {
        let meta = node.child_meta[s];
        *b = if meta == 0 {
            0
        } else if is_inner(meta) {
            1 << (24 + (s as u32 ^ (oct_inv4 & 7)))
        } else {
            1 << (meta & 0x1f)
        };
    }
    for k in rays_of(m) {
        let hits = node.intersect_ray(&rays[k], oct_inv4);
        for (e, b) in entered.iter_mut().zip(bit) {
            if hits & b != 0 {
                *e |= 1 << k;
            }
        }
    }
}

/// The packet node test with AVX2: for each ray, the eight children at once, computed exactly as
/// [`super::node_test::Avx2Ray::hits`] computes them, with the node's planes decoded once for
/// the packet, the near and far planes chosen by the packet's octant once, and each ray's origin
/// and inverse direction already in all eight lanes.
#[cfg(target_arch = "x86_64")]
pub struct Avx2Packet<'a> {
    /// Per axis, whether the rays go down it (their near planes are the high ones).
    down: [bool; 3],
    /// The packet's rays' lanes, written for the rays of `rays` only.
    lanes: &'a Avx2Lanes,
    rays: Mask,
}

/// Per ray of a packet: its origin's and its inverse direction's coordinates, each in all eight
/// lanes; written for the packet's rays only (the rest is never read, nor zeroed).
#[cfg(target_arch = "x86_64")]
pub type Avx2Lanes = [std::mem::MaybeUninit<[std::arch::x86_64::__m256; 6]>; PACKET];

/// From this many rays at a node on, their child masks are transposed into the packet's with
/// byte shifts over all rays at once rather than bit by bit.
#[cfg(target_arch = "x86_64")]
const TRANSPOSE_FROM: u32 = 4;

#[cfg(target_arch = "x86_64")]
impl<'a> Avx2Packet<'a> {
    /// The test for the rays `m` of `rays`, of direction octant code `oct_inv4`, with their
    /// lanes written into `lanes`.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn new(lanes: &'a mut Avx2Lanes, rays: &[Ray], m: Mask, oct_inv4: u32) -> Self {
        use std::arch::x86_64::*;
        for k in rays_of(m) {
            let (o, inv) = (rays[k].origin, rays[k].inv_direction);
            lanes[k].write([o.x, o.y, o.z, inv.x, inv.y, inv.z].map(|x| _mm256_set1_ps(x)));
        }
        Self {
            down: [oct_inv4 & 4 == 0, oct_inv4 & 2 == 0, oct_inv4 & 1 == 0],
            lanes,
            rays: m,
        }
    }

    /// Sets bit `k` of `entered[s]` for each ray `k` of `m` that enters the non-empty child in
    /// slot `s` of `node`. Panics unless `m` is a subset of the packet's rays.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn children(&self, node: &CwBvhNode, rays: &[Ray], m: Mask, entered: &mut [Mask; 8]) {
        use std::arch::x86_64::*;
        let q = |b: &[u8; 8]| {
            _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_cvtsi64_si128(
                u64::from_le_bytes(*b) as i64,
            )))
        };
        let pick = |down: bool, lo: &[u8; 8], hi: &[u8; 8]| {
            if down {
                (q(hi), q(lo))
            } else {
                (q(lo), q(hi))
            }
        };
        let (nx, fx) = pick(self.down[0], &node.child_min_x, &node.child_max_x);
        let (ny, fy) = pick(self.down[1], &node.child_min_y, &node.child_max_y);
        let (nz, fz) = pick(self.down[2], &node.child_min_z, &node.child_max_z);
        let meta = u64::from_le_bytes(node.child_meta);
        let mut used = 0u32;
        for s in 0..8 {
            used |= u32::from(meta >> (8 * s) & 0xff != 0) << s;
        }
        let extent = node.compute_extent();
        let e = [extent.x, extent.y, extent.z].map(|x| _mm256_set1_ps(x));
        let p = node.p;
        let p = [p.x, p.y, p.z].map(|x| _mm256_set1_ps(x));
        let t_min = _mm256_set1_ps(super::T_MIN);
        // The children each ray enters: `Vec3A`'s lane-wise products and differences, so each
        // value is the one the single-ray test computes.
        let hits = |k: usize| {
            assert!(self.rays >> k & 1 != 0, "ray {k} is not in the packet");
            // SAFETY: `new` wrote the lanes of every ray of `self.rays`, checked just above.
            let l = unsafe { self.lanes[k].assume_init_ref() };
            let axis = |a: usize, near: __m256, far: __m256| {
                let scale = _mm256_mul_ps(e[a], l[3 + a]);
                let offset = _mm256_mul_ps(_mm256_sub_ps(p[a], l[a]), l[3 + a]);
                (
                    _mm256_add_ps(_mm256_mul_ps(near, scale), offset),
                    _mm256_add_ps(_mm256_mul_ps(far, scale), offset),
                )
            };
            let (x0, x1) = axis(0, nx, fx);
            let (y0, y1) = axis(1, ny, fy);
            let (z0, z1) = axis(2, nz, fz);
            let t0 = _mm256_max_ps(x0, _mm256_max_ps(y0, z0));
            let t1 = _mm256_min_ps(x1, _mm256_min_ps(y1, z1));
            let t0 = _mm256_max_ps(t0, t_min);
            let t1 = _mm256_min_ps(t1, _mm256_set1_ps(rays[k].tmax));
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OS>(t0, t1)) as u32 & used
        };
        if m.count_ones() < TRANSPOSE_FROM {
            for k in rays_of(m) {
                let mut h = hits(k);
                while h != 0 {
                    let s = h.trailing_zeros() as usize;
                    h &= h - 1;
                    entered[s] |= 1 << k;
                }
            }
            return;
        }
        // One byte per ray, then bit `s` of every byte shifted to the top and gathered.
        let mut bytes = [_mm256_setzero_si256(); 2];
        {
            // SAFETY: `bytes` is 64 bytes, plain integers; `k < PACKET = 64`.
            let b = unsafe { &mut *(bytes.as_mut_ptr() as *mut [u8; PACKET]) };
            for k in rays_of(m) {
                b[k] = hits(k) as u8;
            }
        }
        for (s, entered) in entered.iter_mut().enumerate() {
            if used >> s & 1 == 0 {
                continue;
            }
            let shift = _mm_cvtsi32_si128(7 - s as i32);
            let lo = _mm256_movemask_epi8(_mm256_sll_epi16(bytes[0], shift)) as u32;
            let hi = _mm256_movemask_epi8(_mm256_sll_epi16(bytes[1], shift)) as u32;
            *entered |= u64::from(lo) | u64::from(hi) << 32;
        }
    }
}
