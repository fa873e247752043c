//! The browser stream (issue 17): per-light buffers to every viewer once,
//! then a few bytes of k_i per frame, over one WebSocket (`/api/stream`).
//!
//! The picture is I = Σ k_i · buffer_i (eq. 5). Buffers change only when a
//! light moves; a dimmer or colour change is a new k_i. So a viewer gets, on
//! connect, a hello (size, light count, display settings) and every light's
//! buffer (sparse 16×16 tiles, f16 RGB, raw DEFLATE); afterwards only the
//! buffers whose generation changed, and a k message whenever the k vector
//! or the display settings changed. The page (`/stream.js`) composites eq. 5
//! on the viewer's GPU with WebGL2 and applies [`Display::to_srgb8`]'s white
//! balance, exposure, clipping and sRGB curve. The byte layout is in
//! `docs/stream.md`; [`encode_buffer`]/[`decode_buffer`] are its reference.
//!
//! With fixture bodies ([`Frame::bodies`]) a viewer also gets the body
//! layer's 16×16 tiles that changed (message type 6, [`encode_bodies`]):
//! per pixel the housing's radiance and the lens glow per unit k_i, drawn by
//! the page over its composite with the frame's k_i, so a dimmer change
//! sends no body bytes and a moving head sends only the tiles it touched.
//!
//! Clients without WebGL2 ask for `?mode=pictures`: they get the frame as a
//! PNG (the shared once-per-picture [`PngCache`]) pushed only when the
//! picture changed.
//!
//! Data comes from the frame clock's `watch` channel ([`Frame::k`],
//! [`Frame::buffers`], [`Frame::display`]: `Arc`s, nothing copied per
//! frame). Each client is one task that reads the latest frame when it can
//! send: a client that reads slowly skips frames (the watch keeps only the
//! latest k; buffers are compared by generation, so a light rebuilt three
//! times while the client was stuck is sent once), and at most one message
//! per client is held by the server ([`StreamStats::pending_bytes`]). A send
//! that does not complete within the stall limit drops the client. Encoded
//! buffers are cached per (light, generation) and shared by all clients.
//!
//! Upgraded connections leave the HTTP accept loop, so this module bounds
//! them itself: at most [`MAX_CLIENTS`] streams, client messages of at most
//! [`MAX_CLIENT_MESSAGE`] bytes (anything larger, or not in the protocol,
//! closes that connection only; a ping may carry the 125 bytes RFC 6455
//! allows and is answered with a pong), and every stream ends when the frame
//! clock stops (the daemon's shutdown drops the frame channel's sender).
//!
//! A mode switch makes the server start the stream over (hello and every
//! light's buffer again: megabytes for two bytes received), so switches are
//! rate-limited per client ([`SwitchLimiter`], issue 35): a switch to the
//! mode in force is a no-op, and one within [`MIN_RESTART_INTERVAL`] of the
//! client's last restart is deferred until the interval has passed, only the
//! latest requested mode being applied. The page switches at most once (to
//! pictures, when WebGL2 fails), and a connection's first switch is never
//! deferred, so no real viewer waits.

use super::png::PngCache;
use crate::output::{BodyTiles, Frame, StreamCounters};
use crate::render::bodies::BodyPixel;
use crate::render::buffer::{LightBuffer, TILE};
use crate::render::display::Display;
use axum::body::Bytes;
use axum::extract::ws::{CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Query, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use glam::Vec3;
use std::collections::HashMap;
use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;
use tokio::sync::watch;

/// Protocol version carried in the hello message (3: fixture body tiles).
pub const VERSION: u8 = 3;
/// Message type: hello (first message of every stream).
pub const MSG_HELLO: u8 = 1;
/// Message type: one light's buffer.
pub const MSG_BUFFER: u8 = 2;
/// Message type: the k vector and display settings of a frame.
pub const MSG_FRAME: u8 = 3;
/// Bytes before the first light's k in a frame message ([`encode_frame`]).
pub const FRAME_HEADER_BYTES: usize = 40;
/// Message type: a light's buffer is empty (it reaches nothing in view).
pub const MSG_CLEARED: u8 = 4;
/// Message type: a server-encoded picture (PNG), pictures mode.
pub const MSG_PICTURE: u8 = 5;
/// Message type: tiles of the fixture body layer that changed (version 3).
pub const MSG_BODIES: u8 = 6;
/// Bytes per pixel of a bodies message before DEFLATE: base f32, glow f32, light u32.
pub const BODY_PIXEL_BYTES: usize = 12;
/// Client message type: switch mode (`[0x10, mode]`).
pub const MSG_SET_MODE: u8 = 0x10;
/// Streams open at most; more are refused with 503.
pub const MAX_CLIENTS: usize = 64;
/// Largest client data message accepted (bytes); a larger one closes the
/// stream with 1009.
pub const MAX_CLIENT_MESSAGE: usize = 64;
/// Largest incoming WebSocket frame (payload bytes): the 125 bytes RFC 6455
/// (5.5) allows a control frame, so every legal ping is read and answered;
/// data messages stay limited to [`MAX_CLIENT_MESSAGE`].
pub const MAX_CLIENT_FRAME: usize = 125;
/// Shortest time between two restarts of one client's stream by mode
/// switches; a switch that comes sooner is deferred until this has passed.
/// The page switches at most once per connection (to pictures, when WebGL2
/// fails or its context is lost), and a connection's first switch is applied
/// at once, so no real viewer is ever deferred; a client that switches
/// back and forth costs at most one restart (a hello and, in buffers mode,
/// every light's buffer) per 2 s instead of one per message.
pub const MIN_RESTART_INTERVAL: Duration = Duration::from_secs(2);
/// Default stall limit: a send that takes longer drops the client.
pub const STALL_LIMIT: Duration = Duration::from_secs(10);
/// A k message is sent at least this often even when nothing changed, so a
/// viewer can tell a still picture from a dead link.
pub const KEEPALIVE: Duration = Duration::from_secs(1);
/// Flag bit of a buffer message: the payload is raw DEFLATE.
const FLAG_DEFLATE: u8 = 1;

/// What a stream sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Buffers once, then k vectors: the browser composites.
    Buffers,
    /// Server-encoded pictures (PNG), pushed when the picture changed.
    Pictures,
}

impl Mode {
    fn code(self) -> u8 {
        match self {
            Mode::Buffers => 0,
            Mode::Pictures => 1,
        }
    }
}

