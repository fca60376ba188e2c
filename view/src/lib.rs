//! `ves view`: a session whose device is a web page. One page and one WebSocket are served;
//! the real session ([`ves_runtime::session::run_spaces_with`], the code `ves session` runs) steps the
//! haptic loop at its rate with one [`hands::WebHand`] per hand, and its visualization thread
//! hands each drawn frame to the server, which keeps only the latest: a slow client skips
//! frames instead of queueing them, and a vanished one costs nothing but its own task. Only
//! this server's own page may use it, within connection limits ([`server`]).

pub mod hands;
pub mod loads;
pub mod project;
pub mod protocol;
pub mod server;
pub mod setup;
#[cfg(test)]
mod tests;
pub mod workshop;

use axum::body::Bytes;
use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use hands::{HandSlot, HandStatus, WebHand};
pub use project::Project;
use protocol::{ClientMessage, Extent, FrameHeader, HANDS};
pub use server::Limits;
pub use setup::SetUp;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, RwLock};
use std::time::{Duration, Instant};
use tokio::sync::{Semaphore, broadcast, watch};
use ves_runtime::device::Device;
use ves_runtime::session::{self, Frame, FrameObserver, Hooks, SessionConfig, SessionStats};
use ves_runtime::switching::SpaceInput;
use ves_runtime::visual;
pub use workshop::{Computed, Progress, Workshop, WorkshopError};

const INDEX_HTML: &str = include_str!("../web/index.html");
const APP_JS: &str = include_str!(concat!(env!("OUT_DIR"), "/app.js"));

/// How often the status goes out.
const STATUS_PERIOD: Duration = Duration::from_millis(50);
/// A client that has not taken a message for this long is dropped.
const SEND_TIMEOUT: Duration = Duration::from_secs(5);

/// Viewer settings.
#[derive(Clone, Debug)]
pub struct ViewConfig {
    /// Where to listen (loopback unless the user says otherwise).
    pub addr: SocketAddr,
    /// The session (rate, coupling, watch; `duration_s` is how long the server runs, infinite
    /// to run until stopped).
    pub session: SessionConfig,
    /// Shown in the page's title (the basis file's name).
    pub name: String,
    /// Connection limits (header timeout, connections and clients at once).
    pub limits: Limits,
    /// What each CAD face of a basis's surface is (plane, cylinder …), as JSON for the page's
    /// hover: given by the program that has the pipeline (the `ves` binary); none without.
    pub face_kinds: Option<FaceKinds>,
}

/// [`ViewConfig::face_kinds`]: from a space's surface (corner vertices, triangles, face tags)
/// and the geometry file of the part set up ([`Workshop::geometry`]: for the faces' names, where it
/// states them) to a JSON list the page shows on hover.
pub type FaceKinds = fn(&[[f64; 3]], &[[u32; 3]], &[u32], Option<&std::path::Path>) -> serde_json::Value;

/// What a viewer run measured.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ViewStats {
    /// The last session's own statistics (as `ves session --json`).
    pub session: SessionStats,
    /// Clients that connected.
    pub clients_total: u64,
    /// Most clients connected at once.
    pub clients_max: u64,
    /// Client messages dropped (malformed, oversized, binary, non-finite, far away, or for a
    /// hand another client drives).
    pub messages_dropped: u64,
    /// Frames sent, summed over clients.
    pub frames_sent: u64,
    /// Frames a slow client skipped, summed over clients.
    pub frames_skipped: u64,
    /// Frames the sessions drew.
    pub frames_drawn: u64,
    /// Requests refused: a `Host` or `Origin` other than this server's, or a WebSocket client
    /// beyond the limit.
    pub requests_refused: u64,
    /// Computes asked by the set-up panel, and those that failed or were cancelled.
    pub computes: u64,
    /// See `computes`.
    pub computes_failed: u64,
    /// Times a live session was replaced by one on a new basis.
    pub swaps: u64,
    /// Each session the server ran, in order (a compute ran beside the end of every one but the
    /// last): its haptic loop's timing.
    pub sessions: Vec<SessionTiming>,
}

/// How one session's haptic loop kept time.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SessionTiming {
    /// Haptic steps.
    pub steps: u64,
    /// Steps that ended after their deadline.
    pub missed_deadlines: u64,
    /// 99.9th percentile of the period error, µs.
    pub period_error_us_p999: f64,
    /// Largest period error, µs.
    pub period_error_us_max: f64,
    /// Periods (wake-up to wake-up) longer than 1.1 ms.
    pub periods_over_1_1_ms: u64,
}

