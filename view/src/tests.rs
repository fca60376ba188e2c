//! The server as a hostile client meets it: raw HTTP and WebSocket handshakes over TCP against
//! `serve` running in this process on a one-tetrahedron basis.

use super::*;
use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;

/// One tetrahedron, one mode: enough for the server to have a mesh to send.
fn tet() -> SpaceInput {
    let rest = vec![[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1]];
    let triangles = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let basis = ves_runtime::Basis::new(
        "tet",
        "global",
        rest,
        (0..4).collect(),
        triangles,
        vec![1.0e4],
        &[0.1; 12],
        (0.0, 0.0),
        None,
    )
    .unwrap();
    SpaceInput {
        basis: Arc::new(basis),
        transfers: vec![None],
    }
}

/// A server running until dropped.
struct Running {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    done: Option<std::thread::JoinHandle<Result<ViewStats, ViewError>>>,
}

impl Running {
    fn start(limits: Limits) -> Running {
        Running::start_with("127.0.0.1:0", limits, None)
    }

    /// A server on `addr` with `workshop` as its set-up panel.
    fn start_with(addr: &str, limits: Limits, workshop: Option<Arc<dyn Workshop>>) -> Running {
        let cfg = ViewConfig {
            addr: addr.parse().unwrap(),
            session: SessionConfig {
                duration_s: f64::INFINITY,
                free_body: None,
                ..Default::default()
            },
            name: "tet".into(),
            limits,
            face_kinds: None,
        };
        let (tx, rx) = std::sync::mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let done =
            std::thread::spawn(move || serve_with(Some(vec![tet()]), workshop, &cfg, s, move |a| tx.send(a).unwrap()));
        let addr = rx.recv_timeout(Duration::from_secs(20)).expect("the server starts");
        Running {
            addr,
            stop,
            done: Some(done),
        }
    }

    fn finish(mut self) -> ViewStats {
        self.stop.store(true, Ordering::Relaxed);
        self.done.take().unwrap().join().unwrap().unwrap()
    }

    fn connect(&self) -> TcpStream {
        let s = TcpStream::connect(self.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        s
    }

    /// Sends `request` on a new connection; the response's head and the first bytes after it.
    fn exchange(&self, request: &str) -> (u16, Vec<u8>) {
        let mut s = self.connect();
        s.write_all(request.as_bytes()).unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 4096];
        while !got.windows(4).any(|w| w == b"\r\n\r\n") {
            let n = s.read(&mut buf).unwrap();
            assert!(n > 0, "closed without a response: {}", String::from_utf8_lossy(&got));
            got.extend_from_slice(&buf[..n]);
        }
        let head_end = got.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
        let status = std::str::from_utf8(&got[9..12]).unwrap().parse().unwrap();
        if request.contains("Connection: close") {
            // The whole response: the server closes after it.
            s.read_to_end(&mut got).unwrap();
        } else if status == 101 && got.len() == head_end {
            // The hello message follows the handshake.
            let n = s.read(&mut buf).unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        (status, got[head_end..].to_vec())
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

fn get(host: &str, origin: Option<&str>) -> String {
    let origin = origin.map(|o| format!("Origin: {o}\r\n")).unwrap_or_default();
    format!("GET / HTTP/1.1\r\nHost: {host}\r\n{origin}Connection: close\r\n\r\n")
}

fn websocket(host: &str, origin: Option<&str>) -> String {
    let origin = origin.map(|o| format!("Origin: {o}\r\n")).unwrap_or_default();
    format!(
        "GET /ws HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n{origin}\r\n"
    )
}

/// A foreign `Origin` (any page the user visits) or `Host` (DNS rebinding) gets neither the
/// page nor the WebSocket; a handshake without `Origin` is refused; the server's own page is
/// served and its WebSocket gets the hello.
#[test]
fn only_the_servers_own_host_and_origin_get_the_page_and_the_websocket() {
    let server = Running::start(Limits::default());
    let port = server.addr.port();
    let own = format!("127.0.0.1:{port}");
    let own_origin = format!("http://{own}");
    let evil = "http://evil.example.com";
    let rebound = format!("attacker.example:{port}");

    let (status, body) = server.exchange(&get(&own, None));
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&body).contains("<html"), "the page");
    assert_eq!(server.exchange(&get(&format!("localhost:{port}"), None)).0, 200);
    assert_eq!(server.exchange(&get(&own, Some(&own_origin))).0, 200);
    let (status, hello) = server.exchange(&websocket(&own, Some(&own_origin)));
    assert_eq!(status, 101, "the page's own WebSocket");
    assert_eq!(hello.first(), Some(&0x81), "a text frame (hello) after the handshake");

    let mut refused = 0;
    for (request, expected, what) in [
        (get(&rebound, None), 421, "foreign Host"),
        (
            get(&format!("127.0.0.1:{}", port.wrapping_add(1)), None),
            421,
            "another port in Host",
        ),
        (get(&own, Some(evil)), 403, "foreign Origin on a page request"),
        (websocket(&own, Some(evil)), 403, "foreign Origin on the WebSocket"),
        (websocket(&own, None), 403, "WebSocket without Origin"),
        (
            websocket(&rebound, Some(&format!("http://{rebound}"))),
            421,
            "rebound WebSocket",
        ),
    ] {
        let (status, body) = server.exchange(&request);
        assert_eq!(status, expected, "{what}: {}", String::from_utf8_lossy(&body));
        refused += 1;
    }
    let stats = server.finish();
    assert_eq!(stats.requests_refused, refused);
    assert_eq!(stats.clients_total, 1, "only the own page's WebSocket became a client");
}

/// Whether the server has closed `s`, without waiting.
fn closed(mut s: &TcpStream) -> bool {
    s.set_nonblocking(true).unwrap();
    let mut buf = [0u8; 256];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => continue,
            Err(e) if e.kind() == ErrorKind::WouldBlock => return false,
            Err(_) => return true,
        }
    }
}

