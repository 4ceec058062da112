//! The replicated mode's frame: every rank holds the whole scene and renders image tiles that
//! rank 0 hands out one at a time on request (tiles cost very different amounts), then rank 0
//! gathers the tiles. Every pixel is computed exactly as in a single-process render.
//!
//! Rank 0 renders too: its main thread takes tiles from the same counter that a second thread
//! serves the other ranks' requests from, so MPI must provide `MPI_THREAD_SERIALIZED` or more
//! (the main thread makes no MPI call while that thread runs).

use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use ::mpi::collective::SystemOperation;
use ::mpi::datatype::PartitionMut;
use ::mpi::topology::SimpleCommunicator;
use ::mpi::traits::*;
use anyhow::bail;

use super::pixels::{self, offsets, RECORD};
use super::stats::{cpu_seconds, RankStats};
use amr_render::output::frame::{FrameBuffer, PixelSample};
use amr_render::{render_region, FramePainting, Rect, Scene, View};

/// Tile edge, pixels.
pub const TILE: u32 = 32;
/// Reply that no tiles are left.
const DONE: u32 = u32::MAX;
const TAG_REQUEST: i32 = 11;
const TAG_TILE: i32 = 12;
/// Pause of rank 0's serving thread between polls for requests.
const POLL: Duration = Duration::from_micros(50);

/// The tiles of a frame: their count and the rectangle `(x, y, w, h)` of each.
#[derive(Clone, Copy, Debug)]
pub struct Tiles {
    width: u32,
    height: u32,
    across: u32,
}

impl Tiles {
    /// The tiles of a `width x height` frame.
    pub fn new(width: u32, height: u32) -> Tiles {
        Tiles {
            width,
            height,
            across: width.div_ceil(TILE),
        }
    }

    /// Number of tiles.
    pub fn count(&self) -> u32 {
        self.across * self.height.div_ceil(TILE)
    }

    /// The rectangle of tile `t`.
    pub fn rect(&self, t: u32) -> (u32, u32, u32, u32) {
        let (x, y) = ((t % self.across) * TILE, (t / self.across) * TILE);
        (x, y, TILE.min(self.width - x), TILE.min(self.height - y))
    }
}

/// What this rank rendered: tile ids, their pixel records in the same order, ray queries, and
/// the levels painted by level (bit `l` for level `l`).
#[derive(Default)]
struct Rendered {
    ids: Vec<u32>,
    records: Vec<f32>,
    rays: u64,
    painted_levels: u32,
}

/// The frame gathered on rank 0.
pub struct Gathered {
    /// Its pixels.
    pub frame: FrameBuffer,
    /// The levels painted by level into some pixel by any rank, ascending.
    pub painted_levels: Vec<u32>,
}

impl Rendered {
    fn add(&mut self, t: u32, job: &Job<'_>) -> anyhow::Result<()> {
        let (x0, y0, width, height) = job.tiles.rect(t);
        let region = render_region(
            job.scene,
            job.view,
            job.painting,
            Rect {
                x0,
                y0,
                width,
                height,
            },
        )?;
        self.ids.push(t);
        for s in &region.pixels {
            pixels::push(&mut self.records, s);
        }
        self.rays += region.rays;
        for l in region.painted_levels {
            self.painted_levels |= 1u32.checked_shl(l).unwrap_or(0);
        }
        Ok(())
    }
}

/// A frame to render.
pub struct Job<'a> {
    /// The scene, with its isosurfaces.
    pub scene: &'a Scene,
    /// The view.
    pub view: &'a View,
    /// The frame's colour ranges, found once.
    pub painting: &'a FramePainting,
    /// Its tiles.
    pub tiles: Tiles,
}

