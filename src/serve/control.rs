//! Camera writes over HTTP (issue 16): the only routes that change the
//! daemon's state. Everything else the preview serves is read-only.
//!
//! * `GET /api/views`: the named views and the camera's status.
//! * `POST /api/camera`: `{"position": [x, y, z], "target": [x, y, z], "fov_y": deg}`
//!   or `{"view": "name"}` moves the camera (204); a body with both a view
//!   and pose fields is refused (400), not read as one of them.
//! * `POST /api/views`: `{"name": "…"}` saves the current camera under that
//!   name, in memory only (201 with the view).
//! * `GET /api/display`: the display settings of the latest frame.
//! * `POST /api/display`: `{"white_lux": 500, "white_balance": "auto" | "5600K",
//!   "rolloff": "on" | "off" | 8}` (each optional) changes exposure, white
//!   balance and highlight roll-off from the next frame on, in every
//!   compositor (uniforms, no rebuild); answers 200 with the new settings.
//!
//! **Who may write** ([`write_allowed`]): a client on a loopback address
//! always may. Any other client must send the token the daemon prints at
//! start (header [`TOKEN_HEADER`]); without it the answer is 403. The
//! token exists only when `--http` binds a non-loopback address (on
//! loopback no other machine can connect). The client's address comes from
//! the accepted socket ([`Peer`], set by the server), never from a header.
//! Bodies must be `application/json` (415 otherwise): a cross-site page in
//! the operator's browser cannot send that without a CORS preflight, which
//! this server never grants.

use super::App;
use crate::output::{CameraControl, Pose, WhiteState};
use axum::body::Body;
use axum::extract::{Request, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;

/// The header carrying the write token.
pub const TOKEN_HEADER: &str = "x-footlight-token";

/// Largest accepted write body (a pose or a name is a few hundred bytes).
const MAX_BODY: usize = 4096;

/// The client's socket address, inserted into every request by the
/// server's accept loop ([`super::Server`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Peer(pub SocketAddr);

/// True for a loopback client (IPv4, IPv6 or IPv4-mapped IPv6).
fn is_loopback(ip: IpAddr) -> bool {
    match ip {
        IpAddr::V4(v4) => v4.is_loopback(),
        IpAddr::V6(v6) => v6.is_loopback() || v6.to_ipv4_mapped().is_some_and(|v4| v4.is_loopback()),
    }
}

/// The write policy: loopback clients may write; any other client (or one
/// whose address is unknown) needs `presented` equal to the daemon's
/// `token`; without a token configured only loopback may write.
pub fn write_allowed(peer: Option<IpAddr>, token: Option<&str>, presented: Option<&str>) -> bool {
    if peer.is_some_and(is_loopback) {
        return true;
    }
    match (token, presented) {
        (Some(t), Some(p)) => constant_time_eq(t.as_bytes(), p.as_bytes()),
        _ => false,
    }
}

/// Compares without an early exit on the first differing byte (the time
/// does not tell a remote client how much of its guess was right).
/// Hand-written: four lines, not worth a dependency.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// A fresh write token: 128 bits from the standard library's per-process
/// random hash keys (seeded from the OS; `rand` is built here without its OS
/// source), as 32 hex digits.
pub fn new_token() -> String {
    use std::hash::{BuildHasher, Hasher};
    let part = |salt: u64| {
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u64(salt);
        h.write_u128(std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos()));
        h.finish()
    };
    format!("{:016x}{:016x}", part(1), part(2))
}

fn error(status: StatusCode, message: impl Into<String>) -> Response {
    (status, [(header::CONTENT_TYPE, "text/plain; charset=utf-8")], message.into()).into_response()
}

/// Checks the write policy and reads a small JSON body.
async fn authorized_json<T: for<'de> Deserialize<'de>>(
    app: &App,
    req: Request,
) -> Result<(Arc<dyn CameraControl>, T), Response> {
    let Some(views) = app.state.views.clone() else {
        return Err(error(StatusCode::NOT_FOUND, "this server has no camera control"));
    };
    let peer = req.extensions().get::<Peer>().map(|p| p.0.ip());
    let presented = req.headers().get(TOKEN_HEADER).and_then(|v| v.to_str().ok());
    if !write_allowed(peer, app.state.write_token.as_deref(), presented) {
        tracing::info!("preview: camera write from {peer:?} refused (no valid token)");
        return Err(error(
            StatusCode::FORBIDDEN,
            "camera writes from another machine need the token footlight printed at start (header x-footlight-token)",
        ));
    }
    // JSON only: a cross-site page can send a form or text/plain POST
    // without asking, but a JSON one needs a CORS preflight this server
    // never grants, so another site cannot move the camera from a browser.
    let json = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.trim_start().to_ascii_lowercase().starts_with("application/json"));
    if !json {
        return Err(error(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "camera writes are JSON (content-type: application/json)",
        ));
    }
    let body = axum::body::to_bytes(req.into_body(), MAX_BODY)
        .await
        .map_err(|e| error(StatusCode::PAYLOAD_TOO_LARGE, format!("request body: {e}")))?;
    let value = serde_json::from_slice(&body).map_err(|e| error(StatusCode::BAD_REQUEST, format!("JSON body: {e}")))?;
    Ok((views, value))
}

