//! The partitioned mode's frame: each rank holds the active octants of one run of kd-tree leaves
//! ([`super::partition`]) and their BVH, renders the whole frame of its part, and the partial
//! frames are composited ([`super::composite`]).
//!
//! The extraction is shared out first by leaf count (rank `r` extracts the `r`-th slice of the
//! leaves that may hold the isovalue), the per-leaf counts are summed on every rank, the leaves
//! are cut into runs balanced by count, and the refs are sent to the ranks that own them.
//!
//! Shadows and ambient occlusion need the whole scene (an occluder may be in any part), so this
//! mode renders without them.

use std::time::Instant;

use ::mpi::collective::SystemOperation;
use ::mpi::datatype::{Partition, PartitionMut};
use ::mpi::topology::SimpleCommunicator;
use ::mpi::traits::*;

use super::composite::direct_send;
use super::partition::{balanced_runs, visibility_order};
use super::pixels::offsets;
use super::stats::{cpu_seconds, RankStats};
use amr_render::extract::split_ref;
use amr_render::output::frame::FrameBuffer;
use amr_render::shade::IsoSpec;
use amr_render::{render, Scene, View};
use anyhow::anyhow;

/// Builds this rank's part of `scene` for `isos`, renders it and composites the frame on rank 0
/// (`None` elsewhere). `view` must be without shadows and ambient occlusion. When it has no
/// camera and `frame_surfaces` is set, it is given the camera that frames every rank's surfaces
/// together, the camera a single process frames its surfaces with. Fills in `stats`
/// (`cpu_scene` with the processor time at the start of rendering, render time and rays).
pub fn render_part(
    world: &SimpleCommunicator,
    scene: &mut Scene,
    isos: &[IsoSpec],
    view: &mut View,
    frame_surfaces: bool,
    stats: &mut RankStats,
    progress: &(dyn Fn(u64) + Sync),
) -> anyhow::Result<Option<FrameBuffer>> {
    let n = world.size() as usize;
    let me = world.rank() as usize;
    let mut bytes = 0u64;

    let t = Instant::now();
    let mut local = Vec::with_capacity(isos.len());
    let mut counts = vec![0u64; scene.file().num_leaves()];
    let mut bounds = DoubledBounds::EMPTY;
    let path = scene.path().to_path_buf();
    let frame_surfaces = frame_surfaces && view.camera.is_none();
    // Each surface from its own field's extractor: the fields share the kd-tree's leaves.
    for (spec, ext) in isos.iter().zip(scene.surface_extractors(isos)?) {
        let ext =
            ext.ok_or_else(|| anyhow!("--mpi-mode partitioned needs the octant reconstruction"))?;
        let candidates = ext.candidate_leaves(spec.value);
        let c = candidates.len();
        let slice = &candidates[me * c / n..(me + 1) * c / n];
        let refs = ext.extract_leaves(spec.value, slice)?.refs;
        for &r in &refs {
            counts[split_ref(r).0 as usize] += 1;
        }
        if frame_surfaces {
            let mut bad = None;
            ext.voxel_boxes(&refs, |b| match b {
                Ok(b) => bounds.grow(b),
                Err(e) => bad = bad.take().or(Some(e)),
            });
            if let Some(e) = bad {
                return Err(e.in_file(&path).into());
            }
        }
        local.push(refs);
    }
    let mut total = vec![0u64; counts.len()];
    world.all_reduce_into(&counts[..], &mut total[..], SystemOperation::sum());
    bytes += 8 * counts.len() as u64;
    drop(counts);
    let frame = scene.grid_frame();
    if frame_surfaces {
        if let Some((lo, hi)) = bounds.of_every_rank(world) {
            let world_box = (frame.to_world(lo), frame.to_world(hi));
            *view = view.framing(world_box)?;
        }
    }
    let camera = view.camera(&frame)?;
    let order = visibility_order(&scene.file().tree(), &camera, &frame);
    let owner = balanced_runs(&order, &total, n);
    drop((order, total));
    let extracted = t.elapsed();

    let t = Instant::now();
    let mut parts = Vec::with_capacity(local.len());
    for refs in local {
        let (part, sent) = redistribute(world, refs, &owner);
        bytes += sent;
        parts.push(part);
    }
    let redistributed = t.elapsed();
    stats.redistribute = redistributed.as_secs_f64();
    stats.work = owner.iter().filter(|&&o| o as usize == me).count() as f64;
    drop(owner);

    let scene_stats = scene.set_isosurfaces_from_refs(isos, parts)?;
    stats.extract = (scene_stats.extract + extracted + redistributed).as_secs_f64();
    stats.cpu_scene = cpu_seconds();
    let rendered = render(scene, view, progress)?;
    stats.render = rendered.stats.render.as_secs_f64();
    stats.cpu_render = cpu_seconds() - stats.cpu_scene;
    stats.rays = rendered.stats.rays as f64;

    let t = Instant::now();
    world.barrier();
    stats.wait = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (frame, sent) = direct_send(world, &rendered.frame)?;
    stats.composite = t.elapsed().as_secs_f64();
    bytes += sent;
    stats.bytes_sent = bytes as f64;
    Ok(frame)
}