/// Renders this rank's share of `job` and gathers the frame on rank 0 (`None` elsewhere);
/// `progress(1)` is called on rank 0 as each tile is handed out. Fills in `stats`' render,
/// processor time, wait, composite, bytes sent, rays and tiles.
pub fn render(
    world: &SimpleCommunicator,
    job: &Job<'_>,
    p_origin: [f64; 3],
    stats: &mut RankStats,
    progress: &(dyn Fn(u64) + Sync),
) -> anyhow::Result<Option<Gathered>> {
    let (w, h) = (job.view.size.0 as usize, job.view.size.1 as usize);
    if w * h * RECORD > i32::MAX as usize {
        bail!("a {w}x{h} frame is too large for one MPI message (at most 2^31 values)");
    }
    let t0 = Instant::now();
    let cpu0 = cpu_seconds();
    let mut bytes = 0u64;
    let mut mine = Rendered::default();
    let n = job.tiles.count();
    if world.rank() == 0 {
        let next = AtomicU32::new(0);
        let workers = world.size() as usize - 1;
        let mut failure = None;
        std::thread::scope(|s| {
            let server = (workers > 0).then(|| s.spawn(|| serve(&next, n, workers, progress)));
            loop {
                let t = next.fetch_add(1, Ordering::Relaxed);
                if t >= n {
                    break;
                }
                progress(1);
                if let Err(e) = mine.add(t, job) {
                    // The server goes on handing the other tiles to the other ranks.
                    failure = Some(e);
                    break;
                }
            }
            if let Some(server) = server {
                bytes += server.join().expect("the tile server does not panic");
            }
        });
        if let Some(e) = failure {
            return Err(e);
        }
    } else {
        let root = world.process_at_rank(0);
        root.send_with_tag(&0u32, TAG_REQUEST);
        bytes += 4;
        loop {
            let (t, _) = root.receive_with_tag::<u32>(TAG_TILE);
            if t == DONE {
                break;
            }
            // Ask for the next tile before rendering this one, so the answer is waiting.
            root.send_with_tag(&0u32, TAG_REQUEST);
            bytes += 4;
            mine.add(t, job)?;
        }
    }
    stats.render = t0.elapsed().as_secs_f64();
    stats.cpu_render = cpu_seconds() - cpu0;
    stats.rays = mine.rays as f64;
    stats.work = mine.ids.len() as f64;
    let t1 = Instant::now();
    world.barrier();
    stats.wait = t1.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mut levels = 0u32;
    let root = world.process_at_rank(0);
    match world.rank() {
        0 => root.reduce_into_root(
            &mine.painted_levels,
            &mut levels,
            SystemOperation::bitwise_or(),
        ),
        _ => root.reduce_into(&mine.painted_levels, SystemOperation::bitwise_or()),
    }
    bytes += 4;
    let frame = gather(world, &job.tiles, &mine, w, h, p_origin, &mut bytes);
    stats.composite = t1.elapsed().as_secs_f64();
    stats.bytes_sent = bytes as f64;
    Ok(frame.map(|frame| Gathered {
        frame,
        painted_levels: (0..u32::BITS).filter(|l| levels >> l & 1 == 1).collect(),
    }))
}

/// Rank 0's server: answers tile requests from `workers` ranks until each has been told that
/// none are left; returns the bytes it sent.
fn serve(next: &AtomicU32, n: u32, workers: usize, progress: &(dyn Fn(u64) + Sync)) -> u64 {
    let world = SimpleCommunicator::world();
    let mut active = workers;
    let mut sent = 0u64;
    while active > 0 {
        let Some(status) = world.any_process().immediate_probe_with_tag(TAG_REQUEST) else {
            std::thread::sleep(POLL);
            continue;
        };
        let from = world.process_at_rank(status.source_rank());
        let _ = from.receive_with_tag::<u32>(TAG_REQUEST);
        let t = next.fetch_add(1, Ordering::Relaxed);
        let reply = if t < n {
            progress(1);
            t
        } else {
            active -= 1;
            DONE
        };
        from.send_with_tag(&reply, TAG_TILE);
        sent += 4;
    }
    sent
}

/// Gathers every rank's tiles on rank 0 into the frame.
fn gather(
    world: &SimpleCommunicator,
    tiles: &Tiles,
    mine: &Rendered,
    w: usize,
    h: usize,
    p_origin: [f64; 3],
    bytes: &mut u64,
) -> Option<FrameBuffer> {
    let root = world.process_at_rank(0);
    let count = mine.ids.len() as i32;
    if world.rank() != 0 {
        root.gather_into(&count);
        root.gather_varcount_into(&mine.ids[..]);
        root.gather_varcount_into(&mine.records[..]);
        *bytes += 4 + 4 * (mine.ids.len() + mine.records.len()) as u64;
        return None;
    }
    let n = world.size() as usize;
    let mut counts = vec![0i32; n];
    root.gather_into_root(&count, &mut counts[..]);
    let displs = offsets(&counts);
    let mut ids = vec![0u32; counts.iter().sum::<i32>() as usize];
    root.gather_varcount_into_root(
        &mine.ids[..],
        &mut PartitionMut::new(&mut ids[..], &counts[..], &displs[..]),
    );
    let values = |ids: &[u32]| -> i32 {
        ids.iter()
            .map(|&t| {
                let r = tiles.rect(t);
                (r.2 * r.3) as i32 * RECORD as i32
            })
            .sum()
    };
    let value_counts: Vec<i32> = (0..n)
        .map(|k| {
            let d = displs[k] as usize;
            values(&ids[d..d + counts[k] as usize])
        })
        .collect();
    let value_displs = offsets(&value_counts);
    let mut records = vec![0.0f32; w * h * RECORD];
    root.gather_varcount_into_root(
        &mine.records[..],
        &mut PartitionMut::new(&mut records[..], &value_counts[..], &value_displs[..]),
    );
    let mut px = vec![PixelSample::MISS; w * h];
    let mut at = 0;
    for &t in &ids {
        let (x0, y0, tw, th) = tiles.rect(t);
        for y in y0..y0 + th {
            for x in x0..x0 + tw {
                px[y as usize * w + x as usize] = pixels::read(&records[at..at + RECORD]);
                at += RECORD;
            }
        }
    }
    Some(FrameBuffer::from_pixels(w as u32, h as u32, &px, p_origin))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_frame_once() {
        let tiles = Tiles::new(70, 33);
        let mut hit = vec![0u8; 70 * 33];
        for t in 0..tiles.count() {
            let (x0, y0, w, h) = tiles.rect(t);
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    hit[(y * 70 + x) as usize] += 1;
                }
            }
        }
        assert!(hit.iter().all(|&c| c == 1));
    }
}
