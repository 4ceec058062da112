//! The AVX2 node test of an any-hit packet whose rays go in several direction octants (ambient
//! occlusion rays), eight rays at a time whatever their octants, after a cull by the box the
//! rays can reach.
//!
//! Each lane picks its ray's near and far planes by its own octant (a blend), so one pass over
//! a group of eight rays serves all their octants; each lane computes exactly what
//! [`super::packet::Avx2Packet::children`] computes for its ray in its octant's test. The cull
//! first drops the children that lie outside the box of the rays' reaches (from each origin to
//! where its `tmax` can take the node test along each axis), widened by far more than the
//! rounding of the test: short rays (ambient occlusion's) reach few of a node's children.

use std::arch::x86_64::*;
use std::mem::MaybeUninit;

use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray;

use super::node_test::octant_inv4;
use super::packet::{child_planes, entered_slots, groups_of, rays_of, Mask, PACKET};

/// Per group of eight rays of a packet: origin x, y, z, inverse direction x, y, z, and per axis
/// a lane of all ones where the ray goes down the axis (its near planes are the high ones),
/// zeros in the lanes of the rays not in the packet. Written for the groups holding one of the
/// packet's rays only.
pub type MixedLanes = [MaybeUninit<[__m256; 9]>; PACKET / 8];

/// The margin of the reach cull, relative to a bound `B` of the terms of a plane's position
/// along an axis (the node's corner, 256 node extents, the largest origin and the largest
/// reach, in absolute value): `2^-18 B`. The node test's distance to a plane is within
/// `2^-21 B |inv|` of the exact one (as for [`super::packet::Avx2Packet`]'s cull), that is within
/// `2^-21 B` along the axis, and the cull's own sums round by less than `2^-22 B`.
const REACH_MARGIN: f32 = 1.0 / (1 << 18) as f32;

/// The node test of the rays of a packet of several direction octants.
pub struct MixedPacket<'a> {
    lanes: &'a MixedLanes,
    rays: Mask,
    /// How many rays the packet's slice holds.
    len: usize,
    /// Per axis (lanes 0 to 2), the least and the greatest point of the rays' reaches: each
    /// ray's origin `o` and `o + tmax / inv`.
    reach_lo: __m128,
    reach_hi: __m128,
    /// Per axis, the largest `|o| + |tmax / inv|` of the rays.
    span: __m128,
}

