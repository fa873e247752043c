//! The preview's accept loop: a server no client can hold hostage.
//!
//! Issue 12 items 1 and 9. `axum::serve` has no header-read or idle timeout
//! and its graceful shutdown waits for every connection, so one client that
//! sent `GET / HTTP/1.1\r\n` and nothing more kept the daemon from ever
//! exiting. Here each accepted connection is served by hyper's HTTP/1
//! connection (axum's [`Router`] is the service, upgrades enabled for a
//! later WebSocket route) with:
//!
//! * a **header-read timeout**: hyper starts it whenever it waits for a
//!   request head — on a fresh connection and between keep-alive requests —
//!   so a slow or silent client is closed after it;
//! * an **idle timeout**: a connection on which no byte moved in either
//!   direction for this long is closed (a client that stopped reading a
//!   response, a tablet gone off Wi-Fi mid-download);
//! * a **connection limit**: connections beyond it are answered at once with
//!   `503 Service Unavailable` (written without waiting) and closed; they
//!   never queue, so a flood cannot delay the clients already served;
//! * a **Host check** against DNS rebinding ([`HostPolicy`]): 403 unless the
//!   Host names the bound address or a loopback name with its port; a
//!   request with more than one Host header is refused with 400 whatever
//!   the policy (RFC 9112 3.2: no header may decide for the other);
//! * a **body limit** ([`ServeConfig::max_request_body`]): a larger body is
//!   answered `413 Payload Too Large`. The body is read (and dropped, up to
//!   [`DRAIN_LIMIT`] bytes for at most [`DRAIN_TIME`]) before the answer, so
//!   a client still sending gets the 413: a connection closed with unread
//!   bytes is reset, and the reset throws away the answer on the client's
//!   side before it reads it;
//! * **shutdown**: when the `shutdown` future completes the listener is
//!   closed (the port is free at once), every connection is asked to finish
//!   its current response, and whatever is still open after the grace
//!   period is dropped.
//!
//! Every default is one constant on [`ServeConfig`].
//!
//! A connection upgraded to another protocol (a WebSocket route, issue 17)
//! leaves hyper's connection: its task ends, so it no longer counts toward
//! the connection limit and is not dropped at shutdown by this loop. The
//! upgraded handler must watch the shutdown signal and bound its own
//! connections.

use super::{ServeState, routes};
use axum::Router;
use axum::extract::{Request, State};
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::future::Future;
use std::io;
use std::net::{IpAddr, SocketAddr};
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Semaphore, watch};
use tokio::task::JoinSet;
use tokio::time::Instant;

/// Which Host headers the server answers (DNS-rebinding protection).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HostPolicy {
    /// Only a Host naming the bound address, `localhost:<port>`,
    /// `127.0.0.1:<port>` or `[::1]:<port>` (the port may be left out only
    /// when it is 80); anything else, or no Host, gets 403. A web page that
    /// rebinds its own name to 127.0.0.1 still sends its own name, so it
    /// cannot read the preview.
    Local,
    /// Any Host: the server was bound to a non-loopback address on purpose
    /// (`--http 0.0.0.0:8080` for tablets), where the names it is reached
    /// by cannot be known.
    Any,
}

impl HostPolicy {
    /// The policy an `--http` address implies: [`HostPolicy::Local`] for a
    /// loopback address, [`HostPolicy::Any`] for any other (including the
    /// unspecified `0.0.0.0`/`::`, which serves every interface).
    pub fn for_address(addr: SocketAddr) -> Self {
        if addr.ip().is_loopback() { Self::Local } else { Self::Any }
    }
}

/// Limits of the preview server. Each default is a constant here.
#[derive(Clone, Debug)]
pub struct ServeConfig {
    /// Time a client has to send a complete request head, counted from when
    /// the server starts waiting for it (also between keep-alive requests).
    pub header_read_timeout: Duration,
    /// A connection on which no byte moves either way for this long is closed.
    pub idle_timeout: Duration,
    /// Open connections at most; more are answered 503 and closed at once.
    pub max_connections: usize,
    /// After shutdown, connections get this long to finish their current
    /// response; then they are dropped.
    pub shutdown_grace: Duration,
    /// Which Host headers are answered.
    pub host_policy: HostPolicy,
    /// Largest request body (bytes) any route gets; a larger one is
    /// answered 413 (after it is drained, see the module docs).
    pub max_request_body: usize,
}

