//! Progress bars on stderr, shown only when stderr is a terminal and the work is long.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

/// A progress bar over `total` units, hidden unless stderr is a terminal and `total >= min_total`.
pub fn bar(total: u64, min_total: u64, message: &str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
    if total >= min_total && std::io::stderr().is_terminal() {
        pb.set_draw_target(ProgressDrawTarget::stderr());
        pb.set_style(
            ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ({eta} left)")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        pb.set_message(message.to_string());
    }
    pb
}

/// A bar over a run of known length (`driftless record --duration`), hidden unless stderr is a
/// terminal; its position is in milliseconds and its message says what was done so far.
pub fn timed(total: std::time::Duration) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(
        Some(total.as_millis().max(1) as u64),
        ProgressDrawTarget::hidden(),
    );
    if std::io::stderr().is_terminal() {
        pb.set_draw_target(ProgressDrawTarget::stderr());
        pb.set_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {percent}%")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
    }
    pb
}