/// A connection that never completes its request headers, or never starts one, is closed
/// after the header timeout.
#[test]
fn a_partial_or_silent_connection_is_closed_after_the_header_timeout() {
    let server = Running::start(Limits {
        header_timeout: Duration::from_secs(1),
        ..Limits::default()
    });
    let t0 = Instant::now();
    let mut partial = server.connect();
    partial.write_all(b"GET / HTTP/1.1\r\n").unwrap();
    let mut silent = server.connect();
    for (what, s) in [("partial", &mut partial), ("silent", &mut silent)] {
        // The read blocks until the server closes (or the 10 s read timeout fails the test).
        let mut rest = Vec::new();
        let r = s.read_to_end(&mut rest);
        let waited = t0.elapsed();
        assert!(
            !matches!(&r, Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut)),
            "{what} connection still open after {waited:?}"
        );
        assert!(
            waited >= Duration::from_millis(900) && waited < Duration::from_secs(5),
            "{what} connection closed after {waited:?}, the timeout is 1 s"
        );
    }
    server.finish();
}

/// 200 connections that never finish their headers (slowloris): at most the limit stay open,
/// and a normal request still gets the page at once (the timeout here is far longer than the
/// test: it is the limit that lets the page through, not the timeout).
#[test]
fn a_flood_of_partial_connections_is_capped_and_the_page_stays_reachable() {
    let limits = Limits {
        header_timeout: Duration::from_secs(120),
        connections: 64,
        ..Limits::default()
    };
    let server = Running::start(limits);
    let flood: Vec<TcpStream> = (0..200)
        .map(|_| {
            let mut s = server.connect();
            s.write_all(b"GET / HTTP/1.1\r\n").unwrap();
            s
        })
        .collect();
    let t0 = Instant::now();
    let (status, _) = server.exchange(&get(&format!("127.0.0.1:{}", server.addr.port()), None));
    let took = t0.elapsed();
    assert_eq!(status, 200);
    assert!(took < Duration::from_secs(3), "the page took {took:?} under the flood");
    // The server closes the connections it let go as it accepts new ones; wait for that, with
    // a deadline.
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut open = flood.len();
    while Instant::now() < deadline {
        open = flood.iter().filter(|s| !closed(s)).count();
        if open <= limits.connections {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(
        open <= limits.connections,
        "{open} of 200 partial connections still open; the limit is {}",
        limits.connections
    );
    server.finish();
}

/// A set-up panel that records what it is asked: `open` takes its time (longer for a name that
/// starts with `b`) before the part is replaced, and a compute notes the part it computes and
/// runs until cancelled.
#[derive(Default)]
struct Fake {
    part: Mutex<String>,
    computed: Mutex<Vec<String>>,
}

impl Workshop for Fake {
    fn setup(&self) -> serde_json::Value {
        serde_json::json!({"scene": {"name": *self.part.lock().unwrap()}})
    }
    fn compute(
        &self,
        _scene: &serde_json::Value,
        _progress: Arc<dyn Fn(Progress) + Send + Sync>,
        cancel: Arc<AtomicBool>,
        _ready: &mut dyn FnMut(&Computed) -> Result<(), WorkshopError>,
    ) -> Result<Computed, WorkshopError> {
        let part = self.part.lock().unwrap().clone();
        self.computed.lock().unwrap().push(part);
        while !cancel.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(10));
        }
        Err(WorkshopError::Cancelled { served: false })
    }
    fn open(&self, name: &str, _bytes: &[u8]) -> Result<(), WorkshopError> {
        let ms = if name.starts_with('b') { 500 } else { 100 };
        std::thread::sleep(Duration::from_millis(ms));
        *self.part.lock().unwrap() = name.to_string();
        Ok(())
    }
}

/// POST /open?name=NAME with `body`, its `Content-Length` saying `length` bytes.
fn upload(host: &str, name: &str, length: usize, body: &str) -> String {
    format!(
        "POST /open?name={name} HTTP/1.1\r\nHost: {host}\r\nOrigin: http://{host}\r\n\
         Content-Length: {length}\r\nConnection: close\r\n\r\n{body}"
    )
}

