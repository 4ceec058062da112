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

/// The packet node test with AVX2: the rays of a packet in groups of eight (rays `8g..8g + 8`),
/// one ray per lane, so that one pass over a group tests a child for eight rays, and its result
/// is already the group's byte of the child's ray mask (no transposition). Each lane computes
/// exactly what [`super::node_test::Avx2Ray::hits`] computes for its ray and that child: the
/// same products, sums, `max` and `min` in the same operand order. A node's planes are decoded
/// once for the packet, the near and far planes chosen by the packet's octant once, and each
/// group's scale, offset and `tmax` once per node; only the groups holding a ray that entered
/// the node and only the node's non-empty children are tested.
#[cfg(target_arch = "x86_64")]
pub struct Avx2Packet<'a> {
    /// Per axis, whether the rays go down it (their near planes are the high ones).
    down: [bool; 3],
    /// The packet's groups' lanes, written for the groups holding a ray of `rays` only.
    lanes: &'a Avx2Lanes,
    rays: Mask,
}

/// Per group of eight rays of a packet: the coordinates of its rays' origins (x, y, z) and
/// inverse directions, one ray per lane; written for the groups holding one of the packet's rays
/// only (the rest is never read, nor zeroed), with zeros in the lanes of the rays not in it.
#[cfg(target_arch = "x86_64")]
pub type Avx2Lanes = [std::mem::MaybeUninit<[std::arch::x86_64::__m256; 6]>; PACKET / 8];

/// The rays of the groups of eight whose byte of `m` is not empty, lowest group first: its
/// index and its byte.
#[inline(always)]
fn groups_of(m: Mask) -> impl Iterator<Item = (usize, u32)> {
    let mut bytes = 0u32;
    for g in 0..PACKET / 8 {
        bytes |= u32::from(m >> (8 * g) & 0xff != 0) << g;
    }
    std::iter::from_fn(move || {
        (bytes != 0).then(|| {
            let g = bytes.trailing_zeros() as usize;
            bytes &= bytes - 1;
            (g, (m >> (8 * g) & 0xff) as u32)
        })
    })
}

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
        for (g, byte) in groups_of(m) {
            let mut v = [[0.0f32; 8]; 6];
            for j in rays_of(u64::from(byte)) {
                let r = &rays[8 * g + j];
                let (o, inv) = (r.origin, r.inv_direction);
                for (a, x) in [o.x, o.y, o.z, inv.x, inv.y, inv.z].into_iter().enumerate() {
                    v[a][j] = x;
                }
            }
            // SAFETY: `v[a]` is eight `f32`s; the load is unaligned.
            lanes[g].write(v.map(|x| unsafe { _mm256_loadu_ps(x.as_ptr()) }));
        }
        Self {
            down: [oct_inv4 & 4 == 0, oct_inv4 & 2 == 0, oct_inv4 & 1 == 0],
            lanes,
            rays: m,
        }
    }

    /// Sets bit `k` of `entered[s]` for each ray `k` of `m` that enters the non-empty child in
    /// slot `s` of `node`. Panics unless `m` is a subset of the packet's rays and of `rays`.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn children(&self, node: &CwBvhNode, rays: &[Ray], m: Mask, entered: &mut [Mask; 8]) {
        use std::arch::x86_64::*;
        assert!(
            m & !self.rays == 0 && (rays.len() >= PACKET || m >> rays.len() == 0),
            "rays {m:#x} are not all in the packet"
        );
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
        let meta = _mm_cvtsi64_si128(u64::from_le_bytes(node.child_meta) as i64);
        let empty = _mm_movemask_epi8(_mm_cmpeq_epi8(meta, _mm_setzero_si128())) as u32;
        let used = !empty & 0xff;
        let extent = node.compute_extent();
        let e = [extent.x, extent.y, extent.z].map(|x| _mm256_set1_ps(x));
        let p = node.p;
        let p = [p.x, p.y, p.z].map(|x| _mm256_set1_ps(x));
        let t_min = _mm256_set1_ps(super::T_MIN);
        // Per group of `m`: each axis's scale and offset (`Vec3A`'s lane-wise products and
        // differences, as the single-ray test computes them), its rays' `tmax`, its byte and
        // where that byte goes in a mask.
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let stride = (std::mem::size_of::<Ray>() / 4) as i32;
        let index = _mm256_mullo_epi32(
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
            _mm256_set1_epi32(stride),
        );
        let mut consts = [std::mem::MaybeUninit::<([__m256; 7], u32, u32)>::uninit(); PACKET / 8];
        let mut count = 0;
        for (g, byte) in groups_of(m) {
            // SAFETY: `new` wrote the lanes of every group holding a ray of `self.rays`, and
            // `m` is a subset of it (checked above).
            let l = unsafe { self.lanes[g].assume_init_ref() };
            let scale = |a: usize| _mm256_mul_ps(e[a], l[3 + a]);
            let offset = |a: usize| _mm256_mul_ps(_mm256_sub_ps(p[a], l[a]), l[3 + a]);
            let in_group = _mm256_cmpeq_epi32(
                _mm256_and_si256(_mm256_set1_epi32(byte as i32), lane_bits),
                lane_bits,
            );
            // SAFETY: the gather reads only the lanes of the group's rays of `m`, each the
            // `tmax` of a ray of `rays` (checked above); `8 * g` is at most the index of one.
            let tmax = unsafe {
                let base = rays.as_ptr().add(8 * g).cast::<u8>();
                let base = base.add(std::mem::offset_of!(Ray, tmax)).cast::<f32>();
                _mm256_mask_i32gather_ps::<4>(
                    _mm256_setzero_ps(),
                    base,
                    index,
                    _mm256_castsi256_ps(in_group),
                )
            };
            consts[count].write((
                [
                    scale(0),
                    scale(1),
                    scale(2),
                    offset(0),
                    offset(1),
                    offset(2),
                    tmax,
                ],
                byte,
                8 * g as u32,
            ));
            count += 1;
        }
        // SAFETY: the first `count` entries were written just above.
        let consts = unsafe {
            std::slice::from_raw_parts(consts.as_ptr().cast::<([__m256; 7], u32, u32)>(), count)
        };
        let mut slots = used;
        while slots != 0 {
            let s = slots.trailing_zeros();
            slots &= slots - 1;
            let at = _mm256_set1_epi32(s as i32);
            let lane = |v: __m256| _mm256_permutevar8x32_ps(v, at);
            let (nx, fx, ny, fy, nz, fz) =
                (lane(nx), lane(fx), lane(ny), lane(fy), lane(nz), lane(fz));
            let mut hit: Mask = 0;
            for (c, byte, shift) in consts {
                let axis = |near: __m256, far: __m256, a: usize| {
                    (
                        _mm256_add_ps(_mm256_mul_ps(near, c[a]), c[3 + a]),
                        _mm256_add_ps(_mm256_mul_ps(far, c[a]), c[3 + a]),
                    )
                };
                let (x0, x1) = axis(nx, fx, 0);
                let (y0, y1) = axis(ny, fy, 1);
                let (z0, z1) = axis(nz, fz, 2);
                let t0 = _mm256_max_ps(x0, _mm256_max_ps(y0, z0));
                let t1 = _mm256_min_ps(x1, _mm256_min_ps(y1, z1));
                let t0 = _mm256_max_ps(t0, t_min);
                let t1 = _mm256_min_ps(t1, c[6]);
                let lanes = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OS>(t0, t1)) as u32;
                hit |= Mask::from(lanes & byte) << shift;
            }
            entered[s as usize] |= hit;
        }
    }
}