/// The viewer could not start, or could not move its session to a new basis.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// A session setting out of range.
    #[error(transparent)]
    Setting(#[from] ves_runtime::haptic::InvalidSetting),
    /// The port asked for is taken.
    #[error("port {} on {} is in use: pick another with --port (0 picks a free one)", addr.port(), addr.ip())]
    PortInUse {
        /// The address asked for.
        addr: SocketAddr,
    },
    /// The address cannot be listened on.
    #[error("cannot listen on {addr}: {error}; check --host and --port")]
    Listen {
        /// The address asked for.
        addr: SocketAddr,
        /// The system's error (in the message, so not also a `source`).
        error: std::io::Error,
    },
    /// The listening socket cannot be set up.
    #[error("{0}")]
    Socket(std::io::Error),
    /// The server's runtime cannot be started.
    #[error("cannot start the server: {0}")]
    Runtime(std::io::Error),
    /// Neither a basis nor a workshop to make one.
    #[error("nothing to serve: give a basis, a scene or a geometry file")]
    NothingToServe,
    /// The first compute cannot be started.
    #[error(transparent)]
    Compute(#[from] ComputeError),
    /// The basis computed cannot be loaded.
    #[error(transparent)]
    Load(#[from] ves_runtime::basis::LoadError),
    /// A thread panicked holding the live session.
    #[error("the session lock is poisoned")]
    SessionLock,
    /// The session's thread panicked.
    #[error("the session thread panicked")]
    SessionPanicked,
    /// The session ended with an error.
    #[error(transparent)]
    Session(#[from] session::SessionError),
    /// The session's thread cannot be started.
    #[error("cannot start the session: {0}")]
    SessionThread(std::io::Error),
}

/// Why the server starts no compute (the page is told, or `ves view` ends with it).
#[derive(Debug, thiserror::Error)]
pub enum ComputeError {
    /// The viewer serves a basis file: it has no workshop to compute with.
    #[error("this viewer was opened on a basis: open a scene or a STEP file to set the part up")]
    NoWorkshop,
    /// Another compute (or a part's opening) holds the slot.
    #[error("a compute is already running: wait for it or cancel it")]
    Running,
    /// The compute's thread cannot be started.
    #[error("cannot start the compute: {0}")]
    Thread(std::io::Error),
}

/// One basis being served: what every page is sent when it connects, and what the hand
/// messages are checked against. A compute makes a new one; pages get it at once.
struct Generation {
    hello: serde_json::Value,
    meshes: Vec<Bytes>,
    bases: Vec<Arc<ves_runtime::Basis>>,
    extent: Option<Extent>,
    basis_path: Option<PathBuf>,
    /// Each space's static load cases (listed in the hello; read on request).
    loads: Vec<loads::SpaceLoads>,
    /// Their names, per space, for checking requests.
    load_names: Vec<Vec<String>>,
    /// Each space's felt errors as the file's checks wrote them after the basis was loaded
    /// (the session's basis has them when the file had them at load).
    felt: Vec<Option<Arc<ves_runtime::FeltAt>>>,
}

/// Where the drawing thread's hook publishes (shared by every session the server runs).
#[derive(Clone)]
struct Published {
    frames: Arc<watch::Sender<Bytes>>,
    stress: Arc<watch::Sender<Bytes>>,
    stress_clients: Arc<AtomicUsize>,
    drawn: Arc<AtomicU32>,
    active_space: Arc<AtomicU32>,
    alarm: Arc<AtomicBool>,
    /// Per support of the drawn state, force x y z (N) and moment x y z (N·m); empty without
    /// stored reactions.
    reactions: Arc<std::sync::Mutex<Vec<[f64; 6]>>>,
}

/// The live session, replaced when a compute brings a new basis.
struct Live {
    stop: Arc<AtomicBool>,
    thread: std::thread::JoinHandle<Result<SessionStats, session::SessionError>>,
}

struct Shared {
    hands: [Arc<HandSlot>; HANDS],
    generation: RwLock<Arc<Generation>>,
    /// Bumped at each new generation: every client then sends its page the new hello and meshes.
    generations: watch::Sender<u64>,
    frames: watch::Receiver<Bytes>,
    stress_frames: watch::Receiver<Bytes>,
    published: Published,
    status: watch::Receiver<String>,
    next_client: AtomicU64,
    clients: AtomicU64,
    clients_total: AtomicU64,
    clients_max: AtomicU64,
    dropped: AtomicU64,
    frames_sent: AtomicU64,
    frames_skipped: AtomicU64,
    /// One permit per WebSocket client.
    client_slots: Arc<Semaphore>,
    max_clients: usize,
    refused: Arc<AtomicU64>,
    /// Asks the haptic thread to bring the part back to rest.
    reset: Arc<AtomicBool>,
    /// How long the server runs, s (the sessions themselves run until replaced).
    duration_s: f64,
    cfg: ViewConfig,
    live: Mutex<Option<Live>>,
    last_stats: Mutex<Option<SessionStats>>,
    timings: Mutex<Vec<SessionTiming>>,
    workshop: Option<Arc<dyn Workshop>>,
    computing: AtomicBool,
    /// The running compute's basis is in use and only its checks (the error estimate) remain:
    /// a new Compute stops them and starts at once.
    checking: AtomicBool,
    /// A compute asked for while another's checks were stopping: started when that one ends.
    queued: Mutex<Option<serde_json::Value>>,
    cancel: Arc<AtomicBool>,
    /// Compute progress and outcomes, to every page. A channel that keeps each message (not a
    /// watch, which keeps the last): "computed" is followed at once by the progress of its
    /// checks, and a page that saw only the latter would never learn the basis was ready.
    notes: broadcast::Sender<String>,
    computes: AtomicU64,
    computes_failed: AtomicU64,
    swaps: AtomicU64,
    /// The set-up every page shows (with a workshop), and where it is kept.
    setup: Mutex<SetUp>,
    /// Its message as last sent (empty without a workshop): a watch, since only the latest
    /// state matters and a page that lagged must still get it.
    setup_tx: watch::Sender<String>,
    /// The project on disk, if any; let go when the page opens another part (for that part's
    /// own, through `uploads`).
    project: Mutex<Option<Keeper>>,
    /// [`Studio::uploads`].
    uploads: Option<ProjectFor>,
    /// While the first compute of a part opened in the page runs: the set-up and the project
    /// before it, put back (with the workshop's part) if that compute makes no basis.
    opening: Mutex<Option<(SetUp, Option<Arc<Project>>)>>,
}

/// A project and the thread that writes its set-up: edits come from the server's own thread,
/// which must not wait on a disk. One slot holds the latest state not yet written (a page
/// sending edits faster than the disk takes them replaces it, never queues them).
struct Keeper {
    project: Arc<Project>,
    slot: Arc<Slot>,
    thread: std::thread::JoinHandle<()>,
}

/// The latest set-up to write, and whether the keeper is closing.
type Slot = (Mutex<(Option<SetUp>, bool)>, std::sync::Condvar);

impl Keeper {
    fn start(project: Arc<Project>) -> Keeper {
        let slot: Arc<Slot> = Arc::default();
        let thread = std::thread::spawn({
            let (project, slot) = (project.clone(), slot.clone());
            move || {
                let mut warned = false;
                loop {
                    let next = {
                        let mut g = lock(&slot.0);
                        while g.0.is_none() && !g.1 {
                            g = slot.1.wait(g).unwrap_or_else(|p| p.into_inner());
                        }
                        g.0.take()
                    };
                    let Some(s) = next else { break };
                    if let Err(e) = project.save(&s)
                        && !std::mem::replace(&mut warned, true)
                    {
                        eprintln!(
                            "ves view: {}: cannot keep the set-up: {e}",
                            project.dir().join(project::STATE).display()
                        );
                    }
                }
            }
        });
        Keeper { project, slot, thread }
    }

    /// Puts `s` in the slot (replacing a state not yet written).
    fn keep(&self, s: SetUp) {
        lock(&self.slot.0).0 = Some(s);
        self.slot.1.notify_one();
    }

    /// Writes what is in the slot and ends the thread; the project, to keep again later.
    fn finish(self) -> Arc<Project> {
        lock(&self.slot.0).1 = true;
        self.slot.1.notify_one();
        let _ = self.thread.join();
        self.project
    }
}

/// What the set-up panel computes with and keeps: the workshop, the project on disk and the
/// set-up it resumes.
pub struct Studio {
    /// Makes bases from the page's scenes.
    pub workshop: Arc<dyn Workshop>,
    /// Where the set-up and the basis served are kept, if anywhere.
    pub project: Option<Project>,
    /// The set-up to start from (a project's); the workshop's starting scene without.
    pub setup: Option<SetUp>,
    /// Opens the project of a part opened in the page (**open a part…**); without it such a
    /// part is set up without one.
    pub uploads: Option<ProjectFor>,
}

/// [`Studio::uploads`]: the project (made or resumed) of the part the page opened, from its
/// file name as the user picked it and its bytes; `None` when it cannot be kept (said by the
/// caller).
pub type ProjectFor = Arc<dyn Fn(&str, &[u8]) -> Option<project::Opened> + Send + Sync>;

/// Serves the viewer on `spaces` until the session ends (its duration, Ctrl-C, or `stop`).
/// `ready` gets the bound address before the first client can connect.
pub fn serve(
    spaces: Vec<SpaceInput>,
    cfg: &ViewConfig,
    stop: Arc<AtomicBool>,
    ready: impl FnOnce(SocketAddr),
) -> Result<ViewStats, ViewError> {
    serve_with(Some(spaces), None, cfg, stop, ready)
}

/// [`serve`] with a set-up panel: `workshop` computes new bases from the page's scene, and the
/// live session moves to each one. `spaces` may be `None` until the first compute.
pub fn serve_with(
    spaces: Option<Vec<SpaceInput>>,
    workshop: Option<Arc<dyn Workshop>>,
    cfg: &ViewConfig,
    stop: Arc<AtomicBool>,
    ready: impl FnOnce(SocketAddr),
) -> Result<ViewStats, ViewError> {
    let studio = workshop.map(|workshop| Studio {
        workshop,
        project: None,
        setup: None,
        uploads: None,
    });
    serve_studio(spaces, studio, cfg, stop, ready)
}

/// [`serve_with`] with a project: `spaces` (the project's basis, when it had one) are served
/// under `studio.setup`, and every change of the set-up is kept in `studio.project`.
pub fn serve_studio(
    spaces: Option<Vec<SpaceInput>>,
    studio: Option<Studio>,
    cfg: &ViewConfig,
    stop: Arc<AtomicBool>,
    ready: impl FnOnce(SocketAddr),
) -> Result<ViewStats, ViewError> {
    cfg.session.validate()?;
    let listener = listen(cfg.addr)?;
    let addr = listener.local_addr().map_err(ViewError::Socket)?;
    let (status_tx, status_rx) = watch::channel(String::new());
    let shared = Arc::new(Shared::new(cfg, studio, status_rx));
    // A project's basis is downloadable as a computed one is.
    let basis_path = spaces
        .as_ref()
        .and_then(|s| s.first())
        .and_then(|s| s.basis.source.clone())
        .filter(|_| shared.workshop.is_some());
    match (spaces, &shared.workshop) {
        (Some(spaces), _) => swap(&shared, spaces, basis_path)?,
        // A part without a basis yet: its first compute starts at once, from the scene served
        // last (a project's whose basis is gone) or the one the workshop starts with, and the
        // pages show its progress.
        (None, Some(w)) => {
            let served = lock(&shared.setup).served.clone();
            start_compute(&shared, served.unwrap_or_else(|| w.setup()["scene"].clone()))?;
        }
        (None, None) => return Err(ViewError::NothingToServe),
    }
    publish_setup(&shared);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(ViewError::Runtime)?;
    rt.block_on(run_server(&shared, listener, addr, status_tx, &stop, ready))?;
    rt.shutdown_timeout(Duration::from_millis(200));
    // The set-up's last state on disk before the server's end is reported.
    if let Some(k) = lock(&shared.project).take() {
        k.finish();
    }
    end_session(&shared)?;
    Ok(shared.view_stats())
}

/// The listening socket on `addr`; a port in use says how to pick another.
fn listen(addr: SocketAddr) -> Result<std::net::TcpListener, ViewError> {
    let listener = std::net::TcpListener::bind(addr).map_err(|error| {
        if error.kind() == std::io::ErrorKind::AddrInUse {
            ViewError::PortInUse { addr }
        } else {
            ViewError::Listen { addr, error }
        }
    })?;
    listener.set_nonblocking(true).map_err(ViewError::Socket)?;
    Ok(listener)
}

/// The page, its script, the basis download, the part upload and the WebSocket.
fn router(shared: Arc<Shared>) -> axum::Router {
    axum::Router::new()
        .route(
            "/",
            get(|| async { ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], INDEX_HTML) }),
        )
        .route(
            "/app.js",
            get(|| async { ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], APP_JS) }),
        )
        .route("/favicon.ico", get(|| async { axum::http::StatusCode::NO_CONTENT }))
        .route("/basis.h5", get(basis_file))
        .route("/open", axum::routing::post(open_part))
        .route("/ws", get(upgrade))
        .with_state(shared)
}

