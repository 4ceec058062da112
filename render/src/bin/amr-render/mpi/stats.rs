//! What each rank did and what it cost, gathered on rank 0 for `--stats` and `--stats-json`.

use ::mpi::topology::SimpleCommunicator;
use ::mpi::traits::*;

/// One rank's statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RankStats {
    /// Extraction of its active octants, seconds (in partitioned mode: its share of the leaves,
    /// plus the exchange of refs, see `redistribute`).
    pub extract: f64,
    /// Sending the refs to the ranks that own them (partitioned mode), seconds.
    pub redistribute: f64,
    /// BVH builds, seconds.
    pub bvh: f64,
    /// Its tiles or its frame, seconds.
    pub render: f64,
    /// Waiting at the barrier before compositing for the slowest rank, seconds.
    pub wait: f64,
    /// Gathering and compositing the frame (its part of it), after the barrier, seconds.
    pub composite: f64,
    /// Bytes it sent in MPI messages (refs, pixels, tile requests, counts).
    pub bytes_sent: f64,
    /// Its peak resident set, bytes.
    pub peak_rss: f64,
    /// Active octants it holds, over all isosurfaces.
    pub active_octants: f64,
    /// Resident bytes of its refs.
    pub refs_bytes: f64,
    /// Resident bytes of its BVH nodes.
    pub bvh_bytes: f64,
    /// Largest BVH build scratch it held at once (freed before rendering).
    pub build_scratch: f64,
    /// Ray queries it made.
    pub rays: f64,
    /// Tiles it rendered (replicated) or kd-tree leaves it owns (partitioned).
    pub work: f64,
    /// Processor time of the process (all threads) from the end of the set-up to the start of
    /// rendering: extraction, exchange and BVH builds, seconds.
    pub cpu_scene: f64,
    /// Processor time of the process while rendering, seconds.
    pub cpu_render: f64,
}

/// Processor time this process has used in all its threads (user and system, from
/// `/proc/self/stat` in clock ticks of 1/100 s, Linux's `USER_HZ`), seconds; 0 where unknown.
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the command name (which may hold spaces), from field 3 on.
    let Some((_, rest)) = stat.rsplit_once(')') else {
        return 0.0;
    };
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|f| f.parse::<u64>().ok())
            .unwrap_or(0)
    };
    // utime and stime are fields 14 and 15, at 11 and 12 here.
    (ticks(11) + ticks(12)) as f64 / 100.0
}

const FIELDS: usize = 16;

impl RankStats {
    fn to_array(self) -> [f64; FIELDS] {
        [
            self.extract,
            self.redistribute,
            self.bvh,
            self.render,
            self.wait,
            self.composite,
            self.bytes_sent,
            self.peak_rss,
            self.active_octants,
            self.refs_bytes,
            self.bvh_bytes,
            self.build_scratch,
            self.rays,
            self.work,
            self.cpu_scene,
            self.cpu_render,
        ]
    }

    fn from_array(a: &[f64]) -> RankStats {
        RankStats {
            extract: a[0],
            redistribute: a[1],
            bvh: a[2],
            render: a[3],
            wait: a[4],
            composite: a[5],
            bytes_sent: a[6],
            peak_rss: a[7],
            active_octants: a[8],
            refs_bytes: a[9],
            bvh_bytes: a[10],
            build_scratch: a[11],
            rays: a[12],
            work: a[13],
            cpu_scene: a[14],
            cpu_render: a[15],
        }
    }

    /// Every rank's statistics on rank 0 (rank order), `None` elsewhere.
    pub fn gather(self, world: &SimpleCommunicator) -> Option<Vec<RankStats>> {
        let mine = self.to_array();
        let root = world.process_at_rank(0);
        if world.rank() == 0 {
            let mut all = vec![0.0f64; FIELDS * world.size() as usize];
            root.gather_into_root(&mine[..], &mut all[..]);
            Some(all.chunks(FIELDS).map(RankStats::from_array).collect())
        } else {
            root.gather_into(&mine[..]);
            None
        }
    }

    /// The statistics of rank `rank` as a record for `--stats-json`.
    pub fn record(&self, rank: usize) -> RankRecord {
        RankRecord {
            rank,
            extract_ms: self.extract * 1e3,
            redistribute_ms: self.redistribute * 1e3,
            bvh_ms: self.bvh * 1e3,
            render_ms: self.render * 1e3,
            wait_ms: self.wait * 1e3,
            composite_ms: self.composite * 1e3,
            bytes_sent: self.bytes_sent as u64,
            peak_rss_bytes: self.peak_rss as u64,
            active_octants: self.active_octants as u64,
            refs_bytes: self.refs_bytes as u64,
            bvh_bytes: self.bvh_bytes as u64,
            build_scratch_bytes: self.build_scratch as u64,
            rays: self.rays as u64,
            work: self.work as u64,
            cpu_scene_s: self.cpu_scene,
            cpu_render_s: self.cpu_render,
        }
    }
}

/// One rank's statistics as `--stats-json` writes them.
#[derive(Clone, Debug, serde::Serialize)]
#[allow(missing_docs)]
pub struct RankRecord {
    pub rank: usize,
    pub extract_ms: f64,
    pub redistribute_ms: f64,
    pub bvh_ms: f64,
    pub render_ms: f64,
    pub wait_ms: f64,
    pub composite_ms: f64,
    pub bytes_sent: u64,
    pub peak_rss_bytes: u64,
    pub active_octants: u64,
    pub refs_bytes: u64,
    pub bvh_bytes: u64,
    pub build_scratch_bytes: u64,
    pub rays: u64,
    pub work: u64,
    pub cpu_scene_s: f64,
    pub cpu_render_s: f64,
}

/// A table of the ranks' statistics for a terminal.
pub fn table(ranks: &[RankStats], work: &str) -> String {
    let mut s = format!(
        "{:>4} {:>10} {:>10} {:>9} {:>10} {:>8} {:>12} {:>12} {:>11} {:>10} {:>11} {:>10} {work:>6}\n",
        "rank",
        "extract_ms",
        "redist_ms",
        "bvh_ms",
        "render_ms",
        "wait_ms",
        "composite_ms",
        "bytes_sent",
        "peak_rss_MB",
        "octants",
        "refs+bvh_MB",
        "scratch_MB"
    );
    for (r, st) in ranks.iter().enumerate() {
        s += &format!(
            "{r:>4} {:>10.1} {:>10.1} {:>9.1} {:>10.1} {:>8.1} {:>12.1} {:>12} {:>11.1} {:>10} {:>11.2} {:>10.2} {:>6}\n",
            st.extract * 1e3,
            st.redistribute * 1e3,
            st.bvh * 1e3,
            st.render * 1e3,
            st.wait * 1e3,
            st.composite * 1e3,
            st.bytes_sent,
            st.peak_rss / 1e6,
            st.active_octants,
            (st.refs_bytes + st.bvh_bytes) / 1e6,
            st.build_scratch / 1e6,
            st.work
        );
    }
    s
}
