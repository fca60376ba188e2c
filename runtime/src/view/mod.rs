//! `ves view`: a session whose device is a web page. One page and one WebSocket are served;
//! the real session ([`crate::session::run_spaces_with`], the code `ves session` runs) steps the
//! haptic loop at its rate with one [`hands::WebHand`] per hand, and its visualization thread
//! hands each drawn frame to the server, which keeps only the latest: a slow client skips
//! frames instead of queueing them, and a vanished one costs nothing but its own task. Only
//! this server's own page may use it, within connection limits ([`server`]).

pub mod hands;
pub mod protocol;
pub mod server;
#[cfg(test)]
mod tests;

use crate::device::Device;
use crate::session::{self, Frame, FrameObserver, Hooks, SessionConfig, SessionStats};
use crate::switching::SpaceInput;
use crate::visual;
use axum::body::Bytes;
use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use hands::{HandSlot, HandStatus, WebHand};
use protocol::{ClientMessage, Extent, FrameHeader, HANDS};
pub use server::Limits;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use tokio::sync::{Semaphore, watch};

const INDEX_HTML: &str = include_str!("../../web/index.html");
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
    /// The session (rate, coupling, watch; `duration_s` infinite to run until stopped).
    pub session: SessionConfig,
    /// Shown in the page's title (the basis file's name).
    pub name: String,
    /// Connection limits (header timeout, connections and clients at once).
    pub limits: Limits,
}

/// What a viewer run measured.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ViewStats {
    /// The session's own statistics (as `ves session --json`).
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
    /// Frames the session drew.
    pub frames_drawn: u64,
    /// Requests refused: a `Host` or `Origin` other than this server's, or a WebSocket client
    /// beyond the limit.
    pub requests_refused: u64,
}

/// The viewer could not start.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ViewError(pub String);

struct Shared {
    hands: [Arc<HandSlot>; HANDS],
    /// The hello message; each client's gets its own `client` id.
    hello: serde_json::Value,
    meshes: Vec<Bytes>,
    bases: Vec<Arc<crate::Basis>>,
    extent: Extent,
    frames: watch::Receiver<Bytes>,
    stress_frames: watch::Receiver<Bytes>,
    /// Clients colouring by stress (the drawing thread computes stress fields only for them).
    stress_clients: Arc<AtomicUsize>,
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
}