/// Serves until Ctrl-C, `stop`, the configured duration or the end of the live session.
async fn run_server(
    shared: &Arc<Shared>,
    listener: std::net::TcpListener,
    addr: SocketAddr,
    status_tx: watch::Sender<String>,
    stop: &Arc<AtomicBool>,
    ready: impl FnOnce(SocketAddr),
) -> Result<(), ViewError> {
    let deadline = Instant::now().checked_add(Duration::try_from_secs_f64(shared.duration_s).unwrap_or(Duration::MAX));
    let listener = tokio::net::TcpListener::from_std(listener).map_err(ViewError::Socket)?;
    ready(addr);
    let status = tokio::spawn(status_loop(shared.clone(), status_tx, stop.clone()));
    let (tx, rx) = watch::channel(false);
    let server = tokio::spawn(server::run(
        listener,
        router(shared.clone()),
        Arc::new(server::Guard::new(addr)),
        shared.cfg.limits,
        shared.refused.clone(),
        rx,
    ));
    loop {
        tokio::select! {
            _ = tokio::signal::ctrl_c() => break,
            _ = tokio::time::sleep(Duration::from_millis(100)) => {
                let ended = shared.live.lock().map(|l| l.as_ref().is_some_and(|l| l.thread.is_finished())).unwrap_or(true);
                if stop.load(Ordering::Relaxed) || deadline.is_some_and(|d| Instant::now() >= d) || ended { break; }
            }
        }
    }
    stop.store(true, Ordering::Relaxed);
    shared.cancel.store(true, Ordering::Relaxed);
    let _ = tx.send(true);
    status.abort();
    // Open connections are dropped; the WebSockets end with the runtime.
    let _ = tokio::time::timeout(Duration::from_secs(1), server).await;
    // A compute still running was just cancelled (its process killed): its outcome is counted
    // before the statistics are taken, not raced by them. Bounded: a compute that does not end
    // within this time is reported as it stands.
    let t = Instant::now();
    while shared.computing.load(Ordering::Acquire) && t.elapsed() < COMPUTE_END_WAIT {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    Ok(())
}

/// How long the server's end waits for a cancelled compute to end.
const COMPUTE_END_WAIT: Duration = Duration::from_secs(5);

impl Shared {
    /// The server's state before any session: no basis, no client.
    fn new(cfg: &ViewConfig, studio: Option<Studio>, status: watch::Receiver<String>) -> Shared {
        let (workshop, project, setup, uploads) = match studio {
            Some(s) => {
                let setup = s
                    .setup
                    .unwrap_or_else(|| SetUp::new(s.workshop.setup()["scene"].clone()));
                (Some(s.workshop), s.project, setup, s.uploads)
            }
            None => (None, None, SetUp::default(), None),
        };
        let (frame_tx, frames) = watch::channel(Bytes::new());
        let (stress_tx, stress_frames) = watch::channel(Bytes::new());
        let published = Published {
            frames: Arc::new(frame_tx),
            stress: Arc::new(stress_tx),
            stress_clients: Arc::new(AtomicUsize::new(0)),
            drawn: Arc::new(AtomicU32::new(0)),
            active_space: Arc::new(AtomicU32::new(0)),
            alarm: Arc::new(AtomicBool::new(false)),
            reactions: Arc::default(),
        };
        let mut session_cfg = cfg.session;
        // The server keeps time; each session runs until it is replaced or the server stops.
        session_cfg.duration_s = f64::INFINITY;
        Shared {
            hands: std::array::from_fn(|_| Arc::new(HandSlot::default())),
            generation: RwLock::new(Arc::new(Generation {
                hello: hello(&[], &[], cfg, workshop.as_deref()),
                meshes: Vec::new(),
                bases: Vec::new(),
                extent: None,
                basis_path: None,
                loads: Vec::new(),
                load_names: Vec::new(),
                felt: Vec::new(),
            })),
            generations: watch::channel(0).0,
            frames,
            stress_frames,
            published,
            status,
            next_client: AtomicU64::new(0),
            clients: AtomicU64::new(0),
            clients_total: AtomicU64::new(0),
            clients_max: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            frames_sent: AtomicU64::new(0),
            frames_skipped: AtomicU64::new(0),
            client_slots: Arc::new(Semaphore::new(cfg.limits.clients)),
            max_clients: cfg.limits.clients,
            refused: Arc::new(AtomicU64::new(0)),
            reset: Arc::new(AtomicBool::new(false)),
            duration_s: cfg.session.duration_s,
            cfg: ViewConfig {
                session: session_cfg,
                ..cfg.clone()
            },
            live: Mutex::new(None),
            last_stats: Mutex::new(None),
            timings: Mutex::new(Vec::new()),
            workshop,
            computing: AtomicBool::new(false),
            checking: AtomicBool::new(false),
            queued: Mutex::new(None),
            cancel: Arc::new(AtomicBool::new(false)),
            notes: broadcast::channel(256).0,
            computes: AtomicU64::new(0),
            computes_failed: AtomicU64::new(0),
            swaps: AtomicU64::new(0),
            setup: Mutex::new(setup),
            setup_tx: watch::channel(String::new()).0,
            project: Mutex::new(project.map(|p| Keeper::start(Arc::new(p)))),
            opening: Mutex::new(None),
            uploads,
        }
    }

    /// What the server counted, with the last session's statistics.
    fn view_stats(&self) -> ViewStats {
        let n = |a: &AtomicU64| a.load(Ordering::Relaxed);
        ViewStats {
            session: self.last_stats.lock().ok().and_then(|s| s.clone()).unwrap_or_default(),
            clients_total: n(&self.clients_total),
            clients_max: n(&self.clients_max),
            messages_dropped: n(&self.dropped),
            frames_sent: n(&self.frames_sent),
            frames_skipped: n(&self.frames_skipped),
            frames_drawn: u64::from(self.published.drawn.load(Ordering::Relaxed)),
            requests_refused: n(&self.refused),
            computes: n(&self.computes),
            computes_failed: n(&self.computes_failed),
            swaps: n(&self.swaps),
            sessions: self.timings.lock().map(|t| t.clone()).unwrap_or_default(),
        }
    }
}

/// Stops the live session, if any, and keeps its statistics.
fn end_session(shared: &Shared) -> Result<(), ViewError> {
    let live = shared.live.lock().map_err(|_| ViewError::SessionLock)?.take();
    if let Some(live) = live {
        live.stop.store(true, Ordering::Relaxed);
        let stats = live.thread.join().map_err(|_| ViewError::SessionPanicked)??;
        if let Ok(mut t) = shared.timings.lock() {
            t.push(SessionTiming {
                steps: stats.steps,
                missed_deadlines: stats.missed_deadlines,
                period_error_us_p999: stats.period_error_us_p999,
                period_error_us_max: stats.period_error_us_max,
                periods_over_1_1_ms: stats.periods_over_1_1_ms,
            });
        }
        if let Ok(mut s) = shared.last_stats.lock() {
            *s = Some(stats);
        }
    }
    Ok(())
}

/// Serves `spaces` from now on: the live session (if any) ends, every hand is let go, pages get
/// the new hello and meshes, and a new session starts on the new basis.
fn swap(shared: &Arc<Shared>, spaces: Vec<SpaceInput>, basis_path: Option<PathBuf>) -> Result<(), ViewError> {
    if shared.live.lock().is_ok_and(|l| l.is_some()) {
        shared.swaps.fetch_add(1, Ordering::Relaxed);
    }
    end_session(shared)?;
    for h in &shared.hands {
        h.release_any();
    }
    let bases: Vec<Arc<ves_runtime::Basis>> = spaces.iter().map(|s| s.basis.clone()).collect();
    // The load cases are listed (and checked) now; their arrays are read again on request.
    let space_loads: Vec<loads::SpaceLoads> = bases.iter().map(|b| loads::list(b)).collect();
    for (b, l) in bases.iter().zip(&space_loads) {
        if let Some(e) = &l.error {
            eprintln!("ves view: space {:?} offers no load case: {e}", b.space);
        }
    }
    let generation = Generation {
        hello: hello(&bases, &space_loads, &shared.cfg, shared.workshop.as_deref()),
        load_names: space_loads.iter().map(loads::SpaceLoads::names).collect(),
        loads: space_loads,
        meshes: bases
            .iter()
            .enumerate()
            .map(|(i, b)| Bytes::from(protocol::mesh(i, b)))
            .collect(),
        extent: bases.first().map(|b| Extent::of(b)),
        felt: vec![None; bases.len()],
        bases: bases.clone(),
        basis_path,
    };
    // The session, in its own threads, exactly as `ves session` runs it.
    let dt = 1.0 / shared.cfg.session.rate_hz;
    let devices: Vec<Box<dyn Device>> = shared
        .hands
        .iter()
        .map(|h| Box::new(WebHand::new(h.clone(), dt)) as Box<dyn Device>)
        .collect();
    let stop = Arc::new(AtomicBool::new(false));
    let hooks = Hooks {
        stop: Some(stop.clone()),
        reset: Some(shared.reset.clone()),
        frame: Some(frame_encoder(&bases, &shared.hands, shared.published.clone())),
    };
    let session_cfg = shared.cfg.session;
    let thread = std::thread::Builder::new()
        .name("ves-session".into())
        .spawn(move || session::run_spaces_with(spaces, devices, &session_cfg, hooks))
        .map_err(ViewError::SessionThread)?;
    *shared.live.lock().map_err(|_| ViewError::SessionLock)? = Some(Live { stop, thread });
    if let Ok(mut g) = shared.generation.write() {
        *g = Arc::new(generation);
    }
    shared.generations.send_modify(|n| *n += 1);
    Ok(())
}

/// An unchanged frame is sent again after this long (the page's frame count shows it live).
const KEEPALIVE: Duration = Duration::from_millis(200);

/// Runs one compute of the set-up panel in its own thread; its progress and its end go to every
/// page; on success the session moves to the new basis.
fn start_compute(shared: &Arc<Shared>, scene: serde_json::Value) -> Result<(), ComputeError> {
    let Some(workshop) = shared.workshop.clone() else {
        return Err(ComputeError::NoWorkshop);
    };
    let Some(claim) = Claim::take(shared) else {
        // Under the lock the compute's end takes `queued` with: a request is either queued
        // before that end or finds the checks over, never queued after it and lost.
        let mut queued = shared.queued.lock().unwrap_or_else(|p| p.into_inner());
        if shared.checking.load(Ordering::Acquire) {
            // The part in use is already the last compute's: its estimate gives way.
            *queued = Some(scene);
            shared.cancel.store(true, Ordering::Relaxed);
            return Ok(());
        }
        return Err(ComputeError::Running);
    };
    launch(claim, workshop, scene)
}

/// The compute slot (`Shared::computing`), held: one compute or part opening at a time. Let go
/// when dropped, unless a compute took it over (its end lets it go, see [`start_queued`]).
struct Claim {
    shared: Arc<Shared>,
    passed_on: bool,
}

impl Claim {
    /// The slot, if free.
    fn take(shared: &Arc<Shared>) -> Option<Claim> {
        (!shared.computing.swap(true, Ordering::AcqRel)).then(|| Claim {
            shared: shared.clone(),
            passed_on: false,
        })
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        if !self.passed_on {
            self.shared.computing.store(false, Ordering::Release);
        }
    }
}

/// Starts a compute of `scene` in its own thread, in the slot `claim` holds.
fn launch(mut claim: Claim, workshop: Arc<dyn Workshop>, scene: serde_json::Value) -> Result<(), ComputeError> {
    let shared = claim.shared.clone();
    shared.cancel.store(false, Ordering::Relaxed);
    shared.computes.fetch_add(1, Ordering::Relaxed);
    let spawned = std::thread::Builder::new().name("ves-compute".into()).spawn({
        let shared = shared.clone();
        move || {
            run_compute(&shared, workshop.as_ref(), &scene);
            start_queued(&shared);
        }
    });
    match spawned {
        Ok(_) => {
            claim.passed_on = true;
            Ok(())
        }
        Err(e) => Err(ComputeError::Thread(e)),
    }
}

/// Sends a compute note to every page.
fn note(shared: &Shared, v: serde_json::Value) {
    let _ = shared.notes.send(v.to_string());
}

/// One compute, in the compute thread: progress to every page, the session moved to the basis
/// as soon as it is written (the checks that may follow rewrite the file and are reported when
/// they end), and the outcome.
fn run_compute(shared: &Arc<Shared>, workshop: &dyn Workshop, scene: &serde_json::Value) {
    let t0 = Instant::now();
    let progress: Arc<dyn Fn(Progress) + Send + Sync> = {
        let shared = shared.clone();
        Arc::new(move |p: Progress| {
            note(
                &shared,
                serde_json::json!({"type": "progress", "stage": p.stage, "fraction": p.fraction}),
            );
        })
    };
    progress(Progress {
        stage: "starting".into(),
        fraction: 0.0,
    });
    let before = lock(&shared.setup).served.clone();
    let mut swapped = false;
    let mut ready = |c: &Computed| -> Result<(), WorkshopError> {
        progress(Progress {
            stage: "loading".into(),
            fraction: 0.98,
        });
        let spaces = ves_runtime::switching::load_spaces(&c.basis, None, true).map_err(ViewError::Load)?;
        swap(shared, spaces, Some(c.basis.clone()))?;
        swapped = true;
        // A part opened in the page is served: it reads, the part before is let go.
        if lock(&shared.opening).take().is_some() {
            workshop.settle(true);
        }
        shared.checking.store(true, Ordering::Release);
        change_setup(shared, |s| {
            s.serve(scene.clone(), c.scene.clone(), c.summary.clone(), c.warnings.clone());
            s.mesh = c.mesh.clone();
            true
        });
        if !c.instant {
            keep_basis(shared, &c.basis);
        }
        note(
            shared,
            serde_json::json!({
                "type": "computed", "summary": c.summary, "scene": c.scene,
                "seconds": t0.elapsed().as_secs_f64(),
                "estimated_error": c.estimated_error,
                "warnings": c.warnings,
                "mesh": c.mesh,
                "live": if c.instant { "instant" } else { "converged" },
            }),
        );
        Ok(())
    };
    let done = workshop.compute(scene, progress.clone(), shared.cancel.clone(), &mut ready);
    let record = |outcome: &str, summary: String, warnings: Option<&[String]>| {
        let entry = setup::Entry {
            unix_time: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs()),
            changed: before.as_ref().map(|b| setup::changes(b, scene)).unwrap_or_default(),
            outcome: outcome.into(),
            summary,
            seconds: t0.elapsed().as_secs_f64(),
        };
        change_setup(shared, |s| {
            if outcome == "computed" {
                s.summary = Some(entry.summary.clone());
            }
            if let Some(w) = warnings {
                s.warnings = w.to_vec();
            }
            s.record(entry);
            true
        });
    };
    // The checks wrote the file again, its load cases with their peaks' study among them.
    let refreshed = match &done {
        Ok(_) if swapped => refresh_loads(shared),
        _ => None,
    };
    // The first compute of a part opened in the page made no basis (it failed or was
    // cancelled): the part before is the part again, with its set-up and project.
    if lock(&shared.opening).is_some() {
        let failed = match &done {
            Err(e) => e.to_string(),
            Ok(_) => "the compute made no basis".into(),
        };
        shared.computes_failed.fetch_add(1, Ordering::Relaxed);
        let part = revert_opening(shared, workshop);
        note(
            shared,
            serde_json::json!({"type": "compute_error", "message": format!(
                "the part opened was not computed ({failed}); {part} is still the part set up"
            )}),
        );
        return;
    }
    match &done {
        Ok(c) if swapped => {
            keep_basis(shared, &c.basis);
            record("computed", c.summary.clone(), Some(&c.warnings));
        }
        Err(e) if swapped => {
            let summary = lock(&shared.setup).summary.clone().unwrap_or_default();
            record("computed", format!("{summary}; its checks did not finish: {e}"), None);
        }
        Err(e @ WorkshopError::Cancelled { .. }) => record("cancelled", e.to_string(), None),
        Err(e) => record("failed", e.to_string(), None),
        Ok(_) => record("failed", "the compute made no basis".into(), None),
    }
    let failed = |message: serde_json::Value| {
        shared.computes_failed.fetch_add(1, Ordering::Relaxed);
        note(shared, serde_json::json!({"type": "compute_error", "message": message}));
    };
    match done {
        Ok(c) if swapped => note(
            shared,
            serde_json::json!({
                "type": "checked", "summary": c.summary,
                "seconds": t0.elapsed().as_secs_f64(),
                "estimated_error": c.estimated_error,
                "warnings": c.warnings,
                "loads": refreshed,
            }),
        ),
        Ok(_) => failed("the compute made no basis".into()),
        // The part is in use; only its checks did not finish.
        Err(e) if swapped => note(shared, serde_json::json!({"type": "checked", "error": e.to_string()})),
        Err(e) => failed(e.to_string().into()),
    }
}