impl ServeConfig {
    /// Default [`ServeConfig::header_read_timeout`]: 10 s.
    pub const HEADER_READ_TIMEOUT: Duration = Duration::from_secs(10);
    /// Default [`ServeConfig::idle_timeout`]: 30 s.
    pub const IDLE_TIMEOUT: Duration = Duration::from_secs(30);
    /// Default [`ServeConfig::max_connections`]: 256 (a browser opens up to
    /// six per page, so this holds some 40 viewers; each costs one tokio task).
    pub const MAX_CONNECTIONS: usize = 256;
    /// Default [`ServeConfig::shutdown_grace`]: 0.5 s, the one shutdown
    /// deadline of the whole daemon (`footlight run` exits within a second
    /// of SIGTERM; the daemon's `SHUTDOWN_GRACE` is this value).
    pub const SHUTDOWN_GRACE: Duration = Duration::from_millis(500);
    /// Default [`ServeConfig::max_request_body`]: 16 KiB (the only bodies
    /// are the camera and display writes' JSON, a few hundred bytes; the
    /// write routes take 4 KiB at most themselves).
    pub const MAX_REQUEST_BODY: usize = 16 * 1024;

    /// The defaults, with the Host policy the `--http` address implies
    /// ([`HostPolicy::for_address`]).
    pub fn for_address(http: SocketAddr) -> Self {
        Self { host_policy: HostPolicy::for_address(http), ..Self::default() }
    }
}

impl Default for ServeConfig {
    /// The defaults with [`HostPolicy::Local`].
    fn default() -> Self {
        Self {
            header_read_timeout: Self::HEADER_READ_TIMEOUT,
            idle_timeout: Self::IDLE_TIMEOUT,
            max_connections: Self::MAX_CONNECTIONS,
            shutdown_grace: Self::SHUTDOWN_GRACE,
            host_policy: HostPolicy::Local,
            max_request_body: Self::MAX_REQUEST_BODY,
        }
    }
}

/// Why the server could not run.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The listener has no local address (needed for the Host check).
    #[error("the preview listener has no local address: {0}")]
    LocalAddr(io::Error),
    /// A limit is unusable.
    #[error("invalid preview server setting: {0}")]
    Config(String),
}

/// Counters of the server, shared with whoever asked for them.
#[derive(Debug, Default)]
pub struct ServeStats {
    /// Connections accepted and served.
    pub accepted: AtomicU64,
    /// Connections refused over [`ServeConfig::max_connections`].
    pub refused: AtomicU64,
    /// Connections open now.
    pub open: AtomicU64,
    /// Connections closed by the idle timeout.
    pub idle_closed: AtomicU64,
    /// Connections dropped at shutdown after the grace period.
    pub dropped_at_shutdown: AtomicU64,
    /// Requests refused for their Host header (403; 400 for more than one).
    pub forbidden_host: AtomicU64,
    /// Requests refused for a body over [`ServeConfig::max_request_body`] (413).
    pub body_too_large: AtomicU64,
    /// PNG encodes of frames.
    pub png_encodes: AtomicU64,
    /// `/api/frame.png` responses served.
    pub png_served: AtomicU64,
}

/// A copy of [`ServeStats`] at one moment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StatsSnapshot {
    /// Connections accepted and served.
    pub accepted: u64,
    /// Connections refused over the limit.
    pub refused: u64,
    /// Connections open.
    pub open: u64,
    /// Connections closed by the idle timeout.
    pub idle_closed: u64,
    /// Connections dropped at shutdown after the grace period.
    pub dropped_at_shutdown: u64,
    /// Requests refused for their Host header.
    pub forbidden_host: u64,
    /// Requests refused for their body's size.
    pub body_too_large: u64,
    /// PNG encodes.
    pub png_encodes: u64,
    /// Frame responses served.
    pub png_served: u64,
}

