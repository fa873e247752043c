//! The live preview over HTTP (axum), read-only: nothing here changes the show.
//!
//! * `/`: a page with the live picture (the browser fetches the next frame
//!   as soon as the previous one has loaded, so the rate follows what the
//!   network allows) and, beside it, each light's name, DMX values, build
//!   state and last build time.
//! * `/api/status`: the same as JSON, plus frame rate and input counters.
//! * `/api/frame.png`: a snapshot of the latest frame.

use crate::live::clock::Frame;
use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
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
}

/// The preview's routes.
pub fn router(state: ServeState) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/api/status", get(status))
        .route("/api/frame.png", get(frame_png))
        .with_state(state)
}

async fn index() -> Html<&'static str> {
    Html(include_str!("preview.html"))
}

async fn status(State(s): State<ServeState>) -> Response {
    let frame = s.frames.borrow().clone();
    let mut v = (s.status)();
    if let Some(obj) = v.as_object_mut() {
        obj.insert("frame".into(), frame.number.into());
        obj.insert("width".into(), frame.width.into());
        obj.insert("height".into(), frame.height.into());
        obj.insert("composite_ms".into(), (frame.composite_time.as_secs_f64() * 1e3).into());
    }
    axum::Json(v).into_response()
}

async fn frame_png(State(s): State<ServeState>) -> Response {
    let frame = s.frames.borrow().clone();
    // PNG encoding is CPU work: keep it off the async workers.
    let encoded = tokio::task::spawn_blocking(move || encode_png(&frame)).await;
    match encoded {
        Ok(Ok(png)) => {
            ([(header::CONTENT_TYPE, "image/png"), (header::CACHE_CONTROL, "no-store")], png).into_response()
        }
        Ok(Err(e)) => (StatusCode::INTERNAL_SERVER_ERROR, format!("encoding the frame failed: {e}")).into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, format!("encoder task failed: {e}")).into_response(),
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
