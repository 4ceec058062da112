//! The walk down one CWBVH8 with a packet of rays at once: a node is entered when any active ray
//! enters it, and each ray keeps the mask of the children it enters.
//!
//! Every ray of a packet has the same direction octant, so the children are taken in one order
//! for all of them: the order [`super::walk::walk`] gives each one. The walk is a depth-first
//! pre-order over the tree: at a node, its hit children nearest slot first, leaves and inner
//! nodes alike (a leaf's primitives highest first), each with the rays that entered it.
//! A ray's node tests see its `tmax` as lowered by the primitives it visited before, and a ray
//! visits a node's children with the mask computed when the node was tested, as in the single-ray
//! walk. So each ray visits exactly the primitives, in exactly the order and under exactly the
//! `tmax`, that [`super::walk::walk`] gives it alone (`bvh::tests` compares them visit by visit).
//! What a packet shares is the node: its fetch, the decoding of its 48 plane bytes and its child
//! layout, and with AVX2 ([`Avx2Packet`]) a conservative cull of the children none of its rays
//! enters, and the test of each child left for eight rays at a time.

use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray;

use super::walk::{child_entry, leaf_prims};

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

/// The rays of `m` for which `keep` is true, as a mask.
#[inline(always)]
pub fn rays_where(m: Mask, mut keep: impl FnMut(usize) -> bool) -> Mask {
    rays_of(m)
        .filter(|&k| keep(k))
        .fold(0, |out, k| out | 1 << k)
}

/// Children still to visit: a node or a leaf ([`super::walk::child_entry`]) and the rays that
/// entered it.
pub type PacketStack = Vec<(u64, Mask)>;

/// True when a child's meta byte names an inner node (bits 3 and 4 set: its slot plus 24).
#[inline(always)]
fn is_inner(meta: u8) -> bool {
    meta & 0x18 == 0x18
}

/// Walks `nodes` (empty, or a CWBVH8 whose root is node 0) with the rays of `active`, all of
/// direction octant code `oct_inv4`: `test(node, rays, m, entered)` sets bit `k` of `entered[s]`
/// for each ray `k` of `m` that enters the child in slot `s` (a non-empty one) and returns the
/// slots whose mask is then not empty, and
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
    test: impl Fn(&CwBvhNode, &[Ray], Mask, &mut [Mask; 8]) -> u32,
    mut leaf: impl FnMut(u32, Mask, &mut [Ray], &mut PacketStack),
) {
    if nodes.is_empty() || active == 0 {
        return;
    }
    let floor = stack.len();
    let oct = oct_inv4 & 7;
    stack.push((0, active));
    while stack.len() > floor {
        let Some((entry, m)) = stack.pop() else { break };
        if let Some(prims) = leaf_prims(entry) {
            for i in prims.rev() {
                leaf(i, m, rays, stack);
            }
            continue;
        }
        let node = &nodes[entry as usize];
        let mut entered = [0; 8];
        let hit = test(node, rays, m, &mut entered);
        // The children nearest first, as [`super::walk::walk`] takes them: pushed in the
        // reverse order, slot `i ^ oct` for `i` from 0 up.
        let imask = u32::from(node.imask);
        let mut order = xor_slots(hit, oct);
        while order != 0 {
            let s = order.trailing_zeros() ^ oct;
            order &= order - 1;
            stack.push((child_entry(node, s, imask), entered[s as usize]));
        }
    }
    stack.truncate(floor);
}

/// The slot set `slots` (bit `s` for slot `s`) with each slot `s` moved to `s ^ oct` (`oct < 8`).
#[inline(always)]
pub(super) fn xor_slots(mut slots: u32, oct: u32) -> u32 {
    if oct & 1 != 0 {
        slots = (slots & 0x55) << 1 | (slots >> 1) & 0x55;
    }
    if oct & 2 != 0 {
        slots = (slots & 0x33) << 2 | (slots >> 2) & 0x33;
    }
    if oct & 4 != 0 {
        slots = (slots & 0x0f) << 4 | (slots >> 4) & 0x0f;
    }
    slots
}

/// The packet node test on any CPU: obvhs's own test per ray, its mask read back per slot.
#[inline(always)]
pub fn children_portable(
    node: &CwBvhNode,
    rays: &[Ray],
    m: Mask,
    oct_inv4: u32,
    entered: &mut [Mask; 8],
) -> u32 {
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
    let mut slots = 0;
    for (s, &e) in entered.iter().enumerate() {
        slots |= u32::from(e != 0) << s;
    }
    slots
}

