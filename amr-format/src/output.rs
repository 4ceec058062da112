//! Output paths: refusing one that would replace an input or something that is not a regular
//! file, and the temporaries written beside an output, named so that stale ones can be removed.
//!
//! A temporary for target `DIR/NAME` is `DIR/.NAME.PID.XXXXXX.tmp` (or `.spill`), where PID is
//! the writing process. A writer gone without cleaning up (killed, power loss) leaves its
//! temporaries behind; the next writer of the same target removes those whose PID is no longer
//! a running process ([`remove_stale_temporaries`]).

use std::fs;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

use crate::error::{FormatError, Result};

/// Refuses `output` when writing it would replace something it must not: an existing path that
/// is not a regular file (a directory, a device such as `/dev/null`, a pipe), one of `inputs`
/// (the same file, through any name), a path inside an input directory, or a path in a
/// directory that does not exist (the write would fail only after all the work).
///
/// Writers replace their output by renaming a finished temporary over it, so a device or pipe
/// would be replaced, not written to. Symbolic links are followed for the comparison.
pub fn check_output(output: &Path, inputs: &[&Path]) -> Result<()> {
    let refuse = |reason: String| {
        Err(FormatError::Output {
            path: output.to_path_buf(),
            reason,
        })
    };
    let out_meta = fs::metadata(output).ok();
    if let Some(m) = &out_meta {
        if !m.file_type().is_file() {
            let what = if m.is_dir() {
                "a directory"
            } else {
                "not a regular file (a device, pipe or socket)"
            };
            return refuse(format!(
                "the output is {what}; refusing to replace it (name a new or regular file)"
            ));
        }
    }
    let dir = target_dir(output);
    if !dir.is_dir() {
        return refuse(format!(
            "its directory {} does not exist (make it first)",
            dir.display()
        ));
    }
    let out_dir = output_dir(output);
    for input in inputs {
        let Ok(in_meta) = fs::metadata(input) else {
            continue;
        };
        if let Some(m) = &out_meta {
            if (m.dev(), m.ino()) == (in_meta.dev(), in_meta.ino()) {
                return refuse(format!(
                    "the output is the input {}; refusing to replace it",
                    input.display()
                ));
            }
        }
        if in_meta.is_dir() {
            if let (Some(dir), Ok(input_dir)) = (&out_dir, fs::canonicalize(input)) {
                if dir.starts_with(&input_dir) {
                    return refuse(format!(
                        "the output lies inside the input directory {}; refusing to write there",
                        input.display()
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The directory `output` would be written in, resolved, when it exists.
fn output_dir(output: &Path) -> Option<PathBuf> {
    fs::canonicalize(target_dir(output)).ok()
}

/// Where `output` would be written: its directory resolved (links followed, `.` and `..`
/// gone), then its name; `output` itself when the directory does not exist. Two outputs that
/// resolve alike are one file.
pub fn resolved_path(output: &Path) -> PathBuf {
    match (output_dir(output), output.file_name()) {
        (Some(dir), Some(name)) => dir.join(name),
        _ => output.to_path_buf(),
    }
}

/// A new temporary file for writing `target`, beside it and named after it and this process
/// (see the module documentation), with the permissions of an ordinary new file (it is renamed
/// into place when complete). `suffix` is `.tmp` for the file itself, `.spill` for scratch.
pub fn temporary_for(target: &Path, suffix: &str) -> Result<NamedTempFile> {
    let dir = target_dir(target);
    tempfile::Builder::new()
        .prefix(&format!("{}{}.", temp_prefix(target), std::process::id()))
        .suffix(suffix)
        .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644))
        .tempfile_in(&dir)
        .map_err(|e| FormatError::io(format!("creating a temporary file in {}", dir.display()), e))
}

/// Bytes an unprivileged writer may still put on the file system that `target` would be written
/// to (`statvfs` of its directory: available blocks times their size); `None` when unknown.
pub fn free_bytes_for(target: &Path) -> Option<u64> {
    let st = rustix::fs::statvfs(target_dir(target)).ok()?;
    st.f_bavail.checked_mul(st.f_frsize)
}

/// Refuses to write `need` bytes to `target` when its file system has less free (the writer
/// would fail part way, or fill the disk for others): the error names the file, the bytes
/// needed and those free.
pub fn check_room(target: &Path, need: u64) -> Result<()> {
    match free_bytes_for(target) {
        Some(free) if need > free => Err(FormatError::Output {
            path: target.to_path_buf(),
            reason: format!(
                "the file needs {} and its file system has {} free",
                describe_bytes(need),
                describe_bytes(free)
            ),
        }),
        _ => Ok(()),
    }
}

/// `bytes` for a message: KiB below a MiB, MiB below a GiB, else GiB with one decimal.
pub fn describe_bytes(bytes: u64) -> String {
    const KIB: f64 = 1024.0;
    let b = bytes as f64;
    if b < KIB * KIB {
        format!("{:.0} KiB", b / KIB)
    } else if b < KIB * KIB * KIB {
        format!("{:.0} MiB", b / (KIB * KIB))
    } else {
        format!("{:.1} GiB", b / (KIB * KIB * KIB))
    }
}

/// Removes the temporaries of `target` (named as [`temporary_for`] names them) whose writing
/// process is no longer running; returns how many were removed. Does nothing where running
/// processes cannot be listed (no `/proc`). A failure to remove one is not an error.
pub fn remove_stale_temporaries(target: &Path) -> usize {
    if !Path::new("/proc/self").exists() {
        return 0;
    }
    let prefix = temp_prefix(target);
    let Ok(entries) = fs::read_dir(target_dir(target)) else {
        return 0;
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(pid) = stale_pid(name, &prefix) else {
            continue;
        };
        if !Path::new("/proc").join(pid.to_string()).exists()
            && fs::remove_file(entry.path()).is_ok()
        {
            removed += 1;
        }
    }
    removed
}

/// The PID in `name` when it is a temporary `{prefix}{pid}.XXXXXX{.tmp|.spill}`.
fn stale_pid(name: &str, prefix: &str) -> Option<u32> {
    let rest = name.strip_prefix(prefix)?;
    if !(rest.ends_with(".tmp") || rest.ends_with(".spill")) {
        return None;
    }
    let (pid, _) = rest.split_once('.')?;
    pid.parse().ok()
}

fn temp_prefix(target: &Path) -> String {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    format!(".{name}.")
}

fn target_dir(target: &Path) -> PathBuf {
    match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_output_in_a_missing_directory_is_refused_before_any_work() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("frames").join("f.exr");
        let err = check_output(&missing, &[]).unwrap_err().to_string();
        assert!(
            err.contains("frames") && err.contains("does not exist"),
            "{err}"
        );
        assert!(check_output(&dir.path().join("f.exr"), &[]).is_ok());
        // A bare name is in the directory the command runs in, which exists.
        assert!(check_output(Path::new("f.exr"), &[]).is_ok());
    }

    #[test]
    fn a_file_larger_than_the_free_space_is_refused_naming_both() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("big.amrk");
        let free = free_bytes_for(&target).expect("statvfs works on a temporary directory");
        assert!(free > 0);
        assert!(check_room(&target, 0).is_ok());
        assert!(check_room(&target, free / 2).is_ok());
        let err = check_room(&target, u64::MAX).unwrap_err().to_string();
        assert!(err.contains("big.amrk") && err.contains("iB free"), "{err}");
        assert_eq!(describe_bytes(3_000_000), "3 MiB");
        assert_eq!(describe_bytes(600_000), "586 KiB");
    }

    #[test]
    fn refuses_inputs_directories_devices_and_paths_inside_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.amrk");
        fs::write(&input, b"x").unwrap();
        let link = dir.path().join("link.amrk");
        std::os::unix::fs::symlink(&input, &link).unwrap();
        let plot = dir.path().join("plt");
        fs::create_dir(&plot).unwrap();
        fs::write(plot.join("Header"), b"h").unwrap();
        let msg = |out: &Path, inputs: &[&Path]| check_output(out, inputs).unwrap_err().to_string();
        assert!(msg(&input, &[&input]).contains("is the input"));
        assert!(msg(&link, &[&input]).contains("is the input"));
        assert!(msg(&plot.join("Header"), &[&plot]).contains("inside the input directory"));
        assert!(msg(&plot.join("new.amrk"), &[&plot]).contains("inside the input directory"));
        assert!(msg(&plot, &[]).contains("a directory"));
        assert!(msg(Path::new("/dev/null"), &[]).contains("not a regular file"));
        check_output(&dir.path().join("out.amrk"), &[&input, &plot]).unwrap();
        check_output(&input, &[&plot]).unwrap();
    }

    #[test]
    fn stale_temporaries_of_dead_writers_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.amrk");
        let live = temporary_for(&target, ".tmp").unwrap();
        // A PID above the kernel's maximum (2^22) is never a running process.
        let dead = dir.path().join(".out.amrk.99999999.abc123.tmp");
        let dead_spill = dir.path().join(".out.amrk.99999999.def456.spill");
        let other = dir.path().join(".other.amrk.99999999.abc123.tmp");
        for p in [&dead, &dead_spill, &other] {
            fs::write(p, b"x").unwrap();
        }
        assert_eq!(remove_stale_temporaries(&target), 2);
        assert!(live.path().exists() && other.exists());
        assert!(!dead.exists() && !dead_spill.exists());
    }
}