impl ServeStats {
    /// The counters now.
    pub fn snapshot(&self) -> StatsSnapshot {
        let r = |a: &AtomicU64| a.load(Ordering::Relaxed);
        StatsSnapshot {
            accepted: r(&self.accepted),
            refused: r(&self.refused),
            open: r(&self.open),
            idle_closed: r(&self.idle_closed),
            dropped_at_shutdown: r(&self.dropped_at_shutdown),
            forbidden_host: r(&self.forbidden_host),
            body_too_large: r(&self.body_too_large),
            png_encodes: r(&self.png_encodes),
            png_served: r(&self.png_served),
        }
    }
}

/// Listen backlog of [`bind`]: a burst of new viewers (every tablet
/// reconnecting at once) waits in the kernel's queue instead of having its
/// connection attempts dropped and retried a second later. tokio's own
/// `TcpListener::bind` uses 128.
pub const LISTEN_BACKLOG: u32 = 1024;

/// Binds the preview's listener with [`LISTEN_BACKLOG`] (and `SO_REUSEADDR`
/// on Unix, as tokio's `bind` does). The OS error is returned as is: the
/// caller names the address and the likely cause.
pub fn bind(addr: SocketAddr) -> io::Result<TcpListener> {
    let socket = if addr.is_ipv4() { tokio::net::TcpSocket::new_v4()? } else { tokio::net::TcpSocket::new_v6()? };
    #[cfg(unix)]
    socket.set_reuseaddr(true)?;
    socket.bind(addr)?;
    socket.listen(LISTEN_BACKLOG)
}

/// The preview server before it runs (so its counters can be taken first).
pub struct Server {
    routes: Router,
    config: ServeConfig,
    stats: Arc<ServeStats>,
}

/// Serves the preview on `listener` until `shutdown` completes, then closes
/// every connection within [`ServeConfig::shutdown_grace`] and returns.
/// `Server::new(state, config).run(listener, shutdown)`.
pub async fn serve(
    listener: TcpListener,
    state: ServeState,
    config: ServeConfig,
    shutdown: impl Future<Output = ()>,
) -> Result<(), ServeError> {
    Server::new(state, config).run(listener, shutdown).await
}

impl Server {
    /// The preview's routes under `config`.
    pub fn new(state: ServeState, config: ServeConfig) -> Self {
        let stats = Arc::new(ServeStats::default());
        Self { routes: routes(state, stats.clone()), config, stats }
    }

    /// The server's counters (live: they keep counting while it runs).
    pub fn stats(&self) -> Arc<ServeStats> {
        self.stats.clone()
    }