/// [`children_portable`] of one ray: the slots of the children it enters.
#[inline(always)]
pub fn ray_children_portable(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    children_portable(node, std::slice::from_ref(ray), 1, oct_inv4, &mut [0; 8])
}

/// The packet node test with AVX2: the rays of a packet in groups of eight (rays `8g..8g + 8`),
/// one ray per lane, so that one pass over a group tests a child for eight rays, and its result
/// is already the group's byte of the child's ray mask (no transposition). Each lane computes
/// exactly what [`super::node_test::Avx2Ray::hits`] computes for its ray and that child: the
/// same products, sums, `max` and `min` in the same operand order. A node's planes are decoded
/// once for the packet, the near and far planes chosen by the packet's octant once, and each
/// group's scale, offset and `tmax` once per node; only the groups holding a ray that entered
/// the node and only the node's non-empty children are tested.
///
/// Before that, the children that no ray of those groups can enter are culled for all of them
/// at once, by interval arithmetic: the groups' origins and inverse directions lie in a box,
/// which bounds each child's entry distance from below and its exit distance from above; a
/// child whose bounds, widened by far more than the rounding of either computation (see
/// [`CULL_MARGIN`]), leave no room for an entry is not tested. The cull is conservative: every
/// child a ray enters is still tested, so the masks are the per-ray test's exactly.
#[cfg(target_arch = "x86_64")]
pub struct Avx2Packet<'a> {
    /// Per axis, whether the rays go down it (their near planes are the high ones).
    down: [bool; 3],
    /// The packet's groups' lanes, written for the groups holding a ray of `rays` only.
    lanes: &'a Avx2Lanes,
    rays: Mask,
    /// How many rays the packet's slice holds.
    len: usize,
}

/// Per group of eight rays of a packet: the coordinates of its rays' origins (x, y, z) and
/// inverse directions, one ray per lane, with zeros in the lanes of the rays not in the packet;
/// then the smallest and the largest of each of these coordinates over the group's rays in the
/// packet (origin x, y, z in lanes 0 to 2, inverse direction x, y, z in lanes 4 to 6). Written
/// for the groups holding one of the packet's rays only (the rest is never read, nor zeroed).
#[cfg(target_arch = "x86_64")]
pub type Avx2Lanes = [std::mem::MaybeUninit<[std::arch::x86_64::__m256; 8]>; PACKET / 8];

/// The margin of the interval cull, relative to a bound `B` of the terms of a distance along an
/// axis (the origin's distance to the node's corner plus 256 node extents, times the largest
/// inverse direction): `2^-18 B`. The node test's distance `q * (e * inv) + (p - o) * inv`
/// rounds four times, the cull's `((p - o) + q * e) * inv` three times (`e * inv` and `q * e`
/// are exact: `e` is a power of two), each time by at most `2^-24` of a value no larger than
/// `B`; so the two differ by less than `2^-21 B`, and the margin is eight times that.
const CULL_MARGIN: f32 = 1.0 / (1 << 18) as f32;

/// From this many rays at a node on, the node is tested group by group (with the cull); below,
/// ray by ray, each ray's eight children at once, which costs less than the cull and the
/// groups' set-up when the rays are few (callgrind, far view of the 1e8-cell file).
#[cfg(target_arch = "x86_64")]
const GROUPS_FROM: u32 = 12;

