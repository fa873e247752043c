//! The live preview over HTTP: nothing here changes the show; the camera
//! writes of [`control`] change only what the preview looks from.
//!
//! * `/`: a page with the live picture (the browser fetches the next frame
//!   as soon as the previous one has loaded, so the rate follows what the
//!   network allows) and, beside it, each light's name, DMX values, build
//!   state and last build time.
//! * `/api/status`: the same as JSON: the daemon's typed
//!   [`DaemonStatus`] with this server's frame and stream counters filled in
//!   ([`DaemonStatus::serving`]).
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

use crate::output::{CameraControl, DaemonStatus, Frame, StatusFn};
use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use std::sync::Arc;
use tokio::sync::watch;

/// Shared state of the HTTP handlers.
#[derive(Clone)]
pub struct ServeState {
    /// Latest published frame.
    pub frames: watch::Receiver<Arc<Frame>>,
    /// The daemon's typed status, built per `/api/status` request (a
    /// server without a daemon: `Arc::new(DaemonStatus::default)`).
    pub status: StatusFn,
    /// The camera control (`None`: the camera routes answer 404).
    pub views: Option<Arc<dyn CameraControl>>,
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

/// `GET /api/status`: the daemon's [`DaemonStatus`] with the served frame's
/// figures and the stream's counters, serialised as it is (docs/live.md).
async fn status(State(app): State<App>) -> Response {
    let frame = app.state.frames.borrow().clone();
    let status: DaemonStatus = (app.state.status)().serving(&frame, app.stream.stats.snapshot());
    axum::Json(status).into_response()
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

#[cfg(test)]
mod tests {
    use super::*;
    use axum::body::Body;
    use axum::http::Request;
    use std::collections::BTreeSet;
    use tower::ServiceExt;

    fn frame() -> Frame {
        Frame {
            number: 42,
            width: 8,
            height: 4,
            rgb: Arc::new(vec![0; 8 * 4 * 3]),
            intensity: Arc::new(Vec::new()),
            composite_time: std::time::Duration::from_millis(3),
            update: Default::default(),
            k: Arc::new(Vec::new()),
            buffers: Arc::new(Vec::new()),
            haze_density: None,
            display: crate::render::Display::default(),
            preview: false,
            bodies: None,
        }
    }

    /// The top-level fields docs/live.md lists for `/api/status`.
    fn documented_fields() -> BTreeSet<String> {
        let doc = include_str!("../../docs/live.md");
        let section = doc.split("## `/api/status`").nth(1).expect("docs/live.md has the /api/status section");
        let table = section.split("\n## ").next().unwrap_or_default();
        table
            .lines()
            .filter_map(|l| l.strip_prefix("| `"))
            .flat_map(|l| {
                let cell = l.split(" |").next().unwrap_or_default();
                format!("`{cell}")
                    .split('`')
                    .skip(1)
                    .step_by(2)
                    .map(|name| name.split(['.', '[']).next().unwrap_or_default().to_string())
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    /// Issue 33: `/api/status` is the daemon's typed `DaemonStatus` as it is;
    /// what the server used to patch into the JSON (the served frame's
    /// number, size and composite time, the stream's counters) comes
    /// through `DaemonStatus::serving`, and every field is documented.
    #[tokio::test]
    async fn status_serialises_the_typed_status_with_the_served_frame_and_stream_counters() {
        let (_tx, frames) = watch::channel(Arc::new(frame()));
        let daemon = || DaemonStatus { warnings: vec!["patch universe 2: stale".into()], ..DaemonStatus::default() };
        let state = ServeState { frames, status: Arc::new(daemon), views: None, write_token: None };
        let response =
            router(state).oneshot(Request::builder().uri("/api/status").body(Body::empty()).unwrap()).await.unwrap();
        assert_eq!(response.status(), StatusCode::OK);
        let body = axum::body::to_bytes(response.into_body(), usize::MAX).await.unwrap();
        let json: serde_json::Value = serde_json::from_slice(&body).unwrap();
        // The served frame's figures, not the daemon's zeros.
        assert_eq!(
            (json["frame"].as_u64(), json["width"].as_u64(), json["height"].as_u64()),
            (Some(42), Some(8), Some(4))
        );
        assert_eq!(json["composite_ms"].as_f64(), Some(3.0));
        // The stream's counters, every one of them, typed.
        let stream = json["stream"].as_object().expect("stream is an object");
        let counters = serde_json::to_value(crate::output::StreamCounters::default()).unwrap();
        let keys = |o: &serde_json::Map<String, serde_json::Value>| o.keys().cloned().collect::<BTreeSet<_>>();
        assert_eq!(keys(stream), keys(counters.as_object().unwrap()));
        assert!(stream.contains_key("open") && stream.contains_key("max_pending_per_client"), "{stream:?}");
        assert!(stream.values().all(|v| v.as_u64() == Some(0)), "{stream:?}");
        // The daemon's own fields pass through as they are.
        assert_eq!(json["warnings"], serde_json::json!(["patch universe 2: stale"]));
        assert_eq!(json["version"], env!("CARGO_PKG_VERSION"));
        // docs/live.md lists exactly the fields the JSON has.
        assert_eq!(keys(json.as_object().unwrap()), documented_fields());
        // The daemon's own status (DaemonHandle::status) has no stream part.
        assert!(serde_json::to_value(daemon()).unwrap().get("stream").is_none());
    }
}
