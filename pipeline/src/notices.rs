//! The warnings a computation gave, kept for its caller: `--json`'s `warnings`, Python's
//! `VesWarning`s. The library warns through `tracing`; a front end hands each WARN or ERROR
//! event to [`record`] (the `ves` binary from a layer of its subscriber, the Python package
//! through [`Collector`]), and [`collect`] gathers those of every thread while a computation
//! runs — meshing workers and rayon's pool included. Without that, nothing is gathered.

use std::sync::{Arc, Mutex};

/// The collections open now, by id.
type Open = Vec<(u64, Arc<Mutex<Vec<String>>>)>;
static OPEN: Mutex<Open> = Mutex::new(Vec::new());

/// Most warnings kept per collection (a runaway loop must not fill the memory); the rest are
/// counted in one last line.
const MAX_KEPT: usize = 200;

/// Runs `work`, returning what it returned and the warnings given meanwhile (in order, each
/// once, on one line). Collections may nest or overlap (two Python threads): each gets every
/// warning given while it is open.
pub fn collect<T>(work: impl FnOnce() -> T) -> (T, Vec<String>) {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let id = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let kept = Arc::new(Mutex::new(Vec::new()));
    OPEN.lock().unwrap_or_else(|p| p.into_inner()).push((id, kept.clone()));
    // Closed whatever `work` does (a panic unwinds through here too).
    struct Close(u64);
    impl Drop for Close {
        fn drop(&mut self) {
            OPEN.lock()
                .unwrap_or_else(|p| p.into_inner())
                .retain(|(i, _)| *i != self.0);
        }
    }
    let close = Close(id);
    let out = work();
    drop(close);
    let mut list = std::mem::take(&mut *kept.lock().unwrap_or_else(|p| p.into_inner()));
    let mut seen = std::collections::HashSet::new();
    list.retain(|w| seen.insert(w.clone()));
    let n = list.len();
    if n > MAX_KEPT {
        list.truncate(MAX_KEPT);
        list.push(format!("… and {} more warnings", n - MAX_KEPT));
    }
    (out, list)
}

/// Gives `message` to every open collection (a front end's `tracing` layer calls it for each
/// WARN or ERROR event, with [`line`]).
pub fn record(message: String) {
    let open = OPEN.lock().unwrap_or_else(|p| p.into_inner());
    for (_, kept) in open.iter() {
        let mut k = kept.lock().unwrap_or_else(|p| p.into_inner());
        if k.len() <= MAX_KEPT {
            k.push(message.clone());
        }
    }
}

/// Whether any collection is open (a layer can skip formatting otherwise).
pub fn collecting() -> bool {
    !OPEN.lock().unwrap_or_else(|p| p.into_inner()).is_empty()
}

/// An event's message and its other fields, on one line: "message (field = value, …)".
pub fn line(event: &tracing::Event<'_>) -> String {
    let mut line = Line::default();
    event.record(&mut line);
    let text = match (line.message.is_empty(), line.fields.is_empty()) {
        (_, true) => line.message,
        (true, false) => line.fields.join(" "),
        (false, false) => format!("{} ({})", line.message, line.fields.join(", ")),
    };
    text.replace('\n', " ")
}

/// An event's message and other fields, as text.
#[derive(Default)]
struct Line {
    message: String,
    fields: Vec<String>,
}

impl tracing::field::Visit for Line {
    fn record_str(&mut self, field: &tracing::field::Field, value: &str) {
        if field.name() == "message" {
            self.message = value.to_string();
        } else {
            self.fields.push(format!("{} = {value}", field.name()));
        }
    }

    fn record_debug(&mut self, field: &tracing::field::Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.message = format!("{value:?}");
        } else {
            self.fields.push(format!("{} = {value:?}", field.name()));
        }
    }
}

/// A whole `tracing` subscriber for a front end without one of its own (the Python package):
/// WARN and ERROR events go to [`collect`]; with `echo`, events at that level and above are
/// also printed to stderr ("WARN target: message").
pub struct Collector {
    echo: Option<tracing::Level>,
}

impl Collector {
    /// Echoing what `VES_LOG` names: one of error, warn, info, debug, trace (none when unset
    /// or anything else).
    pub fn from_env() -> Collector {
        let echo = std::env::var("VES_LOG")
            .ok()
            .and_then(|v| v.trim().parse::<tracing::Level>().ok());
        Collector { echo }
    }
}

impl tracing::Subscriber for Collector {
    fn enabled(&self, metadata: &tracing::Metadata<'_>) -> bool {
        let wanted = self.echo.map_or(tracing::Level::WARN, |e| e.max(tracing::Level::WARN));
        *metadata.level() <= wanted
    }

    fn new_span(&self, _span: &tracing::span::Attributes<'_>) -> tracing::span::Id {
        tracing::span::Id::from_u64(1)
    }

    fn record(&self, _span: &tracing::span::Id, _values: &tracing::span::Record<'_>) {}

    fn record_follows_from(&self, _span: &tracing::span::Id, _follows: &tracing::span::Id) {}

    fn event(&self, event: &tracing::Event<'_>) {
        let level = *event.metadata().level();
        if level <= tracing::Level::WARN && collecting() {
            record(line(event));
        }
        if self.echo.is_some_and(|e| level <= e) {
            eprintln!("{level} {}: {}", event.metadata().target(), line(event));
        }
    }

    fn enter(&self, _span: &tracing::span::Id) {}

    fn exit(&self, _span: &tracing::span::Id) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warnings_are_collected_while_open_and_only_then() {
        let _default = tracing::subscriber::set_default(Collector { echo: None });
        tracing::warn!("before");
        let ((), got) = collect(|| {
            tracing::info!("not a warning");
            tracing::warn!(output = "b.h5", "the sidecar was rewritten");
            tracing::warn!("the sidecar was rewritten");
            tracing::warn!("the sidecar was rewritten");
        });
        tracing::warn!("after");
        assert_eq!(
            got,
            ["the sidecar was rewritten (output = b.h5)", "the sidecar was rewritten"]
        );
    }
}