/// Sends each of `refs` to the rank that owns its leaf; returns the refs this rank owns (in leaf
/// order) and the bytes sent to other ranks.
fn redistribute(world: &SimpleCommunicator, refs: Vec<u64>, owner: &[u32]) -> (Vec<u64>, u64) {
    let n = world.size() as usize;
    let me = world.rank() as usize;
    let dest = |r: u64| owner[split_ref(r).0 as usize] as usize;
    let mut send_counts = vec![0i32; n];
    for &r in &refs {
        send_counts[dest(r)] += 1;
    }
    let send_displs = offsets(&send_counts);
    let mut send = vec![0u64; refs.len()];
    let mut at: Vec<usize> = send_displs.iter().map(|&d| d as usize).collect();
    for &r in &refs {
        let d = dest(r);
        send[at[d]] = r;
        at[d] += 1;
    }
    drop(refs);
    let mut recv_counts = vec![0i32; n];
    world.all_to_all_into(&send_counts[..], &mut recv_counts[..]);
    let recv_displs = offsets(&recv_counts);
    let mut recv = vec![0u64; recv_counts.iter().map(|&c| c as usize).sum()];
    world.all_to_all_varcount_into(
        &Partition::new(&send[..], &send_counts[..], &send_displs[..]),
        &mut PartitionMut::new(&mut recv[..], &recv_counts[..], &recv_displs[..]),
    );
    let sent = 4 * n as u64 + 8 * (send.len() - send_counts[me] as usize) as u64;
    drop(send);
    recv.sort_unstable();
    (recv, sent)
}

/// The union of voxel boxes in doubled coordinates, as the BVH build records a surface's.
struct DoubledBounds {
    lo: [i64; 3],
    hi: [i64; 3],
}

impl DoubledBounds {
    const EMPTY: DoubledBounds = DoubledBounds {
        lo: [i64::MAX; 3],
        hi: [i64::MIN; 3],
    };

    fn grow(&mut self, (lo, hi): ([i64; 3], [i64; 3])) {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(lo[a]);
            self.hi[a] = self.hi[a].max(hi[a]);
        }
    }

    /// The union of every rank's bounds (a collective call), `None` when no rank has a voxel.
    fn of_every_rank(&self, world: &SimpleCommunicator) -> Option<([f64; 3], [f64; 3])> {
        let (mut lo, mut hi) = ([0i64; 3], [0i64; 3]);
        world.all_reduce_into(&self.lo[..], &mut lo[..], SystemOperation::min());
        world.all_reduce_into(&self.hi[..], &mut hi[..], SystemOperation::max());
        (0..3)
            .all(|a| lo[a] <= hi[a])
            .then(|| (lo.map(|x| x as f64), hi.map(|x| x as f64)))
    }
}
