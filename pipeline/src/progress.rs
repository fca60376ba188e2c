//! Progress display on stderr (hidden when stderr is not a terminal).

use indicatif::{ProgressBar, ProgressStyle};
use std::sync::atomic::{AtomicBool, Ordering};

static INNER_HIDDEN: AtomicBool = AtomicBool::new(false);

/// Hides the bars of inner stages (a batch shows one bar for all its scenes instead).
pub fn hide_inner(hidden: bool) {
    INNER_HIDDEN.store(hidden, Ordering::Relaxed);
}

/// A bar of `len` steps counting `unit` (hidden inside a batch).
pub fn bar(len: u64, unit: &str) -> ProgressBar {
    if INNER_HIDDEN.load(Ordering::Relaxed) {
        return ProgressBar::hidden();
    }
    outer_bar(len, unit)
}

/// A bar that shows even inside a batch (the batch's own).
pub fn outer_bar(len: u64, unit: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    let style = ProgressStyle::with_template(&format!(
        "{{spinner}} [{{elapsed_precise}}] {{bar:30}} {{pos}}/{{len}} {unit} {{msg}}"
    ))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.enable_steady_tick(std::time::Duration::from_millis(120));
    bar
}
