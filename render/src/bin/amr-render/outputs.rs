//! What a render leaves behind: the EXR frame, the PNG preview and the statistics (printed and
//! as JSON), with outputs checked against the inputs before any work starts.

use std::path::{Path, PathBuf};

use amr_render::mapping::mapped_resident_bytes;
use std::io::Write;

use amr_format::output::temporary_for;
use amr_render::output::exr_file::{write_exr_with, ExrCompression};
use amr_render::output::legend::Legend;
use amr_render::output::png_preview::{preview_rgb8, write_png};
use amr_render::{FrameStats, Rendered, Scene, SceneStats};
use anyhow::Context;
use serde::Serialize;

use crate::render_args::Outputs;
use amr_render::system_memory::peak_rss_bytes;

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

/// The files of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameFiles {
    /// The EXR frame.
    pub exr: PathBuf,
    /// Its PNG preview.
    pub preview: Option<PathBuf>,
    /// How the EXR is compressed.
    pub compression: ExrCompression,
}

impl FrameFiles {
    /// The PNG picture written of the frame, if any: the frame itself or its preview.
    pub fn picture(&self) -> Option<&Path> {
        match is_png(&self.exr) {
            true => Some(&self.exr),
            false => self.preview.as_deref(),
        }
    }

    /// The files of frame `k` of `n`: the names given for one frame; `NAME_0000.ext`,
    /// `NAME_0001.ext`, ... for several. A preview is made beside the EXR when `want_png` asks
    /// for one and none is named.
    pub fn numbered(outputs: &Outputs, k: u32, n: u32, want_png: bool) -> FrameFiles {
        let preview = match &outputs.preview {
            Some(p) => Some(p.clone()),
            None if want_png => Some(outputs.exr.with_extension("png")),
            None => None,
        };
        FrameFiles {
            exr: numbered(&outputs.exr, k, n),
            preview: preview.map(|p| numbered(&p, k, n)),
            compression: outputs.exr_compression,
        }
    }
}

/// `path` itself for a single frame, else `path` with `_{k}` (four digits at least) before its
/// extension.
pub fn numbered(path: &Path, k: u32, n: u32) -> PathBuf {
    if n <= 1 {
        return path.to_path_buf();
    }
    let width = (n - 1).to_string().len().max(4);
    let stem = path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let name = match path.extension() {
        Some(ext) => format!("{stem}_{k:0width$}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{k:0width$}"),
    };
    path.with_file_name(name)
}