/// Serves the viewer until the session ends (its duration, Ctrl-C, or `stop`). `ready` gets
/// the bound address before the first client can connect.
pub fn serve(
    spaces: Vec<SpaceInput>,
    cfg: &ViewConfig,
    stop: Arc<AtomicBool>,
    ready: impl FnOnce(SocketAddr),
) -> Result<ViewStats, ViewError> {
    cfg.session.validate().map_err(|e| ViewError(e.to_string()))?;
    let listener = std::net::TcpListener::bind(cfg.addr).map_err(|e| {
        ViewError(if e.kind() == std::io::ErrorKind::AddrInUse {
            format!(
                "port {} on {} is in use: pick another with --port (0 picks a free one)",
                cfg.addr.port(),
                cfg.addr.ip()
            )
        } else {
            format!("cannot listen on {}: {e}; check --host and --port", cfg.addr)
        })
    })?;
    listener.set_nonblocking(true).map_err(|e| ViewError(e.to_string()))?;
    let addr = listener.local_addr().map_err(|e| ViewError(e.to_string()))?;
    let bases: Vec<Arc<crate::Basis>> = spaces.iter().map(|s| s.basis.clone()).collect();
    let (frame_tx, frame_rx) = watch::channel(Bytes::new());
    let (stress_tx, stress_rx) = watch::channel(Bytes::new());
    let stress_clients = Arc::new(AtomicUsize::new(0));
    let (status_tx, status_rx) = watch::channel(String::new());
    let shared = Arc::new(Shared {
        hands: std::array::from_fn(|_| Arc::new(HandSlot::default())),
        hello: hello(&bases, cfg),
        meshes: bases
            .iter()
            .enumerate()
            .map(|(i, b)| Bytes::from(protocol::mesh(i, b)))
            .collect(),
        extent: Extent::of(&bases[0]),
        bases: bases.clone(),
        frames: frame_rx,
        stress_frames: stress_rx,
        stress_clients: stress_clients.clone(),
        status: status_rx,
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
    });
    let drawn = Arc::new(AtomicU32::new(0));
    let active_space = Arc::new(AtomicU32::new(0));
    let alarm = Arc::new(AtomicBool::new(false));

    // The session, in its own threads, exactly as `ves session` runs it.
    let dt = 1.0 / cfg.session.rate_hz;
    let devices: Vec<Box<dyn Device>> = shared
        .hands
        .iter()
        .map(|h| Box::new(WebHand::new(h.clone(), dt)) as Box<dyn Device>)
        .collect();
    let hooks = Hooks {
        stop: Some(stop.clone()),
        reset: Some(shared.reset.clone()),
        frame: Some(frame_encoder(
            &bases,
            &shared.hands,
            Published {
                frames: frame_tx,
                stress: stress_tx,
                stress_clients,
                drawn: drawn.clone(),
                active_space: active_space.clone(),
                alarm: alarm.clone(),
            },
        )),
    };
    let session_cfg = cfg.session;
    let session = std::thread::Builder::new()
        .name("ves-session".into())
        .spawn(move || session::run_spaces_with(spaces, devices, &session_cfg, hooks))
        .map_err(|e| ViewError(format!("cannot start the session: {e}")))?;

    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(|e| ViewError(format!("cannot start the server: {e}")))?;
    let served = rt.block_on(async {
        let listener = tokio::net::TcpListener::from_std(listener).map_err(|e| ViewError(e.to_string()))?;
        let app = axum::Router::new()
            .route(
                "/",
                get(|| async { ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], INDEX_HTML) }),
            )
            .route(
                "/app.js",
                get(|| async { ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], APP_JS) }),
            )
            .route("/favicon.ico", get(|| async { axum::http::StatusCode::NO_CONTENT }))
            .route("/ws", get(upgrade))
            .with_state(shared.clone());
        ready(addr);
        let status = tokio::spawn(status_loop(
            shared.clone(),
            status_tx,
            drawn.clone(),
            active_space,
            alarm,
            stop.clone(),
        ));
        let ended = {
            let stop = stop.clone();
            async move {
                loop {
                    tokio::select! {
                        _ = tokio::signal::ctrl_c() => { stop.store(true, Ordering::Relaxed); break; }
                        _ = tokio::time::sleep(Duration::from_millis(100)) => {
                            if stop.load(Ordering::Relaxed) || session.is_finished() { break; }
                        }
                    }
                }
                stop.store(true, Ordering::Relaxed);
                session
            }
        };
        let (tx, rx) = watch::channel(false);
        let server = tokio::spawn(server::run(
            listener,
            app,
            Arc::new(server::Guard::new(addr)),
            cfg.limits,
            shared.refused.clone(),
            rx,
        ));
        let session = ended.await;
        let _ = tx.send(true);
        status.abort();
        // Open connections are dropped; the WebSockets end with the runtime below.
        let _ = tokio::time::timeout(Duration::from_secs(1), server).await;
        Ok::<_, ViewError>(session)
    })?;
    rt.shutdown_timeout(Duration::from_millis(200));
    let stats = served
        .join()
        .map_err(|_| ViewError("the session thread panicked".into()))?
        .map_err(ViewError)?;
    Ok(ViewStats {
        session: stats,
        clients_total: shared.clients_total.load(Ordering::Relaxed),
        clients_max: shared.clients_max.load(Ordering::Relaxed),
        messages_dropped: shared.dropped.load(Ordering::Relaxed),
        frames_sent: shared.frames_sent.load(Ordering::Relaxed),
        frames_skipped: shared.frames_skipped.load(Ordering::Relaxed),
        frames_drawn: u64::from(drawn.load(Ordering::Relaxed)),
        requests_refused: shared.refused.load(Ordering::Relaxed),
    })
}

/// The visualization thread's hook: encodes each drawn frame and publishes it as the latest.
/// Where the drawing thread's hook publishes.
struct Published {
    frames: watch::Sender<Bytes>,
    stress: watch::Sender<Bytes>,
    stress_clients: Arc<AtomicUsize>,
    drawn: Arc<AtomicU32>,
    active_space: Arc<AtomicU32>,
    alarm: Arc<AtomicBool>,
}

