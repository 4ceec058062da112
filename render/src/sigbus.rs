//! A SIGBUS on a mapped file (it was truncated while it was read) becomes a clear error naming
//! the file and exit status 1, instead of a signal death.
//!
//! [`watch`] records a map's address range and its file's path in a fixed table of atomics.
//! A program opts in with [`install`] (`amr-render` does, first thing): a signal handler is
//! process-wide, so a library must not take it from the application that embeds it. The handler
//! finds the faulting address in the table, writes `Error: FILE: the file changed or was
//! truncated while it was read` with `write(2)` and leaves with `_exit(1)`: both
//! async-signal-safe, and the table is read with atomic loads only. A fault outside every
//! watched map goes to the handler installed before (or the default action, which kills the
//! process as before).

use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::sync::{Once, OnceLock};

/// Maps watched at once; a map opened when all are taken is not watched (it still works).
const SLOTS: usize = 64;
/// Path bytes kept per map; longer paths are cut (with "...").
const PATH_BYTES: usize = 1024;

struct Slot {
    used: AtomicBool,
    start: AtomicUsize,
    end: AtomicUsize,
    len: AtomicUsize,
    path: [AtomicU8; PATH_BYTES],
}

impl Slot {
    const fn new() -> Self {
        Self {
            used: AtomicBool::new(false),
            start: AtomicUsize::new(0),
            end: AtomicUsize::new(0),
            len: AtomicUsize::new(0),
            path: [const { AtomicU8::new(0) }; PATH_BYTES],
        }
    }
}

static TABLE: [Slot; SLOTS] = [const { Slot::new() }; SLOTS];
static INSTALL: Once = Once::new();
/// The SIGBUS action [`install`] replaced, for faults outside every watched map.
static PREVIOUS: OnceLock<libc::sigaction> = OnceLock::new();

/// A watched map: dropping it (before the map is unmapped) stops watching.
#[derive(Debug)]
pub struct Watch {
    slot: Option<usize>,
}

impl Drop for Watch {
    fn drop(&mut self) {
        if let Some(i) = self.slot {
            let s = &TABLE[i];
            s.end.store(0, Ordering::Release);
            s.start.store(0, Ordering::Release);
            s.used.store(false, Ordering::Release);
        }
    }
}

/// Watches the mapped bytes `map` of the file `path`: once [`install`] was called, a SIGBUS
/// there ends the process with a message naming `path` and exit status 1.
pub fn watch(path: &std::path::Path, map: &[u8]) -> Watch {
    let Some(i) = TABLE.iter().position(|s| {
        s.used
            .compare_exchange(false, true, Ordering::AcqRel, Ordering::Relaxed)
            .is_ok()
    }) else {
        return Watch { slot: None };
    };
    let s = &TABLE[i];
    let bytes = path.as_os_str().as_encoded_bytes();
    let cut = bytes.len() > PATH_BYTES;
    let keep = if cut { PATH_BYTES - 3 } else { bytes.len() };
    for (dst, &b) in s.path.iter().zip(bytes[..keep].iter().chain(b"...")) {
        dst.store(b, Ordering::Relaxed);
    }
    s.len
        .store(if cut { PATH_BYTES } else { keep }, Ordering::Relaxed);
    let start = map.as_ptr() as usize;
    s.start.store(start, Ordering::Release);
    s.end.store(start + map.len(), Ordering::Release);
    Watch { slot: Some(i) }
}

/// Installs, once per process, the SIGBUS handler that turns a fault on a watched map into an
/// error naming its file and exit status 1. For programs; a library leaves the choice to them.
pub fn install() {
    INSTALL.call_once(|| {
        // SAFETY: `action` is fully initialised (zeroed, then the handler, flags and an empty
        // mask set) before `sigaction` reads it, and `previous` is written by `sigaction`
        // before it is read; the handler has the three-argument signature SA_SIGINFO requires.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_sigbus as *const () as libc::sighandler_t;
            action.sa_flags = libc::SA_SIGINFO;
            libc::sigemptyset(&mut action.sa_mask);
            let mut previous: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(libc::SIGBUS, &action, &mut previous) == 0 {
                let _ = PREVIOUS.set(previous);
            }
        }
    });
}

/// Hands a fault outside every watched map to the action [`install`] replaced: its handler, or
/// the default action (restored, so that the fault, repeated on return, kills the process).
///
/// # Safety
/// Only from the SIGBUS handler, with the arguments the kernel passed it.
unsafe fn pass_on(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
    // SAFETY: `PREVIOUS` holds the action `sigaction` reported, whose handler field is SIG_DFL,
    // SIG_IGN or a function of the signature its SA_SIGINFO flag says; calling it as the kernel
    // would is what chaining handlers means. signal(2) is async-signal-safe.
    unsafe {
        match PREVIOUS.get() {
            Some(p) if p.sa_sigaction != libc::SIG_DFL && p.sa_sigaction != libc::SIG_IGN => {
                if p.sa_flags & libc::SA_SIGINFO != 0 {
                    let handler: extern "C" fn(
                        libc::c_int,
                        *mut libc::siginfo_t,
                        *mut libc::c_void,
                    ) = std::mem::transmute(p.sa_sigaction);
                    handler(sig, info, ctx);
                } else {
                    let handler: extern "C" fn(libc::c_int) = std::mem::transmute(p.sa_sigaction);
                    handler(sig);
                }
            }
            _ => {
                libc::signal(libc::SIGBUS, libc::SIG_DFL);
            }
        }
    }
}

extern "C" fn on_sigbus(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
    // SAFETY: the kernel passes a valid siginfo for SA_SIGINFO handlers; `si_addr` is the faulting
    // address for SIGBUS. write(2), _exit(2) and signal(2) are async-signal-safe, and the
    // buffers written live on this stack frame.
    unsafe {
        let addr = (*info).si_addr() as usize;
        let Some(s) = TABLE.iter().find(|s| {
            let start = s.start.load(Ordering::Acquire);
            start != 0 && start <= addr && addr < s.end.load(Ordering::Acquire)
        }) else {
            pass_on(sig, info, ctx);
            return;
        };
        let mut path = [0u8; PATH_BYTES];
        let len = s.len.load(Ordering::Relaxed).min(PATH_BYTES);
        for (dst, src) in path.iter_mut().zip(&s.path).take(len) {
            *dst = src.load(Ordering::Relaxed);
        }
        for part in [
            &b"Error: "[..],
            &path[..len],
            &b": the file changed or was truncated while it was read\n"[..],
        ] {
            libc::write(2, part.as_ptr().cast(), part.len());
        }
        libc::_exit(1);
    }
}
