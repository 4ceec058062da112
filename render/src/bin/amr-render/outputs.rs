//! What a render leaves behind: the EXR frame, the PNG preview and the statistics (printed and
//! as JSON), with outputs checked against the inputs before any work starts.

use std::path::{Path, PathBuf};

use amr_render::mapping::mapped_resident_bytes;
use amr_render::output::exr_file::{temp_path, write_exr};
use amr_render::output::legend::Legend;
use amr_render::output::png_preview::{preview_rgb8, write_png};
use amr_render::{FrameStats, Rendered, Scene, SceneStats};
use anyhow::{bail, Context};
use serde::Serialize;

use crate::probe::peak_rss_bytes;
use crate::render_args::Outputs;

/// The statistics of one render, as `--stats` prints them and `--stats-json` writes them.
#[derive(Serialize)]
pub struct RunStats<X: Serialize> {
    /// The scene's extraction and build.
    #[serde(flatten)]
    pub scene: SceneStats,
    /// The frame.
    #[serde(flatten)]
    pub frame: FrameStats,
    /// Peak resident memory of the process.
    pub peak_rss_bytes: Option<u64>,
    /// The field rendered.
    pub field: String,
    /// Size of the file.
    pub file_bytes: u64,
    /// What the run adds (memory of one process, or the ranks of an MPI run).
    #[serde(flatten)]
    pub extra: X,
}

/// The memory of a single-process render.
#[derive(Serialize)]
pub struct ProcessMemory {
    /// Bytes held by the per-thread voxel caches.
    pub voxel_cache_bytes: u64,
    /// Bytes of the map resident at the end.
    pub mapped_resident_bytes: Option<u64>,
    /// Most map bytes resident at once.
    pub mapped_resident_peak_bytes: u64,
}

impl<X: Serialize> RunStats<X> {
    /// The statistics of `rendered`, a frame of `scene`, with `extra`.
    pub fn new(scene: &Scene, frame: FrameStats, extra: X) -> Self {
        RunStats {
            scene: scene.stats().clone(),
            frame,
            peak_rss_bytes: peak_rss_bytes(),
            field: scene.field_name().to_string(),
            file_bytes: scene.file().bytes().len() as u64,
            extra,
        }
    }
}

impl ProcessMemory {
    /// The memory `scene` holds now.
    pub fn of(scene: &Scene) -> Self {
        let bytes = scene.file().bytes();
        let resident = mapped_resident_bytes(bytes);
        ProcessMemory {
            voxel_cache_bytes: scene.source().voxel_cache_bytes(),
            mapped_resident_bytes: resident,
            mapped_resident_peak_bytes: scene
                .source()
                .mapped_resident_peak_bytes()
                .unwrap_or(0)
                .max(resident.unwrap_or(0)),
        }
    }
}

/// Refuses outputs that would replace an input or something that is not a regular file.
pub fn check(outputs: &Outputs, inputs: &[&Path]) -> anyhow::Result<()> {
    let paths: Vec<&PathBuf> = [Some(&outputs.exr), outputs.preview.as_ref(), outputs.stats_json.as_ref()]
        .into_iter()
        .flatten()
        .collect();
    for out in paths {
        if let Ok(meta) = std::fs::metadata(out) {
            if !meta.is_file() {
                bail!("{}: the output exists and is not a regular file; refusing to replace it", out.display());
            }
            for input in inputs {
                if same_file(out, input) {
                    bail!("{}: the output is the input {}; refusing to replace it", out.display(), input.display());
                }
            }
        }
    }
    Ok(())
}

/// True when `a` and `b` name the same file.
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

/// Writes the frame, the preview and the statistics as `outputs` asks.
pub fn write<X: Serialize>(
    outputs: &Outputs,
    rendered: &Rendered,
    header: &[(String, String)],
    stats: &RunStats<X>,
    print_also: &str,
    legend: &Legend,
) -> anyhow::Result<()> {
    if is_png(&outputs.exr) {
        write_picture(&outputs.exr, rendered, legend)?;
    } else {
        write_exr(&outputs.exr, &rendered.frame, header)?;
    }
    if let Some(p) = &outputs.preview {
        write_picture(p, rendered, legend)?;
    }
    let json = serde_json::to_value(stats)?;
    if outputs.print_stats {
        if let Some(map) = json.as_object() {
            let width = map.keys().map(String::len).max().unwrap_or(0);
            for (k, v) in map.iter().filter(|(_, v)| !v.is_array()) {
                eprintln!("{k:<width$}  {v}");
            }
        }
        eprint!("{print_also}");
    }
    if let Some(p) = &outputs.stats_json {
        write_json(p, &json)?;
    }
    Ok(())
}

/// True when `path` names a PNG file.
pub fn is_png(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"))
}

/// Writes the tone-mapped picture of `rendered` with `legend` drawn on it as a PNG.
fn write_picture(path: &Path, rendered: &Rendered, legend: &Legend) -> anyhow::Result<()> {
    let frame = &rendered.frame;
    let mut rgb = preview_rgb8(frame);
    legend.draw(&mut rgb, frame.width, frame.height);
    write_png(path, frame.width, frame.height, &rgb)?;
    Ok(())
}

/// Writes `value` as pretty JSON to `path` through a temporary file.
pub fn write_json(path: &Path, value: &impl Serialize) -> anyhow::Result<()> {
    let tmp = temp_path(path);
    let body = serde_json::to_string_pretty(value)? + "\n";
    if let Err(e) = std::fs::write(&tmp, body) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("cannot write {}", path.display()));
    }
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}
