//! Progress on the terminal: the stages of a long computation as lines with the seconds since
//! the start, above a spinner showing the current one; each count as a bar; log lines written
//! with the bars lifted. When stderr is not a terminal (a batch job, a CI log, `nohup`) nothing
//! is drawn: each stage is one log line (target `ves::progress`, level INFO) with the seconds
//! since the start, and a stage that lasts is told again every [`STILL_EVERY`].

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use ves_pipeline::progress::{Count, Watcher};

/// Every bar of this process, drawn together (two bars drawn apart overwrite each other).
fn bars() -> &'static MultiProgress {
    static BARS: std::sync::OnceLock<MultiProgress> = std::sync::OnceLock::new();
    BARS.get_or_init(MultiProgress::new)
}

/// How often a stage that lasts is told again in a log (`VES_PROGRESS_EVERY` seconds replaces it).
pub const STILL_EVERY: std::time::Duration = std::time::Duration::from_secs(30);

/// [`STILL_EVERY`], or `VES_PROGRESS_EVERY` (seconds, 1 to 86400) when set.
fn still_every() -> std::time::Duration {
    std::env::var("VES_PROGRESS_EVERY")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| (1.0..=86_400.0).contains(s))
        .map_or(STILL_EVERY, std::time::Duration::from_secs_f64)
}

/// The log target of progress lines (shown at INFO by default when stderr is not a terminal).
pub const PROGRESS_TARGET: &str = "ves::progress";

/// The terminal as a watcher of the library's computations.
pub struct Terminal {
    visible: bool,
    /// Stages as log lines (stderr is not a terminal).
    logged: bool,
    /// Drawn from the first stage on (a command that tells no stage shows no spinner).
    spinner: std::sync::OnceLock<ProgressBar>,
    start: std::time::Instant,
    /// The stage going on and when it began (for the lines of a stage that lasts).
    current: std::sync::Arc<std::sync::Mutex<Option<(String, std::time::Instant)>>>,
    /// Stops the thread that tells a lasting stage again (dropped with the terminal).
    ticker: std::sync::OnceLock<std::sync::mpsc::Sender<()>>,
}

impl Terminal {
    /// Drawn when `visible` (and stderr is a terminal: the caller checks).
    pub fn new(visible: bool) -> Terminal {
        Terminal {
            visible,
            logged: false,
            spinner: std::sync::OnceLock::new(),
            start: std::time::Instant::now(),
            current: Default::default(),
            ticker: std::sync::OnceLock::new(),
        }
    }

    /// Stages logged as lines (when `wanted`: not `--quiet`, rank 0 under MPI).
    pub fn logged(wanted: bool) -> Terminal {
        let mut t = Terminal::new(false);
        t.logged = wanted;
        t
    }

    /// Starts the thread that tells a stage again every [`STILL_EVERY`] while it lasts.
    fn tick(&self) {
        self.ticker.get_or_init(|| {
            let (stop, stopped) = std::sync::mpsc::channel::<()>();
            let (current, start, every) = (self.current.clone(), self.start, still_every());
            let _ = std::thread::Builder::new().name("ves-progress".into()).spawn(move || {
                while let Err(std::sync::mpsc::RecvTimeoutError::Timeout) = stopped.recv_timeout(every / 6) {
                    let mut c = current.lock().unwrap_or_else(|p| p.into_inner());
                    if let Some((name, since)) = c.as_mut()
                        && since.elapsed() >= every
                    {
                        let t = start.elapsed().as_secs_f64();
                        tracing::info!(target: PROGRESS_TARGET, "{t:.1} s  {name} (still)");
                        *since = std::time::Instant::now();
                    }
                }
            });
            stop
        });
    }

    fn spinner(&self) -> &ProgressBar {
        self.spinner.get_or_init(|| {
            if !self.visible {
                return ProgressBar::hidden();
            }
            let bar = bars().add(ProgressBar::new_spinner());
            let style = ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner());
            bar.set_style(style);
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            bar
        })
    }

    /// Drawn when stderr is a terminal and `wanted` (not `--quiet`, rank 0 under MPI); logged
    /// as lines when stderr is not a terminal and `wanted`.
    pub fn on_stderr(wanted: bool) -> std::sync::Arc<Terminal> {
        std::sync::Arc::new(if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
            Terminal::new(wanted)
        } else {
            Terminal::logged(wanted)
        })
    }
}

impl Watcher for Terminal {
    fn stage(&self, name: &str, fraction: f64) {
        let t = self.start.elapsed().as_secs_f64();
        if self.logged {
            tracing::info!(target: PROGRESS_TARGET, "{t:.1} s  {name} ({:.0} %)", 100.0 * fraction);
            *self.current.lock().unwrap_or_else(|p| p.into_inner()) =
                Some((name.to_string(), std::time::Instant::now()));
            self.tick();
            return;
        }
        let spinner = self.spinner();
        spinner.println(format!("{t:7.1} s  {name}"));
        spinner.set_message(format!("{name} ({:.0} %)", 100.0 * fraction));
    }

    fn count(&self, len: u64, unit: &str) -> Box<dyn Count> {
        if !self.visible {
            return Box::new(Bar(ProgressBar::hidden()));
        }
        let bar = bars().add(ProgressBar::new(len));
        let style = ProgressStyle::with_template(&format!(
            "{{spinner}} [{{elapsed_precise}}] {{bar:30}} {{pos}}/{{len}} {unit} {{msg}}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar());
        bar.set_style(style);
        bar.enable_steady_tick(std::time::Duration::from_millis(120));
        Box::new(Bar(bar))
    }

    /// Printed whether or not bars are drawn (a batch's outcomes are its log).
    fn note(&self, line: &str) {
        bars().suspend(|| eprintln!("{line}"));
    }
}

impl Drop for Terminal {
    fn drop(&mut self) {
        if let Some(s) = self.spinner.get() {
            s.finish_and_clear();
        }
    }
}

/// A count drawn as a bar, cleared when the count ends.
struct Bar(ProgressBar);

impl Count for Bar {
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }

    fn message(&self, what: &str) {
        self.0.set_message(what.to_string());
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.0.finish_and_clear();
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

/// Hands each WARN or ERROR event to the pipeline's collections ([`ves_pipeline::notices`]):
/// `--json`'s `warnings`.
pub struct Notices;

impl<S: tracing::Subscriber> tracing_subscriber::Layer<S> for Notices {
    fn on_event(&self, event: &tracing::Event<'_>, _ctx: tracing_subscriber::layer::Context<'_, S>) {
        if *event.metadata().level() <= tracing::Level::WARN && ves_pipeline::notices::collecting() {
            ves_pipeline::notices::record(ves_pipeline::notices::line(event));
        }
    }
}