/// The served spaces' load cases listed again from their file (rewritten by a compute's
/// checks: the cases' peak stresses are studied there), in the generation a new page is sent
/// and, per space, for the pages already open; `None` when nothing is served.
fn refresh_loads(shared: &Arc<Shared>) -> Option<serde_json::Value> {
    let g = shared.generation.read().ok()?.clone();
    if g.bases.is_empty() {
        return None;
    }
    let space_loads: Vec<loads::SpaceLoads> = g.bases.iter().map(|b| loads::list(b)).collect();
    let lists = serde_json::json!(space_loads.iter().map(|l| &l.cases).collect::<Vec<_>>());
    let generation = Generation {
        hello: hello(&g.bases, &space_loads, &shared.cfg, shared.workshop.as_deref()),
        load_names: space_loads.iter().map(loads::SpaceLoads::names).collect(),
        loads: space_loads,
        meshes: g.meshes.clone(),
        extent: g.extent,
        // The checks wrote what a hand feels wrong at each vertex (`felt/`); a file that cannot
        // be read again keeps the hands without it.
        felt: g
            .bases
            .iter()
            .map(|b| b.read_felt().ok().flatten().map(Arc::new))
            .collect(),
        bases: g.bases.clone(),
        basis_path: g.basis_path.clone(),
    };
    if let Ok(mut w) = shared.generation.write() {
        *w = Arc::new(generation);
    }
    Some(lists)
}