/// The rays of the groups of eight whose byte of `m` is not empty, lowest group first: its
/// index and its byte.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn groups_of(m: Mask) -> impl Iterator<Item = (usize, u32)> {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of x86_64.
    let empty = unsafe {
        _mm_movemask_epi8(_mm_cmpeq_epi8(
            _mm_cvtsi64_si128(m as i64),
            _mm_setzero_si128(),
        ))
    };
    let mut bytes = !empty as u32 & 0xff;
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
            let (mut lo, mut hi) = (
                _mm256_set1_ps(f32::INFINITY),
                _mm256_set1_ps(f32::NEG_INFINITY),
            );
            for j in rays_of(u64::from(byte)) {
                let r = &rays[8 * g + j];
                let (o, inv) = (r.origin, r.inv_direction);
                for (a, x) in [o.x, o.y, o.z, inv.x, inv.y, inv.z].into_iter().enumerate() {
                    v[a][j] = x;
                }
                let both = _mm256_set_m128(inv.into(), o.into());
                lo = _mm256_min_ps(lo, both);
                hi = _mm256_max_ps(hi, both);
            }
            // SAFETY: `v[a]` is eight `f32`s; the load is unaligned.
            let v = v.map(|x| unsafe { _mm256_loadu_ps(x.as_ptr()) });
            lanes[g].write([v[0], v[1], v[2], v[3], v[4], v[5], lo, hi]);
        }
        assert!(
            rays.len() >= PACKET || m >> rays.len() == 0,
            "rays {m:#x} of a packet of {}",
            rays.len()
        );
        Self {
            down: [oct_inv4 & 4 == 0, oct_inv4 & 2 == 0, oct_inv4 & 1 == 0],
            lanes,
            rays: m,
            len: rays.len(),
        }
    }

    /// Sets bit `k` of `entered[s]` for each ray `k` of `m` that enters the non-empty child in
    /// slot `s` of `node`, and returns the slots whose mask is then not empty. Panics unless `m`
    /// is a subset of the packet's rays and `rays` is the packet's slice.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn children(
        &self,
        node: &CwBvhNode,
        rays: &[Ray],
        m: Mask,
        entered: &mut [Mask; 8],
    ) -> u32 {
        use std::arch::x86_64::*;
        assert!(
            m & !self.rays == 0 && rays.len() == self.len,
            "rays {m:#x} are not all in the packet"
        );
        let (low, high, used) = child_planes(node);
        let pick = |a: usize| match self.down[a] {
            true => (high[a], low[a]),
            false => (low[a], high[a]),
        };
        let ((nx, fx), (ny, fy), (nz, fz)) = (pick(0), pick(1), pick(2));
        if m.count_ones() < GROUPS_FROM {
            return self.ray_by_ray(node, rays, m, [nx, fx, ny, fy, nz, fz], used, entered);
        }
        // The box of the origins and inverse directions of the groups of `m`, and each group's
        // rays' `tmax` (zero in the lanes of the rays not in `m`).
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let stride = (std::mem::size_of::<Ray>() / 4) as i32;
        let index = _mm256_mullo_epi32(
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
            _mm256_set1_epi32(stride),
        );
        let (mut lo, mut hi) = (
            _mm256_set1_ps(f32::INFINITY),
            _mm256_set1_ps(f32::NEG_INFINITY),
        );
        let mut tmax = [std::mem::MaybeUninit::<__m256>::uninit(); PACKET / 8];
        let mut tmax_hi = _mm256_setzero_ps();
        for (g, byte) in groups_of(m) {
            // SAFETY: `new` wrote the lanes of every group holding a ray of `self.rays`, and
            // `m` is a subset of it (checked above).
            let l = unsafe { self.lanes[g].assume_init_ref() };
            lo = _mm256_min_ps(lo, l[6]);
            hi = _mm256_max_ps(hi, l[7]);
            let in_group = _mm256_cmpeq_epi32(
                _mm256_and_si256(_mm256_set1_epi32(byte as i32), lane_bits),
                lane_bits,
            );
            // SAFETY: the gather reads only the lanes of the group's rays of `m`, each the
            // `tmax` of a ray of `rays` (checked above); `8 * g` is at most the index of one.
            let t = unsafe {
                let base = rays.as_ptr().add(8 * g).cast::<u8>();
                let base = base.add(std::mem::offset_of!(Ray, tmax)).cast::<f32>();
                _mm256_mask_i32gather_ps::<4>(
                    _mm256_setzero_ps(),
                    base,
                    index,
                    _mm256_castsi256_ps(in_group),
                )
            };
            tmax[g].write(t);
            tmax_hi = _mm256_max_ps(tmax_hi, t);
        }
        let mut slots = used & !self.culled(node, [nx, fx, ny, fy, nz, fz], lo, hi, tmax_hi);
        if slots == 0 {
            return 0;
        }
        // Each child left: its slot and its planes, each in all eight lanes.
        let mut left = [const { std::mem::MaybeUninit::<([__m256; 6], usize)>::uninit() }; 8];
        let mut count = 0;
        while slots != 0 {
            let s = slots.trailing_zeros();
            slots &= slots - 1;
            let at = _mm256_set1_epi32(s as i32);
            let lane = |v: __m256| _mm256_permutevar8x32_ps(v, at);
            left[count].write((
                [lane(nx), lane(fx), lane(ny), lane(fy), lane(nz), lane(fz)],
                s as usize,
            ));
            count += 1;
        }
        // SAFETY: the first `count` entries were written just above.
        let left = unsafe {
            std::slice::from_raw_parts(left.as_ptr().cast::<([__m256; 6], usize)>(), count)
        };
        let extent = node.compute_extent();
        let e = [extent.x, extent.y, extent.z].map(|x| _mm256_set1_ps(x));
        let p = node.p;
        let p = [p.x, p.y, p.z].map(|x| _mm256_set1_ps(x));
        let t_min = _mm256_set1_ps(super::T_MIN);
        for (g, byte) in groups_of(m) {
            // SAFETY: as above.
            let l = unsafe { self.lanes[g].assume_init_ref() };
            // Each axis's scale and offset: `Vec3A`'s lane-wise products and differences, so
            // each lane's value is the one the single-ray test computes for its ray.
            let scale = [0, 1, 2].map(|a| _mm256_mul_ps(e[a], l[3 + a]));
            let offset = [0, 1, 2].map(|a| _mm256_mul_ps(_mm256_sub_ps(p[a], l[a]), l[3 + a]));
            for (planes, s) in left {
                let axis = |a: usize| {
                    (
                        _mm256_add_ps(_mm256_mul_ps(planes[2 * a], scale[a]), offset[a]),
                        _mm256_add_ps(_mm256_mul_ps(planes[2 * a + 1], scale[a]), offset[a]),
                    )
                };
                let (x0, x1) = axis(0);
                let (y0, y1) = axis(1);
                let (z0, z1) = axis(2);
                let t0 = _mm256_max_ps(x0, _mm256_max_ps(y0, z0));
                let t1 = _mm256_min_ps(x1, _mm256_min_ps(y1, z1));
                let t0 = _mm256_max_ps(t0, t_min);
                // SAFETY: written for each group of `m` above.
                let t1 = _mm256_min_ps(t1, unsafe { tmax[g].assume_init() });
                let lanes = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OS>(t0, t1)) as u32;
                entered[s & 7] |= Mask::from(lanes & byte) << (8 * g);
            }
        }
        entered_slots(left, entered)
    }

    /// [`Avx2Packet::children`] one ray at a time, the eight children in the lanes, given the
    /// node's near and far planes `q` (x near, x far, y near, ...) and its non-empty slots
    /// `used`: each lane computes what [`super::node_test::Avx2Ray::hits`] computes.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn ray_by_ray(
        &self,
        node: &CwBvhNode,
        rays: &[Ray],
        m: Mask,
        q: [std::arch::x86_64::__m256; 6],
        used: u32,
        entered: &mut [Mask; 8],
    ) -> u32 {
        use std::arch::x86_64::*;
        let extent = node.compute_extent();
        let e = [extent.x, extent.y, extent.z].map(|x| _mm256_set1_ps(x));
        let p = node.p;
        let p = [p.x, p.y, p.z].map(|x| _mm256_set1_ps(x));
        let mut any = 0;
        for k in rays_of(m) {
            // SAFETY: `new` wrote the lanes of every group holding a ray of `self.rays`, and
            // `m` is a subset of it (checked by the caller).
            let l = unsafe { self.lanes[k / 8].assume_init_ref() };
            // SAFETY: `l[a]` is eight `f32`s, and `k % 8` one of them.
            let lane = |a: usize| unsafe {
                _mm256_broadcast_ss(&*(l.as_ptr().add(a).cast::<f32>().add(k % 8)))
            };
            let (o, inv) = ([lane(0), lane(1), lane(2)], [lane(3), lane(4), lane(5)]);
            let axis = |a: usize| {
                let scale = _mm256_mul_ps(e[a], inv[a]);
                let offset = _mm256_mul_ps(_mm256_sub_ps(p[a], o[a]), inv[a]);
                (
                    _mm256_add_ps(_mm256_mul_ps(q[2 * a], scale), offset),
                    _mm256_add_ps(_mm256_mul_ps(q[2 * a + 1], scale), offset),
                )
            };
            let slabs = [axis(0), axis(1), axis(2)];
            any |= enter_children(slabs, rays[k].tmax, used, k, entered);
        }
        any
    }

    /// The children of `node` that no ray enters whose origin and inverse direction lie in the
    /// box `lo..=hi` (lanes 0 to 2: origin x, y, z; 4 to 6: inverse direction x, y, z) and
    /// whose `tmax` is at most the largest lane of `tmax_hi`, given the children's quantized
    /// near and far planes `q` (x near, x far, y near, ...), one child per lane: a bit per slot.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn culled(
        &self,
        node: &CwBvhNode,
        q: [std::arch::x86_64::__m256; 6],
        lo: std::arch::x86_64::__m256,
        hi: std::arch::x86_64::__m256,
        tmax_hi: std::arch::x86_64::__m256,
    ) -> u32 {
        use std::arch::x86_64::*;
        let extent = node.compute_extent();
        let (p, e) = (node.p, [extent.x, extent.y, extent.z]);
        let p = [p.x, p.y, p.z];
        // Per axis (lanes 0 to 2), the bound of the terms of a distance the margin is taken of.
        let abs = |v: __m128| _mm_andnot_ps(_mm_set1_ps(-0.0), v);
        let (o_lo, o_hi) = (_mm256_castps256_ps128(lo), _mm256_castps256_ps128(hi));
        let (i_lo, i_hi) = (
            _mm256_extractf128_ps::<1>(lo),
            _mm256_extractf128_ps::<1>(hi),
        );
        let pv = _mm_setr_ps(p[0], p[1], p[2], 0.0);
        let ev = _mm_setr_ps(e[0], e[1], e[2], 0.0);
        // The node's corner less the lowest and the highest origin.
        let (p_lo, p_hi) = (_mm_sub_ps(pv, o_lo), _mm_sub_ps(pv, o_hi));
        let reach = _mm_mul_ps(
            _mm_add_ps(
                _mm_max_ps(abs(p_lo), abs(p_hi)),
                _mm_mul_ps(ev, _mm_set1_ps(256.0)),
            ),
            _mm_max_ps(abs(i_lo), abs(i_hi)),
        );
        let margin = _mm_mul_ps(reach, _mm_set1_ps(CULL_MARGIN));
        let at = |v: __m256, i: i32| _mm256_permutevar8x32_ps(v, _mm256_set1_epi32(i));
        let wide = |v: __m128| _mm256_castps128_ps256(v);
        let mut t0 = _mm256_set1_ps(super::T_MIN);
        let mut t1 = _mm256_max_ps(tmax_hi, _mm256_permute2f128_ps::<1>(tmax_hi, tmax_hi));
        t1 = _mm256_max_ps(t1, _mm256_shuffle_ps::<0b01_00_11_10>(t1, t1));
        t1 = _mm256_max_ps(t1, _mm256_shuffle_ps::<0b10_11_00_01>(t1, t1));
        for a in 0..3 {
            let i = a as i32;
            let margin = at(wide(margin), i);
            // A plane's offset from an origin, as `(p - o) + q * e` (`q * e` is exact: `e` is a
            // power of two), so that it rounds relative to the offset, not to the coordinates.
            // Going up the axis, the earliest entry is from the highest origin and the latest
            // exit from the lowest; going down, the other way round. Over the inverse
            // directions, the extremes are at either end.
            let (po_near, po_far) = if self.down[a] {
                (p_lo, p_hi)
            } else {
                (p_hi, p_lo)
            };
            let e = _mm256_set1_ps(e[a]);
            let d_near = _mm256_add_ps(at(wide(po_near), i), _mm256_mul_ps(q[2 * a], e));
            let d_far = _mm256_add_ps(at(wide(po_far), i), _mm256_mul_ps(q[2 * a + 1], e));
            let (i_lo, i_hi) = (at(lo, 4 + i), at(hi, 4 + i));
            let enter = _mm256_min_ps(_mm256_mul_ps(d_near, i_lo), _mm256_mul_ps(d_near, i_hi));
            let exit = _mm256_max_ps(_mm256_mul_ps(d_far, i_lo), _mm256_mul_ps(d_far, i_hi));
            t0 = _mm256_max_ps(t0, _mm256_sub_ps(enter, margin));
            t1 = _mm256_min_ps(t1, _mm256_add_ps(exit, margin));
        }
        // An ordered comparison: a NaN anywhere culls nothing.
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(t0, t1)) as u32
    }
}