/// Query of `/api/stream`.
#[derive(Debug, serde::Deserialize)]
pub struct StreamQuery {
    /// `buffers` (default) or `pictures`.
    pub mode: Option<Mode>,
    /// Stall limit in ms for this client (50-10000; default 10000): a client
    /// may ask to be dropped sooner (tests, viewers that prefer to reconnect).
    pub stall_ms: Option<u64>,
}

/// Counters of the stream, shown under `stream` in `/api/status`.
#[derive(Debug, Default)]
pub struct StreamStats {
    /// Streams open now.
    pub open: AtomicU64,
    /// Streams accepted since start.
    pub accepted: AtomicU64,
    /// Streams refused over [`MAX_CLIENTS`].
    pub refused: AtomicU64,
    /// Buffer (and cleared) messages sent.
    pub buffer_messages: AtomicU64,
    /// Body-tile messages sent (fixture bodies, type 6).
    pub body_messages: AtomicU64,
    /// Body tiles sent in them.
    pub body_tiles: AtomicU64,
    /// Bodies messages encoded (one per snapshot step, shared by the clients making it).
    pub body_encodes: AtomicU64,
    /// k messages sent.
    pub frame_messages: AtomicU64,
    /// Picture messages sent.
    pub picture_messages: AtomicU64,
    /// Bytes sent over all streams.
    pub bytes_sent: AtomicU64,
    /// Frames a client skipped because it was still sending an older one.
    pub frames_skipped: AtomicU64,
    /// Clients dropped for a send that exceeded the stall limit.
    pub dropped_stalled: AtomicU64,
    /// Streams closed for a malformed or oversized client message.
    pub closed_bad_message: AtomicU64,
    /// Mode-switch messages received (`[0x10, mode]`).
    pub mode_switches: AtomicU64,
    /// Restarts of a stream by a mode switch (hello and everything again).
    pub mode_restarts: AtomicU64,
    /// Mode-switch messages not applied at once ([`SwitchLimiter`]): a
    /// switch to the mode in force, or one within [`MIN_RESTART_INTERVAL`]
    /// of the client's last restart (deferred; only the latest is applied).
    pub switches_limited: AtomicU64,
    /// Buffers encoded (f16 + DEFLATE), over all clients.
    pub buffer_encodes: AtomicU64,
    /// Message bytes held by the server for all clients now (at most one
    /// message each).
    pub pending_bytes: AtomicU64,
    /// The largest message one client had pending at a time (the per-client
    /// queue bound: never more than one message).
    pub max_pending_per_client: AtomicU64,
}

impl StreamStats {
    /// The counters now (`stream` in `/api/status`).
    pub fn snapshot(&self) -> StreamCounters {
        let r = |a: &AtomicU64| a.load(Ordering::Relaxed);
        StreamCounters {
            open: r(&self.open),
            accepted: r(&self.accepted),
            refused: r(&self.refused),
            buffer_messages: r(&self.buffer_messages),
            body_messages: r(&self.body_messages),
            body_tiles: r(&self.body_tiles),
            body_encodes: r(&self.body_encodes),
            frame_messages: r(&self.frame_messages),
            picture_messages: r(&self.picture_messages),
            bytes_sent: r(&self.bytes_sent),
            frames_skipped: r(&self.frames_skipped),
            dropped_stalled: r(&self.dropped_stalled),
            closed_bad_message: r(&self.closed_bad_message),
            mode_switches: r(&self.mode_switches),
            mode_restarts: r(&self.mode_restarts),
            switches_limited: r(&self.switches_limited),
            buffer_encodes: r(&self.buffer_encodes),
            pending_bytes: r(&self.pending_bytes),
            max_pending_per_client: r(&self.max_pending_per_client),
        }
    }
}

/// Shared state of the stream route.
#[derive(Clone)]
pub struct StreamState {
    /// Latest published frame.
    pub frames: watch::Receiver<Arc<Frame>>,
    /// The shared PNG encoder (pictures mode).
    pub png: Arc<PngCache>,
    /// Counters.
    pub stats: Arc<StreamStats>,
    /// Encoded buffers by light: (generation, message).
    cache: Arc<tokio::sync::Mutex<HashMap<usize, (u64, Bytes)>>>,
    /// The last bodies message: from which tiles (`None`: a fresh client)
    /// to which, shared by every client that makes the same step.
    body_cache: Arc<tokio::sync::Mutex<Option<BodyStep>>>,
}

/// A bodies message from one tile snapshot (`None`: none held) to another.
type BodyStep = (Option<Arc<BodyTiles>>, Arc<BodyTiles>, Bytes);

impl StreamState {
    /// Stream state over `frames`, encoding pictures with `png`.
    pub fn new(frames: watch::Receiver<Arc<Frame>>, png: Arc<PngCache>) -> Self {
        Self {
            frames,
            png,
            stats: Arc::new(StreamStats::default()),
            cache: Default::default(),
            body_cache: Default::default(),
        }
    }

    /// The buffer message of `light` at `generation`, encoded once for all clients.
    async fn buffer_message(&self, light: usize, generation: u64, buffer: &Arc<LightBuffer>) -> Bytes {
        let mut cache = self.cache.lock().await;
        if let Some((g, bytes)) = cache.get(&light)
            && *g == generation
        {
            return bytes.clone();
        }
        let buffer = buffer.clone();
        let encoded = tokio::task::spawn_blocking(move || encode_buffer(light as u32, generation, &buffer))
            .await
            .unwrap_or_else(|e| {
                tracing::error!("stream: encoding light {light}'s buffer failed: {e}");
                encode_cleared(light as u32, generation)
            });
        self.stats.buffer_encodes.fetch_add(1, Ordering::Relaxed);
        cache.insert(light, (generation, encoded.clone()));
        encoded
    }
}