/// True for `-`, the name of standard output (`--stats-json -`).
pub fn is_stdout(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Refuses the files of a frame, and the statistics file, when one would replace an input or
/// something that is not a regular file ([`amr_format::output::check_output`]), or names a
/// format this program does not write ([`check_names`]).
pub fn check_frame(files: &FrameFiles, outputs: &Outputs, inputs: &[&Path]) -> anyhow::Result<()> {
    let paths = [
        Some(&files.exr),
        files.preview.as_ref(),
        outputs.stats_json.as_ref().filter(|p| !is_stdout(p)),
    ];
    for out in paths.into_iter().flatten() {
        amr_format::output::check_output(out, inputs)?;
    }
    check_names(&files.exr, files.preview.as_deref())
}

/// Refuses two outputs of a run that are one file: two frames' files, the statistics or the
/// movie over a frame's file, each compared by where it resolves to. A PNG frame and its preview
/// may be one file (the picture is written once).
pub fn check_distinct(files: &[FrameFiles], outputs: &Outputs) -> anyhow::Result<()> {
    let mut named: Vec<(PathBuf, String)> = Vec::new();
    for (k, f) in files.iter().enumerate() {
        named.push((f.exr.clone(), format!("frame {k}")));
        if let Some(p) = f
            .preview
            .as_ref()
            .filter(|p| !(is_png(&f.exr) && *p == &f.exr))
        {
            named.push((p.clone(), format!("frame {k}'s preview")));
        }
    }
    if let Some(p) = outputs.stats_json.as_ref().filter(|p| !is_stdout(p)) {
        named.push((p.clone(), "--stats-json".into()));
    }
    if let Some((p, _)) = &outputs.movie {
        named.push((p.clone(), "--movie".into()));
    }
    let mut seen: std::collections::HashMap<PathBuf, &str> = std::collections::HashMap::new();
    for (path, what) in &named {
        if let Some(first) = seen.insert(amr_format::output::resolved_path(path), what) {
            anyhow::bail!(
                "{}: the output of {what} is also that of {first}; give each its own name",
                path.display()
            );
        }
    }
    Ok(())
}

/// Writes a frame's EXR and its preview.
pub fn write_frame(
    files: &FrameFiles,
    rendered: &Rendered,
    header: &[(String, String)],
    legend: Option<&Legend>,
) -> anyhow::Result<()> {
    if is_png(&files.exr) {
        write_picture(&files.exr, rendered, legend)?;
    } else {
        write_exr_with(&files.exr, &rendered.frame, header, files.compression)?;
    }
    if let Some(p) = &files.preview {
        write_picture(p, rendered, legend)?;
    }
    Ok(())
}

/// Prints the statistics (`--stats`: one row per key of an object, one line per element of a
/// list) followed by `print_also`, and writes them as JSON (`--stats-json`).
pub fn report(outputs: &Outputs, stats: &impl Serialize, print_also: &str) -> anyhow::Result<()> {
    let json = serde_json::to_value(stats)?;
    if outputs.print_stats {
        match &json {
            serde_json::Value::Object(map) => {
                let width = map.keys().map(String::len).max().unwrap_or(0);
                for (k, v) in map.iter().filter(|(_, v)| !v.is_array()) {
                    eprintln!("{k:<width$}  {v}");
                }
            }
            serde_json::Value::Array(items) => {
                for item in items {
                    eprintln!("{item}");
                }
            }
            other => eprintln!("{other}"),
        }
        eprint!("{print_also}");
    }
    if let Some(p) = &outputs.stats_json {
        write_json(p, &json)?;
    }
    Ok(())
}

/// Refuses an output named for a format `amr-render` does not write: the frame must end in
/// `.exr` or `.png` (or have no extension: OpenEXR), a preview in `.png`, whatever the case.
pub fn check_names(output: &Path, preview: Option<&Path>) -> anyhow::Result<()> {
    let ext = |p: &Path| {
        p.extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
    };
    if let Some(e) = ext(output).filter(|e| e != "exr" && e != "png") {
        anyhow::bail!(
            "{}: amr-render writes OpenEXR (.exr) or PNG (.png) frames, not .{e}",
            output.display()
        );
    }
    if let Some(p) = preview.filter(|p| ext(p).as_deref() != Some("png")) {
        anyhow::bail!("{}: the preview is a PNG file: name it .png", p.display());
    }
    Ok(())
}

/// True when `path` names a PNG file.
pub fn is_png(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
}

/// Writes the tone-mapped picture of `rendered` with `legend`, if any, drawn on it as a PNG.
fn write_picture(path: &Path, rendered: &Rendered, legend: Option<&Legend>) -> anyhow::Result<()> {
    let frame = &rendered.frame;
    let mut rgb = preview_rgb8(frame, &rendered.background);
    if let Some(legend) = legend {
        legend.draw(&mut rgb, frame.width, frame.height);
    }
    write_png(path, frame.width, frame.height, &rgb)?;
    Ok(())
}

/// Writes `value` as pretty JSON to `path` through a temporary file.
pub fn write_json(path: &Path, value: &impl Serialize) -> anyhow::Result<()> {
    if is_stdout(path) {
        let body = serde_json::to_string_pretty(value)? + "\n";
        let mut out = std::io::stdout().lock();
        return out
            .write_all(body.as_bytes())
            .and_then(|()| out.flush())
            .context("cannot write the statistics to standard output");
    }
    let fail = || format!("cannot write {}", path.display());
    let mut tmp = temporary_for(path, ".tmp").with_context(fail)?;
    let body = serde_json::to_string_pretty(value)? + "\n";
    tmp.write_all(body.as_bytes()).with_context(fail)?;
    tmp.persist(path).map_err(|e| e.error).with_context(fail)?;
    Ok(())
}
