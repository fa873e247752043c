//! The live preview over HTTP: nothing here changes the show; the camera
//! writes of [`control`] change only what the preview looks from.
//!
//! * `/`: a page with the live picture (the browser fetches the next frame
//!   as soon as the previous one has loaded, so the rate follows what the
//!   network allows) and, beside it, each light's name, DMX values, build
//!   state and last build time.
//! * `/api/status`: the same as JSON, plus frame rate and input counters.
//! * `/api/frame.png`: the latest frame as PNG.
//! * `/api/stream`: the browser stream (WebSocket, [`stream`], issue 17):
//!   per-light buffers once, then k_i per frame; the page composites eq. 5
//!   with WebGL2 (`/stream.js`, shaders in `shaders/`).
//! * `/api/camera`, `/api/views`, `/api/display`, `/camera.js`: the camera and display controls
//!   ([`control`]); the only writes, allowed from loopback or with the token.
//!
//! Frames come from the frame clock's `watch` channel ([`ServeState::frames`]);
//! each published picture is PNG-encoded at most once, on one blocking
//! thread, and the bytes are shared by every client ([`png`]). The accept
//! loop ([`server`]) is ours, not `axum::serve`: it bounds the time a client
//! may take to send its request head, closes connections on which nothing
//! moves, caps the number of open connections, checks the Host header
//! against DNS rebinding, and on shutdown closes every connection after a
//! short grace period, so no client can hold the daemon open. [`load`] is a
//! bounded loopback client for the tests and `footlight bench`.
//!
//! Routes live in [`router`]; a later WebSocket route (the browser stream)
//! belongs there too: connections are served with upgrades enabled.

pub mod control;
pub mod load;
pub mod png;
pub mod server;
pub mod stream;

pub use server::{HostPolicy, LISTEN_BACKLOG, ServeConfig, ServeError, ServeStats, Server, StatsSnapshot, bind, serve};

use crate::live::clock::Frame;
use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use std::sync::Arc;
use tokio::sync::watch;

/// Extra status fields supplied by the daemon (input counters, rates).
pub type StatusFn = Arc<dyn Fn() -> serde_json::Value + Send + Sync>;

/// Shared state of the HTTP handlers.
#[derive(Clone)]
pub struct ServeState {
    /// Latest published frame.
    pub frames: watch::Receiver<Arc<Frame>>,
    /// Daemon-wide status fields merged into `/api/status`.
    pub status: StatusFn,
    /// The camera control (`None`: the camera routes answer 404).
    pub views: Option<Arc<crate::live::views::Views>>,
    /// The write token non-loopback clients must send ([`control`]).
    pub write_token: Option<String>,
}

/// What the handlers share: the daemon's state, the PNG cache and the counters.
#[derive(Clone)]
struct App {
    state: ServeState,
    png: Arc<png::PngCache>,
    stream: stream::StreamState,
}

/// The preview's routes, with their own counters (no Host check, no
/// timeouts: [`serve`] adds those around it).
pub fn router(state: ServeState) -> Router {
    routes(state, Arc::new(ServeStats::default()))
}

/// The routes counting into `stats`.
fn routes(state: ServeState, stats: Arc<ServeStats>) -> Router {
    let png = Arc::new(png::PngCache::new(stats));
    let stream = stream::StreamState::new(state.frames.clone(), png.clone());
    let app = App { state, png, stream: stream.clone() };
    Router::new()
        .route("/", get(index))
        .route("/stream.js", get(stream_js))
        .route("/api/status", get(status))
        .route("/api/frame.png", get(frame_png))
        .route("/api/camera", post(control::post_camera))
        .route("/api/views", get(control::get_views).post(control::post_view))
        .route("/api/display", get(control::get_display).post(control::post_display))
        .route("/camera.js", get(control::camera_js))
        .with_state(app)
        .merge(Router::new().route("/api/stream", get(stream::handler)).with_state(stream))
}

/// The page's compositor module, with the GLSL of `shaders/` spliced in.
async fn stream_js() -> Response {
    static JS: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    let js = JS.get_or_init(|| {
        include_str!("stream.js")
            .replace(
                "/*VERTEX*/",
                &serde_json::to_string(include_str!("../../shaders/composite.vert")).unwrap_or_default(),
            )
            .replace(
                "/*FRAGMENT*/",
                &serde_json::to_string(include_str!("../../shaders/composite.frag")).unwrap_or_default(),
            )
    });
    ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], js.as_str()).into_response()
}

async fn index() -> Html<&'static str> {
    Html(include_str!("preview.html"))
}

async fn status(State(app): State<App>) -> Response {
    let frame = app.state.frames.borrow().clone();
    let mut v = (app.state.status)();
    if let Some(obj) = v.as_object_mut() {
        obj.insert("frame".into(), frame.number.into());
        obj.insert("width".into(), frame.width.into());
        obj.insert("height".into(), frame.height.into());
        obj.insert("composite_ms".into(), (frame.composite_time.as_secs_f64() * 1e3).into());
        obj.insert("stream".into(), app.stream.stats.json());
    }
    axum::Json(v).into_response()
}

async fn frame_png(State(app): State<App>) -> Response {
    let frame = app.state.frames.borrow().clone();
    match app.png.get(frame).await {
        Ok(png) => (
            [
                (header::CONTENT_TYPE, "image/png".to_string()),
                (header::CACHE_CONTROL, "no-store".to_string()),
                (header::HeaderName::from_static(png::FRAME_HEADER), png.number.to_string()),
            ],
            png.bytes,
        )
            .into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, format!("encoding the frame failed: {e}")).into_response(),
    }
}

/// Encodes a frame as PNG (fast compression: it is a live preview).
pub fn encode_png(frame: &Frame) -> Result<Vec<u8>, image::ImageError> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    );
    enc.write_image(&frame.rgb, frame.width, frame.height, image::ExtendedColorType::Rgb8)?;
    Ok(out)
}