/// At a compute's end: the compute asked for during its checks, if any, starts now. Decided
/// under the lock a request is queued with, so none is queued after this and lost.
fn start_queued(shared: &Arc<Shared>) {
    let next = {
        let mut queued = shared.queued.lock().unwrap_or_else(|p| p.into_inner());
        shared.checking.store(false, Ordering::Release);
        shared.computing.store(false, Ordering::Release);
        queued.take()
    };
    if let Some(scene) = next
        && let Err(e) = start_compute(shared, scene)
    {
        note(
            shared,
            serde_json::json!({"type": "compute_error", "message": e.to_string()}),
        );
    }
}

/// A mutex's guard; a thread that panicked while holding it left a state still worth using.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Copies the basis served into the project, if there is one (best effort: said once).
fn keep_basis(shared: &Shared, basis: &std::path::Path) {
    let project = lock(&shared.project).as_ref().map(|k| k.project.clone());
    if let Some(p) = project
        && let Err(e) = p.keep_basis(basis)
    {
        eprintln!(
            "ves view: {}: cannot keep the basis: {e}",
            p.dir().join(project::BASIS).display()
        );
    }
}

/// A part opened in the page made no basis: the part before is the part again (the workshop's,
/// with its set-up and project; the project made for the new part now, which keeps nothing,
/// removed). Returns the name of the part set up again.
fn revert_opening(shared: &Shared, workshop: &dyn Workshop) -> String {
    let Some((setup_before, project_before)) = lock(&shared.opening).take() else {
        return String::new();
    };
    workshop.settle(false);
    let new_part = lock(&shared.setup).history.is_empty();
    if let Some(k) = lock(&shared.project).take() {
        let p = k.finish();
        if new_part {
            p.discard();
        }
    }
    *lock(&shared.project) = project_before.map(Keeper::start);
    *lock(&shared.setup) = setup_before;
    publish_setup(shared);
    shared
        .generation
        .read()
        .ok()
        .and_then(|g| g.hello["name"].as_str().map(String::from))
        .unwrap_or_else(|| "the part before".into())
}

/// Sends the set-up to every page and queues it for the project.
fn publish_setup(shared: &Shared) {
    if shared.workshop.is_none() {
        return;
    }
    let s = lock(&shared.setup);
    let project = lock(&shared.project);
    let folder = project.as_ref().map(|k| k.project.dir().display().to_string());
    if let Some(k) = project.as_ref() {
        k.keep(s.clone());
    }
    let mut message = s.message(folder.as_deref());
    // A part opened in the page whose first compute runs: its name (the drawing is still the
    // part before's).
    if lock(&shared.opening).is_some()
        && let Some(name) = shared.workshop.as_ref().and_then(|w| w.geometry())
    {
        message["opening"] = name.file_name().unwrap_or_default().to_string_lossy().into();
    }
    shared.setup_tx.send_replace(message.to_string());
}

/// Applies `f` to the set-up and, if it says it changed it, publishes it.
fn change_setup(shared: &Shared, f: impl FnOnce(&mut SetUp) -> bool) {
    let changed = f(&mut lock(&shared.setup));
    if changed {
        publish_setup(shared);
    }
}

/// How long a part's upload may take once it holds the compute slot: a page that sends its
/// file slowly on purpose cannot keep the slot for ever.
const UPLOAD_TIME: Duration = Duration::from_secs(120);

/// POST /open?name=FILE: the page opens a geometry file (the body) as the part; its first
/// compute starts at once. The answer is JSON: `{"ok": true}` or `{"error": "one line"}`.
/// Everything that can refuse the upload (its announced size, a compute running) is decided
/// before its body is read; then the compute slot is this request's until its compute starts
/// (or the opening fails), so no other page can open or compute another part in between.
async fn open_part(
    State(shared): State<Arc<Shared>>,
    axum::extract::Query(q): axum::extract::Query<std::collections::HashMap<String, String>>,
    headers: axum::http::HeaderMap,
    body: axum::body::Body,
) -> Response {
    let answer = |status: StatusCode, v: serde_json::Value| {
        (status, [(header::CONTENT_TYPE, "application/json")], v.to_string()).into_response()
    };
    let Some(workshop) = shared.workshop.clone() else {
        return answer(
            StatusCode::NOT_FOUND,
            serde_json::json!({"error": "this viewer serves a basis file: start ves view on a STEP file or a scene to open parts"}),
        );
    };
    let name = q.get("name").cloned().unwrap_or_default();
    let too_large = |bytes: String| {
        let shown = ves_format::identifier::escape_for_terminal(&name);
        answer(
            StatusCode::PAYLOAD_TOO_LARGE,
            serde_json::json!({"error": format!(
                "{shown}: {bytes} bytes, more than the {} MiB a page may send; simplify the part or open it with ves view PART.step",
                workshop::MAX_UPLOAD >> 20
            )}),
        )
    };
    let length = headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok());
    if let Some(n) = length.filter(|n| n.parse::<usize>().map_or(true, |n| n > workshop::MAX_UPLOAD)) {
        return too_large(n.to_string());
    }
    let Some(claim) = Claim::take(&shared) else {
        return answer(
            StatusCode::CONFLICT,
            serde_json::json!({"error": "a compute is running: cancel it or wait, then open the part"}),
        );
    };
    let bytes = match tokio::time::timeout(UPLOAD_TIME, axum::body::to_bytes(body, workshop::MAX_UPLOAD)).await {
        Ok(Ok(b)) => b,
        // Without a Content-Length (chunked), the limit shows while reading.
        Ok(Err(_)) if length.is_none() => return too_large(format!("more than {}", workshop::MAX_UPLOAD)),
        Ok(Err(e)) => {
            return answer(
                StatusCode::BAD_REQUEST,
                serde_json::json!({"error": format!("the upload of {name:?} broke off: {e}")}),
            );
        }
        Err(_) => {
            return answer(
                StatusCode::REQUEST_TIMEOUT,
                serde_json::json!({"error": format!("the upload of {name:?} took more than {} s", UPLOAD_TIME.as_secs())}),
            );
        }
    };
    // The opening and the compute's start in one blocking task that owns the slot: a page
    // that goes away meanwhile cannot leave the slot taken or let another part in between.
    let shared_open = shared.clone();
    let opened = tokio::task::spawn_blocking(move || {
        workshop.open(&name, &bytes).map_err(OpenFailure::Refused)?;
        // Another part: the project before (the part ves view was given, or one opened before)
        // stays as it was left, and this part's own is made or resumed. Both come back if the
        // new part's first compute makes no basis (a file that starts as STEP but does not read).
        let before = lock(&shared_open.project).take().map(Keeper::finish);
        *lock(&shared_open.opening) = Some((lock(&shared_open.setup).clone(), before));
        let opened = shared_open.uploads.as_ref().and_then(|f| f(&name, &bytes));
        let start = workshop.setup()["scene"].clone();
        // A compute that cannot start, or a project's basis that cannot be served: the part
        // before stays the part.
        let reverted = |e: OpenFailure| {
            revert_opening(&shared_open, workshop.as_ref());
            e
        };
        let Some(opened) = opened else {
            *lock(&shared_open.setup) = SetUp::new(start.clone());
            publish_setup(&shared_open);
            return launch(claim, workshop.clone(), start)
                .map_err(|e| reverted(OpenFailure::NotStarted(e)))
                .map(|()| None);
        };
        if let Some(n) = &opened.notice {
            eprintln!("ves view: {n}");
        }
        let dir = opened.project.dir().display().to_string();
        let resumed = opened.resumed.as_ref().map(|r| r.setup.computes());
        let (setup, basis) = match opened.resumed {
            Some(r) => (r.setup, r.basis),
            None => (SetUp::new(start.clone()), None),
        };
        // The project's basis, served at once as when `ves view` resumes a project; one that
        // cannot be read is computed again.
        let spaces = basis.as_ref().and_then(|b| {
            ves_runtime::switching::load_spaces(b, None, true)
                .map_err(|e| eprintln!("ves view: {}: {e}; its scene is computed again", b.display()))
                .ok()
        });
        *lock(&shared_open.project) = Some(Keeper::start(Arc::new(opened.project)));
        let served = setup.served.clone();
        *lock(&shared_open.setup) = setup;
        eprintln!(
            "ves view: project {dir}: {}",
            project::resumed_words(resumed, spaces.is_some())
        );
        match (spaces, basis) {
            (Some(spaces), Some(b)) => {
                workshop.served_from_project(&b);
                swap(&shared_open, spaces, Some(b)).map_err(|e| reverted(OpenFailure::Serve(e)))?;
                // Served: the part reads, the one before is let go.
                lock(&shared_open.opening).take();
                workshop.settle(true);
                publish_setup(&shared_open);
                drop(claim);
                Ok(resumed)
            }
            _ => {
                publish_setup(&shared_open);
                let scene = served.unwrap_or(start);
                launch(claim, workshop.clone(), scene)
                    .map_err(|e| reverted(OpenFailure::NotStarted(e)))
                    .map(|()| None)
            }
        }
    })
    .await
    .unwrap_or_else(|e| Err(OpenFailure::Panicked(e)));
    match opened {
        // `resumed`: the part's project was served as it was left (how many computes it had).
        Ok(resumed) => answer(StatusCode::OK, serde_json::json!({"ok": true, "resumed": resumed})),
        Err(e) => answer(e.status(), serde_json::json!({"error": e.to_string()})),
    }
}