/// A camera write: a pose or a named view.
#[derive(Debug, PartialEq)]
enum CameraWrite {
    Pose(Pose),
    Named { view: String },
}

/// The fields of a [`Pose`] in JSON.
const POSE_FIELDS: [&str; 4] = ["position", "target", "fov_y", "up"];

impl CameraWrite {
    /// Reads a camera write from its JSON: `{"view": "name"}` or a pose
    /// (`position`, `target`, `fov_y`, optional `up`). A body naming a view
    /// and pose fields is an error naming both (which one was meant cannot
    /// be told), as is anything else that is neither.
    fn from_json(value: serde_json::Value) -> Result<Self, String> {
        let Some(fields) = value.as_object() else {
            return Err(format!("a camera write is a JSON object, not {value}"));
        };
        if fields.contains_key("view") {
            let pose: Vec<&str> = POSE_FIELDS.into_iter().filter(|f| fields.contains_key(*f)).collect();
            if !pose.is_empty() {
                return Err(format!(
                    "a camera write names a view or gives a pose, not both: got \"view\" and {}",
                    pose.iter().map(|f| format!("{f:?}")).collect::<Vec<_>>().join(", ")
                ));
            }
            #[derive(Deserialize)]
            #[serde(deny_unknown_fields)]
            struct Named {
                view: String,
            }
            let named: Named = serde_json::from_value(value).map_err(|e| format!("camera view: {e}"))?;
            return Ok(Self::Named { view: named.view });
        }
        serde_json::from_value(value).map(Self::Pose).map_err(|e| format!("camera pose: {e}"))
    }
}