    /// Runs the accept loop until `shutdown` completes (see [`serve`]).
    pub async fn run(self, listener: TcpListener, shutdown: impl Future<Output = ()>) -> Result<(), ServeError> {
        let Self { routes, config, stats } = self;
        if config.max_connections == 0 {
            return Err(ServeError::Config("max_connections must be at least 1".into()));
        }
        for (name, d) in [("header_read_timeout", config.header_read_timeout), ("idle_timeout", config.idle_timeout)] {
            if d.is_zero() {
                return Err(ServeError::Config(format!("{name} must be longer than 0 s")));
            }
        }
        let local = listener.local_addr().map_err(ServeError::LocalAddr)?;
        let hosts = Arc::new(AllowedHosts::new(config.host_policy, local, stats.clone()));
        let limit = BodyLimit { max: config.max_request_body, stats: stats.clone() };
        // Layers run outside in: the Host check first, then the body limit.
        let app = routes
            .layer(axum::middleware::from_fn_with_state(Arc::new(limit), limit_body))
            .layer(axum::middleware::from_fn_with_state(hosts, check_host));
        let mut http = hyper::server::conn::http1::Builder::new();
        http.timer(TokioTimer::new()).header_read_timeout(config.header_read_timeout).keep_alive(true);
        let limit = Arc::new(Semaphore::new(config.max_connections));
        let (close_tx, close_rx) = watch::channel(false);
        let mut conns = JoinSet::new();
        tokio::pin!(shutdown);
        loop {
            tokio::select! {
                biased;
                () = &mut shutdown => break,
                Some(_) = conns.join_next(), if !conns.is_empty() => {}
                accepted = listener.accept() => {
                    let (stream, peer) = match accepted {
                        Ok(a) => a,
                        Err(e) => {
                            // Per-connection errors (reset before accept) and
                            // fd exhaustion: log, breathe, keep serving.
                            tracing::warn!("preview: accept failed: {e}");
                            tokio::time::sleep(Duration::from_millis(50)).await;
                            continue;
                        }
                    };
                    let Ok(permit) = limit.clone().try_acquire_owned() else {
                        stats.refused.fetch_add(1, Ordering::Relaxed);
                        tracing::debug!("preview: {peer} refused: {} connections open", config.max_connections);
                        let _ = stream.try_write(REFUSED);
                        continue;
                    };
                    let _ = stream.set_nodelay(true);
                    stats.accepted.fetch_add(1, Ordering::Relaxed);
                    stats.open.fetch_add(1, Ordering::Relaxed);
                    let open = OpenGuard(stats.clone());
                    let conn = Connection {
                        http: http.clone(),
                        app: app.clone(),
                        idle: config.idle_timeout,
                        close: close_rx.clone(),
                        stats: stats.clone(),
                    };
                    conns.spawn(async move {
                        let _permit = permit;
                        conn.serve(stream, peer, open).await;
                    });
                }
            }
        }
        drop(listener);
        let _ = close_tx.send(true);
        let drained =
            tokio::time::timeout(config.shutdown_grace, async { while conns.join_next().await.is_some() {} }).await;
        if drained.is_err() {
            let n = conns.len();
            stats.dropped_at_shutdown.fetch_add(n as u64, Ordering::Relaxed);
            tracing::info!("preview: dropping {n} connection(s) still open after the shutdown grace period");
            conns.shutdown().await;
        }
        Ok(())
    }
}

/// What a connection over the limit is told before it is closed.
const REFUSED: &[u8] =
    b"HTTP/1.1 503 Service Unavailable\r\nConnection: close\r\nRetry-After: 1\r\nContent-Length: 0\r\n\r\n";

/// Counts a connection as open while it lives.
struct OpenGuard(Arc<ServeStats>);

impl Drop for OpenGuard {
    fn drop(&mut self) {
        self.0.open.fetch_sub(1, Ordering::Relaxed);
    }
}

/// One accepted connection and what serving it needs.
struct Connection {
    http: hyper::server::conn::http1::Builder,
    app: Router,
    idle: Duration,
    close: watch::Receiver<bool>,
    stats: Arc<ServeStats>,
}

impl Connection {
    async fn serve(mut self, stream: TcpStream, peer: SocketAddr, open: OpenGuard) {
        let activity = Arc::new(Activity::new());
        let io = TokioIo::new(Tracked { inner: stream, activity: activity.clone() });
        // The peer address, for the camera routes' write policy (control.rs).
        let app = self.app.layer(axum::Extension(super::control::Peer(peer)));
        let conn = self.http.serve_connection(io, TowerToHyperService::new(app)).with_upgrades();
        tokio::pin!(conn);
        // Declared after the connection, so dropped before it: the open count
        // is down before the socket closes (a client that saw the close sees
        // the count without it).
        let _open = open;
        let mut closing = false;
        loop {
            let deadline = activity.last() + self.idle;
            tokio::select! {
                result = conn.as_mut() => {
                    if let Err(e) = result {
                        tracing::debug!("preview: connection from {peer} ended: {e}");
                    }
                    return;
                }
                _ = self.close.wait_for(|c| *c), if !closing => {
                    // Finish the response in progress, then close.
                    conn.as_mut().graceful_shutdown();
                    closing = true;
                }
                () = tokio::time::sleep_until(deadline) => {
                    if activity.last() + self.idle <= Instant::now() {
                        self.stats.idle_closed.fetch_add(1, Ordering::Relaxed);
                        tracing::debug!("preview: closing {peer}: nothing moved for {:?}", self.idle);
                        return;
                    }
                }
            }
        }
    }
}

/// When bytes last moved on a connection.
struct Activity {
    start: Instant,
    /// Milliseconds after `start`.
    last_ms: AtomicU64,
}

