//! Progress bars for long work (indicatif), hidden when stderr is not a terminal or in CI.

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar over `len` items with an ETA, labelled `what`. Hidden (but still counting)
/// when stderr is not a terminal.
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        ProgressBar::new(len)
    } else {
        ProgressBar::hidden()
    };
    pb.set_style(
        ProgressStyle::with_template(
            "{msg:>12} [{elapsed_precise}] {wide_bar} {pos}/{len} (ETA {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.set_message(what.to_string());
    pb
}
