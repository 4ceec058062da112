//! The CWBVH8 node test: which of a node's eight children a ray enters, all eight at once.
//!
//! The test is obvhs's `CwBvhNode::intersect_ray` (its SSE version), computed bit for bit the
//! same way: each child's quantized planes are turned into `f32`, scaled and offset into ray
//! distances with one multiply and one add (no fused multiply-add), clamped by the same `max` and
//! `min` in the same operand order, and the hit children are encoded into the same mask. So the
//! traversal visits exactly the nodes and leaves, in exactly the order, that obvhs's would.
//! obvhs converts the 48 plane bytes one scalar at a time into two SSE registers of four children
//! and builds the mask child by child; with AVX2 the eight children are one register, the bytes
//! are widened eight at a time (`vpmovzxbd`), and the mask is built with a variable shift and an
//! OR reduction: about 85 instructions per node instead of over 160 (callgrind).

use glam::Vec3A;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray;

/// The lower bound of a child's entry distance in obvhs's node test (its private `EPSILON`):
/// a child the ray leaves before it is not entered.
pub const T_MIN: f32 = 0.0001;

/// The octant code of a ray direction that obvhs's traversal uses to order children (its
/// `Traversal::oct_inv4`): for each axis, a bit set when the direction is not negative, repeated
/// in each byte.
pub fn octant_inv4(dir: Vec3A) -> u32 {
    (if dir.x < 0.0 { 0 } else { 0x0404_0404 })
        | (if dir.y < 0.0 { 0 } else { 0x0202_0202 })
        | (if dir.z < 0.0 { 0 } else { 0x0101_0101 })
}

/// The node test on any CPU: obvhs's own.
#[inline(always)]
pub fn hits_portable(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    node.intersect_ray(ray, oct_inv4)
}

/// A ray's constants for the AVX2 node test, computed once per ray.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct Avx2Ray {
    origin: Vec3A,
    inv_direction: Vec3A,
    /// Per axis, all lanes set when the ray goes down the axis (its near planes are the high
    /// ones).
    down: [std::arch::x86_64::__m256; 3],
    /// The octant code's byte in every lane.
    octant: std::arch::x86_64::__m256i,
}

#[cfg(target_arch = "x86_64")]
impl Avx2Ray {
    /// The constants of `ray`, whose octant code is `oct_inv4`.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn new(ray: &Ray, oct_inv4: u32) -> Self {
        use std::arch::x86_64::*;
        let down = |d: f32| _mm256_castsi256_ps(_mm256_set1_epi32(-i32::from(d < 0.0)));
        Self {
            origin: ray.origin,
            inv_direction: ray.inv_direction,
            down: [
                down(ray.direction.x),
                down(ray.direction.y),
                down(ray.direction.z),
            ],
            octant: _mm256_set1_epi32((oct_inv4 & 0xff) as i32),
        }
    }

    /// The node test with AVX2 for a ray with these constants and `tmax`: the same mask as
    /// [`hits_portable`] on x86 (obvhs's SSE test).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn hits(&self, node: &CwBvhNode, tmax: f32) -> u32 {
        use std::arch::x86_64::*;
        let scale = node.compute_extent() * self.inv_direction;
        let offset = (Vec3A::from(node.p) - self.origin) * self.inv_direction;
        let planes = |q: &[u8; 8], s: f32, o: f32| {
            let q = _mm256_cvtepi32_ps(widen(u64::from_le_bytes(*q)));
            _mm256_add_ps(_mm256_mul_ps(q, _mm256_set1_ps(s)), _mm256_set1_ps(o))
        };
        let slab = |lo: &[u8; 8], hi: &[u8; 8], down: __m256, s: f32, o: f32| {
            let (lo, hi) = (planes(lo, s, o), planes(hi, s, o));
            (
                _mm256_blendv_ps(lo, hi, down),
                _mm256_blendv_ps(hi, lo, down),
            )
        };
        let (x0, x1) = slab(
            &node.child_min_x,
            &node.child_max_x,
            self.down[0],
            scale.x,
            offset.x,
        );
        let (y0, y1) = slab(
            &node.child_min_y,
            &node.child_max_y,
            self.down[1],
            scale.y,
            offset.y,
        );
        let (z0, z1) = slab(
            &node.child_min_z,
            &node.child_max_z,
            self.down[2],
            scale.z,
            offset.z,
        );
        let t0 = _mm256_max_ps(x0, _mm256_max_ps(y0, z0));
        let t1 = _mm256_min_ps(x1, _mm256_min_ps(y1, z1));
        let t0 = _mm256_max_ps(t0, _mm256_set1_ps(T_MIN));
        let t1 = _mm256_min_ps(t1, _mm256_set1_ps(tmax));
        let entered = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OS>(t0, t1));
        // Each child's bits in the mask (obvhs's `get_child_and_index_bits`, lane by lane): an
        // inner child (both bits 3 and 4 of its meta set) is one bit at its slot plus 24 mixed
        // with the octant code, a leaf its unary primitive count at its primitive offset.
        let meta = widen(u64::from_le_bytes(node.child_meta));
        let inner_bits = _mm256_set1_epi32(0x18);
        let inner = _mm256_cmpeq_epi32(_mm256_and_si256(meta, inner_bits), inner_bits);
        let index = _mm256_and_si256(
            _mm256_xor_si256(meta, _mm256_and_si256(inner, self.octant)),
            _mm256_set1_epi32(0x1f),
        );
        let bits = _mm256_sllv_epi32(_mm256_srli_epi32::<5>(meta), index);
        let m = _mm256_and_si256(bits, entered);
        let m = _mm_or_si128(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
        let m = _mm_or_si128(m, _mm_shuffle_epi32::<0b01_00_11_10>(m));
        let m = _mm_or_si128(m, _mm_shuffle_epi32::<0b10_11_00_01>(m));
        _mm_cvtsi128_si32(m) as u32
    }
}