impl Activity {
    fn new() -> Self {
        Self { start: Instant::now(), last_ms: AtomicU64::new(0) }
    }

    fn touch(&self) {
        let ms = self.start.elapsed().as_millis().min(u128::from(u64::MAX)) as u64;
        self.last_ms.fetch_max(ms, Ordering::Relaxed);
    }

    fn last(&self) -> Instant {
        self.start + Duration::from_millis(self.last_ms.load(Ordering::Relaxed))
    }
}

/// A TCP stream that records when bytes move, for the idle timeout.
struct Tracked {
    inner: TcpStream,
    activity: Arc<Activity>,
}

impl AsyncRead for Tracked {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let before = buf.filled().len();
        let r = Pin::new(&mut this.inner).poll_read(cx, buf);
        if matches!(r, Poll::Ready(Ok(()))) && buf.filled().len() > before {
            this.activity.touch();
        }
        r
    }
}

impl AsyncWrite for Tracked {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, data: &[u8]) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let r = Pin::new(&mut this.inner).poll_write(cx, data);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            this.activity.touch();
        }
        r
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let r = Pin::new(&mut this.inner).poll_write_vectored(cx, bufs);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            this.activity.touch();
        }
        r
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_shutdown(cx)
    }
}

/// The Host values a [`HostPolicy::Local`] server answers.
struct AllowedHosts {
    /// `None`: any Host.
    names: Option<Vec<String>>,
    stats: Arc<ServeStats>,
}

impl AllowedHosts {
    fn new(policy: HostPolicy, local: SocketAddr, stats: Arc<ServeStats>) -> Self {
        let names = match policy {
            HostPolicy::Any => None,
            HostPolicy::Local => {
                let port = local.port();
                let bound = match local.ip() {
                    IpAddr::V4(ip) => ip.to_string(),
                    IpAddr::V6(ip) => format!("[{ip}]"),
                };
                let mut hosts: Vec<String> = Vec::new();
                for h in [bound.as_str(), "localhost", "127.0.0.1", "[::1]"] {
                    hosts.push(format!("{h}:{port}"));
                    if port == 80 {
                        hosts.push(h.to_string());
                    }
                }
                Some(hosts)
            }
        };
        Self { names, stats }
    }

    fn allows(&self, host: Option<&str>) -> bool {
        match (&self.names, host) {
            (None, _) => true,
            (Some(_), None) => false,
            (Some(names), Some(h)) => names.iter().any(|n| n.eq_ignore_ascii_case(h.trim())),
        }
    }
}

/// Middleware: 400 for more than one Host header, 403 for a Host (header,
/// or the authority of an absolute request target) the policy does not allow.
async fn check_host(State(hosts): State<Arc<AllowedHosts>>, req: Request, next: Next) -> Response {
    if req.headers().get_all(header::HOST).iter().nth(1).is_some() {
        hosts.stats.forbidden_host.fetch_add(1, Ordering::Relaxed);
        let message = "400: more than one Host header; a request names its host once.\n";
        return (StatusCode::BAD_REQUEST, [(header::CONNECTION, "close")], message).into_response();
    }
    let header = req.headers().get(header::HOST).map(|h| h.to_str().unwrap_or("\u{fffd}"));
    let authority = req.uri().authority().map(|a| a.as_str());
    let ok = hosts.allows(header.or(authority)) && authority.is_none_or(|a| hosts.allows(Some(a)));
    if ok {
        return next.run(req).await;
    }
    hosts.stats.forbidden_host.fetch_add(1, Ordering::Relaxed);
    let shown = header.or(authority).unwrap_or("(none)").chars().take(100).collect::<String>();
    let message = format!(
        "403: Host {shown:?} is not this server's address. The preview answers only requests \
         addressed to its bound address or localhost (protection against DNS rebinding); \
         to serve other names, bind it to a non-loopback address with --http.\n"
    );
    (StatusCode::FORBIDDEN, [(header::CONNECTION, "close")], message).into_response()
}

/// Bytes of an oversized body read and dropped before the 413 goes out;
/// beyond them the connection is closed (and reset) without one.
pub const DRAIN_LIMIT: u64 = 64 << 20;
/// Time an oversized body may take to drain before the 413 goes out anyway.
pub const DRAIN_TIME: Duration = Duration::from_secs(10);

