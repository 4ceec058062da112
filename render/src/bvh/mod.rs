//! A compressed wide BVH (obvhs's CWBVH8) over active voxel refs.
//!
//! Only the refs and the BVH nodes stay resident: a voxel's box is decoded from its ref while
//! building, and its corner values while tracing. After the build the refs are put in the BVH's
//! leaf order, so the BVH's own primitive index array is dropped and a leaf's primitive `i` is
//! simply `refs[i]`. [`BvhBuilder`] keeps the build scratch (boxes, PLOC buffers, the binary BVH)
//! so that a new isovalue rebuilds without reallocating.

use glam::{UVec2, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ploc::PlocBuilder;
use obvhs::ray::Ray;
use obvhs::BvhBuildParams;
use rayon::prelude::*;

/// Bytes of one CWBVH node (obvhs: "repr(C), Pod, 80 bytes").
pub const NODE_BYTES: usize = 80;

/// A BVH over active voxels, each named by a 64-bit ref.
#[derive(Clone, Default, Debug)]
pub struct OctantBvh {
    refs: Vec<u64>,
    bvh: CwBvh,
}

/// Build scratch kept between builds.
#[derive(Default)]
pub struct BvhBuilder {
    boxes: Vec<Aabb>,
    ploc: PlocBuilder,
    bvh2: Bvh2,
    reinsertion: ReinsertionOptimizer,
    /// Bytes of scratch held at the end of the last build (boxes, PLOC buffers, binary BVH).
    pub last_scratch_bytes: usize,
}

impl BvhBuilder {
    /// A builder with no scratch allocated yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Builds a BVH over `refs`, whose boxes `bounds(r)` gives in grid coordinates; every box
    /// is grown by `pad` (grid units) so that `f32` traversal never misses a voxel the exact
    /// `f64` intersection would hit. Reuses the scratch and `out`'s buffers.
    pub fn build_into(
        &mut self,
        out: &mut OctantBvh,
        refs: &[u64],
        pad: f64,
        bounds: impl Fn(u64) -> ([f64; 3], [f64; 3]) + Sync,
    ) {
        out.refs.clear();
        out.refs.extend_from_slice(refs);
        self.boxes.clear();
        self.boxes.par_extend(refs.par_iter().map(|&r| {
            let (lo, hi) = bounds(r);
            let v = |p: [f64; 3], s: f64| {
                Vec3A::new((p[0] + s) as f32, (p[1] + s) as f32, (p[2] + s) as f32)
            };
            Aabb::new(v(lo, -pad), v(hi, pad))
        }));
        if refs.is_empty() {
            out.bvh = CwBvh::default();
            return;
        }
        let params = BvhBuildParams::fast_build();
        let indices: Vec<u32> = (0..refs.len() as u32).collect();
        self.ploc.build_with_bvh(
            &mut self.bvh2,
            params.ploc_search_distance,
            &self.boxes,
            indices,
            params.sort_precision,
            params.search_depth_threshold,
        );
        self.reinsertion
            .run(&mut self.bvh2, params.reinsertion_batch_ratio, None);
        out.bvh = bvh2_to_cwbvh(
            &self.bvh2,
            params.max_prims_per_leaf.clamp(1, 3),
            true,
            false,
        );
        let mut perm = std::mem::take(&mut out.bvh.primitive_indices);
        gather_in_place(&mut out.refs, &mut perm);
        out.refs.shrink_to_fit();
        out.bvh.nodes.shrink_to_fit();
        out.bvh.primitive_indices = perm;
        out.bvh.primitive_indices.clear();
        out.bvh.primitive_indices.shrink_to_fit();
        self.last_scratch_bytes = self.boxes.capacity() * size_of::<Aabb>()
            + (self.ploc.current_nodes.capacity()
                + self.ploc.next_nodes.capacity()
                + self.bvh2.nodes.capacity())
                * size_of::<Bvh2Node>()
            + self.ploc.mortons.capacity() * 32
            + self.bvh2.primitive_indices.capacity() * 4;
    }

    /// Builds a new BVH (see [`BvhBuilder::build_into`]).
    pub fn build(
        &mut self,
        refs: &[u64],
        pad: f64,
        bounds: impl Fn(u64) -> ([f64; 3], [f64; 3]) + Sync,
    ) -> OctantBvh {
        let mut out = OctantBvh::default();
        self.build_into(&mut out, refs, pad, bounds);
        out
    }

    /// Frees the scratch.
    pub fn release(&mut self) {
        *self = Self::default();
    }
}

/// `values[i] = old values[perm[i]]` without a second array; `perm` is destroyed.
fn gather_in_place(values: &mut [u64], perm: &mut [u32]) {
    const DONE: u32 = u32::MAX;
    for start in 0..perm.len() {
        if perm[start] == DONE {
            continue;
        }
        let first = values[start];
        let mut j = start;
        loop {
            let k = perm[j] as usize;
            perm[j] = DONE;
            if k == start {
                values[j] = first;
                break;
            }
            values[j] = values[k];
            j = k;
        }
    }
}

impl OctantBvh {
    /// The refs, in BVH leaf order.
    pub fn refs(&self) -> &[u64] {
        &self.refs
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.refs.len()
    }

    /// True when the BVH holds no voxel.
    pub fn is_empty(&self) -> bool {
        self.refs.is_empty()
    }

    /// Resident bytes of the refs.
    pub fn refs_bytes(&self) -> usize {
        self.refs.capacity() * 8
    }

    /// Resident bytes of the BVH nodes (and of obvhs's index array, empty after the build).
    pub fn bvh_bytes(&self) -> usize {
        self.bvh.nodes.capacity() * NODE_BYTES + self.bvh.primitive_indices.capacity() * 4
    }

    /// Number of BVH nodes.
    pub fn num_nodes(&self) -> usize {
        self.bvh.nodes.len()
    }

    /// Calls `visit(r, &mut tmax)` for the refs of every leaf the `f32` ray reaches before its
    /// `tmax`, nearest leaves first; `visit` may lower `tmax` (closest-hit search) and returns
    /// `true` to stop (any-hit search).
    #[inline]
    pub fn traverse(&self, mut ray: Ray, mut visit: impl FnMut(u64, &mut f32) -> bool) {
        if self.refs.is_empty() || self.bvh.nodes.is_empty() {
            return;
        }
        let bvh = &self.bvh;
        let mut state = bvh.new_traversal(ray.direction);
        let mut node;
        obvhs::traverse!(
            bvh,
            node,
            state,
            node.intersect_ray(&ray, state.oct_inv4),
            {
                let r = self.refs[state.primitive_id as usize];
                if visit(r, &mut ray.tmax) {
                    break;
                }
            }
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gather_permutes() {
        let mut v: Vec<u64> = vec![10, 11, 12, 13, 14];
        let mut p: Vec<u32> = vec![3, 0, 4, 1, 2];
        gather_in_place(&mut v, &mut p);
        assert_eq!(v, vec![13, 10, 14, 11, 12]);
    }

    #[test]
    fn every_box_hit_by_a_ray_is_visited() {
        let refs: Vec<u64> = (0..1000).collect();
        let bounds = |r: u64| {
            let (x, y, z) = ((r % 10) as f64, ((r / 10) % 10) as f64, (r / 100) as f64);
            ([x, y, z], [x + 1.0, y + 1.0, z + 1.0])
        };
        let bvh = BvhBuilder::new().build(&refs, 1e-4, bounds);
        assert_eq!(bvh.len(), 1000);
        let mut sorted = bvh.refs().to_vec();
        sorted.sort();
        assert_eq!(sorted, refs);
        let ray = Ray::new(
            Vec3A::new(-1.0, 4.5, 4.5),
            Vec3A::new(1.0, 0.0, 0.0),
            0.0,
            f32::INFINITY,
        );
        let mut seen = Vec::new();
        bvh.traverse(ray, |r, _| {
            seen.push(r);
            false
        });
        for x in 0..10 {
            assert!(seen.contains(&(x + 40 + 400)), "missing {x}");
        }
    }
}