/// Why `POST /open` did not open the part, once its body was read.
#[derive(Debug, thiserror::Error)]
enum OpenFailure {
    /// The workshop refused the part.
    #[error(transparent)]
    Refused(WorkshopError),
    /// The part is open but its compute did not start.
    #[error(transparent)]
    NotStarted(ComputeError),
    /// The part's project basis could not be served.
    #[error(transparent)]
    Serve(ViewError),
    /// The opening task panicked.
    #[error("opening failed: {0}")]
    Panicked(tokio::task::JoinError),
}

impl OpenFailure {
    /// The answer's status: a part the workshop refuses is the page's to change (422, whatever
    /// the reason, a compute that started meanwhile included); the others are the server's.
    fn status(&self) -> StatusCode {
        match self {
            OpenFailure::Refused(_) => StatusCode::UNPROCESSABLE_ENTITY,
            OpenFailure::NotStarted(_) | OpenFailure::Serve(_) | OpenFailure::Panicked(_) => {
                StatusCode::INTERNAL_SERVER_ERROR
            }
        }
    }
}

/// The file name a downloaded basis is offered under: the part's name with anything but ASCII
/// letters, digits, `.`, `-` and `_` made `_` (a name is not a path, nor a header), at most 100
/// characters; "basis" for an empty one. Every download was "basis.h5" before, whatever the part.
fn download_name(name: &str) -> String {
    let clean: String = name
        .chars()
        .take(100)
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    let clean = clean.trim_start_matches('.').to_string();
    if clean.is_empty() { "basis".into() } else { clean }
}

/// GET /basis.h5: the basis being served, for "save basis" (only the server's own page may ask:
/// the same `Host` and `Origin` rules as every request).
async fn basis_file(State(shared): State<Arc<Shared>>) -> Response {
    let served = shared.generation.read().ok().and_then(|g| {
        Some((
            g.basis_path.clone()?,
            download_name(g.hello["name"].as_str().unwrap_or_default()),
        ))
    });
    let Some((path, name)) = served else {
        return (StatusCode::NOT_FOUND, "no basis computed here yet").into_response();
    };
    match tokio::task::spawn_blocking(move || std::fs::read(&path))
        .await
        .unwrap_or_else(|e| Err(std::io::Error::other(e)))
    {
        Ok(bytes) => (
            [
                (header::CONTENT_TYPE, "application/x-hdf5".to_string()),
                (
                    header::CONTENT_DISPOSITION,
                    format!("attachment; filename=\"{name}.h5\""),
                ),
            ],
            bytes,
        )
            .into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, format!("cannot read the basis: {e}")).into_response(),
    }
}

/// The visualization thread's hook: encodes each drawn frame and publishes it as the latest.
fn frame_encoder(bases: &[Arc<ves_runtime::Basis>], hands: &[Arc<HandSlot>; HANDS], out: Published) -> FrameObserver {
    let bases = bases.to_vec();
    let hands = hands.clone();
    let mut vm: Vec<Vec<f32>> = bases.iter().map(|b| vec![0.0; b.vertex_count()]).collect();
    let mut p1: Vec<Vec<f32>> = bases.iter().map(|b| vec![0.0; b.vertex_count()]).collect();
    let mut seq = 0u32;
    Box::new(move |f: &Frame| {
        let i = f.space;
        // Which hand message each hand had read is taken before the drawn state: a frame never
        // claims to show a message it may not (it may show one more, by one haptic step).
        let hand_seq = [hands[0].seq_read(), hands[1].seq_read()];
        seq = seq.wrapping_add(1);
        // The stress fields cost a 3×3 eigenvalue problem per vertex: only while a client
        // colours by stress, and sent apart (kind 3) to those clients only.
        let wanted = out.stress_clients.load(Ordering::Relaxed) > 0;
        if let Some(s) = f.stress.filter(|_| wanted) {
            for ((m, p), s) in vm[i].iter_mut().zip(p1[i].iter_mut()).zip(s.chunks_exact(6)) {
                let s: [f64; 6] = std::array::from_fn(|k| f64::from(s[k]));
                *m = visual::von_mises(s) as f32;
                *p = visual::principal_stresses(s)[0] as f32;
            }
            let mut b = Vec::new();
            protocol::stress_frame(&mut b, i, seq, &vm[i], &p1[i]);
            out.stress.send_replace(Bytes::from(b));
        }
        let mut pose = [0.0; 7];
        pose.copy_from_slice(&f.pose[..7]);
        let header = FrameHeader {
            space: i,
            seq,
            alarm: f.alarm,
            hand_seq,
            time: f.time,
            pose,
            von_mises_max: f.von_mises_max,
        };
        let mut b = Vec::with_capacity(protocol::FRAME_HEADER + 4 * f.displacements.len());
        protocol::frame(&mut b, &header, f.displacements, f.stress.is_some());
        out.frames.send_replace(Bytes::from(b));
        out.drawn.store(seq, Ordering::Relaxed);
        out.active_space.store(i as u32, Ordering::Relaxed);
        out.alarm.store(f.alarm, Ordering::Relaxed);
        // The status loop reads it a few times a second: never waited for here.
        if let Ok(mut r) = out.reactions.try_lock() {
            r.clear();
            r.extend_from_slice(f.reactions.unwrap_or_default());
        }
    })
}

fn hello(
    bases: &[Arc<ves_runtime::Basis>],
    space_loads: &[loads::SpaceLoads],
    cfg: &ViewConfig,
    workshop: Option<&dyn Workshop>,
) -> serde_json::Value {
    let part = workshop.and_then(|w| w.geometry());
    let spaces: Vec<_> = bases
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let l = space_loads.get(i);
            let (compliance, at) = b.largest_compliance();
            serde_json::json!({
                "name": b.space,
                "vertices": b.vertex_count(),
                "largest_compliance": compliance,
                "largest_compliance_vertex": at,
                "triangles": b.triangles.len(),
                "voi": b.voi,
                "has_stress": b.stress.is_some(),
                // A nonlinear model moves visibly and its shape is only right at true size.
                "nonlinear": b.nonlinear.is_some(),
                "frequencies_hz": b.eigenvalues.iter().map(|l| l.sqrt() / (2.0 * std::f64::consts::PI)).collect::<Vec<_>>(),
                "loads": l.map(|l| l.cases.clone()).unwrap_or_default(),
                "loads_error": l.and_then(|l| l.error.clone()),
                "faces": cfg.face_kinds.zip(b.surface_faces.as_ref()).map(|(kinds, faces)| {
                    kinds(&b.rest[..b.vertex_count()], &b.triangles, faces, part.as_deref())
                }),
            })
        })
        .collect();
    let s = &cfg.session;
    let first = bases.first();
    serde_json::json!({
        "type": "hello",
        "protocol": protocol::VERSION,
        // The part set up now (one opened in the page included), else the file given.
        "name": part
            .as_ref()
            .and_then(|p| p.file_name())
            .map_or_else(|| cfg.name.clone(), |n| n.to_string_lossy().into_owned()),
        "client": 0,
        "rate_hz": s.rate_hz,
        "max_force": s.coupling.max_force,
        "stiffness": s.coupling.stiffness,
        "damping": s.coupling.damping,
        "yield_strength": first.and_then(|b| b.yield_strength),
        "min_safety_factor": s.watch.min_safety_factor,
        "strain_limit": s.watch.limit,
        "free_body": first.is_some_and(|b| b.rigid.is_some()),
        // How many rigid motions the supports leave (6: a free body; a shaft in bearings 1).
        "free_motions": first.and_then(|b| b.rigid.map(|r| r.free.count())),
        "center": first.and_then(|b| b.rigid.map(|r| r.center)),
        "gravity": s.free_body.map(|(g, _)| g),
        "spaces": spaces,
        // Where each `[[fixed]]` support's moment is taken about (the status's `supports`).
        "support_centres": first.and_then(|b| b.support_reactions.as_ref().map(|r| r.centres.clone())),
        "setup": workshop.map(|w| w.setup()),
    })
}

