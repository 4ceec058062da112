//! Rendering one frame with several MPI ranks (`mpirun -n N amr-render FILE.amrk ...`), built
//! with the `mpi` cargo feature; see docs/mpi.md. Every rank opens the same [`Scene`] through
//! the library as a single process does.
//!
//! - [`run`]: one rank's run: set-up, the mode's frame, and rank 0's outputs.
//! - [`replicated`]: every rank holds the whole scene; rank 0 hands out image tiles on request.
//! - [`partition`]: the kd-tree leaves in visibility order, cut into runs balanced by count.
//! - [`partitioned`]: every rank holds one part of the scene and renders the whole frame of it.
//! - [`composite`]: the partial frames combined by depth and in visibility order.
//! - [`pixels`]: pixel samples as flat `f32` records for messages.
//! - [`stats`]: per-rank statistics gathered on rank 0.
//!
//! [`Scene`]: amr_render::Scene

pub mod composite;
pub mod partition;
pub mod partitioned;
pub mod pixels;
pub mod replicated;
pub mod run;
pub mod stats;

/// How the ranks of an MPI run share a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MpiMode {
    /// Every rank extracts and builds the whole scene and renders a share of the tiles.
    Replicated,
    /// Every rank holds the active octants of one group of kd-tree leaves and renders the whole
    /// frame of it; the frames are composited.
    Partitioned,
}

impl MpiMode {
    /// The name used on the command line and in statistics.
    pub fn name(self) -> &'static str {
        match self {
            MpiMode::Replicated => "replicated",
            MpiMode::Partitioned => "partitioned",
        }
    }

    /// The mode `--mpi-mode` names (replicated by default).
    pub fn parse(s: Option<&str>) -> anyhow::Result<MpiMode> {
        match s.map(|s| s.trim().to_ascii_lowercase()).as_deref() {
            None | Some("replicated") => Ok(MpiMode::Replicated),
            Some("partitioned") => Ok(MpiMode::Partitioned),
            Some(other) => {
                anyhow::bail!("--mpi-mode {other}: unknown mode (replicated, partitioned)")
            }
        }
    }
}
