//! The viewer's HTTP side: who may talk to it and for how long.
//!
//! Any web page the user visits can make the browser talk to a server on the user's machine: a
//! WebSocket is not bound by the same-origin policy (only its `Origin` header tells), and a
//! page whose name the attacker re-points at 127.0.0.1 (DNS rebinding) reads our responses as
//! its own (only its `Host` header tells). So every request must name this server in `Host`,
//! and a request that carries an `Origin` (every WebSocket handshake from a browser does) must
//! come from this server's page, served from the address the request was sent to. Connections are served here rather than by `axum::serve`,
//! which gives no header timeout and no connection limit: one that does not complete its
//! request headers in time is closed, and when the limit is reached the oldest HTTP
//! connection makes way for the new one, so connections held open on purpose cannot lock the
//! page out.

use axum::body::Body;
use axum::http::{HeaderMap, Response, StatusCode, Uri, header};
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use std::collections::VecDeque;
use std::convert::Infallible;
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::sync::{oneshot, watch};
use tower_service::Service;

/// Limits on the viewer's connections.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// A connection must complete each request's headers within this (counted from when the
    /// server starts waiting for them: a fresh or kept-alive connection) or it is closed.
    pub header_timeout: Duration,
    /// HTTP connections open at once (page, script, WebSocket handshakes; not the WebSockets
    /// themselves). One more replaces the oldest.
    pub connections: usize,
    /// WebSocket clients at once; one more is answered 503.
    pub clients: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            header_timeout: Duration::from_secs(10),
            connections: 64,
            clients: 64,
        }
    }
}

/// Which `Host` and `Origin` values name this server: the `Origin` must be the `Host`.
#[derive(Debug)]
pub(crate) struct Guard {
    port: u16,
    /// Any IP literal (listening on all interfaces: the user may connect through any of them,
    /// or through a forwarded port). A rebinding page always has a name, never an address.
    any_ip: bool,
    /// The address listened on, when it is one address.
    ip: Option<IpAddr>,
    /// Names besides IP literals: `localhost`, and on all interfaces the machine's host name.
    names: Vec<String>,
}

/// Why a request was refused.
#[derive(Debug, PartialEq)]
pub(crate) struct Refusal {
    pub status: StatusCode,
    pub why: String,
}

impl Guard {
    /// The guard for a server bound to `bound` (its real port, after binding port 0).
    pub(crate) fn new(bound: SocketAddr) -> Guard {
        let any_ip = bound.ip().is_unspecified();
        let mut names = vec!["localhost".to_string()];
        if any_ip && let Some(h) = ves_runtime::os::hostname() {
            names.push(format!("{h}.local"));
            names.push(h);
        }
        Guard {
            port: bound.port(),
            any_ip,
            ip: (!any_ip).then_some(bound.ip()),
            names,
        }
    }

    /// Whether `host[:port]` names this server.
    fn authority_ok(&self, authority: &str) -> bool {
        let Some((host, port)) = split_authority(authority) else {
            return false;
        };
        if port != self.port {
            return false;
        }
        match ip_literal(host) {
            Some(ip) => self.any_ip || ip.is_loopback() || Some(ip) == self.ip,
            None => self.names.iter().any(|n| n.eq_ignore_ascii_case(host)),
        }
    }

    /// Whether an `Origin` header is this server's page: `http://` and the authority the
    /// request was sent to (`host`, its `Host` header, already checked). Any address names a
    /// server on all interfaces, so a page served by another machine of the network at
    /// `http://ITS-ADDRESS:PORT` would pass a check of the origin alone.
    fn origin_ok(&self, origin: &str, host: &str) -> bool {
        let Some(a) = origin
            .get(..7)
            .filter(|s| s.eq_ignore_ascii_case("http://"))
            .map(|_| &origin[7..])
            .filter(|a| !a.contains('/') && self.authority_ok(a))
        else {
            return false;
        };
        match (split_authority(a), split_authority(host)) {
            (Some((oh, op)), Some((hh, hp))) => {
                let same = match (ip_literal(oh), ip_literal(hh)) {
                    (Some(o), Some(h)) => o == h,
                    (None, None) => oh.eq_ignore_ascii_case(hh),
                    _ => false,
                };
                same && op == hp
            }
            _ => false,
        }
    }

