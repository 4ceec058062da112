//! A progress bar for long frames, and a spinner for the steps before a frame (opening a file,
//! extracting, building): drawn on stderr once they have taken more than a second, and only
//! when stderr is a terminal.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A bar of `len` units labelled `unit`, and the callback the library advances it through.
pub fn bar(len: u64, unit: &str) -> (ProgressBar, impl Fn(u64) + Sync) {
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::hidden());
    let template = format!("{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {unit} ({{eta}})");
    if let Ok(style) = ProgressStyle::with_template(&template) {
        bar.set_style(style);
    }
    let start = Instant::now();
    let shown = AtomicBool::new(false);
    let terminal = std::io::stderr().is_terminal();
    let b = bar.clone();
    let advance = move |n: u64| {
        b.inc(n);
        if terminal && !shown.load(Ordering::Relaxed) && start.elapsed() > Duration::from_secs(1) {
            shown.store(true, Ordering::Relaxed);
            b.set_draw_target(ProgressDrawTarget::stderr());
        }
    };
    (bar, advance)
}

/// A step before a frame, shown as a spinner with `what` and the time spent once it has taken
/// more than a second (on a terminal); cleared when dropped.
pub struct Stage {
    bar: ProgressBar,
    done: Arc<AtomicBool>,
}

/// Starts showing `what` as a [`Stage`].
pub fn stage(what: &str) -> Stage {
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    if let Ok(style) = ProgressStyle::with_template("{elapsed_precise} {spinner} {msg}") {
        bar.set_style(style);
    }
    bar.set_message(what.to_string());
    let done = Arc::new(AtomicBool::new(false));
    if std::io::stderr().is_terminal() {
        let (b, d) = (bar.clone(), Arc::clone(&done));
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_secs(1));
            if !d.load(Ordering::Acquire) {
                b.set_draw_target(ProgressDrawTarget::stderr());
                b.enable_steady_tick(Duration::from_millis(120));
                // The stage may have ended meanwhile: its drop cleared a bar not yet shown.
                if d.load(Ordering::Acquire) {
                    b.finish_and_clear();
                }
            }
        });
    }
    Stage { bar, done }
}

impl Drop for Stage {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Release);
        self.bar.finish_and_clear();
    }
}
