//! Who watches a long computation: told each stage, each count's steps, and asked whether to
//! stop. The library draws nothing itself; the `ves` binary's terminal, the viewer's progress bar
//! and Python's tqdm are watchers.
//!
//! Watchers nest: [`watch`] puts one on top for as long as its guard lives, and dropping the
//! guard removes that one only (a batch's quiet inner watcher ends, the terminal's stays).

use std::sync::{Arc, Mutex};

/// A watcher of long computations.
pub trait Watcher: Send + Sync {
    /// A stage began; `fraction` of the whole computation is done.
    fn stage(&self, name: &str, fraction: f64);
    /// The computation should stop at the next stage.
    fn cancelled(&self) -> bool {
        false
    }
    /// A count of `len` steps of `unit` begins (a bar on a terminal).
    fn count(&self, _len: u64, _unit: &str) -> Box<dyn Count> {
        Box::new(Uncounted)
    }
    /// An outcome worth a line of its own (a batch's scene done or failed).
    fn note(&self, _line: &str) {}
}

/// The steps of one count, told as they are done (from any thread).
pub trait Count: Send + Sync {
    /// `n` more steps are done.
    fn inc(&self, n: u64);
    /// What the current step is.
    fn message(&self, _what: &str) {}
}

/// A count nobody watches.
struct Uncounted;

impl Count for Uncounted {
    fn inc(&self, _n: u64) {}
}

/// A watcher on the stack, and the share of the whole (from, to) that the current part (a
/// space among several) covers.
struct Watched {
    id: u64,
    watcher: Arc<dyn Watcher>,
    lo: f64,
    hi: f64,
}

/// The watchers, innermost last, and the next guard's id.
static WATCHERS: Mutex<(Vec<Watched>, u64)> = Mutex::new((Vec::new(), 0));

fn with_top<T>(f: impl FnOnce(&mut Watched) -> T) -> Option<T> {
    let mut g = WATCHERS.lock().unwrap_or_else(|p| p.into_inner());
    g.0.last_mut().map(f)
}

/// Watches what this process computes until the guard drops; an inner watch hides the outer
/// one meanwhile.
pub fn watch(w: Arc<dyn Watcher>) -> WatchGuard {
    let mut g = WATCHERS.lock().unwrap_or_else(|p| p.into_inner());
    g.1 += 1;
    let id = g.1;
    g.0.push(Watched {
        id,
        watcher: w,
        lo: 0.0,
        hi: 1.0,
    });
    WatchGuard { id }
}

/// Ends its [`watch`] (only its own, wherever it is on the stack).
#[must_use = "the watch ends when the guard drops"]
pub struct WatchGuard {
    id: u64,
}

impl Drop for WatchGuard {
    fn drop(&mut self) {
        let mut g = WATCHERS.lock().unwrap_or_else(|p| p.into_inner());
        g.0.retain(|w| w.id != self.id);
    }
}

/// The innermost watcher and its span.
fn current() -> Option<(Arc<dyn Watcher>, f64, f64)> {
    with_top(|w| (w.watcher.clone(), w.lo, w.hi))
}

/// The stages that follow cover `lo..hi` of the whole (a space among several).
pub fn span(lo: f64, hi: f64) {
    with_top(|w| (w.lo, w.hi) = (lo, hi));
}

/// Whether the watcher asked to stop (long stages look between their steps).
pub fn cancelled() -> bool {
    current().is_some_and(|(w, _, _)| w.cancelled())
}

/// Stage `name` begins, `at` (0 to 1) of the way through the current span. Fails when the
/// watcher asked to stop, so the computation ends there with nothing written.
pub fn stage(name: &str, at: f64) -> anyhow::Result<()> {
    if let Some((w, lo, hi)) = current() {
        if w.cancelled() {
            anyhow::bail!("cancelled before {name}: nothing was written");
        }
        w.stage(name, lo + at.clamp(0.0, 1.0) * (hi - lo));
    }
    Ok(())
}

/// Says `what` on the watcher's stage log (a line that is not a stage: the fraction stays where
/// it is).
pub fn say(what: &str) {
    if let Some((w, lo, _)) = current() {
        w.stage(what, lo);
    }
}

/// A count of `len` steps of `unit`, shown by the innermost watcher (nowhere without one).
pub fn count(len: u64, unit: &str) -> Box<dyn Count> {
    match current() {
        Some((w, _, _)) => w.count(len, unit),
        None => Box::new(Uncounted),
    }
}

/// A watcher that shows nothing and passes cancellation on from another: a batch's scenes run
/// under it, so the batch's own count is the only one drawn.
pub struct Quiet(pub Arc<dyn Watcher>);

impl Watcher for Quiet {
    fn stage(&self, _name: &str, _fraction: f64) {}

    fn cancelled(&self) -> bool {
        self.0.cancelled()
    }
}

/// The innermost watcher, to wrap in a [`Quiet`] (or `None`).
pub fn innermost() -> Option<Arc<dyn Watcher>> {
    current().map(|(w, _, _)| w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Counts this test's own lines only: other tests in the process may announce stages.
    #[derive(Default)]
    struct Seen(AtomicUsize);

    impl Watcher for Seen {
        fn stage(&self, name: &str, _fraction: f64) {
            if name.starts_with("guards test") {
                self.0.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// An inner watch hides the outer; dropping the outer's guard first leaves the inner one
    /// watching (the old single slot cleared whichever watcher was there). No other unit test
    /// of this crate installs a watcher.
    #[test]
    fn guards_remove_only_their_own_watcher() {
        let (a, b) = (Arc::new(Seen::default()), Arc::new(Seen::default()));
        let ga = watch(a.clone());
        let gb = watch(b.clone());
        say("guards test x");
        assert_eq!((a.0.load(Ordering::Relaxed), b.0.load(Ordering::Relaxed)), (0, 1));
        drop(ga);
        say("guards test y");
        assert_eq!((a.0.load(Ordering::Relaxed), b.0.load(Ordering::Relaxed)), (0, 2));
        drop(gb);
        say("guards test z");
        assert_eq!((a.0.load(Ordering::Relaxed), b.0.load(Ordering::Relaxed)), (0, 2));
    }
}