fn frame_encoder(bases: &[Arc<crate::Basis>], hands: &[Arc<HandSlot>; HANDS], out: Published) -> FrameObserver {
    let bases = bases.to_vec();
    let hands = hands.clone();
    let mut u: Vec<Vec<f32>> = bases.iter().map(|b| vec![0.0; 3 * b.vertex_count()]).collect();
    let mut vm: Vec<Vec<f32>> = bases.iter().map(|b| vec![0.0; b.vertex_count()]).collect();
    let mut p1: Vec<Vec<f32>> = bases.iter().map(|b| vec![0.0; b.vertex_count()]).collect();
    let mut seq = 0u32;
    Box::new(move |f: &Frame| {
        let i = f.space;
        // Which hand message each hand had read is taken before the drawn state: a frame never
        // claims to show a message it may not (it may show one more, by one haptic step).
        let hand_seq = [hands[0].seq_read(), hands[1].seq_read()];
        visual::displacements(&bases[i], f.modal, &mut u[i]);
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
        let mut b = Vec::with_capacity(protocol::FRAME_HEADER + 4 * u[i].len());
        protocol::frame(&mut b, &header, &u[i], f.stress.is_some());
        out.frames.send_replace(Bytes::from(b));
        out.drawn.store(seq, Ordering::Relaxed);
        out.active_space.store(i as u32, Ordering::Relaxed);
        out.alarm.store(f.alarm, Ordering::Relaxed);
    })
}

fn hello(bases: &[Arc<crate::Basis>], cfg: &ViewConfig) -> serde_json::Value {
    let spaces: Vec<_> = bases
        .iter()
        .map(|b| {
            let (compliance, at) = b.largest_compliance();
            serde_json::json!({
                "name": b.space,
                "vertices": b.vertex_count(),
                "largest_compliance": compliance,
                "largest_compliance_vertex": at,
                "triangles": b.triangles.len(),
                "voi": b.voi,
                "has_stress": b.stress.is_some(),
                "frequencies_hz": b.eigenvalues.iter().map(|l| l.sqrt() / (2.0 * std::f64::consts::PI)).collect::<Vec<_>>(),
            })
        })
        .collect();
    let s = &cfg.session;
    serde_json::json!({
        "type": "hello",
        "name": cfg.name,
        "client": 0,
        "rate_hz": s.rate_hz,
        "max_force": s.coupling.max_force,
        "stiffness": s.coupling.stiffness,
        "damping": s.coupling.damping,
        "yield_strength": bases[0].yield_strength,
        "min_safety_factor": s.strain.min_safety_factor,
        "strain_limit": s.strain.limit,
        "free_body": bases[0].rigid.is_some(),
        "center": bases[0].rigid.map(|r| r.center),
        "gravity": s.free_body.map(|(g, _)| g),
        "spaces": spaces,
    })
}