/// `GET /api/stream`: upgrades to the stream (see the module docs).
pub async fn handler(
    ws: WebSocketUpgrade,
    headers: HeaderMap,
    Query(q): Query<StreamQuery>,
    State(s): State<StreamState>,
) -> Response {
    if !same_origin(&headers) {
        return (StatusCode::FORBIDDEN, "the stream is served to pages of this server only").into_response();
    }
    let open = s.stats.open.fetch_add(1, Ordering::Relaxed);
    if open as usize >= MAX_CLIENTS {
        s.stats.open.fetch_sub(1, Ordering::Relaxed);
        s.stats.refused.fetch_add(1, Ordering::Relaxed);
        return (StatusCode::SERVICE_UNAVAILABLE, "too many stream clients").into_response();
    }
    s.stats.accepted.fetch_add(1, Ordering::Relaxed);
    let guard = OpenGuard(s.stats.clone());
    let mode = q.mode.unwrap_or(Mode::Buffers);
    let stall = q.stall_ms.map_or(STALL_LIMIT, |ms| Duration::from_millis(ms.clamp(50, 10_000)));
    ws.max_message_size(MAX_CLIENT_MESSAGE).max_frame_size(MAX_CLIENT_FRAME).on_upgrade(move |socket| async move {
        let _guard = guard;
        Client {
            socket,
            s,
            mode,
            stall,
            sent: Vec::new(),
            body_sent: Vec::new(),
            last_bodies: None,
            last_k: None,
            last_picture: None,
            shown: 0,
            limiter: SwitchLimiter::default(),
        }
        .run()
        .await;
    })
}

/// A browser names the page that opens a WebSocket in `Origin`; any page may
/// open one to 127.0.0.1 (the Host check cannot see it), so a page of
/// another site is refused. Clients that are not browsers send no Origin.
fn same_origin(headers: &HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN) else { return true };
    let host = headers.get(header::HOST).and_then(|h| h.to_str().ok()).unwrap_or("");
    let origin = origin.to_str().unwrap_or("");
    let authority = origin.strip_prefix("http://").or_else(|| origin.strip_prefix("https://"));
    authority.is_some_and(|a| !host.is_empty() && a.eq_ignore_ascii_case(host))
}

/// Decrements the open count when a stream ends (or its upgrade fails).
struct OpenGuard(Arc<StreamStats>);

impl Drop for OpenGuard {
    fn drop(&mut self) {
        self.0.open.fetch_sub(1, Ordering::Relaxed);
    }
}

/// Why a client's stream ended.
enum End {
    /// The client closed, or the frame clock stopped.
    Closed,
    /// A send exceeded the stall limit or failed.
    Stalled,
    /// A message outside the protocol (code, reason).
    Bad(u16, &'static str),
}

/// One client's stream.
struct Client {
    socket: WebSocket,
    s: StreamState,
    mode: Mode,
    stall: Duration,
    /// Buffers mode: the generation of each light's buffer the client holds.
    sent: Vec<Option<u64>>,
    /// Buffers mode: the revision of each body tile the client holds (0: empty, as at hello).
    body_sent: Vec<u64>,
    /// The body tiles last compared (skips the comparison while they are the same `Arc`).
    last_bodies: Option<Arc<BodyTiles>>,
    /// The last k message's content (k, display) and when it went out.
    last_k: Option<(Arc<Vec<Vec3>>, Display, tokio::time::Instant)>,
    /// Pictures mode: the pixels last pushed.
    last_picture: Option<Arc<Vec<u8>>>,
    /// The number of the last frame handled.
    shown: u64,
    /// This client's mode switches: when they may restart the stream.
    limiter: SwitchLimiter,
}

/// The rate limit of one client's mode switches (see the module docs): a
/// pure state machine over the instants it is given, so it is tested without
/// a clock.
#[derive(Debug, Default)]
struct SwitchLimiter {
    /// When a switch last restarted the stream (`None`: never; the
    /// connection's own start does not count, so its first switch is free).
    last_restart: Option<tokio::time::Instant>,
    /// The mode a deferred switch asks for (the latest one requested),
    /// applied at [`SwitchLimiter::due`].
    pending: Option<Mode>,
}

impl SwitchLimiter {
    /// A switch to `wanted` received at `now` while `current` is in force:
    /// `Some(mode)` to restart in `mode` now; `None` when it is limited (the
    /// mode already in force, or deferred: then the latest request decides
    /// what [`SwitchLimiter::take_due`] applies).
    fn request(&mut self, current: Mode, wanted: Mode, now: tokio::time::Instant) -> Option<Mode> {
        if self.pending.is_some() {
            // Already deferred: the latest request decides (back to the
            // mode in force cancels it).
            self.pending = (wanted != current).then_some(wanted);
            return None;
        }
        if wanted == current {
            return None;
        }
        if self.last_restart.is_some_and(|t| now < t + MIN_RESTART_INTERVAL) {
            self.pending = Some(wanted);
            return None;
        }
        self.last_restart = Some(now);
        Some(wanted)
    }

    /// When the deferred switch may be applied (`None`: none deferred).
    fn due(&self) -> Option<tokio::time::Instant> {
        self.pending.and(self.last_restart).map(|t| t + MIN_RESTART_INTERVAL)
    }

    /// The deferred switch's mode if it is due at `now` (it then counts as
    /// the last restart).
    fn take_due(&mut self, now: tokio::time::Instant) -> Option<Mode> {
        if self.due().is_none_or(|due| now < due) {
            return None;
        }
        self.last_restart = Some(now);
        self.pending.take()
    }
}

impl Client {
    async fn run(mut self) {
        let mut frames = self.s.frames.clone();
        let frame = frames.borrow_and_update().clone();
        self.shown = frame.number;
        let end = match self.start(&frame).await {
            Err(end) => end,
            Ok(()) => match self.serve(&mut frames).await {
                Err(end) => end,
                Ok(never) => match never {},
            },
        };
        // Frames published while the last send was stuck were skipped too.
        let latest = frames.borrow().number;
        self.s.stats.frames_skipped.fetch_add(latest.saturating_sub(self.shown), Ordering::Relaxed);
        match end {
            End::Closed => {}
            End::Stalled => {
                self.s.stats.dropped_stalled.fetch_add(1, Ordering::Relaxed);
            }
            End::Bad(code, reason) => {
                self.s.stats.closed_bad_message.fetch_add(1, Ordering::Relaxed);
                let close = Message::Close(Some(CloseFrame { code, reason: reason.into() }));
                let _ = tokio::time::timeout(self.stall, self.socket.send(close)).await;
            }
        }
    }

    async fn start(&mut self, frame: &Arc<Frame>) -> Result<(), End> {
        self.send(encode_hello(frame, self.mode)).await?;
        self.update(frame).await
    }