/// The non-empty children of `node` that `ray`, of direction octant code `oct_inv4`, enters:
/// a bit per slot. What [`Avx2Packet::children`] sets for a packet's lone ray, bit for bit (the
/// same products, sums, `max` and `min` in the same operand order), from the ray itself, with
/// no lanes and no per-child ray masks: the test of an any-hit walk's node reached by one ray
/// ([`super::packet_any::walk_packet_any`]).
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub fn ray_children(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    use std::arch::x86_64::*;
    let (low, high, used) = child_planes(node);
    // The near and far planes along an axis: the high ones first where the ray goes down it.
    let pick = |a: usize, up: u32| match oct_inv4 & up == 0 {
        true => (high[a], low[a]),
        false => (low[a], high[a]),
    };
    let near_far = [pick(0, 4), pick(1, 2), pick(2, 1)];
    let extent = node.compute_extent();
    let (e, p) = ([extent.x, extent.y, extent.z], node.p);
    let p = [p.x, p.y, p.z];
    let (o, inv) = (ray.origin, ray.inv_direction);
    let (o, inv) = ([o.x, o.y, o.z], [inv.x, inv.y, inv.z]);
    let axis = |a: usize| {
        let inv = _mm256_set1_ps(inv[a]);
        let scale = _mm256_mul_ps(_mm256_set1_ps(e[a]), inv);
        let offset = _mm256_mul_ps(
            _mm256_sub_ps(_mm256_set1_ps(p[a]), _mm256_set1_ps(o[a])),
            inv,
        );
        let (near, far) = near_far[a];
        (
            _mm256_add_ps(_mm256_mul_ps(near, scale), offset),
            _mm256_add_ps(_mm256_mul_ps(far, scale), offset),
        )
    };
    slab_hits([axis(0), axis(1), axis(2)], ray.tmax, used)
}