impl<'a> MixedPacket<'a> {
    /// The test for the rays `m` of `rays`, with their lanes written into `lanes`. A ray's
    /// octant is [`octant_inv4`] of its direction, which must have no `-0.0` (as after
    /// `super::by_octant`), and its `tmax` must not grow while the test is used.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn new(lanes: &'a mut MixedLanes, rays: &[Ray], m: Mask) -> Self {
        let (mut lo, mut hi) = (_mm_set1_ps(f32::INFINITY), _mm_set1_ps(f32::NEG_INFINITY));
        let mut span = _mm_setzero_ps();
        // Lanes where some ray's reach is not a number: no cull along that axis.
        let mut unknown = _mm_setzero_ps();
        let abs = |v: __m128| _mm_andnot_ps(_mm_set1_ps(-0.0), v);
        for (g, byte) in groups_of(m) {
            let mut v = [[0.0f32; 8]; 9];
            for j in rays_of(u64::from(byte)) {
                let r = &rays[8 * g + j];
                let (o, inv) = (r.origin, r.inv_direction);
                let oct = octant_inv4(r.direction);
                let down = |bit: u32| f32::from_bits(if oct & bit == 0 { !0 } else { 0 });
                let row = [
                    o.x,
                    o.y,
                    o.z,
                    inv.x,
                    inv.y,
                    inv.z,
                    down(4),
                    down(2),
                    down(1),
                ];
                for (a, x) in row.into_iter().enumerate() {
                    v[a][j] = x;
                }
                let (o, inv) = (__m128::from(o), __m128::from(inv));
                let reach = _mm_div_ps(_mm_set1_ps(r.tmax), inv);
                let end = _mm_add_ps(o, reach);
                let both = _mm_add_ps(end, _mm_add_ps(abs(o), abs(reach)));
                unknown = _mm_or_ps(unknown, _mm_cmpunord_ps(both, both));
                lo = _mm_min_ps(lo, _mm_min_ps(o, end));
                hi = _mm_max_ps(hi, _mm_max_ps(o, end));
                span = _mm_max_ps(span, _mm_add_ps(abs(o), abs(reach)));
            }
            // SAFETY: `v[a]` is eight `f32`s; the load is unaligned.
            lanes[g].write(v.map(|x| unsafe { _mm256_loadu_ps(x.as_ptr()) }));
        }
        assert!(
            rays.len() >= PACKET || m >> rays.len() == 0,
            "rays {m:#x} of a packet of {}",
            rays.len()
        );
        let lo = _mm_blendv_ps(lo, _mm_set1_ps(f32::NEG_INFINITY), unknown);
        let hi = _mm_blendv_ps(hi, _mm_set1_ps(f32::INFINITY), unknown);
        let span = _mm_blendv_ps(span, _mm_setzero_ps(), unknown);
        Self {
            lanes,
            rays: m,
            len: rays.len(),
            reach_lo: lo,
            reach_hi: hi,
            span,
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
        assert!(
            m & !self.rays == 0 && rays.len() == self.len,
            "rays {m:#x} are not all in the packet"
        );
        let (lo, hi, used) = child_planes(node);
        let extent = node.compute_extent();
        let (e, p) = ([extent.x, extent.y, extent.z], node.p);
        let p = [p.x, p.y, p.z];
        let mut slots = used & !self.outside_reach(&lo, &hi, e, p);
        if slots == 0 {
            return 0;
        }
        // Each child left: its slot and its low and high planes, each in all eight lanes (the
        // loop of `Avx2Packet::children`: a function for both was not inlined, +0.25 % on the
        // close-up frame).
        let mut left = [const { MaybeUninit::<([__m256; 6], usize)>::uninit() }; 8];
        let mut count = 0;
        while slots != 0 {
            let s = slots.trailing_zeros();
            slots &= slots - 1;
            let at = _mm256_set1_epi32(s as i32);
            let lane = |v: __m256| _mm256_permutevar8x32_ps(v, at);
            left[count].write((
                [
                    lane(lo[0]),
                    lane(hi[0]),
                    lane(lo[1]),
                    lane(hi[1]),
                    lane(lo[2]),
                    lane(hi[2]),
                ],
                s as usize,
            ));
            count += 1;
        }
        // SAFETY: the first `count` entries were written just above.
        let left = unsafe {
            std::slice::from_raw_parts(left.as_ptr().cast::<([__m256; 6], usize)>(), count)
        };
        let e = e.map(|x| _mm256_set1_ps(x));
        let p = p.map(|x| _mm256_set1_ps(x));
        let t_min = _mm256_set1_ps(super::T_MIN);
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let stride = (std::mem::size_of::<Ray>() / 4) as i32;
        let index = _mm256_mullo_epi32(
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
            _mm256_set1_epi32(stride),
        );
        for (g, byte) in groups_of(m) {
            // SAFETY: `new` wrote the lanes of every group holding a ray of `self.rays`, and
            // `m` is a subset of it (checked above).
            let l = unsafe { self.lanes[g].assume_init_ref() };
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
            // Each axis's scale and offset: `Vec3A`'s lane-wise products and differences, so
            // each lane's value is the one the single-ray test computes for its ray.
            let scale = [0, 1, 2].map(|a| _mm256_mul_ps(e[a], l[3 + a]));
            let offset = [0, 1, 2].map(|a| _mm256_mul_ps(_mm256_sub_ps(p[a], l[a]), l[3 + a]));
            for (planes, s) in left {
                let axis = |a: usize| {
                    let down = l[6 + a];
                    let near = _mm256_blendv_ps(planes[2 * a], planes[2 * a + 1], down);
                    let far = _mm256_blendv_ps(planes[2 * a + 1], planes[2 * a], down);
                    (
                        _mm256_add_ps(_mm256_mul_ps(near, scale[a]), offset[a]),
                        _mm256_add_ps(_mm256_mul_ps(far, scale[a]), offset[a]),
                    )
                };
                let (x0, x1) = axis(0);
                let (y0, y1) = axis(1);
                let (z0, z1) = axis(2);
                let t0 = _mm256_max_ps(x0, _mm256_max_ps(y0, z0));
                let t1 = _mm256_min_ps(x1, _mm256_min_ps(y1, z1));
                let t0 = _mm256_max_ps(t0, t_min);
                let t1 = _mm256_min_ps(t1, tmax);
                let lanes = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OS>(t0, t1)) as u32;
                entered[s & 7] |= Mask::from(lanes & byte) << (8 * g);
            }
        }
        entered_slots(left, entered)
    }

    /// The children (a bit per slot) that lie, along some axis, outside the box of the rays'
    /// reaches widened by the margin: no ray of the packet enters them. `lo` and `hi` are the
    /// children's quantized low and high planes per axis, one child per lane, `e` and `p` the
    /// node's extents and corner.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn outside_reach(&self, lo: &[__m256; 3], hi: &[__m256; 3], e: [f32; 3], p: [f32; 3]) -> u32 {
        let pv = _mm_setr_ps(p[0], p[1], p[2], 0.0);
        let ev = _mm_setr_ps(e[0], e[1], e[2], 0.0);
        let abs = |v: __m128| _mm_andnot_ps(_mm_set1_ps(-0.0), v);
        let bound = _mm_add_ps(
            _mm_add_ps(abs(pv), self.span),
            _mm_mul_ps(ev, _mm_set1_ps(256.0)),
        );
        let margin = _mm_mul_ps(bound, _mm_set1_ps(REACH_MARGIN));
        let (b_lo, b_hi) = (
            _mm_sub_ps(self.reach_lo, margin),
            _mm_add_ps(self.reach_hi, margin),
        );
        let at = |v: __m128, a: i32| {
            _mm256_permutevar8x32_ps(_mm256_castps128_ps256(v), _mm256_set1_epi32(a))
        };
        let mut outside = _mm256_setzero_ps();
        for a in 0..3 {
            let i = a as i32;
            let (p, e) = (_mm256_set1_ps(p[a]), _mm256_set1_ps(e[a]));
            let low = _mm256_add_ps(p, _mm256_mul_ps(lo[a], e));
            let high = _mm256_add_ps(p, _mm256_mul_ps(hi[a], e));
            // Ordered comparisons: a NaN anywhere culls nothing.
            outside = _mm256_or_ps(outside, _mm256_cmp_ps::<_CMP_LT_OQ>(high, at(b_lo, i)));
            outside = _mm256_or_ps(outside, _mm256_cmp_ps::<_CMP_GT_OQ>(low, at(b_hi, i)));
        }
        _mm256_movemask_ps(outside) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::packet::ray_children;
    use crate::bvh::test_scene::{random_boxes_bvh, Lcg};
    use glam::Vec3A;

    #[test]
    fn each_ray_enters_the_children_its_own_test_gives() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 on this CPU: nothing to test");
            return;
        }
        let mut rng = Lcg(11);
        let bvh = random_boxes_bvh(&mut rng);
        let (mut culled, mut entered_any) = (0usize, 0usize);
        for p in 0..40 {
            // Rays every way from points near one another, as a tile's AO rays go, some with
            // zero components; short, long or endless.
            let base = Vec3A::new(rng.next(), rng.next(), rng.next()) * 100.0;
            let rays: Vec<Ray> = (0..64)
                .map(|k| {
                    let start = base + Vec3A::new(rng.next(), rng.next(), rng.next()) * 3.0;
                    let mut dir = Vec3A::new(rng.next(), rng.next(), rng.next()) * 2.0 - 1.0;
                    if k % 9 == 0 {
                        dir[k % 3] = 0.0;
                    }
                    let tmax = match (p + k) % 13 {
                        0 => f32::INFINITY,
                        1 => 1e3,
                        _ => rng.next() * 8.0,
                    };
                    Ray::new(start, dir + Vec3A::ZERO, 0.0, tmax)
                })
                .collect();
            let m = if p % 3 == 0 {
                0x5555_aaaa_f0f0_0ff1
            } else {
                u64::MAX
            };
            let mut lanes: MixedLanes = [const { MaybeUninit::uninit() }; PACKET / 8];
            // SAFETY: the CPU has AVX2, checked above.
            let test = unsafe { MixedPacket::new(&mut lanes, &rays, m) };
            for node in &bvh.nodes {
                let mut entered = [0; 8];
                // SAFETY: as above.
                let slots = unsafe { test.children(node, &rays, m, &mut entered) };
                let mut want = [0; 8];
                for k in rays_of(m) {
                    let ray = &rays[k];
                    // SAFETY: as above.
                    let hit = unsafe { ray_children(node, ray, octant_inv4(ray.direction)) };
                    for (s, w) in want.iter_mut().enumerate() {
                        *w |= Mask::from(hit >> s & 1) << k;
                    }
                }
                assert_eq!(entered, want, "packet {p}, node {node:?}");
                let nonempty = want
                    .iter()
                    .enumerate()
                    .map(|(s, &w)| u32::from(w != 0) << s);
                assert_eq!(slots, nonempty.sum::<u32>(), "packet {p}");
                entered_any += usize::from(slots != 0);
                let lo = [&node.child_min_x, &node.child_min_y, &node.child_min_z].map(|b| {
                    // SAFETY: as above.
                    unsafe {
                        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_cvtsi64_si128(
                            i64::from_le_bytes(*b),
                        )))
                    }
                });
                let hi = [&node.child_max_x, &node.child_max_y, &node.child_max_z].map(|b| {
                    // SAFETY: as above.
                    unsafe {
                        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_cvtsi64_si128(
                            i64::from_le_bytes(*b),
                        )))
                    }
                });
                let extent = node.compute_extent();
                let (e, q) = ([extent.x, extent.y, extent.z], node.p);
                // SAFETY: as above.
                let out = unsafe { test.outside_reach(&lo, &hi, e, [q.x, q.y, q.z]) };
                culled += out.count_ones() as usize;
            }
        }
        assert!(
            culled > 1000 && entered_any > 1000,
            "{culled} children culled, {entered_any} nodes entered"
        );
    }
}
