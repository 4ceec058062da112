//! Rendering one frame with several MPI ranks (`mpirun -n N amr-render FILE.amrk ...`), built
//! with the `mpi` cargo feature; see docs/mpi.md.
//!
//! - [`replicated`]: every rank holds the whole scene; rank 0 hands out image tiles on request.
//! - [`partition`]: the kd-tree leaves in visibility order, cut into runs balanced by count.
//! - [`partitioned`]: every rank holds one part of the scene and renders the whole frame of it.
//! - [`composite`]: the partial frames combined by depth and in visibility order.
//! - [`pixels`]: pixel samples as flat `f32` records for messages.
//! - [`stats`]: per-rank statistics gathered on rank 0.

#[cfg(feature = "mpi")]
pub mod composite;
#[cfg(feature = "mpi")]
pub mod partition;
#[cfg(feature = "mpi")]
pub mod partitioned;
#[cfg(feature = "mpi")]
pub mod pixels;
#[cfg(feature = "mpi")]
pub mod replicated;
#[cfg(feature = "mpi")]
mod run;
#[cfg(feature = "mpi")]
pub mod stats;

use anyhow::bail;
use clap::ValueEnum;

use crate::render_cmd::{Method, RenderArgs};

#[cfg(feature = "mpi")]
pub use run::render_file;

/// How the ranks of an MPI run share a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
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
}

/// Environment variables that MPI launchers set in every process they start (Open MPI, PMI as in
/// MPICH's Hydra, PMIx).
const LAUNCHER_VARS: [&str; 3] = ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"];

/// True when this process was started by `mpirun` (or another MPI launcher).
pub fn launched_by_mpirun() -> bool {
    LAUNCHER_VARS.iter().any(|v| std::env::var_os(v).is_some())
}

/// Whether a render with `args` runs through MPI: true under `mpirun` in a build with the `mpi`
/// feature; an error when `--mpi-mode` or `mpirun` asks for MPI that this build or launch
/// cannot give.
pub fn use_mpi(args: &RenderArgs) -> anyhow::Result<bool> {
    let launched = launched_by_mpirun();
    if !cfg!(feature = "mpi") {
        if launched {
            bail!(
                "started by mpirun, but this amr-render was built without MPI; \
                 rebuild with `cargo build --release -p amr-render --features mpi`"
            );
        }
        if args.mpi_mode.is_some() {
            bail!("--mpi-mode needs a build with `--features mpi` and a start with mpirun");
        }
        return Ok(false);
    }
    if !launched {
        if args.mpi_mode.is_some() {
            bail!("--mpi-mode needs a start with mpirun (mpirun -n N amr-render ...)");
        }
        return Ok(false);
    }
    let (w, h) = args.size;
    // Pixel messages count 12 `f32` per pixel in a C `int`.
    if u64::from(w) * u64::from(h) * 12 > i32::MAX as u64 {
        bail!("--size {w}x{h} is too large for MPI messages (at most 178 M pixels)");
    }
    if args.mpi_mode == Some(MpiMode::Partitioned) && args.method != Method::Hybrid {
        bail!("--mpi-mode partitioned needs --method hybrid (it partitions the active octants)");
    }
    Ok(true)
}

/// Without the `mpi` feature no render runs through MPI ([`use_mpi`] says so first).
#[cfg(not(feature = "mpi"))]
pub fn render_file(
    _args: &RenderArgs,
    _cfg: crate::render_cmd::RenderConfig,
) -> anyhow::Result<()> {
    bail!("this amr-render was built without the `mpi` feature")
}
