//! Deterministic test inputs for the node tests: a stream of numbers and a BVH over random boxes.

use glam::Vec3A;
use obvhs::aabb::Aabb;

use obvhs::cwbvh::CwBvh;

use super::wide::WideBuilder;

/// A deterministic stream of numbers in `[0, 1)`.
pub struct Lcg(pub u64);

impl Lcg {
    /// The next number.
    pub fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A point with coordinates in `[0, scale)`.
    pub fn point(&mut self, scale: f32) -> Vec3A {
        Vec3A::new(self.next(), self.next(), self.next()) * scale
    }
}

/// A BVH over 3,000 boxes of up to 4 units a side with corners in `[0, 100)`, drawn from `rng`.
pub fn random_boxes_bvh(rng: &mut Lcg) -> CwBvh {
    let boxes: Vec<Aabb> = (0..3000)
        .map(|_| {
            let lo = rng.point(100.0);
            Aabb::new(lo, lo + rng.point(4.0))
        })
        .collect();
    WideBuilder::default().build(&boxes)
}