/// The eight bytes of `b` (little-endian), one per 32-bit lane.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn widen(b: u64) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(b as i64))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::test_scene::{random_boxes_bvh, Lcg};
    use crate::bvh::wide::WideBuilder;
    use obvhs::aabb::Aabb;

    #[test]
    fn octant_code_is_obvhs_one() {
        for d in [
            Vec3A::new(1.0, 2.0, 3.0),
            Vec3A::new(-1.0, 0.0, 3.0),
            Vec3A::new(0.5, -2.0, -0.0),
            Vec3A::new(-1.0, -1.0, -1.0),
        ] {
            let bvh = WideBuilder::default().build(&[Aabb::new(Vec3A::ZERO, Vec3A::ONE)]);
            assert_eq!(octant_inv4(d), bvh.new_traversal(d).oct_inv4, "{d}");
        }
    }

    #[test]
    fn avx2_test_gives_obvhs_mask_on_every_node() {
        #[cfg(target_arch = "x86_64")]
        {
            if !std::arch::is_x86_feature_detected!("avx2") {
                eprintln!("no AVX2 on this CPU: only the portable node test runs");
                return;
            }
            let mut rng = Lcg(7);
            let bvh = random_boxes_bvh(&mut rng);
            let (mut tested, mut hit) = (0usize, 0usize);
            for k in 0..400 {
                let origin = Vec3A::new(rng.next(), rng.next(), rng.next()) * 140.0 - 20.0;
                let mut dir = Vec3A::new(rng.next(), rng.next(), rng.next()) * 2.0 - 1.0;
                if k % 5 == 0 {
                    dir[k % 3] = 0.0;
                }
                if k % 7 == 0 {
                    dir = Vec3A::ZERO;
                    dir[k % 3] = if k % 2 == 0 { 1.0 } else { -1.0 };
                }
                let tmax = if k % 3 == 0 {
                    rng.next() * 80.0
                } else {
                    f32::MAX
                };
                let ray = Ray::new(origin, dir, 0.0, tmax);
                let oct = octant_inv4(dir);
                for node in &bvh.nodes {
                    // SAFETY: the CPU has AVX2, checked above.
                    let fast = unsafe { Avx2Ray::new(&ray, oct).hits(node, ray.tmax) };
                    assert_eq!(
                        fast,
                        hits_portable(node, &ray, oct),
                        "ray {k}, node {node:?}"
                    );
                    tested += 1;
                    hit += usize::from(fast != 0);
                }
            }
            assert!(
                hit > 1000 && hit < tested,
                "{hit} of {tested} node tests hit"
            );
        }
    }
}