/// Two pages open two parts at once: one is answered 200 and computed, the other 409 and
/// changes nothing (before: both were opened, the later one replacing the part after the
/// first had been answered 200).
#[test]
fn of_two_parts_opened_at_once_the_one_answered_200_is_the_one_computed() {
    let fake = Arc::new(Fake::default());
    let server = Running::start_with("127.0.0.1:0", Limits::default(), Some(fake.clone()));
    let host = format!("127.0.0.1:{}", server.addr.port());
    let body = "ISO-10303-21;";
    let answers: Vec<(String, u16)> = std::thread::scope(|s| {
        let asks: Vec<_> = ["a.step", "b.step"]
            .map(|name| {
                let (server, host) = (&server, &host);
                s.spawn(move || {
                    (
                        name.to_string(),
                        server.exchange(&upload(host, name, body.len(), body)).0,
                    )
                })
            })
            .into_iter()
            .collect();
        asks.into_iter().map(|a| a.join().unwrap()).collect()
    });
    let ok: Vec<_> = answers
        .iter()
        .filter(|(_, s)| *s == 200)
        .map(|(n, _)| n.clone())
        .collect();
    assert_eq!(ok.len(), 1, "{answers:?}");
    assert!(answers.iter().any(|(_, s)| *s == 409), "{answers:?}");
    // Whatever the refused request was still doing is over by now.
    std::thread::sleep(Duration::from_millis(800));
    assert_eq!(*fake.computed.lock().unwrap(), ok, "the part computed ({answers:?})");
    assert_eq!(
        *fake.part.lock().unwrap(),
        ok[0],
        "the part open after both ({answers:?})"
    );
    server.finish();
}

/// Sends `head` (a request whose body is announced but never sent) and reads the status: the
/// answer must come before the body, within 3 s.
fn status_before_body(server: &Running, head: &str) -> Result<u16, String> {
    let mut s = server.connect();
    s.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
    s.write_all(head.as_bytes()).unwrap();
    let mut got = [0u8; 12];
    s.read_exact(&mut got)
        .map_err(|e| format!("no answer before the body: {e}"))?;
    std::str::from_utf8(&got[9..12])
        .unwrap()
        .parse()
        .map_err(|e| format!("{e}"))
}

/// An upload larger than the limit is refused on its `Content-Length`, and one sent while a
/// compute runs is refused at once: neither body is read (before, 16 parallel 60 MiB uploads
/// were all held in memory to be told a compute was running).
#[test]
fn an_upload_too_large_or_while_computing_is_refused_before_its_body_is_read() {
    let fake = Arc::new(Fake::default());
    let server = Running::start_with("127.0.0.1:0", Limits::default(), Some(fake.clone()));
    let host = format!("127.0.0.1:{}", server.addr.port());
    let big = workshop::MAX_UPLOAD + 1;
    assert_eq!(
        status_before_body(&server, &upload(&host, "big.step", big, "")),
        Ok(413)
    );
    assert!(fake.part.lock().unwrap().is_empty(), "nothing opened");
    let body = "ISO-10303-21;";
    assert_eq!(server.exchange(&upload(&host, "a.step", body.len(), body)).0, 200);
    assert_eq!(
        status_before_body(&server, &upload(&host, "b.step", 1 << 20, "")),
        Ok(409)
    );
    assert_eq!(*fake.part.lock().unwrap(), "a.step");
    server.finish();
}

/// On all interfaces, a page served by another machine of the network (its `Origin`) cannot
/// use the server through the address the user opened.
#[test]
fn on_all_interfaces_a_page_of_another_host_is_refused() {
    let server = Running::start_with("0.0.0.0:0", Limits::default(), None);
    let port = server.addr.port();
    let host = format!("10.0.0.5:{port}");
    assert_eq!(server.exchange(&get(&host, Some(&format!("http://{host}")))).0, 200);
    let foreign = format!("http://10.9.9.9:{port}");
    assert_eq!(server.exchange(&get(&host, Some(&foreign))).0, 403);
    assert_eq!(server.exchange(&websocket(&host, Some(&foreign))).0, 403);
    server.finish();
}

/// Frames a client skipped: the gap between two frame numbers, and nothing when a new session
/// numbers its frames from 1 again (not 2³² − k).
#[test]
fn a_new_sessions_frame_numbers_are_no_skipped_frames() {
    assert_eq!(super::skipped(10, 11), 0);
    assert_eq!(super::skipped(10, 14), 3);
    assert_eq!(super::skipped(1200, 3), 0);
    assert_eq!(super::skipped(7, 7), 0);
}

/// A downloaded basis is offered under its part's name, made safe for a file name and a header.
#[test]
fn a_downloaded_basis_is_named_for_its_part() {
    assert_eq!(super::download_name("pmi_block_2holes"), "pmi_block_2holes");
    assert_eq!(super::download_name("a\"b\r\nc/../d"), "a_b__c_.._d");
    assert_eq!(super::download_name("..hidden"), "hidden");
    assert_eq!(super::download_name(""), "basis");
    assert_eq!(super::download_name(&"x".repeat(500)).len(), 100);
}