    /// Lets a request through, or says why not: a `Host` (or an absolute request URI) that
    /// does not name this server is 421; an `Origin` from another page, or a WebSocket
    /// handshake without one (browsers always send it), is 403.
    pub(crate) fn check(&self, uri: &Uri, headers: &HeaderMap) -> Result<(), Refusal> {
        let misdirected = |what: String| Refusal {
            status: StatusCode::MISDIRECTED_REQUEST,
            why: format!(
                "{what} is not this server (port {}): open the URL `ves view` printed",
                self.port
            ),
        };
        let mut hosts = headers.get_all(header::HOST).iter();
        let host = match (hosts.next(), hosts.next()) {
            (Some(h), None) => match h.to_str() {
                Ok(h) if self.authority_ok(h) => h,
                _ => return Err(misdirected(format!("Host {h:?}"))),
            },
            (None, _) => return Err(misdirected("a request without Host".into())),
            (Some(_), Some(_)) => return Err(misdirected("a request with two Host headers".into())),
        };
        if let Some(a) = uri.authority().filter(|a| !self.authority_ok(a.as_str())) {
            return Err(misdirected(format!("the request's address {a}")));
        }
        let forbidden = |why: String| Refusal {
            status: StatusCode::FORBIDDEN,
            why,
        };
        let websocket = headers
            .get(header::UPGRADE)
            .and_then(|u| u.to_str().ok())
            .is_some_and(|u| u.eq_ignore_ascii_case("websocket"));
        let mut origins = headers.get_all(header::ORIGIN).iter();
        match (origins.next(), origins.next()) {
            (None, _) if websocket => Err(forbidden(
                "a WebSocket handshake without Origin: only this server's page may connect".into(),
            )),
            (None, _) => Ok(()),
            (Some(o), None) if o.to_str().is_ok_and(|o| self.origin_ok(o, host)) => Ok(()),
            (Some(o), None) => Err(forbidden(format!(
                "Origin {o:?} is not this server's page at {host}: only the page `ves view` serves may use it"
            ))),
            (Some(_), Some(_)) => Err(forbidden("a request with two Origin headers".into())),
        }
    }
}

/// `host[:port]` (IPv6 in brackets) to its host and port (80 when absent, as a browser omits
/// it); `None` when it is not one.
fn split_authority(a: &str) -> Option<(&str, u16)> {
    let (host, port) = if a.starts_with('[') {
        let end = a.find(']')?;
        let rest = &a[end + 1..];
        let port = if rest.is_empty() {
            None
        } else {
            Some(rest.strip_prefix(':')?)
        };
        (&a[..=end], port)
    } else {
        match a.rsplit_once(':') {
            Some((h, p)) => (h, Some(p)),
            None => (a, None),
        }
    };
    if host.is_empty() || (!host.starts_with('[') && host.contains([':', '@', '/'])) {
        return None;
    }
    let port = match port {
        None => 80,
        Some(p) if !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()) => p.parse().ok()?,
        Some(_) => return None,
    };
    Some((host, port))
}

/// The address an authority's host names literally (`127.0.0.1`, `[::1]`).
fn ip_literal(host: &str) -> Option<IpAddr> {
    match host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        Some(v6) => v6.parse::<std::net::Ipv6Addr>().ok().map(IpAddr::V6),
        None => host.parse::<std::net::Ipv4Addr>().ok().map(IpAddr::V4),
    }
}

/// Open HTTP connections, oldest first, each with the way to close it.
type Open = Mutex<VecDeque<(u64, oneshot::Sender<()>)>>;

fn lock(open: &Open) -> MutexGuard<'_, VecDeque<(u64, oneshot::Sender<()>)>> {
    open.lock().unwrap_or_else(|e| e.into_inner())
}

/// Refusals go to stderr, the first few: enough to see why a page cannot connect without
/// letting a hostile page fill the terminal. All are counted.
fn log_refusal(peer: SocketAddr, r: &Refusal, refused: &AtomicU64) {
    if refused.fetch_add(1, Ordering::Relaxed) < 5 {
        eprintln!("ves view: refused a request from {peer} ({}): {}", r.status, r.why);
    }
}