/// A node's children's boxes, one child per lane: their quantized low and high planes per axis
/// (x, y, z) as floats, and the slots that hold a child (a bit per slot).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn child_planes(
    node: &CwBvhNode,
) -> (
    [std::arch::x86_64::__m256; 3],
    [std::arch::x86_64::__m256; 3],
    u32,
) {
    use std::arch::x86_64::*;
    let q = |b: &[u8; 8]| {
        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_cvtsi64_si128(
            u64::from_le_bytes(*b) as i64,
        )))
    };
    let low = [&node.child_min_x, &node.child_min_y, &node.child_min_z].map(q);
    let high = [&node.child_max_x, &node.child_max_y, &node.child_max_z].map(q);
    let meta = _mm_cvtsi64_si128(u64::from_le_bytes(node.child_meta) as i64);
    let empty = _mm_movemask_epi8(_mm_cmpeq_epi8(meta, _mm_setzero_si128())) as u32;
    (low, high, !empty & 0xff)
}

/// The slots of `left` (children and their slots) that some ray entered (`entered`, a ray
/// mask per slot).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(super) fn entered_slots<T>(left: &[(T, usize)], entered: &[Mask; 8]) -> u32 {
    let mut hit = 0;
    for &(_, s) in left {
        hit |= u32::from(entered[s & 7] != 0) << s;
    }
    hit
}

