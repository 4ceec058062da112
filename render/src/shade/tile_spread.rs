//! How far apart the nearest hits of a tile of primary rays lie, in voxels: whether the
//! secondary rays leaving them (shadow and ambient-occlusion rays) share enough of the BVH's
//! nodes to be traced as packets.
//!
//! A packet walk shares a node's fetch and decoding among the rays that enter it, and costs
//! some bookkeeping per node whatever the rays. Rays leaving points a voxel or two apart enter
//! the same nodes down to the leaves; rays leaving points tens of voxels apart (a far view,
//! where a pixel spans a voxel or more) share only the top of the tree, and the bookkeeping
//! costs more than the sharing saves (`docs/benchmarks-render.md`, "Packets of AO rays").

use crate::trace::tracer::SurfaceHit;

/// Most spread ([`spread`]) of a tile whose key-light shadow rays (of all its layers,
/// [`crate::shade::integrate::KeyShadow`]) are traced as packets; they are parallel, so they
/// share nodes over a wider spread than AO rays.
pub const SHADOW_PACKETS_UP_TO: f64 = 8.0;
/// Most spread of a tile whose first-layer ambient-occlusion rays are traced as packets.
pub const AO_PACKETS_UP_TO: f64 = 4.0;

/// Rays of a tile of 8x8 between two rays sampled for [`spread`]: its diagonal.
const SAMPLE_STEP: usize = 9;

/// The spread of the nearest hits of the `m` rays of a tile, of which `first(k)` gives ray `k`'s
/// nearest hit (its first layer, [`crate::shade::layers`]): the largest side of the bounding box of the sampled rays'
/// nearest hits (those on the tile's diagonal) over their mean voxel size; infinite when fewer
/// than two of them hit anything.
pub fn spread(m: usize, mut first: impl FnMut(usize) -> Option<SurfaceHit>) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let (mut size, mut n) = (0.0, 0u32);
    for k in (0..m).step_by(SAMPLE_STEP) {
        let Some(h) = first(k) else {
            continue;
        };
        for a in 0..3 {
            lo[a] = lo[a].min(h.pos[a]);
            hi[a] = hi[a].max(h.pos[a]);
        }
        size += h.size;
        n += 1;
    }
    if n < 2 {
        return f64::INFINITY;
    }
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    extent / (size / f64::from(n))
}