/// Serves `app` on `listener` until `stop` changes: each request through `guard`, each
/// connection within `limits`. Refusals are counted in `refused`.
pub(crate) async fn run(
    listener: tokio::net::TcpListener,
    app: axum::Router,
    guard: Arc<Guard>,
    limits: Limits,
    refused: Arc<AtomicU64>,
    mut stop: watch::Receiver<bool>,
) {
    let mut http = hyper::server::conn::http1::Builder::new();
    http.timer(TokioTimer::new()).header_read_timeout(limits.header_timeout);
    let open: Arc<Open> = Arc::default();
    let mut tasks = tokio::task::JoinSet::new();
    let mut next = 0u64;
    loop {
        let (tcp, peer) = tokio::select! {
            r = listener.accept() => match r {
                Ok(c) => c,
                // Out of file descriptors, or the peer gave up before the accept: try again
                // shortly rather than spin.
                Err(_) => {
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            Some(_) = tasks.join_next(), if !tasks.is_empty() => continue,
            _ = stop.changed() => break,
        };
        next += 1;
        let id = next;
        let (close, closed) = oneshot::channel();
        {
            let mut open = lock(&open);
            while open.len() >= limits.connections.max(1) {
                if let Some((_, oldest)) = open.pop_front() {
                    let _ = oldest.send(());
                }
            }
            open.push_back((id, close));
        }
        let (app, guard, refused) = (app.clone(), guard.clone(), refused.clone());
        let service = hyper::service::service_fn(move |req: axum::http::Request<Incoming>| {
            let checked = guard.check(req.uri(), req.headers());
            let (mut app, refused) = (app.clone(), refused.clone());
            async move {
                match checked {
                    Ok(()) => app.call(req).await,
                    Err(r) => {
                        log_refusal(peer, &r, &refused);
                        let mut res = Response::new(Body::from(format!("{}\n", r.why)));
                        *res.status_mut() = r.status;
                        res.headers_mut().insert(
                            header::CONTENT_TYPE,
                            header::HeaderValue::from_static("text/plain; charset=utf-8"),
                        );
                        Ok::<_, Infallible>(res)
                    }
                }
            }
        });
        let conn = http.serve_connection(TokioIo::new(tcp), service).with_upgrades();
        let open = open.clone();
        tasks.spawn(async move {
            // A WebSocket leaves this connection once upgraded and lives on in its own task.
            tokio::select! {
                _ = conn => {}
                _ = closed => {}
            }
            lock(&open).retain(|(i, _)| *i != id);
        });
    }
    tasks.shutdown().await;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(&str, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(
                header::HeaderName::from_bytes(k.as_bytes()).unwrap(),
                header::HeaderValue::from_str(v).unwrap(),
            );
        }
        h
    }

    fn status(g: &Guard, pairs: &[(&str, &str)]) -> u16 {
        match g.check(&Uri::from_static("/"), &headers(pairs)) {
            Ok(()) => 200,
            Err(r) => r.status.as_u16(),
        }
    }

    /// Loopback: the loopback names on the served port; nothing else, whatever the port.
    #[test]
    fn a_loopback_server_answers_to_its_loopback_names_on_its_port_only() {
        let g = Guard::new("127.0.0.1:8765".parse().unwrap());
        for ok in [
            "127.0.0.1:8765",
            "localhost:8765",
            "LocalHost:8765",
            "[::1]:8765",
            "127.0.0.2:8765",
        ] {
            assert_eq!(status(&g, &[("host", ok)]), 200, "{ok}");
            assert_eq!(
                status(&g, &[("host", ok), ("origin", &format!("http://{ok}"))]),
                200,
                "{ok}"
            );
        }
        for bad in [
            "attacker.example:8765",
            "attacker.example",
            "127.0.0.1:8766",
            "127.0.0.1",
            "127.0.0.1:",
            "192.168.1.7:8765",
            "localhost.attacker.example:8765",
            "user@127.0.0.1:8765",
            "[::1:8765",
            "",
        ] {
            assert_eq!(status(&g, &[("host", bad)]), 421, "{bad:?}");
        }
        assert_eq!(status(&g, &[]), 421, "no Host");
        assert_eq!(status(&g, &[("host", "127.0.0.1:8765"), ("host", "evil:8765")]), 421);
        let own = ("host", "127.0.0.1:8765");
        for bad in [
            "http://evil.example.com",
            "http://127.0.0.1:8766",
            "https://127.0.0.1:8765",
            "http://127.0.0.1:8765/x",
            "null",
            "file://",
        ] {
            assert_eq!(status(&g, &[own, ("origin", bad)]), 403, "{bad}");
        }
        let ws = [own, ("upgrade", "websocket"), ("connection", "Upgrade")];
        assert_eq!(status(&g, &ws), 403, "a WebSocket handshake without Origin");
        assert_eq!(
            status(&g, &[ws[0], ws[1], ws[2], ("origin", "http://127.0.0.1:8765")]),
            200
        );
        // An absolute request URI must name this server too.
        let uri = Uri::from_static("http://attacker.example:8765/");
        assert!(g.check(&uri, &headers(&[own])).is_err());
    }

    /// On all interfaces: any IP address with the served port (the one the user typed), the
    /// machine's host name; still no other name.
    #[test]
    fn a_server_on_all_interfaces_answers_to_addresses_and_its_host_name() {
        let g = Guard::new("0.0.0.0:8765".parse().unwrap());
        for ok in ["192.168.1.7:8765", "[fe80::1]:8765", "localhost:8765", "10.0.0.2:8765"] {
            assert_eq!(
                status(&g, &[("host", ok), ("origin", &format!("http://{ok}"))]),
                200,
                "{ok}"
            );
        }
        if let Some(h) = ves_runtime::os::hostname() {
            assert_eq!(status(&g, &[("host", &format!("{h}:8765"))]), 200, "{h}");
        }
        for bad in ["attacker.example:8765", "192.168.1.7:80", "192.168.1.7"] {
            assert_eq!(status(&g, &[("host", bad)]), 421, "{bad}");
        }
        // One given address: that one and loopback.
        let g = Guard::new("192.168.1.7:8765".parse().unwrap());
        assert_eq!(status(&g, &[("host", "192.168.1.7:8765")]), 200);
        assert_eq!(status(&g, &[("host", "192.168.1.8:8765")]), 421);
        // Port 80: a browser leaves it out.
        let g = Guard::new("127.0.0.1:80".parse().unwrap());
        assert_eq!(
            status(&g, &[("host", "localhost"), ("origin", "http://localhost")]),
            200
        );
    }

    /// On all interfaces any address names the server, but a page's `Origin` must be the
    /// address the request was sent to: a page of another machine of the network
    /// (http://10.9.9.9:PORT) must not drive the part through the user's own address.
    #[test]
    fn an_origin_must_name_the_host_the_request_was_sent_to() {
        for bound in ["0.0.0.0:8765", "[::]:8765", "127.0.0.1:8765"] {
            let g = Guard::new(bound.parse().unwrap());
            let host = if bound.starts_with('1') {
                "127.0.0.1:8765"
            } else {
                "10.0.0.5:8765"
            };
            assert_eq!(
                status(&g, &[("host", host), ("origin", &format!("http://{host}"))]),
                200,
                "{bound}"
            );
            for foreign in ["http://10.9.9.9:8765", "http://127.0.0.2:8765", "http://localhost:8765"] {
                assert_eq!(
                    status(&g, &[("host", host), ("origin", foreign)]),
                    403,
                    "{bound}: {foreign}"
                );
                let ws = [("host", host), ("upgrade", "websocket"), ("origin", foreign)];
                assert_eq!(status(&g, &ws), 403, "{bound}: WebSocket from {foreign}");
            }
        }
        let g = Guard::new("0.0.0.0:8765".parse().unwrap());
        // The same host spelled in another case, and IPv6 literals, are the same host.
        assert_eq!(
            status(&g, &[("host", "LOCALHOST:8765"), ("origin", "http://localhost:8765")]),
            200
        );
        assert_eq!(
            status(&g, &[("host", "[fe80::1]:8765"), ("origin", "http://[FE80::1]:8765")]),
            200
        );
        assert_eq!(
            status(&g, &[("host", "[fe80::1]:8765"), ("origin", "http://[fe80::2]:8765")]),
            403
        );
    }
}
