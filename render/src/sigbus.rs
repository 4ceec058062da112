//! A SIGBUS on a mapped file (it was truncated while it was read) becomes a clear error naming
//! the file and exit status 1, instead of a signal death.
//!
//! [`watch`] records a map's address range and its file's path in a fixed table of atomics and
//! installs, once, a SIGBUS handler. The handler finds the faulting address in the table, writes
//! `Error: FILE: the file changed or was truncated while it was read` with `write(2)` and leaves
//! with `_exit(1)`: both async-signal-safe, and the table is read with atomic loads only. A fault
//! outside every watched map restores the default action, so it kills the process as before.

use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::sync::Once;

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

/// Watches the mapped bytes `map` of the file `path`: a SIGBUS there ends the process with a
/// message naming `path` and exit status 1.
pub fn watch(path: &std::path::Path, map: &[u8]) -> Watch {
    INSTALL.call_once(install);
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

fn install() {
    // SAFETY: `action` is fully initialised (zeroed, then the handler, flags and an empty mask
    // set) before `sigaction` reads it; the handler has the three-argument signature SA_SIGINFO
    // requires and only does async-signal-safe things (atomic loads, write(2), _exit(2)).
    unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = on_sigbus as *const () as libc::sighandler_t;
        action.sa_flags = libc::SA_SIGINFO;
        libc::sigemptyset(&mut action.sa_mask);
        libc::sigaction(libc::SIGBUS, &action, std::ptr::null_mut());
    }
}

extern "C" fn on_sigbus(_sig: libc::c_int, info: *mut libc::siginfo_t, _ctx: *mut libc::c_void) {
    // SAFETY: the kernel passes a valid siginfo for SA_SIGINFO handlers; `si_addr` is the faulting
    // address for SIGBUS. write(2), _exit(2) and signal(2) are async-signal-safe, and the
    // buffers written live on this stack frame.
    unsafe {
        let addr = (*info).si_addr() as usize;
        let Some(s) = TABLE.iter().find(|s| {
            let start = s.start.load(Ordering::Acquire);
            start != 0 && start <= addr && addr < s.end.load(Ordering::Acquire)
        }) else {
            // Not a watched map: let the fault happen again with the default action.
            libc::signal(libc::SIGBUS, libc::SIG_DFL);
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