/// Status at [`STATUS_PERIOD`]: rates, hands, clients.
async fn status_loop(
    shared: Arc<Shared>,
    tx: watch::Sender<String>,
    drawn: Arc<AtomicU32>,
    active_space: Arc<AtomicU32>,
    alarm: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
) {
    let mut tick = tokio::time::interval(STATUS_PERIOD);
    let (mut t0, mut steps0, mut frames0) = (Instant::now(), shared.hands[0].steps(), drawn.load(Ordering::Relaxed));
    let (mut haptic_hz, mut visual_hz) = (0.0, 0.0);
    while !stop.load(Ordering::Relaxed) {
        tick.tick().await;
        let (t, steps, frames) = (Instant::now(), shared.hands[0].steps(), drawn.load(Ordering::Relaxed));
        let dt = t.duration_since(t0).as_secs_f64();
        if dt >= 0.5 {
            haptic_hz = steps.wrapping_sub(steps0) as f64 / dt;
            visual_hz = f64::from(frames.wrapping_sub(frames0)) / dt;
            (t0, steps0, frames0) = (t, steps, frames);
        }
        let hands: Vec<HandStatus> = shared.hands.iter().map(|h| h.status()).collect();
        let status = serde_json::json!({
            "type": "status",
            "space": active_space.load(Ordering::Relaxed),
            "haptic_hz": haptic_hz,
            "visual_hz": visual_hz,
            "clients": shared.clients.load(Ordering::Relaxed),
            "messages_dropped": shared.dropped.load(Ordering::Relaxed),
            "alarm": alarm.load(Ordering::Relaxed),
            "hands": hands,
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
    let mut hello = shared.hello.clone();
    hello["client"] = id.into();
    let mut ok = send(&mut socket, Message::Text(hello.to_string().into())).await;
    for m in &shared.meshes {
        ok = ok && send(&mut socket, Message::Binary(m.clone())).await;
    }
    let (mut frames, mut status) = (shared.frames.clone(), shared.status.clone());
    let mut stress = shared.stress_frames.clone();
    let mut wants_stress = false;
    let mut last_seq: Option<u32> = None;
    while ok {
        tokio::select! {
            m = socket.recv() => match m {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => break,
                Some(Ok(Message::Text(t))) => match handle(&shared, id, t.as_str()) {
                    Reply::Send(reply) => ok = send(&mut socket, Message::Binary(reply)).await,
                    Reply::Stress(on) if on != wants_stress => {
                        wants_stress = on;
                        if on {
                            shared.stress_clients.fetch_add(1, Ordering::Relaxed);
                            stress.mark_unchanged();
                        } else {
                            shared.stress_clients.fetch_sub(1, Ordering::Relaxed);
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
                if f.len() < 20 { continue; }
                let seq = u32::from_le_bytes([f[16], f[17], f[18], f[19]]);
                if let Some(l) = last_seq {
                    shared.frames_skipped.fetch_add(u64::from(seq.wrapping_sub(l).saturating_sub(1)), Ordering::Relaxed);
                }
                last_seq = Some(seq);
                ok = send(&mut socket, Message::Binary(f)).await;
                shared.frames_sent.fetch_add(u64::from(ok), Ordering::Relaxed);
            }
            r = stress.changed(), if wants_stress => {
                if r.is_err() { break; }
                let f = stress.borrow_and_update().clone();
                ok = send(&mut socket, Message::Binary(f)).await;
            }
            r = status.changed() => {
                if r.is_err() { break; }
                let s = status.borrow_and_update().clone();
                ok = send(&mut socket, Message::Text(s.into())).await;
            }
        }
    }
    for h in &shared.hands {
        h.release(id);
    }
    if wants_stress {
        shared.stress_clients.fetch_sub(1, Ordering::Relaxed);
    }
    shared.clients.fetch_sub(1, Ordering::Relaxed);
}

/// What a client message asks of its connection.
enum Reply {
    /// Nothing.
    None,
    /// Send these bytes (a mode shape).
    Send(Bytes),
    /// Send the stress frames, or stop.
    Stress(bool),
}

/// Applies one client message.
fn handle(shared: &Shared, id: u64, text: &str) -> Reply {
    let dropped = || {
        shared.dropped.fetch_add(1, Ordering::Relaxed);
        Reply::None
    };
    match protocol::parse(text, shared.bases.len(), &shared.extent) {
        Ok(ClientMessage::Hand(h, c)) => {
            if shared.hands[h].command(id, &c) {
                Reply::None
            } else {
                dropped()
            }
        }
        Ok(ClientMessage::Mode { space, index }) => match protocol::mode(space, &shared.bases[space], index) {
            Some(b) => Reply::Send(Bytes::from(b)),
            None => dropped(),
        },
        Ok(ClientMessage::Fields { stress }) => Reply::Stress(stress),
        Ok(ClientMessage::Reset) => {
            for h in &shared.hands {
                h.release_any();
            }
            shared.reset.store(true, Ordering::Relaxed);
            Reply::None
        }
        Err(e) => {
            tracing_drop(id, &e);
            dropped()
        }
    }
}

/// Dropped messages are counted; the first few reasons go to stderr for whoever debugs a client.
fn tracing_drop(id: u64, why: &str) {
    static SHOWN: AtomicU32 = AtomicU32::new(0);
    if SHOWN.fetch_add(1, Ordering::Relaxed) < 5 {
        eprintln!("ves view: dropped a message from client {id}: {why}");
    }
}