    async fn serve(&mut self, frames: &mut watch::Receiver<Arc<Frame>>) -> Result<std::convert::Infallible, End> {
        let mut keepalive = tokio::time::interval(KEEPALIVE);
        keepalive.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            let due = self.limiter.due();
            tokio::select! {
                changed = frames.changed() => {
                    if changed.is_err() {
                        let _ = tokio::time::timeout(self.stall, self.socket.send(Message::Close(None))).await;
                        return Err(End::Closed);
                    }
                    let frame = frames.borrow_and_update().clone();
                    let skipped = frame.number.saturating_sub(self.shown + 1);
                    self.s.stats.frames_skipped.fetch_add(skipped, Ordering::Relaxed);
                    self.shown = frame.number;
                    self.update(&frame).await?;
                }
                msg = self.socket.recv() => {
                    let frame = frames.borrow().clone();
                    self.receive(msg, &frame).await?;
                }
                () = tokio::time::sleep_until(due.unwrap_or_else(tokio::time::Instant::now)), if due.is_some() => {
                    if let Some(mode) = self.limiter.take_due(tokio::time::Instant::now()) {
                        let frame = frames.borrow().clone();
                        self.restart(mode, &frame).await?;
                    }
                }
                _ = keepalive.tick() => {
                    let frame = frames.borrow().clone();
                    if self.mode == Mode::Buffers
                        && self.last_k.as_ref().is_some_and(|(_, _, at)| at.elapsed() >= KEEPALIVE)
                    {
                        self.send_k(&frame).await?;
                    }
                }
            }
        }
    }

    /// A client message: `[MSG_SET_MODE, mode]` switches mode (rate-limited
    /// by [`SwitchLimiter`]); control frames are answered by the WebSocket
    /// layer (a ping's pong goes out with the next read); anything else
    /// closes the stream.
    async fn receive(&mut self, msg: Option<Result<Message, axum::Error>>, frame: &Arc<Frame>) -> Result<(), End> {
        match msg {
            None => Err(End::Closed),
            Some(Err(e)) => {
                tracing::debug!("stream: client error: {e}");
                use tokio_tungstenite::tungstenite::Error;
                use tokio_tungstenite::tungstenite::error::ProtocolError;
                match e.into_inner().downcast::<Error>().map(|e| *e) {
                    Ok(Error::Capacity(_)) => Err(End::Bad(1009, "message too large")),
                    Ok(Error::Protocol(ProtocolError::ResetWithoutClosingHandshake)) => Err(End::Closed),
                    Ok(Error::Protocol(_) | Error::Utf8(_)) => Err(End::Bad(1002, "malformed message")),
                    // The connection went away (reset, closed without a handshake).
                    _ => Err(End::Closed),
                }
            }
            Some(Ok(Message::Close(_))) => Err(End::Closed),
            Some(Ok(Message::Ping(_) | Message::Pong(_))) => Ok(()),
            Some(Ok(Message::Binary(b))) if b.len() == 2 && b[0] == MSG_SET_MODE && b[1] <= 1 => {
                let wanted = if b[1] == 0 { Mode::Buffers } else { Mode::Pictures };
                self.s.stats.mode_switches.fetch_add(1, Ordering::Relaxed);
                match self.limiter.request(self.mode, wanted, tokio::time::Instant::now()) {
                    Some(mode) => self.restart(mode, frame).await,
                    None => {
                        self.s.stats.switches_limited.fetch_add(1, Ordering::Relaxed);
                        Ok(())
                    }
                }
            }
            Some(Ok(_)) => Err(End::Bad(1003, "not a footlight stream message")),
        }
    }

    /// Starts the stream over in `mode`: hello, then everything as on connect.
    async fn restart(&mut self, mode: Mode, frame: &Arc<Frame>) -> Result<(), End> {
        self.s.stats.mode_restarts.fetch_add(1, Ordering::Relaxed);
        self.mode = mode;
        self.sent.clear();
        self.body_sent.clear();
        self.last_bodies = None;
        self.last_k = None;
        self.last_picture = None;
        self.start(frame).await
    }

    /// Sends what `frame` changed for this client.
    async fn update(&mut self, frame: &Arc<Frame>) -> Result<(), End> {
        match self.mode {
            // The camera moves: the frame is the server's moving preview,
            // not a sum of the buffers the client holds; push it as a
            // picture, and send k again once the buffers are back.
            Mode::Buffers if frame.preview => {
                self.last_k = None;
                self.push_picture(frame).await
            }
            Mode::Buffers => {
                let n = frame.buffers.len();
                self.sent.resize(n, None);
                let mut any = false;
                for (i, (generation, buffer)) in frame.buffers.iter().enumerate() {
                    if self.sent[i] == Some(*generation) {
                        continue;
                    }
                    let msg = if buffer.occupied_tiles() == 0 {
                        encode_cleared(i as u32, *generation)
                    } else {
                        self.s.buffer_message(i, *generation, buffer).await
                    };
                    self.send(msg).await?;
                    self.s.stats.buffer_messages.fetch_add(1, Ordering::Relaxed);
                    self.sent[i] = Some(*generation);
                    any = true;
                }
                self.send_bodies(frame).await?;
                let same = self
                    .last_k
                    .as_ref()
                    .is_some_and(|(k, d, _)| (Arc::ptr_eq(k, &frame.k) || **k == *frame.k) && *d == frame.display);
                if any || !same {
                    self.send_k(frame).await?;
                }
                Ok(())
            }
            Mode::Pictures => self.push_picture(frame).await,
        }
    }

    /// Pushes the frame's picture (the shared PNG) when its pixels changed.
    async fn push_picture(&mut self, frame: &Arc<Frame>) -> Result<(), End> {
        if self.last_picture.as_ref().is_some_and(|p| Arc::ptr_eq(p, &frame.rgb)) {
            return Ok(());
        }
        match self.s.png.get(frame.clone()).await {
            Ok(png) => {
                self.send(encode_picture(png.number, &png.bytes)).await?;
                self.s.stats.picture_messages.fetch_add(1, Ordering::Relaxed);
                self.last_picture = Some(frame.rgb.clone());
            }
            Err(e) => tracing::warn!("stream: encoding the picture failed: {e}"),
        }
        Ok(())
    }

