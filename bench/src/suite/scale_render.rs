//! The render the scale section measures for each file: the scene pipeline of `amr-render FILE
//! --iso V --size 256x256 --ao 0 --no-shadows` (octant reconstruction, hybrid tracer, map pages
//! released between the stages) with the statistics its `--stats-json` holds under the same
//! keys. It runs in a child `amr-bench render-stats FILE --iso V` so that the peak RSS
//! (`VmHWM`) is the render's own.

use std::path::Path;
use std::process::Command;

use amr_render::mapping::mapped_resident_bytes;
use amr_render::{
    render, FrameStats, IsoSpec, Reconstruction, Scene, SceneOptions, SceneStats, TraceMethod, View,
};
use anyhow::{bail, Context};
use serde::Serialize;

use crate::probe::peak_rss_bytes;

/// The hidden `amr-bench` subcommand that runs [`render_stats`] and prints it as JSON.
pub const CHILD_COMMAND: &str = "render-stats";

/// Image width and height of the measured frame.
pub const SIZE: (u32, u32) = (256, 256);

/// What one render cost, with the keys of `amr-render --stats-json`.
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// Extraction and BVH build.
    #[serde(flatten)]
    pub scene: SceneStats,
    /// The frame.
    #[serde(flatten)]
    pub frame: FrameStats,
    /// Peak resident memory of the process after the frame.
    pub peak_rss_bytes: Option<u64>,
    /// Bytes of the map resident after the frame.
    pub mapped_resident_bytes: Option<u64>,
    /// Most map bytes resident at once.
    pub mapped_resident_peak_bytes: u64,
}

/// Opens `path`, extracts and builds the surface `iso` and renders one frame, as `amr-render`
/// does with the arguments in the module's description.
pub fn render_stats(path: &Path, iso: f32) -> anyhow::Result<RenderStats> {
    let options = SceneOptions {
        field: None,
        reconstruction: Reconstruction::Octant,
        method: TraceMethod::Hybrid,
        release_pages: true,
    };
    let mut scene = Scene::open(path, &options)?;
    scene.set_isosurfaces(&[IsoSpec::new(iso)])?;
    let view = View {
        size: SIZE,
        shadows: false,
        ao_rays: 0,
        ..View::default()
    };
    let frame = render(&scene, &view, &|_| {})?;
    let resident = mapped_resident_bytes(scene.file().bytes());
    let peak = scene.source().mapped_resident_peak_bytes().unwrap_or(0);
    Ok(RenderStats {
        scene: scene.stats().clone(),
        frame: frame.stats,
        peak_rss_bytes: peak_rss_bytes(),
        mapped_resident_bytes: resident,
        mapped_resident_peak_bytes: peak.max(resident.unwrap_or(0)),
    })
}

/// [`render_stats`] of `path` run by a child `exe` (an `amr-bench`), or in this process when
/// `exe` is `None` (the peak RSS is then this whole process's): the numeric values by key.
pub fn measure(exe: Option<&Path>, path: &Path, iso: f32) -> anyhow::Result<Vec<(String, f64)>> {
    let json = match exe {
        None => serde_json::to_value(render_stats(path, iso)?)?,
        Some(exe) => {
            let out = Command::new(exe)
                .arg(CHILD_COMMAND)
                .arg(path)
                .args(["--iso", &iso.to_string()])
                .output()
                .with_context(|| format!("cannot run the child render {}", exe.display()))?;
            if !out.status.success() {
                bail!(
                    "child render failed: {}",
                    String::from_utf8_lossy(&out.stderr)
                );
            }
            serde_json::from_slice(&out.stdout).context("the child render's statistics")?
        }
    };
    let serde_json::Value::Object(map) = json else {
        bail!("the render statistics are not a JSON object");
    };
    Ok(map
        .into_iter()
        .filter_map(|(k, v)| Some((k, v.as_f64()?)))
        .collect())
}