/// Each hand's felt error from the checks' table when the session's basis was loaded before
/// the checks wrote it.
fn felt_errors(shared: &Shared, space: usize, hands: &mut [HandStatus]) {
    let Ok(g) = shared.generation.read() else { return };
    let (Some(Some(felt)), Some(basis)) = (g.felt.get(space), g.bases.get(space)) else {
        return;
    };
    for h in hands.iter_mut().filter(|h| h.output.felt_error.is_nan()) {
        let i = h.output.vertex as usize;
        let corrected = basis.compliance_of(i).is_some();
        h.output.felt_error = felt.error(i, corrected, basis.eigenvalues.len()).unwrap_or(f64::NAN);
    }
}

/// Status at [`STATUS_PERIOD`]: rates, hands, clients.
async fn status_loop(shared: Arc<Shared>, tx: watch::Sender<String>, stop: Arc<AtomicBool>) {
    let mut tick = tokio::time::interval(STATUS_PERIOD);
    let drawn = &shared.published.drawn;
    let (mut t0, mut steps0, mut frames0) = (Instant::now(), shared.hands[0].steps(), drawn.load(Ordering::Relaxed));
    let (mut haptic_hz, mut visual_hz) = (0.0, 0.0);
    while !stop.load(Ordering::Relaxed) {
        tick.tick().await;
        let (t, steps, frames) = (Instant::now(), shared.hands[0].steps(), drawn.load(Ordering::Relaxed));
        let dt = t.duration_since(t0).as_secs_f64();
        if dt >= 0.5 {
            haptic_hz = steps.wrapping_sub(steps0) as f64 / dt;
            // A new session numbers its frames from 1 again: no rate for that interval, not a wrap.
            visual_hz = f64::from(frames.saturating_sub(frames0)) / dt;
            (t0, steps0, frames0) = (t, steps, frames);
        }
        let space = shared.published.active_space.load(Ordering::Relaxed) as usize;
        let mut hands: Vec<HandStatus> = shared.hands.iter().map(|h| h.status()).collect();
        felt_errors(&shared, space, &mut hands);
        let supports: Vec<serde_json::Value> = shared
            .published
            .reactions
            .lock()
            .map(|r| {
                r.iter()
                    .map(|v| serde_json::json!({"force_n": &v[..3], "moment_nm": &v[3..]}))
                    .collect()
            })
            .unwrap_or_default();
        let status = serde_json::json!({
            "type": "status",
            "space": shared.published.active_space.load(Ordering::Relaxed),
            "haptic_hz": haptic_hz,
            "visual_hz": visual_hz,
            "clients": shared.clients.load(Ordering::Relaxed),
            "messages_dropped": shared.dropped.load(Ordering::Relaxed),
            "alarm": shared.published.alarm.load(Ordering::Relaxed),
            "computing": shared.computing.load(Ordering::Relaxed),
            "checking": shared.checking.load(Ordering::Relaxed),
            "hands": hands,
            "supports": supports,
        });
        tx.send_replace(status.to_string());
    }
}

async fn upgrade(ws: WebSocketUpgrade, State(shared): State<Arc<Shared>>) -> Response {
    let Ok(slot) = shared.client_slots.clone().try_acquire_owned() else {
        shared.refused.fetch_add(1, Ordering::Relaxed);
        let why = format!(
            "{} clients are connected, the most this server takes: close a page and reload",
            shared.max_clients
        );
        return (StatusCode::SERVICE_UNAVAILABLE, why).into_response();
    };
    // Oversized messages beyond this end the connection inside the WebSocket layer; up to it,
    // `protocol::parse` drops and counts them.
    ws.max_message_size(64 * 1024)
        .max_frame_size(64 * 1024)
        .on_upgrade(move |socket| async move {
            client(socket, shared).await;
            drop(slot);
        })
        .into_response()
}

async fn send(socket: &mut WebSocket, m: Message) -> bool {
    matches!(tokio::time::timeout(SEND_TIMEOUT, socket.send(m)).await, Ok(Ok(())))
}

async fn client(mut socket: WebSocket, shared: Arc<Shared>) {
    let id = shared.next_client.fetch_add(1, Ordering::Relaxed) + 1;
    let now = shared.clients.fetch_add(1, Ordering::Relaxed) + 1;
    shared.clients_total.fetch_add(1, Ordering::Relaxed);
    shared.clients_max.fetch_max(now, Ordering::Relaxed);
    let mut generations = shared.generations.subscribe();
    let (mut frames, mut status) = (shared.frames.clone(), shared.status.clone());
    let mut stress = shared.stress_frames.clone();
    let mut notes = shared.notes.subscribe();
    let mut setup = shared.setup_tx.subscribe();
    let mut wants_stress = false;
    let mut gate = FrameGate::default();
    // The hello and meshes first: nothing else means anything to the page before them.
    let mut ok = send_generation(&mut socket, &shared, id).await;
    generations.borrow_and_update();
    // Then the set-up every page shows.
    let mut acked = 0u32;
    let first = setup.borrow_and_update().clone();
    if ok && !first.is_empty() {
        ok = send(&mut socket, Message::Text(with_ack(&first, acked).into())).await;
    }
    while ok {
        tokio::select! {
            r = generations.changed() => {
                if r.is_err() { break; }
                ok = next_generation(&mut socket, &shared, id, (&mut generations, &mut frames, &mut gate)).await;
            }
            m = socket.recv() => match m {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => break,
                Some(Ok(Message::Text(t))) => match handle(&shared, id, t.as_str()) {
                    Reply::Send(reply) => ok = send(&mut socket, Message::Binary(reply)).await,
                    Reply::Note(text) => ok = send(&mut socket, Message::Text(text.into())).await,
                    Reply::Edited(seq, note) => {
                        acked = seq;
                        if let Some(text) = note {
                            ok = send(&mut socket, Message::Text(text.into())).await;
                        }
                    }
                    Reply::Load(space, index) => {
                        let reply = load_case(&shared, space, index).await;
                        ok = send(&mut socket, reply).await;
                    }
                    Reply::Stress(on) if on != wants_stress => {
                        wants_stress = on;
                        want_stress(&shared, on);
                        if on {
                            stress.mark_unchanged();
                        }
                    }
                    _ => {}
                },
                Some(Ok(Message::Binary(_))) => { shared.dropped.fetch_add(1, Ordering::Relaxed); }
                Some(Ok(_)) => {}
            },
            r = frames.changed() => {
                if r.is_err() { break; }
                let f = frames.borrow_and_update().clone();
                let Some(f) = gate.pass(&shared, f) else { continue };
                ok = send(&mut socket, Message::Binary(f)).await;
                shared.frames_sent.fetch_add(u64::from(ok), Ordering::Relaxed);
            }
            r = stress.changed(), if wants_stress => {
                if r.is_err() { break; }
                let f = stress.borrow_and_update().clone();
                ok = send(&mut socket, Message::Binary(f)).await;
            }
            r = setup.changed() => {
                if r.is_err() { break; }
                let s = with_ack(&setup.borrow_and_update(), acked);
                ok = send(&mut socket, Message::Text(s.into())).await;
            }
            r = status.changed() => {
                if r.is_err() { break; }
                let s = status.borrow_and_update().clone();
                ok = send(&mut socket, Message::Text(s.into())).await;
            }
            r = notes.recv() => match r {
                Ok(n) => {
                    // A `computed` note follows its swap: the page gets the basis it names (the
                    // new hello and meshes) before the note, never after (select! picks among
                    // ready branches at random, and a page that took a note for the basis
                    // shown read an instant basis's frequencies as the converged one's).
                    if generations.has_changed().unwrap_or(false) {
                        ok = next_generation(&mut socket, &shared, id, (&mut generations, &mut frames, &mut gate)).await;
                    }
                    ok = ok && send(&mut socket, Message::Text(n.into())).await;
                }
                // Progress lost to a slow page is no loss; the channel is large enough that the
                // outcomes, few and far apart, are not.
                Err(broadcast::error::RecvError::Lagged(_)) => {}
                Err(broadcast::error::RecvError::Closed) => break,
            },
        }
    }
    for h in &shared.hands {
        h.release(id);
    }
    if wants_stress {
        want_stress(&shared, false);
    }
    shared.clients.fetch_sub(1, Ordering::Relaxed);
}

