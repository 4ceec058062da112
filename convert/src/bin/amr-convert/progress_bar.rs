//! A terminal progress bar for the library's [`Progress`] reports.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use amr_format::progress::Progress;

/// A terminal progress bar on stderr counting bytes, with rate and ETA; hidden when stderr is
/// not a terminal.
pub struct Bar {
    bar: ProgressBar,
}

impl Bar {
    /// A byte-counting bar labelled `message`.
    pub fn bytes(message: &str) -> Self {
        let bar = ProgressBar::with_draw_target(Some(0), Self::target());
        let style = ProgressStyle::with_template(
            "{msg} [{bar:40.cyan/blue}] {bytes}/{total_bytes} {bytes_per_sec} ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
        bar.set_style(style);
        bar.set_message(message.to_string());
        Bar { bar }
    }

    fn target() -> ProgressDrawTarget {
        if std::io::stderr().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        }
    }
}

impl Progress for Bar {
    fn set_total(&self, n: u64) {
        self.bar.set_length(n);
    }
    fn advance(&self, n: u64) {
        self.bar.inc(n);
    }
    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
