//! Reading HDF5 (Chombo, Enzo) in a child process: a crash of the HDF5 library on a corrupt
//! file becomes a clear error, not the converter's death (`docs/dependencies.md` says why).
//!
//! For each HDF5 input the parent runs this program again on that input alone, with the same
//! options and [`CHILD_ENV`] set, and waits. The child converts as usual; its output, messages
//! and failure pass through. When it dies of a
//! signal, the parent removes the temporaries it left and reports the input as probably corrupt.

use std::ffi::OsString;
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::Command;

use amr_convert::dump::{detect, InputFormat};
use anyhow::{bail, Context};

/// Set in the child's environment: the child converts in-process.
pub const CHILD_ENV: &str = "AMR_CONVERT_HDF5_CHILD";

/// Test hook: a child with this variable set dies before reading, of SIGABRT as a crash inside
/// the HDF5 library would kill it, or of SIGKILL when the value is `kill`.
pub const TEST_CRASH_ENV: &str = "AMR_CONVERT_TEST_CRASH_CHILD";

/// Signals a crash raises (a bad access, an abort, an illegal instruction): a child dying of
/// another one was killed from outside (Ctrl-C, `kill`), which says nothing about the file.
const CRASH_SIGNALS: [i32; 5] = [
    libc::SIGSEGV,
    libc::SIGBUS,
    libc::SIGABRT,
    libc::SIGILL,
    libc::SIGFPE,
];

/// True when `input` is read through HDF5 (a Chombo or AMReX HDF5 file, an Enzo dataset) and
/// this process is not already the child that reads it.
pub fn needs_child(input: &Path) -> bool {
    let hdf5 = matches!(
        detect(input),
        Ok(InputFormat::ChomboHdf5 | InputFormat::Enzo { .. })
    );
    hdf5 && !is_child()
}

/// True in a child started by [`convert_in_child`].
pub fn is_child() -> bool {
    std::env::var_os(CHILD_ENV).is_some()
}

/// In a child, the crash [`TEST_CRASH_ENV`] asks for.
pub fn crash_if_asked() {
    if !is_child() {
        return;
    }
    match std::env::var(TEST_CRASH_ENV).as_deref() {
        Ok("kill") => {
            let _ = Command::new("kill")
                .args(["-KILL", &std::process::id().to_string()])
                .status();
        }
        Ok(_) => std::process::abort(),
        Err(_) => {}
    }
}

/// The child failed and reported why itself (its exit status was not 0).
#[derive(Debug, thiserror::Error)]
#[error("the converting child process exited with status {0}")]
pub struct ChildFailed(pub i32);

/// Runs this program again as a child converting `input` to `output` with `options` (the
/// command line's other options) and waits; a child killed by a signal is an error naming
/// `input`, a child that failed is [`ChildFailed`].
pub fn convert_in_child(input: &Path, output: &Path, options: &[String]) -> anyhow::Result<()> {
    let mut args: Vec<OsString> = vec![input.into(), "-o".into(), output.into()];
    args.extend(options.iter().map(OsString::from));
    in_child(input, &args, Some(output))
}

/// Runs this program again as a child with `args`, which read `input` (and write `output`, if
/// any), and waits: as [`convert_in_child`].
pub fn in_child(input: &Path, args: &[OsString], output: Option<&Path>) -> anyhow::Result<()> {
    let exe = std::env::current_exe().with_context(|| {
        format!(
            "{}: cannot find this program to run its child",
            input.display()
        )
    })?;
    let status = Command::new(exe)
        .args(args)
        .env(CHILD_ENV, "1")
        .status()
        .with_context(|| {
            format!(
                "{}: cannot start the converting child process (was amr-convert replaced or \
                 removed while it ran?)",
                input.display()
            )
        })?;
    match status.code() {
        Some(0) => return Ok(()),
        Some(code) => return Err(ChildFailed(code).into()),
        None => {}
    }
    if let Some(output) = output {
        amr_format::output::remove_stale_temporaries(output);
    }
    let signal = status.signal().unwrap_or(0);
    if CRASH_SIGNALS.contains(&signal) {
        bail!(
            "{}: the HDF5 library crashed reading it (signal {signal}); the file is probably corrupt",
            input.display()
        )
    }
    bail!(
        "{}: the child process reading it was killed by signal {signal}",
        input.display()
    )
}
