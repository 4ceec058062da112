//! `amr-render FILE.amrk ...`: the frames of a request, in this process or with MPI ranks.

use amr_render::scene::field_named;
use amr_render::shade::IsoSpec;
use amr_render::Scene;
use anyhow::bail;

use crate::animation::SweptSurface;
use crate::frames;
use crate::render_args::{RenderArgs, RenderRequest};

/// Environment variables that MPI launchers set in every process they start (Open MPI, PMI as in
/// MPICH's Hydra, PMIx).
const LAUNCHER_VARS: [&str; 3] = ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"];

/// True when this process was started by `mpirun` (or another MPI launcher).
pub fn launched_by_mpirun() -> bool {
    LAUNCHER_VARS.iter().any(|v| std::env::var_os(v).is_some())
}

/// Runs the render command.
pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let request = args.request()?;
    let work = || -> anyhow::Result<()> {
        if launched_by_mpirun() {
            if request.clip.is_some() || request.extract_in_view {
                bail!("--clip and --extract-in-view are not supported under mpirun");
            }
            #[cfg(feature = "mpi")]
            return crate::mpi::run::run(&request, args.mpi_mode.as_deref());
            #[cfg(not(feature = "mpi"))]
            bail!(
                "started by mpirun, but this amr-render was built without MPI; \
                 rebuild with `cargo build --release -p amr-render --features mpi`"
            );
        }
        if args.mpi_mode.is_some() {
            bail!("--mpi-mode needs a start with mpirun (mpirun -n N amr-render ...)");
        }
        frames::render_all(&request)
    };
    match request.threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()?
            .install(work),
        None => work(),
    }
}

/// The `--iso-sweep` surface in `scene`'s file, if any: the index of the field it names
/// (`None` for `--field`'s) and the isovalue of every frame, percentiles taken in this file.
pub fn swept_surface(
    request: &RenderRequest,
    scene: &Scene,
) -> anyhow::Result<Option<SweptSurface>> {
    let Some(sweep) = &request.animation.sweep else {
        return Ok(None);
    };
    let field = match &sweep.field {
        Some(n) => Some(field_named(scene.file(), n).map_err(|e| e.in_file(scene.path()))?),
        None => None,
    };
    let index = field.unwrap_or(scene.field());
    let values = sweep.values(scene.file(), scene.path(), index)?;
    Ok(Some(SweptSurface { field, values }))
}

/// The request's isosurfaces for `scene` (the median of the field's values when none given,
/// none for `--iso none`), their fields' names resolved in its file.
pub fn request_isos(request: &RenderRequest, scene: &Scene) -> anyhow::Result<Vec<IsoSpec>> {
    let default = request.isos.is_empty() && request.animation.sweep.is_none();
    match default && !request.no_isosurface {
        true => Ok(vec![IsoSpec::new(scene.default_isovalue())]),
        false => request.isos.iter().map(|s| s.resolve(scene)).collect(),
    }
}
