//! A movie of the frames' PNG previews, encoded by `ffmpeg` when it is installed; without it, the
//! command that would encode them is printed instead (the frames are written either way).

use std::path::Path;
use std::process::Command;

use anyhow::{bail, Context};

/// Encodes `pngs` (numbered `NAME_0000.png`, ... in order) at `fps` frames per second into
/// `movie`.
pub fn encode(pngs: &[&Path], fps: u32, movie: &Path) -> anyhow::Result<()> {
    let Some(first) = pngs.first() else {
        bail!("{}: no frames to encode", movie.display());
    };
    let pattern = frame_pattern(first);
    let args = [
        "-y".to_string(),
        "-loglevel".into(),
        "error".into(),
        "-framerate".into(),
        fps.to_string(),
        "-start_number".into(),
        "0".into(),
        "-i".into(),
        pattern.clone(),
        // H.264 wants even sizes and 4:2:0 for players to accept it.
        "-vf".into(),
        "pad=ceil(iw/2)*2:ceil(ih/2)*2".into(),
        "-pix_fmt".into(),
        "yuv420p".into(),
        movie.display().to_string(),
    ];
    match Command::new("ffmpeg").args(&args).status() {
        Ok(status) if status.success() => {
            eprintln!("wrote {}", movie.display());
            Ok(())
        }
        Ok(status) => bail!("{}: ffmpeg failed ({status})", movie.display()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            eprintln!(
                "note: ffmpeg is not installed, so {} was not made; the frames are written. \
                 Encode them with:\n  ffmpeg -framerate {fps} -start_number 0 -i {pattern} \
                 -pix_fmt yuv420p {}",
                movie.display(),
                movie.display()
            );
            Ok(())
        }
        Err(e) => Err(e).with_context(|| format!("{}: cannot run ffmpeg", movie.display())),
    }
}

/// The printf pattern (`NAME_%04d.png`) of numbered frames named like `first`.
fn frame_pattern(first: &Path) -> String {
    let name = first
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let (stem, ext) = name.rsplit_once('.').unwrap_or((&name, ""));
    let (prefix, digits) = stem.rsplit_once('_').unwrap_or((stem, ""));
    let file = format!("{prefix}_%0{}d.{ext}", digits.len().max(1));
    first.with_file_name(file).display().to_string()
}
