//! Progress display on stderr (hidden when stderr is not a terminal).

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use std::sync::atomic::{AtomicBool, Ordering};

/// Every bar of this process, drawn together (two bars drawn apart overwrite each other).
fn bars() -> &'static MultiProgress {
    static BARS: std::sync::OnceLock<MultiProgress> = std::sync::OnceLock::new();
    BARS.get_or_init(MultiProgress::new)
}

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
    let bar = bars().add(ProgressBar::new(len));
    let style = ProgressStyle::with_template(&format!(
        "{{spinner}} [{{elapsed_precise}}] {{bar:30}} {{pos}}/{{len}} {unit} {{msg}}"
    ))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.enable_steady_tick(std::time::Duration::from_millis(120));
    bar
}

/// Who watches a long computation besides the terminal (the viewer's progress bar): told each
/// stage, and asked whether to stop.
pub trait Watcher: Send + Sync {
    /// A stage began; `fraction` of the whole computation is done.
    fn stage(&self, name: &str, fraction: f64);
    /// The computation should stop at the next stage.
    fn cancelled(&self) -> bool;
}

/// A watcher and the share of the whole (from, to) that the current part (a space) covers.
type Watched = (std::sync::Arc<dyn Watcher>, f64, f64);

static WATCHER: std::sync::Mutex<Option<Watched>> = std::sync::Mutex::new(None);

/// Watches what this process computes until the guard drops (one computation at a time).
pub fn watch(w: std::sync::Arc<dyn Watcher>) -> WatchGuard {
    if let Ok(mut g) = WATCHER.lock() {
        *g = Some((w, 0.0, 1.0));
    }
    WatchGuard
}

/// Ends a [`watch`].
pub struct WatchGuard;

impl Drop for WatchGuard {
    fn drop(&mut self) {
        if let Ok(mut g) = WATCHER.lock() {
            *g = None;
        }
    }
}

/// The stages that follow cover `lo..hi` of the whole (a space among several).
pub fn span(lo: f64, hi: f64) {
    if let Ok(mut g) = WATCHER.lock()
        && let Some(w) = g.as_mut()
    {
        (w.1, w.2) = (lo, hi);
    }
}

/// Whether the watcher asked to stop (long stages look between their steps).
pub fn cancelled() -> bool {
    WATCHER
        .lock()
        .ok()
        .and_then(|g| g.as_ref().map(|w| w.0.cancelled()))
        .unwrap_or(false)
}

/// Stage `name` begins, `at` (0 to 1) of the way through the current span. Fails when the
/// watcher asked to stop, so the computation ends there with nothing written.
pub fn stage(name: &str, at: f64) -> anyhow::Result<()> {
    let w = WATCHER.lock().ok().and_then(|g| g.clone());
    if let Some((w, lo, hi)) = w {
        if w.cancelled() {
            anyhow::bail!("cancelled before {name}: nothing was written");
        }
        w.stage(name, lo + at.clamp(0.0, 1.0) * (hi - lo));
    }
    Ok(())
}

/// The stages of a long computation on the terminal: a line per stage with the seconds since
/// the start (printed above a spinner that shows the current one), on stderr, and nothing when
/// stderr is not a terminal or a batch shows its own bar.
pub struct Terminal {
    bar: ProgressBar,
    start: std::time::Instant,
}

impl Terminal {
    /// Shown when `visible` and stderr is a terminal.
    pub fn new(visible: bool) -> Terminal {
        let bar = if visible && !INNER_HIDDEN.load(Ordering::Relaxed) {
            let bar = bars().add(ProgressBar::new_spinner());
            let style = ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner());
            bar.set_style(style);
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            bar
        } else {
            ProgressBar::hidden()
        };
        Terminal {
            bar,
            start: std::time::Instant::now(),
        }
    }
}

impl Watcher for Terminal {
    fn stage(&self, name: &str, fraction: f64) {
        let t = self.start.elapsed().as_secs_f64();
        self.bar.println(format!("{t:7.1} s  {name}"));
        self.bar.set_message(format!("{name} ({:.0} %)", 100.0 * fraction));
    }

    fn cancelled(&self) -> bool {
        false
    }
}

impl Drop for Terminal {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

/// Says `what` on the terminal's stage log, if one is watching (a line that is not a stage: the
/// fraction stays where it is).
pub fn say(what: &str) {
    let w = WATCHER.lock().ok().and_then(|g| g.clone());
    if let Some((w, lo, _)) = w {
        w.stage(what, lo);
    }
}

/// Where log lines go: stderr, each line written with the bars lifted and drawn again after it
/// (indicatif's `suspend`). Written straight to stderr, a warning printed while a bar was drawn
/// was partly erased by the bar's next redraw, and the bar's old frames were left above it.
pub struct LogWriter;

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for LogWriter {
    type Writer = LogLine;

    fn make_writer(&'a self) -> LogLine {
        LogLine(Vec::new())
    }
}

/// One log event, collected and written to stderr as a whole when dropped.
pub struct LogLine(Vec<u8>);

impl std::io::Write for LogLine {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Drop for LogLine {
    fn drop(&mut self) {
        if self.0.is_empty() {
            return;
        }
        let line = std::mem::take(&mut self.0);
        bars().suspend(|| {
            // Nothing to do when stderr itself cannot be written.
            let _ = std::io::Write::write_all(&mut std::io::stderr(), &line);
        });
    }
}