/// The children (slots of `used`, one per lane) whose slabs `slabs` (per axis, the distances
/// along a ray to the children's near and far planes) the ray enters within `[T_MIN, tmax]`:
/// a bit per slot. The one slab test of the ray-by-ray node tests ([`enter_children`],
/// [`ray_children`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn slab_hits(
    slabs: [(std::arch::x86_64::__m256, std::arch::x86_64::__m256); 3],
    tmax: f32,
    used: u32,
) -> u32 {
    use std::arch::x86_64::*;
    let [(x0, x1), (y0, y1), (z0, z1)] = slabs;
    let t0 = _mm256_max_ps(x0, _mm256_max_ps(y0, z0));
    let t1 = _mm256_min_ps(x1, _mm256_min_ps(y1, z1));
    let t0 = _mm256_max_ps(t0, _mm256_set1_ps(super::T_MIN));
    let t1 = _mm256_min_ps(t1, _mm256_set1_ps(tmax));
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OS>(t0, t1)) as u32 & used
}

/// The children (slots of `used`) whose slabs `slabs` ray `k` enters ([`slab_hits`]): sets
/// bit `k` of their `entered` and returns them. The slab test of the ray-by-ray node tests of
/// several rays ([`Avx2Packet::children`]'s and [`super::packet_any::children_of_octants`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn enter_children(
    slabs: [(std::arch::x86_64::__m256, std::arch::x86_64::__m256); 3],
    tmax: f32,
    used: u32,
    k: usize,
    entered: &mut [Mask; 8],
) -> u32 {
    let hit = slab_hits(slabs, tmax, used);
    let mut h = hit;
    while h != 0 {
        let s = h.trailing_zeros() as usize;
        h &= h - 1;
        entered[s] |= 1 << k;
    }
    hit
}