/// What [`limit_body`] needs.
struct BodyLimit {
    max: usize,
    stats: Arc<ServeStats>,
}

/// Middleware: reads the request body (at most `max` bytes) before the
/// route sees it; a larger one (declared or sent) is drained and answered
/// 413, so the answer reaches a client that is still sending.
async fn limit_body(State(limit): State<Arc<BodyLimit>>, req: Request, next: Next) -> Response {
    use futures_util::StreamExt;
    let (parts, body) = req.into_parts();
    let declared = parts
        .headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    let too_large = |limit: &BodyLimit| {
        limit.stats.body_too_large.fetch_add(1, Ordering::Relaxed);
        let message = format!("413: the request body is over {} bytes\n", limit.max);
        (StatusCode::PAYLOAD_TOO_LARGE, [(header::CONNECTION, "close")], message).into_response()
    };
    if declared.is_some_and(|n| n > limit.max as u64) {
        // A client waiting for `100 Continue` has sent nothing: answering
        // without reading is clean (reading would ask it for the body).
        let waits =
            parts.headers.get(header::EXPECT).is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(b"100-continue"));
        if !waits && declared.is_some_and(|n| n <= DRAIN_LIMIT) {
            drain(body.into_data_stream()).await;
        }
        return too_large(&limit);
    }
    let mut stream = body.into_data_stream();
    let mut bytes = Vec::new();
    while let Some(chunk) = stream.next().await {
        let Ok(chunk) = chunk else {
            let message = "400: the request body ended early\n";
            return (StatusCode::BAD_REQUEST, [(header::CONNECTION, "close")], message).into_response();
        };
        if bytes.len() + chunk.len() > limit.max {
            drain(stream).await;
            return too_large(&limit);
        }
        bytes.extend_from_slice(&chunk);
    }
    next.run(Request::from_parts(parts, axum::body::Body::from(bytes))).await
}

/// Reads and drops what is left of a body, at most [`DRAIN_LIMIT`] bytes
/// for at most [`DRAIN_TIME`].
async fn drain(mut stream: axum::body::BodyDataStream) {
    use futures_util::StreamExt;
    let _ = tokio::time::timeout(DRAIN_TIME, async {
        let mut read = 0u64;
        while let Some(Ok(chunk)) = stream.next().await {
            read += chunk.len() as u64;
            if read > DRAIN_LIMIT {
                break;
            }
        }
    })
    .await;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn host_policy_names() {
        let stats = Arc::new(ServeStats::default());
        let local: SocketAddr = "127.0.0.1:8080".parse().unwrap();
        let h = AllowedHosts::new(HostPolicy::Local, local, stats.clone());
        for ok in ["127.0.0.1:8080", "localhost:8080", "LOCALHOST:8080", "[::1]:8080"] {
            assert!(h.allows(Some(ok)), "{ok}");
        }
        for bad in ["evil.example:8080", "localhost", "127.0.0.1:8081", "localhost:8080.evil", ""] {
            assert!(!h.allows(Some(bad)), "{bad}");
        }
        assert!(!h.allows(None));
        let h = AllowedHosts::new(HostPolicy::Local, "127.0.0.2:80".parse().unwrap(), stats.clone());
        assert!(h.allows(Some("127.0.0.2")) && h.allows(Some("127.0.0.2:80")) && h.allows(Some("localhost")));
        let h = AllowedHosts::new(HostPolicy::Any, local, stats);
        assert!(h.allows(Some("evil.example")) && h.allows(None));
        assert_eq!(HostPolicy::for_address("127.0.0.1:1".parse().unwrap()), HostPolicy::Local);
        assert_eq!(HostPolicy::for_address("[::1]:1".parse().unwrap()), HostPolicy::Local);
        assert_eq!(HostPolicy::for_address("0.0.0.0:1".parse().unwrap()), HostPolicy::Any);
        assert_eq!(HostPolicy::for_address("192.168.1.5:1".parse().unwrap()), HostPolicy::Any);
    }
}