/// A set-up message (a JSON object's text) with this connection's `ack` first.
fn with_ack(message: &str, acked: u32) -> String {
    format!("{{\"ack\":{acked},{}", message.strip_prefix('{').unwrap_or(message))
}

/// Counts a client that starts (or stops) colouring by stress: the drawing thread makes the
/// stress fields only while some client wants them.
fn want_stress(shared: &Shared, on: bool) {
    if on {
        shared.published.stress_clients.fetch_add(1, Ordering::Relaxed);
    } else {
        shared.published.stress_clients.fetch_sub(1, Ordering::Relaxed);
    }
}

/// Frames between `last` and `seq` a client did not get. A new session numbers its frames from 1
/// again, and its first frames can reach a client before the swap's generation does: a number
/// below the last is a restart, not 2³² − 1 − k skipped frames (the `frames_skipped:
/// 4294966184` a user saw in `--json`).
fn skipped(last: u32, seq: u32) -> u64 {
    u64::from(seq.checked_sub(last).map_or(0, |d| d.saturating_sub(1)))
}

/// Which drawn frames one client is sent.
#[derive(Default)]
struct FrameGate {
    /// The number of the last frame seen (frames between two seen ones were skipped).
    last_seq: Option<u32>,
    /// The last frame sent and when.
    last_sent: Option<(Bytes, Instant)>,
}

impl FrameGate {
    /// The frame to send, if any. A part at rest is not sent again at the visual rate (on the
    /// mould 250 kB at 60 Hz kept the browser busy on two cores): a frame that differs from
    /// the last one sent only in its number and time waits, up to KEEPALIVE.
    fn pass(&mut self, shared: &Shared, f: Bytes) -> Option<Bytes> {
        let seq = protocol::frame_seq(&f)?;
        if let Some(l) = self.last_seq {
            shared.frames_skipped.fetch_add(skipped(l, seq), Ordering::Relaxed);
        }
        self.last_seq = Some(seq);
        if self
            .last_sent
            .as_ref()
            .is_some_and(|(l, at)| protocol::frames_draw_the_same(l, &f) && at.elapsed() < KEEPALIVE)
        {
            return None;
        }
        self.last_sent = Some((f.clone(), Instant::now()));
        Some(f)
    }
}

/// Sends the basis being served (new at each compute): its hello, then its meshes.
/// The generation that replaced the one a client was sent: its hello and meshes, and no frame of
/// the session before (not for these meshes).
async fn next_generation(
    socket: &mut WebSocket,
    shared: &Shared,
    id: u64,
    (generations, frames, gate): (&mut watch::Receiver<u64>, &mut watch::Receiver<Bytes>, &mut FrameGate),
) -> bool {
    generations.borrow_and_update();
    let ok = send_generation(socket, shared, id).await;
    frames.borrow_and_update();
    gate.last_seq = None;
    ok
}

async fn send_generation(socket: &mut WebSocket, shared: &Shared, id: u64) -> bool {
    let g = shared.generation.read().ok().map(|g| Arc::clone(&g));
    let Some(g) = g else { return false };
    let mut hello = g.hello.clone();
    hello["client"] = id.into();
    let mut ok = send(socket, Message::Text(hello.to_string().into())).await;
    for m in &g.meshes {
        ok = ok && send(socket, Message::Binary(m.clone())).await;
    }
    ok
}

/// What a client message asks of its connection.
enum Reply {
    /// Nothing.
    None,
    /// An edit of the set-up (its `seq`) applied, and a note for this page if any.
    Edited(u32, Option<String>),
    /// Send these bytes (a mode shape).
    Send(Bytes),
    /// Send this text to this page only (why its compute did not start).
    Note(String),
    /// Send the stress frames, or stop.
    Stress(bool),
    /// Send load case `.1` of space `.0` (read from the file first).
    Load(usize, usize),
}

/// Applies one client message.
fn handle(shared: &Arc<Shared>, id: u64, text: &str) -> Reply {
    let dropped = || {
        shared.dropped.fetch_add(1, Ordering::Relaxed);
        Reply::None
    };
    let Ok(g) = shared.generation.read().map(|g| g.clone()) else {
        return dropped();
    };
    match protocol::parse_with(text, g.bases.len(), g.extent.as_ref(), &g.load_names) {
        Ok(ClientMessage::Hand(h, c)) => {
            if shared.hands[h].command(id, &c) {
                Reply::None
            } else {
                dropped()
            }
        }
        Ok(ClientMessage::Mode { space, index }) => match protocol::mode(space, &g.bases[space], index) {
            Some(b) => Reply::Send(Bytes::from(b)),
            None => dropped(),
        },
        Ok(ClientMessage::Fields { stress }) => Reply::Stress(stress),
        Ok(ClientMessage::Load { space, index }) => Reply::Load(space, index),
        Ok(ClientMessage::Reset) => {
            for h in &shared.hands {
                h.release_any();
            }
            shared.reset.store(true, Ordering::Relaxed);
            Reply::None
        }
        Ok(ClientMessage::Compute { scene, seq }) if shared.workshop.is_some() => {
            // Sent back even when unchanged: the page waits for its edits' echo.
            change_setup(shared, |s| {
                s.edit(scene.clone());
                true
            });
            match start_compute(shared, scene) {
                Ok(()) => Reply::Edited(seq, None),
                Err(e) => Reply::Edited(
                    seq,
                    Some(serde_json::json!({"type": "compute_error", "message": e.to_string()}).to_string()),
                ),
            }
        }
        Ok(ClientMessage::Compute { scene, .. }) => match start_compute(shared, scene) {
            Ok(()) => Reply::None,
            Err(e) => Reply::Note(serde_json::json!({"type": "compute_error", "message": e.to_string()}).to_string()),
        },
        Ok(ClientMessage::Cancel) => {
            shared.cancel.store(true, Ordering::Relaxed);
            // The panel back to the scene served (undo brings the edits back).
            change_setup(shared, SetUp::revert);
            Reply::None
        }
        Ok(ClientMessage::Edit { scene, seq }) if shared.workshop.is_some() => {
            change_setup(shared, |s| {
                s.edit(scene);
                true
            });
            Reply::Edited(seq, None)
        }
        Ok(ClientMessage::Undo) if shared.workshop.is_some() => {
            change_setup(shared, SetUp::undo);
            Reply::None
        }
        Ok(ClientMessage::Redo) if shared.workshop.is_some() => {
            change_setup(shared, SetUp::redo);
            Reply::None
        }
        Ok(ClientMessage::Revert) if shared.workshop.is_some() => {
            change_setup(shared, SetUp::revert);
            Reply::None
        }
        Ok(ClientMessage::Edit { .. } | ClientMessage::Undo | ClientMessage::Redo | ClientMessage::Revert) => dropped(),
        Err(e) => {
            tracing_drop(id, &e);
            dropped()
        }
    }
}

/// Load case `index` of `space` of the basis served now, read from its file (off the server's
/// thread) and encoded as kind 4; or, if the file cannot give it, a `load_error` note for this
/// page. A client's requests are answered one after the other (its own loop waits), so a page
/// asking again and again only slows itself.
async fn load_case(shared: &Shared, space: usize, index: usize) -> Message {
    let g = shared.generation.read().ok().map(|g| Arc::clone(&g));
    let found = g.and_then(|g| {
        let basis = g.bases.get(space)?.clone();
        let l = g.loads.get(space)?;
        Some((basis, l.cases.get(index)?.name.clone(), l.node_count))
    });
    let read = match found {
        // The basis changed between the request and now: the page gets the new hello anyway.
        None => Err(loads::LoadsError::BasisChanged),
        Some((basis, name, nodes)) => tokio::task::spawn_blocking(move || {
            let case = loads::read(&basis, &name, nodes)?;
            protocol::load_case(space, index, &basis, &case).ok_or(loads::LoadsError::DoesNotFit { name })
        })
        .await
        .unwrap_or_else(|e| Err(loads::LoadsError::Failed(e))),
    };
    match read {
        Ok(b) => Message::Binary(Bytes::from(b)),
        Err(e) => Message::Text(
            serde_json::json!({"type": "load_error", "space": space, "index": index, "message": e.to_string()})
                .to_string()
                .into(),
        ),
    }
}

/// Dropped messages are counted; the first few reasons go to stderr for whoever debugs a client.
fn tracing_drop(id: u64, why: &protocol::MessageError) {
    static SHOWN: AtomicU32 = AtomicU32::new(0);
    if SHOWN.fetch_add(1, Ordering::Relaxed) < 5 {
        eprintln!("ves view: dropped a message from client {id}: {why}");
    }
}