/// `POST /api/camera`.
pub(super) async fn post_camera(State(app): State<App>, req: Request) -> Response {
    let (views, write) = match authorized_json::<serde_json::Value>(&app, req).await {
        Ok(x) => x,
        Err(r) => return r,
    };
    let write = match CameraWrite::from_json(write) {
        Ok(w) => w,
        Err(e) => return error(StatusCode::BAD_REQUEST, e),
    };
    let result = match write {
        CameraWrite::Pose(pose) => views.move_to_pose(pose),
        CameraWrite::Named { view } => views.go_to(&view),
    };
    match result {
        Ok(()) => StatusCode::NO_CONTENT.into_response(),
        Err(e) => error(StatusCode::BAD_REQUEST, e),
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SaveView {
    name: String,
}

/// `POST /api/views`.
pub(super) async fn post_view(State(app): State<App>, req: Request) -> Response {
    let (views, save) = match authorized_json::<SaveView>(&app, req).await {
        Ok(x) => x,
        Err(r) => return r,
    };
    match views.save(&save.name) {
        Ok(v) => (StatusCode::CREATED, axum::Json(v)).into_response(),
        Err(e) => error(StatusCode::BAD_REQUEST, e),
    }
}

/// A display write: each field optional, the rest kept.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DisplayWrite {
    /// Illuminance on a white Lambert surface shown as white (lx).
    white_lux: Option<f32>,
    /// `auto` (the rig's own white at full), `none`, `tungsten` or a
    /// colour temperature (`5600K`).
    white_balance: Option<String>,
    /// `on`, `off`, or the level shown as white (a number over 1).
    rolloff: Option<serde_json::Value>,
}

/// The display settings as JSON (what `GET /api/display` answers): the
/// white balance as its gains, the setting in force (`auto`, `tungsten`…),
/// what it makes neutral, and the rig's own white (what `auto` gives).
fn display_json(d: &crate::render::Display, white: Option<&WhiteState>) -> serde_json::Value {
    let rig = white.and_then(|w| w.rig.as_ref()).map(|r| {
        serde_json::json!({ "xy": r.xy.to_array(), "cct_k": r.cct_k, "lights": r.lights, "tungsten": r.tungsten,
            "note": r.describe() })
    });
    serde_json::json!({
        "exposure": d.exposure,
        "white_lux": std::f32::consts::PI / d.exposure,
        "white_balance": d.white_balance.to_array(),
        "white_balance_setting": white.map(|w| w.choice.setting.clone()),
        "white_balance_note": white.map(|w| w.choice.note.clone()),
        "rig_white": rig,
        "rolloff": d.rolloff.map(|r| serde_json::json!({ "knee": r.knee, "white": r.white })),
    })
}

/// `GET /api/display`.
pub(super) async fn get_display(State(app): State<App>) -> Response {
    let display = app.state.frames.borrow().display;
    let white = app.state.views.as_ref().map(|v| v.white());
    axum::Json(display_json(&display, white.as_ref())).into_response()
}

/// `POST /api/display`.
pub(super) async fn post_display(State(app): State<App>, req: Request) -> Response {
    use crate::render::display::{parse_rolloff, white_balance_for};
    let (views, write) = match authorized_json::<DisplayWrite>(&app, req).await {
        Ok(x) => x,
        Err(r) => return r,
    };
    let mut d = app.state.frames.borrow().display;
    if let Some(lux) = write.white_lux {
        if !(lux.is_finite() && lux > 0.0 && lux <= 1e7) {
            return error(StatusCode::BAD_REQUEST, format!("white_lux {lux}: must be above 0 and at most 1e7 lx"));
        }
        d.exposure = std::f32::consts::PI / lux;
    }
    let mut white = views.white();
    if let Some(wb) = &write.white_balance {
        match white_balance_for(wb, white.rig.as_ref()) {
            Ok(c) => {
                d.white_balance = c.gains;
                white.choice = c;
            }
            Err(e) => return error(StatusCode::BAD_REQUEST, format!("white_balance {e}")),
        }
    }
    if let Some(r) = &write.rolloff {
        let text = match r {
            serde_json::Value::String(s) => s.clone(),
            serde_json::Value::Number(n) => n.to_string(),
            other => {
                return error(
                    StatusCode::BAD_REQUEST,
                    format!("rolloff {other}: expected \"on\", \"off\" or a number"),
                );
            }
        };
        match parse_rolloff(&text) {
            Ok(r) => d.rolloff = r,
            Err(e) => return error(StatusCode::BAD_REQUEST, format!("rolloff {e}")),
        }
    }
    views.set_display(d);
    views.set_white(white.choice.clone(), white.rig.clone());
    axum::Json(display_json(&d, Some(&white))).into_response()
}

/// `GET /api/views`.
pub(super) async fn get_views(State(app): State<App>) -> Response {
    match &app.state.views {
        Some(views) => {
            axum::Json(serde_json::json!({ "views": views.list(), "camera": views.status() })).into_response()
        }
        None => error(StatusCode::NOT_FOUND, "this server has no camera control"),
    }
}

/// `GET /camera.js`: the page's camera controls (a separate script module).
pub(super) async fn camera_js() -> Response {
    Response::builder()
        .header(header::CONTENT_TYPE, "text/javascript; charset=utf-8")
        .header(header::CACHE_CONTROL, "no-cache")
        .body(Body::from(include_str!("camera.js")))
        .unwrap_or_else(|_| StatusCode::INTERNAL_SERVER_ERROR.into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_writes_need_no_token_and_others_need_the_right_one() {
        let lo4: IpAddr = "127.0.0.1".parse().unwrap();
        let lo6: IpAddr = "::1".parse().unwrap();
        let mapped: IpAddr = "::ffff:127.0.0.1".parse().unwrap();
        let lan: IpAddr = "192.168.1.20".parse().unwrap();
        for ip in [lo4, lo6, mapped] {
            assert!(write_allowed(Some(ip), None, None));
            assert!(write_allowed(Some(ip), Some("t0k3n"), None));
        }
        assert!(!write_allowed(Some(lan), None, None));
        assert!(!write_allowed(Some(lan), None, Some("anything")));
        assert!(!write_allowed(Some(lan), Some("t0k3n"), None));
        assert!(!write_allowed(Some(lan), Some("t0k3n"), Some("t0k3m")));
        assert!(!write_allowed(Some(lan), Some("t0k3n"), Some("t0k3n ")));
        assert!(write_allowed(Some(lan), Some("t0k3n"), Some("t0k3n")));
        // Unknown peer: treated as remote.
        assert!(!write_allowed(None, Some("t0k3n"), None));
        assert!(write_allowed(None, Some("t0k3n"), Some("t0k3n")));
    }

    /// Issue 35: a write with both a view and a pose was read as the view.
    #[test]
    fn a_camera_write_is_a_view_or_a_pose_never_both() {
        let read = |s: &str| CameraWrite::from_json(serde_json::from_str(s).unwrap());
        assert_eq!(read(r#"{"view": "front"}"#), Ok(CameraWrite::Named { view: "front".into() }));
        let pose = read(r#"{"position": [0, 1, 5], "target": [0, 1, 0], "fov_y": 40}"#).unwrap();
        assert!(matches!(pose, CameraWrite::Pose(p) if p.fov_y == 40.0 && p.up.is_none()), "{pose:?}");
        let both = read(r#"{"view": "front", "position": [0, 1, 5], "target": [0, 1, 0], "fov_y": 40}"#);
        let e = both.expect_err("view and pose together are refused");
        assert!(e.contains("\"view\"") && e.contains("\"position\"") && e.contains("\"fov_y\""), "{e}");
        let e = read(r#"{"view": "front", "up": [0, 1, 0]}"#).unwrap_err();
        assert!(e.contains("\"view\"") && e.contains("\"up\""), "{e}");
        for bad in [r#"{"view": "front", "zoom": 2}"#, r#"{"position": [0, 1, 5]}"#, r#"{}"#, "[1]", r#"{"view": 3}"#] {
            assert!(read(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn tokens_are_32_hex_digits_and_differ() {
        let (a, b) = (new_token(), new_token());
        assert_eq!(a.len(), 32);
        assert!(a.chars().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
    }
}