    /// Sends, in one message, the body tiles whose revision this client
    /// has not seen (the browser draws them over its composite).
    async fn send_bodies(&mut self, frame: &Arc<Frame>) -> Result<(), End> {
        let Some(tiles) = &frame.bodies else { return Ok(()) };
        if self.last_bodies.as_ref().is_some_and(|b| Arc::ptr_eq(b, tiles)) {
            return Ok(());
        }
        self.body_sent.resize(tiles.tiles.len(), 0);
        let which: Vec<usize> =
            (0..tiles.tiles.len()).filter(|&i| tiles.tiles[i].revision != self.body_sent[i]).collect();
        if !which.is_empty() {
            // Clients that keep up all step from the same snapshot to the same
            // one (what a client holds is exactly its last snapshot's
            // revisions): the message is encoded once for them.
            let same = |a: &Option<Arc<BodyTiles>>, b: &Option<Arc<BodyTiles>>| match (a, b) {
                (None, None) => true,
                (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                _ => false,
            };
            let mut cache = self.s.body_cache.lock().await;
            let msg = match &*cache {
                Some((from, to, msg)) if same(from, &self.last_bodies) && Arc::ptr_eq(to, tiles) => msg.clone(),
                _ => {
                    let t = tiles.clone();
                    let list = which.clone();
                    let msg = tokio::task::spawn_blocking(move || encode_bodies(&t, &list)).await.map_err(|e| {
                        tracing::error!("stream: encoding the body tiles failed: {e}");
                        End::Closed
                    })?;
                    self.s.stats.body_encodes.fetch_add(1, Ordering::Relaxed);
                    *cache = Some((self.last_bodies.clone(), tiles.clone(), msg.clone()));
                    msg
                }
            };
            drop(cache);
            self.send(msg).await?;
            self.s.stats.body_messages.fetch_add(1, Ordering::Relaxed);
            self.s.stats.body_tiles.fetch_add(which.len() as u64, Ordering::Relaxed);
            for i in which {
                self.body_sent[i] = tiles.tiles[i].revision;
            }
        }
        self.last_bodies = Some(tiles.clone());
        Ok(())
    }

    async fn send_k(&mut self, frame: &Arc<Frame>) -> Result<(), End> {
        self.send(encode_frame(frame)).await?;
        self.s.stats.frame_messages.fetch_add(1, Ordering::Relaxed);
        self.last_k = Some((frame.k.clone(), frame.display, tokio::time::Instant::now()));
        Ok(())
    }

    /// Sends one message, holding it (and counting it pending) until the
    /// socket took it, for at most the stall limit.
    async fn send(&mut self, bytes: Bytes) -> Result<(), End> {
        let n = bytes.len() as u64;
        let stats = &self.s.stats;
        stats.pending_bytes.fetch_add(n, Ordering::Relaxed);
        stats.max_pending_per_client.fetch_max(n, Ordering::Relaxed);
        let sent = tokio::time::timeout(self.stall, self.socket.send(Message::Binary(bytes))).await;
        stats.pending_bytes.fetch_sub(n, Ordering::Relaxed);
        match sent {
            Ok(Ok(())) => {
                stats.bytes_sent.fetch_add(n, Ordering::Relaxed);
                Ok(())
            }
            Ok(Err(_)) => Err(End::Closed),
            Err(_) => Err(End::Stalled),
        }
    }
}

/// Hello: `[1, VERSION, mode, 0, width u32, height u32, lights u32, tile u32,
/// exposure f32, wb r g b f32, knee f32, white f32]`, little-endian (44
/// bytes); the display block is [`push_display`]'s.
pub fn encode_hello(frame: &Frame, mode: Mode) -> Bytes {
    let mut b = Vec::with_capacity(44);
    b.extend_from_slice(&[MSG_HELLO, VERSION, mode.code(), 0]);
    for v in [frame.width, frame.height, frame.buffers.len() as u32, TILE as u32] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    push_display(&mut b, &frame.display);
    Bytes::from(b)
}

/// The display block (24 bytes): exposure, white-balance gains R G B, and
/// the highlight roll-off's knee and white (display.rs
/// `HighlightRolloff::uniforms`), both 0 when the display clips at white.
fn push_display(b: &mut Vec<u8>, d: &Display) {
    let [knee, white] = d.rolloff.map_or([0.0; 2], |r| r.uniforms());
    for v in [d.exposure, d.white_balance.x, d.white_balance.y, d.white_balance.z, knee, white] {
        b.extend_from_slice(&v.to_le_bytes());
    }
}

/// The power-of-two scale a buffer is sent with, so its largest value is
/// at most 2^14 in f16 (f16 overflows at 65504): value = f16 · scale. The
/// rule the live tracer's compact buffers are stored with
/// ([`crate::render::buffer::f16_scale`]), so a compact buffer goes out
/// with its own scale and its own f16 values.
pub fn buffer_scale(buffer: &LightBuffer) -> f32 {
    crate::render::buffer::f16_scale(buffer.values())
}

/// Buffer: header `[2, flags, 0, 0, light u32, generation u64, tiles u32,
/// scale f32, payload length u32]` (28 bytes), then the payload (raw
/// DEFLATE when flags bit 0 is set): the occupied tiles' indices (u32,
/// row-major over the tile grid, ascending), then per tile 16×16 pixels
/// row-major of f16 R, G, B (value / scale).
pub fn encode_buffer(light: u32, generation: u64, buffer: &LightBuffer) -> Bytes {
    let scale = buffer_scale(buffer);
    let occupied = buffer.occupied();
    let tiles_x = (buffer.width as usize).div_ceil(TILE);
    let mut raw = Vec::with_capacity(occupied.len() * (4 + TILE * TILE * 6));
    for &(tx, ty) in &occupied {
        raw.extend_from_slice(&((ty * tiles_x + tx) as u32).to_le_bytes());
    }
    for &(tx, ty) in &occupied {
        for p in buffer.tile(tx, ty).unwrap_or_default().iter() {
            for c in p.to_array() {
                raw.extend_from_slice(&half::f16::from_f32(c / scale).to_bits().to_le_bytes());
            }
        }
    }
    let mut z = flate2::write::DeflateEncoder::new(Vec::with_capacity(raw.len() / 2), flate2::Compression::fast());
    let payload = z.write_all(&raw).and_then(|()| z.finish());
    let (flags, payload) = match payload {
        Ok(p) if p.len() < raw.len() => (FLAG_DEFLATE, p),
        _ => (0, raw),
    };
    let mut b = Vec::with_capacity(28 + payload.len());
    b.extend_from_slice(&[MSG_BUFFER, flags, 0, 0]);
    b.extend_from_slice(&light.to_le_bytes());
    b.extend_from_slice(&generation.to_le_bytes());
    b.extend_from_slice(&(occupied.len() as u32).to_le_bytes());
    b.extend_from_slice(&scale.to_le_bytes());
    b.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    b.extend_from_slice(&payload);
    Bytes::from(b)
}

/// Cleared: `[4, 0, 0, 0, light u32, generation u64]` (16 bytes): the
/// light's buffer is empty.
pub fn encode_cleared(light: u32, generation: u64) -> Bytes {
    let mut b = vec![MSG_CLEARED, 0, 0, 0];
    b.extend_from_slice(&light.to_le_bytes());
    b.extend_from_slice(&generation.to_le_bytes());
    Bytes::from(b)
}

/// Frame: `[3, 0, 0, 0, lights u32, frame u64, exposure f32, wb r g b f32,
/// knee f32, white f32]` (40 bytes), then per light k_i R, G, B and a time factor (strobe phase
/// placeholder, always 1), f32 each (16 bytes per light).
pub fn encode_frame(frame: &Frame) -> Bytes {
    let mut b = Vec::with_capacity(FRAME_HEADER_BYTES + 16 * frame.k.len());
    b.extend_from_slice(&[MSG_FRAME, 0, 0, 0]);
    b.extend_from_slice(&(frame.k.len() as u32).to_le_bytes());
    b.extend_from_slice(&frame.number.to_le_bytes());
    push_display(&mut b, &frame.display);
    debug_assert_eq!(b.len(), FRAME_HEADER_BYTES);
    for k in frame.k.iter() {
        for v in [k.x, k.y, k.z, 1.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    Bytes::from(b)
}

/// Bodies: header `[6, flags, 0, 0, lights u32, tiles u32, payload length
/// u32]` (16 bytes), then the payload (raw DEFLATE when flags bit 0 is set):
/// the tiles' indices (u32, row-major over the 16×16 tile grid), then per
/// tile 16×16 pixels row-major of [`BODY_PIXEL_BYTES`]: base f32 (the
/// housing's radiance, cd/m², grey; negative: no body, the composite shows),
/// glow f32 (cd/m² per cd of k_light), light u32. The picture there is
/// base + k_light · glow through the display ([`BodyPixel::radiance`]).
pub fn encode_bodies(tiles: &BodyTiles, which: &[usize]) -> Bytes {
    let mut raw = Vec::with_capacity(which.len() * (4 + TILE * TILE * BODY_PIXEL_BYTES));
    for &i in which {
        raw.extend_from_slice(&(i as u32).to_le_bytes());
    }
    for &i in which {
        for p in &tiles.tiles[i].pixels {
            let p = p.unwrap_or(BodyPixel { base: -1.0, glow: 0.0, light: 0 });
            raw.extend_from_slice(&p.base.to_le_bytes());
            raw.extend_from_slice(&p.glow.to_le_bytes());
            raw.extend_from_slice(&p.light.to_le_bytes());
        }
    }
    let mut z = flate2::write::DeflateEncoder::new(Vec::with_capacity(raw.len() / 8), flate2::Compression::fast());
    let (flags, payload) = match z.write_all(&raw).and_then(|()| z.finish()) {
        Ok(p) if p.len() < raw.len() => (FLAG_DEFLATE, p),
        _ => (0, raw),
    };
    let mut b = Vec::with_capacity(16 + payload.len());
    b.extend_from_slice(&[MSG_BODIES, flags, 0, 0]);
    for v in [tiles.lights, which.len() as u32, payload.len() as u32] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&payload);
    Bytes::from(b)
}

/// The tiles of a bodies message: (tile index, 16×16 pixels, `None`: no body).
pub type DecodedBodyTiles = Vec<(u32, Vec<Option<BodyPixel>>)>;

/// Decodes a bodies message into (lights, tiles): the reference decoder of
/// the layout (tests, bench).
pub fn decode_bodies(b: &[u8]) -> Result<(u32, DecodedBodyTiles), DecodeError> {
    if b.first() != Some(&MSG_BODIES) {
        return Err(DecodeError("not a bodies message".into()));
    }
    let lights = u32_at(b, 4)?;
    let tiles = u32_at(b, 8)? as usize;
    let len = u32_at(b, 12)? as usize;
    let payload = b.get(16..16 + len).ok_or_else(|| DecodeError("payload shorter than its length".into()))?;
    let want = tiles
        .checked_mul(4 + TILE * TILE * BODY_PIXEL_BYTES)
        .ok_or_else(|| DecodeError("tile count overflows".into()))?;
    let raw = payload_bytes(b[1], payload, want, &format!("{tiles} body tiles"))?;
    let px = tiles * 4;
    (0..tiles)
        .map(|t| {
            let index = u32_at(&raw, 4 * t)?;
            let pixels = (0..TILE * TILE)
                .map(|j| {
                    let at = px + (t * TILE * TILE + j) * BODY_PIXEL_BYTES;
                    let base = f32::from_bits(u32_at(&raw, at)?);
                    let glow = f32::from_bits(u32_at(&raw, at + 4)?);
                    let light = u32_at(&raw, at + 8)?;
                    Ok((base >= 0.0).then_some(BodyPixel { base, glow, light }))
                })
                .collect::<Result<Vec<_>, DecodeError>>()?;
            Ok((index, pixels))
        })
        .collect::<Result<Vec<_>, DecodeError>>()
        .map(|t| (lights, t))
}

/// Picture: `[5, 0, 0, 0, frame u64]` then the PNG file.
pub fn encode_picture(number: u64, png: &[u8]) -> Bytes {
    let mut b = Vec::with_capacity(12 + png.len());
    b.extend_from_slice(&[MSG_PICTURE, 0, 0, 0]);
    b.extend_from_slice(&number.to_le_bytes());
    b.extend_from_slice(png);
    Bytes::from(b)
}

/// A message that does not follow `docs/stream.md`.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("stream message: {0}")]
pub struct DecodeError(String);

/// A message's payload bytes: inflated when `flags` has [`FLAG_DEFLATE`]
/// (never past `want` + 1 bytes), else as sent; an error naming `what`
/// unless exactly `want` bytes result.
fn payload_bytes(flags: u8, payload: &[u8], want: usize, what: &str) -> Result<Vec<u8>, DecodeError> {
    let raw = if flags & FLAG_DEFLATE != 0 {
        let mut out = Vec::with_capacity(want.min(1 << 28));
        flate2::read::DeflateDecoder::new(payload)
            .take(want as u64 + 1)
            .read_to_end(&mut out)
            .map_err(|e| DecodeError(format!("DEFLATE: {e}")))?;
        out
    } else {
        payload.to_vec()
    };
    if raw.len() != want {
        return Err(DecodeError(format!("{} payload bytes for {what} (want {want})", raw.len())));
    }
    Ok(raw)
}

fn u32_at(b: &[u8], at: usize) -> Result<u32, DecodeError> {
    b.get(at..at + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
        .ok_or_else(|| DecodeError(format!("truncated at byte {at}")))
}

fn u64_at(b: &[u8], at: usize) -> Result<u64, DecodeError> {
    Ok(u64::from(u32_at(b, at)?) | (u64::from(u32_at(b, at + 4)?) << 32))
}

/// Decodes a buffer message for a `width`×`height` picture into (light,
/// generation, buffer): the reference decoder of the layout (tests, bench).
pub fn decode_buffer(b: &[u8], width: u32, height: u32) -> Result<(u32, u64, LightBuffer), DecodeError> {
    if b.first() != Some(&MSG_BUFFER) {
        return Err(DecodeError("not a buffer message".into()));
    }
    let light = u32_at(b, 4)?;
    let generation = u64_at(b, 8)?;
    let tiles = u32_at(b, 16)? as usize;
    let scale = f32::from_bits(u32_at(b, 20)?);
    let len = u32_at(b, 24)? as usize;
    let payload = b.get(28..28 + len).ok_or_else(|| DecodeError("payload shorter than its length".into()))?;
    let want = tiles.checked_mul(4 + TILE * TILE * 6).ok_or_else(|| DecodeError("tile count overflows".into()))?;
    let raw = payload_bytes(b[1], payload, want, &format!("{tiles} tiles"))?;
    let pixels = &raw[tiles * 4..];
    let list = (0..tiles)
        .map(|t| {
            let index = u32_at(&raw, t * 4)? as usize;
            let px = &pixels[t * TILE * TILE * 6..(t + 1) * TILE * TILE * 6];
            let f = |i: usize| half::f16::from_bits(u16::from_le_bytes([px[2 * i], px[2 * i + 1]])).to_f32() * scale;
            Ok((index, (0..TILE * TILE).map(|p| Vec3::new(f(3 * p), f(3 * p + 1), f(3 * p + 2))).collect()))
        })
        .collect::<Result<Vec<_>, DecodeError>>()?;
    Ok((light, generation, LightBuffer::from_tile_list(width, height, list)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn buffer(w: u32, h: u32, peak: f32) -> LightBuffer {
        let mut dense = vec![Vec3::ZERO; (w * h) as usize];
        // A spot in the lower right (edge tiles) and a lone pixel at the top left.
        for y in 0..h {
            for x in 0..w {
                let d = ((x as f32 - 30.0).powi(2) + (y as f32 - 18.0).powi(2)).sqrt();
                if d < 12.0 {
                    dense[(y * w + x) as usize] = Vec3::new(1.0, 0.5, 0.25) * peak * (1.0 - d / 12.0) + 1e-4;
                }
            }
        }
        dense[0] = Vec3::new(3e-3, 0.0, 7.0);
        LightBuffer::from_dense(w, h, &dense)
    }

    #[test]
    fn buffer_round_trips_within_f16_precision_and_keeps_the_tile_layout() {
        let (w, h) = (37, 29);
        for peak in [1.0f32, 2.0e5, 1.0e-3] {
            let b = buffer(w, h, peak);
            let msg = encode_buffer(3, 42, &b);
            assert_eq!(msg[0], MSG_BUFFER);
            let (light, generation, back) = decode_buffer(&msg, w, h).unwrap();
            assert_eq!((light, generation), (3, 42));
            assert_eq!(back.occupied(), b.occupied(), "same tiles, same order");
            let scale = buffer_scale(&b);
            for (a, z) in b.to_dense().iter().zip(back.to_dense()) {
                for c in 0..3 {
                    // f16: 11 significant bits (relative 2^-11), subnormals below 2^-14 · scale.
                    let tol = a[c].abs() * 2f32.powi(-11) + scale * 2f32.powi(-24);
                    assert!((a[c] - z[c]).abs() <= tol, "peak {peak}: {} vs {}", a[c], z[c]);
                    assert!(z[c].is_finite());
                }
            }
            // A compact buffer (the live tracer's) goes out with its own
            // scale and exactly its own values.
            let c = b.clone().compact();
            assert_eq!(buffer_scale(&c), scale);
            let (_, _, back) = decode_buffer(&encode_buffer(3, 42, &c), w, h).unwrap();
            assert_eq!(back.to_dense(), c.to_dense(), "peak {peak}");
        }
    }

    #[test]
    fn tile_indices_are_row_major_over_the_grid() {
        let (w, h) = (40, 20); // 3×2 tiles
        let mut dense = vec![Vec3::ZERO; (w * h) as usize];
        dense[(19 * w + 39) as usize] = Vec3::ONE; // tile (2, 1) = index 5
        dense[(2 * w + 17) as usize] = Vec3::ONE; // tile (1, 0) = index 1
        let msg = encode_buffer(0, 1, &LightBuffer::from_dense(w, h, &dense));
        let flags = msg[1];
        let payload = &msg[28..];
        let mut raw = Vec::new();
        if flags & 1 != 0 {
            flate2::read::DeflateDecoder::new(payload).read_to_end(&mut raw).unwrap();
        } else {
            raw = payload.to_vec();
        }
        assert_eq!(u32_at(&msg, 16).unwrap(), 2);
        assert_eq!((u32_at(&raw, 0).unwrap(), u32_at(&raw, 4).unwrap()), (1, 5));
        // Tile 5's pixel (7, 3) (picture pixel (39, 19)): R at f16 offset 3 · (3·16 + 7) after the first tile.
        let at = 8 + TILE * TILE * 6 + 6 * (3 * 16 + 7);
        let scale = f32::from_bits(u32_at(&msg, 20).unwrap());
        assert_eq!(half::f16::from_bits(u16::from_le_bytes([raw[at], raw[at + 1]])).to_f32() * scale, 1.0);
    }

    #[test]
    fn malformed_buffer_messages_are_errors() {
        let msg = encode_buffer(1, 2, &buffer(37, 29, 1.0));
        assert!(decode_buffer(&msg[..20], 37, 29).is_err());
        assert!(decode_buffer(&msg[..msg.len() - 1], 37, 29).is_err());
        let mut lie = msg.to_vec();
        lie[16] = lie[16].wrapping_add(1); // one more tile than the payload holds
        assert!(decode_buffer(&lie, 37, 29).is_err());
        lie[16..20].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode_buffer(&lie, 37, 29).is_err());
        assert!(decode_buffer(&encode_cleared(1, 2), 37, 29).is_err());
    }

    #[test]
    fn body_tiles_round_trip_exactly() {
        use crate::output::{BodyTile, BodyTiles};
        let px = |j: usize| match j % 3 {
            0 => None,
            1 => Some(BodyPixel { base: 0.3, glow: 0.0, light: 0 }),
            _ => Some(BodyPixel { base: 0.3, glow: 1234.5 + j as f32, light: 7 }),
        };
        let tile = |seed: usize| {
            Arc::new(BodyTile { revision: seed as u64, pixels: (0..TILE * TILE).map(|j| px(j + seed)).collect() })
        };
        let tiles = BodyTiles { width: 40, height: 20, lights: 9, tiles: (0..6).map(tile).collect() };
        let msg = encode_bodies(&tiles, &[1, 5]);
        assert_eq!((msg[0], msg[1] & 1), (MSG_BODIES, 1), "repetitive pixels deflate");
        let (lights, back) = decode_bodies(&msg).unwrap();
        assert_eq!(lights, 9);
        assert_eq!(back.len(), 2);
        for ((index, pixels), want) in back.iter().zip([1usize, 5]) {
            assert_eq!((*index as usize, pixels), (want, &tiles.tiles[want].pixels));
        }
        assert!(decode_bodies(&msg[..msg.len() - 1]).is_err());
        assert!(decode_bodies(&encode_cleared(1, 2)).is_err());
    }

    /// Issue 35: a connection's first switch restarts at once; later ones
    /// within [`MIN_RESTART_INTERVAL`] of the last restart wait for it, the
    /// latest request deciding; a switch to the mode in force does nothing.
    #[test]
    fn mode_switches_restart_at_most_once_per_interval_latest_mode_wins() {
        use Mode::{Buffers, Pictures};
        let t0 = tokio::time::Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let mut l = SwitchLimiter::default();
        assert_eq!(l.request(Buffers, Buffers, at(0)), None, "the mode in force: a no-op");
        assert_eq!(l.due(), None);
        assert_eq!(l.request(Buffers, Pictures, at(1)), Some(Pictures), "the first switch is not deferred");
        // A storm within the interval: deferred, the latest mode decides.
        for i in 0..100u64 {
            let wanted = if i % 2 == 0 { Pictures } else { Buffers };
            assert_eq!(l.request(Pictures, wanted, at(2 + i)), None);
        }
        assert_eq!(l.due(), Some(at(1) + MIN_RESTART_INTERVAL), "the latest request (buffers) waits for the interval");
        assert_eq!(l.request(Pictures, Buffers, at(200)), None);
        assert_eq!(l.take_due(at(1) + MIN_RESTART_INTERVAL - Duration::from_millis(1)), None, "not yet");
        assert_eq!(l.take_due(at(1) + MIN_RESTART_INTERVAL), Some(Buffers), "the latest, once due");
        assert_eq!((l.due(), l.take_due(at(10_000))), (None, None), "applied once");
        // Back to the mode in force while deferred cancels the switch.
        let t1 = at(1) + MIN_RESTART_INTERVAL;
        assert_eq!(l.request(Buffers, Pictures, t1 + Duration::from_millis(5)), None);
        assert!(l.due().is_some());
        assert_eq!(l.request(Buffers, Buffers, t1 + Duration::from_millis(6)), None);
        assert_eq!(l.due(), None, "cancelled");
        // After the interval a switch is applied at once again.
        assert_eq!(l.request(Buffers, Pictures, t1 + MIN_RESTART_INTERVAL), Some(Pictures));
        // Any number of switches over 10 s restart at most 1 + 10 s / interval times.
        let mut l = SwitchLimiter::default();
        let mut mode = Buffers;
        let mut restarts = 0;
        for ms in 0..10_000u64 {
            let wanted = if ms % 2 == 0 { Pictures } else { Buffers };
            for m in [l.request(mode, wanted, at(ms)), l.take_due(at(ms))].into_iter().flatten() {
                mode = m;
                restarts += 1;
            }
        }
        let bound = 1 + (10_000 / MIN_RESTART_INTERVAL.as_millis()) as u32;
        assert!(restarts <= bound && restarts >= bound - 1, "{restarts} restarts, bound {bound}");
    }

    #[test]
    fn frame_message_layout() {
        let display = Display::default();
        let frame = Frame {
            number: 7,
            width: 4,
            height: 2,
            rgb: Arc::new(vec![0; 24]),
            intensity: Arc::new(vec![]),
            composite_time: Duration::ZERO,
            update: Default::default(),
            k: Arc::new(vec![Vec3::new(1.0, 2.0, 3.0), Vec3::splat(0.5)]),
            buffers: Arc::new(vec![]),
            display,
            preview: false,
            bodies: None,
            haze_density: None,
        };
        let m = encode_frame(&frame);
        assert_eq!(m.len(), 40 + 2 * 16);
        assert_eq!((m[0], u32_at(&m, 4).unwrap(), u64_at(&m, 8).unwrap()), (MSG_FRAME, 2, 7));
        assert_eq!(f32::from_bits(u32_at(&m, 16).unwrap()), display.exposure);
        assert_eq!(f32::from_bits(u32_at(&m, 28).unwrap()), display.white_balance.z);
        assert_eq!([u32_at(&m, 32).unwrap(), u32_at(&m, 36).unwrap()], [0, 0], "no roll-off: clip");
        let f = |i: usize| f32::from_bits(u32_at(&m, 40 + 4 * i).unwrap());
        assert_eq!([f(0), f(1), f(2), f(3), f(4)], [1.0, 2.0, 3.0, 1.0, 0.5]);
        let h = encode_hello(&frame, Mode::Pictures);
        assert_eq!((h.len(), h[0], h[1], h[2], u32_at(&h, 4).unwrap()), (44, MSG_HELLO, VERSION, 1, 4));
        let rolled = Frame { display: display.with_rolloff(Some(Default::default())), ..frame };
        let m = encode_frame(&rolled);
        let f = |i: usize| f32::from_bits(u32_at(&m, 32 + 4 * i).unwrap());
        assert_eq!([f(0), f(1)], crate::render::display::HighlightRolloff::default().uniforms());
    }
}
