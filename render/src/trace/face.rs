//! Exact intersection of a ray with a face slab of the `nearest` reconstruction
//! (`extract/nearest.rs`): the surface is the face, the plane through the slab's middle across
//! the one axis on which its corner values change.

use crate::reconstruct::interp::straddles;
use crate::trace::octant::VoxelHit;
use crate::trace::ray::GridRay;
use crate::trace::source::Voxel;

/// Relative widening of the face rectangle, so that a ray through a shared edge or corner of two
/// faces hits at least one of them despite round-off.
const FACE_WIDEN: f64 = 1e-9;

/// The hit of `ray` with the face of slab `v` when the face separates a value below `iso` from
/// one at or above it and the ray crosses it with `t` in `[tmin, tmax]`. A ray in the face's
/// plane never crosses it.
#[inline]
pub fn intersect_face(
    v: &Voxel,
    iso: f32,
    ray: &GridRay,
    tmin: f64,
    tmax: f64,
) -> Option<VoxelHit> {
    let a = (0..3).find(|&a| v.values[0] != v.values[1 << a])?;
    let (below, above) = (v.values[0], v.values[1 << a]);
    if !straddles(below.min(above), below.max(above), iso) || ray.d[a] == 0.0 {
        return None;
    }
    let plane = 0.5 * (v.lo[a] + v.hi[a]);
    let t = (plane - ray.o[a]) / ray.d[a];
    if !(t >= tmin && t <= tmax) {
        return None;
    }
    let mut local = [0.5; 3];
    for b in (0..3).filter(|&b| b != a) {
        let w = v.hi[b] - v.lo[b];
        let x = ray.o[b] + t * ray.d[b];
        let slack = FACE_WIDEN * w + 8.0 * f64::EPSILON * x.abs().max(v.hi[b].abs());
        if x < v.lo[b] - slack || x > v.hi[b] + slack {
            return None;
        }
        local[b] = ((x - v.lo[b]) / w).clamp(0.0, 1.0);
    }
    Some(VoxelHit { t, local })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slab(axis: usize, below: f32, above: f32) -> Voxel {
        Voxel {
            lo: [0.0; 3],
            hi: [2.0; 3],
            values: std::array::from_fn(|k| if k >> axis & 1 == 1 { above } else { below }),
            level: 0,
        }
    }

    #[test]
    fn hits_the_middle_plane_from_either_side() {
        let v = slab(1, 0.0, 1.0);
        let ray = GridRay {
            o: [0.5, -3.0, 1.5],
            d: [0.0, 2.0, 0.0],
        };
        let h = intersect_face(&v, 0.5, &ray, 0.0, f64::INFINITY).unwrap();
        assert_eq!(h.t, 2.0);
        assert_eq!(h.local, [0.25, 0.5, 0.75]);
        let back = GridRay {
            o: [0.5, 5.0, 1.5],
            d: [0.0, -1.0, 0.0],
        };
        assert_eq!(intersect_face(&v, 0.5, &back, 0.0, 10.0).unwrap().t, 4.0);
        assert!(intersect_face(&v, 0.5, &back, 0.0, 3.9).is_none());
    }

    #[test]
    fn activity_rule_edges_and_parallel_rays() {
        let v = slab(0, 0.0, 1.0);
        let ray = GridRay {
            o: [-1.0, 2.0, 0.0],
            d: [1.0, 0.0, 0.0],
        };
        // On the rectangle's corner: a hit.
        assert!(intersect_face(&v, 0.5, &ray, 0.0, 9.0).is_some());
        // `iso` equal to the upper value counts; equal to the lower does not.
        assert!(intersect_face(&v, 1.0, &ray, 0.0, 9.0).is_some());
        assert!(intersect_face(&v, 0.0, &ray, 0.0, 9.0).is_none());
        let outside = GridRay {
            o: [-1.0, 2.001, 0.0],
            d: [1.0, 0.0, 0.0],
        };
        assert!(intersect_face(&v, 0.5, &outside, 0.0, 9.0).is_none());
        let parallel = GridRay {
            o: [1.0, -1.0, 1.0],
            d: [0.0, 1.0, 0.0],
        };
        assert!(intersect_face(&v, 0.5, &parallel, 0.0, 9.0).is_none());
        assert!(intersect_face(&slab(2, 1.0, 1.0), 1.0, &ray, 0.0, 9.0).is_none());
    }
}
