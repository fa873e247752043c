//! Fixture bodies (issue 14 item 5): what a moving body costs the server
//! and the browser stream. The 44 moving heads of `tests/replays/chase-44.toml`
//! (estimated body boxes: a TOML patch has no GDTF model) follow the chase's
//! pan/tilt formula ([`super::chase::chase_pan_tilt`]) frame by frame at
//! 60 Hz, decoded through [`crate::live::Show`] as the daemon does, and
//! [`LiveBodies::apply`] draws them over a fixed composite: the redraw of
//! the moved bodies' old and new rectangles, the stream tiles, and the
//! overlay written over a copy of the composite. Rows: none, one and all 44
//! heads moving, and a dimmer-only change (every head's dimmer steps each
//! frame: the lens glow is re-shaded, no body moves, no body byte is sent).
//!
//! Bytes per frame: the body-tile message ([`crate::serve::stream::encode_bodies`])
//! of the tiles whose revision changed since the previous frame: what one
//! viewer that keeps up receives. No light buffer is touched by any of it
//! (bodies are not in the scene the lights are traced against). Run with
//! `footlight bench --bodies-only`.

use super::chase::{HEADS, chase_pan_tilt};
use crate::fixture::Universes;
use crate::live::bodies::LiveBodies;
use crate::live::{Decode, Show};
use crate::output::BodyTiles;
use crate::render::Display;
use crate::render::bodies::body_models;
use crate::scene::{Camera, Scene};
use std::sync::Arc;
use std::time::Instant;

/// One scenario's per-frame costs.
#[derive(Clone, Debug)]
pub struct BodiesRow {
    /// What moves.
    pub name: String,
    /// Bodies whose pose changes every frame.
    pub moving: usize,
    /// Frames measured.
    pub frames: usize,
    /// Server: [`LiveBodies::apply`] per frame, ms (mean, standard deviation).
    pub apply_ms: (f64, f64),
    /// Pixels ray-tested per frame (old and new rectangles of the moved bodies).
    pub pixels_tested: f64,
    /// Stream: body tiles changed per frame.
    pub tiles: f64,
    /// Stream: body-message bytes per frame (0 when no tile changed).
    pub bytes: f64,
    /// Stream: encoding the body message, ms per frame (mean, standard deviation).
    pub encode_ms: (f64, f64),
}

/// What the bodies section measured.
#[derive(Clone, Debug)]
pub struct BodiesReport {
    /// Picture size.
    pub size: (u32, u32),
    /// Bodies in the rig.
    pub bodies: usize,
    /// Bodies whose screen rectangle lies (partly) inside the picture at the start.
    pub visible: usize,
    /// Casting the whole layer (first frame, every camera change), ms.
    pub layer_build_ms: f64,
    /// The scenarios.
    pub rows: Vec<BodiesRow>,
}

/// A scenario: its name, which heads move, whether every dimmer steps each frame.
type Scenario = (&'static str, Box<dyn Fn(usize) -> bool>, bool);

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (mean, var.sqrt())
}

/// The two chase universes at frame time `t`: heads in `moving` follow the
/// chase, the rest stay at its t = 0 pose; every dimmer at `dimmer`.
fn universes(moving: &dyn Fn(usize) -> bool, t: f64, dimmer: u8) -> Universes {
    let mut u = Universes::new();
    for universe in 1..=2u16 {
        for k in 0..HEADS / 2 {
            let head = usize::from(universe - 1) * (HEADS / 2) + k;
            let (pan, tilt) = chase_pan_tilt(head, if moving(head) { t } else { 0.0 });
            let at = (k * 16) as u16;
            let [p0, p1] = pan.to_be_bytes();
            let [t0, t1] = tilt.to_be_bytes();
            for (o, v) in [(1, p0), (2, p1), (3, t0), (4, t1), (8, 64), (11, 255), (12, dimmer)] {
                u.set_slot(universe, at + o, v);
            }
        }
    }
    u
}

/// Measures `frames` frames per scenario at `(w, h)` seen from `camera`.
pub fn run(scene: &Arc<Scene>, camera: Camera, (w, h): (u32, u32), frames: usize) -> Result<BodiesReport, String> {
    let path = crate::bundled::find("tests/replays/chase-44.toml").map_err(|e| e.to_string())?;
    let patch = crate::Patch::load(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let show = Show::new(patch).map_err(|e| e.to_string())?;
    let names: Vec<String> = show.patch().fixtures.iter().map(|f| f.name.clone()).collect();
    let display = Display::default();
    let composite = Arc::new(vec![0u8; (w * h * 3) as usize]);
    let still = |_: usize| false;
    let mut rows = Vec::new();
    let mut build = None;
    let scenarios: [Scenario; 4] = [
        ("none moving", Box::new(still), false),
        ("dimmer only (every head, each frame)", Box::new(still), true),
        ("1 head moving", Box::new(|h| h == 0), false),
        ("44 heads moving", Box::new(|_| true), false),
    ];
    for (name, moving, dimmer_steps) in scenarios {
        let (models, _) = body_models(&path, &names, &show.fixture_ids());
        let count = models.len();
        let mut bodies = LiveBodies::new(models, scene.clone());
        let inputs = show.decode(&universes(&*moving, 0.0, 255));
        let t = Instant::now();
        bodies.apply(&camera, 1, w, h, &inputs, composite.clone(), &display);
        let build_ms = t.elapsed().as_secs_f64() * 1e3;
        let visible = (0..count).filter(|&i| bodies.rect(i).is_some_and(|r| r.0 < r.2 && r.1 < r.3)).count();
        build.get_or_insert((build_ms, count, visible));
        let mut last: Arc<BodyTiles> = bodies.tiles().ok_or("no body tiles after the first frame")?;
        let (mut apply, mut encode) = (Vec::new(), Vec::new());
        let (mut tested, mut tiles, mut bytes) = (0u64, 0usize, 0usize);
        for f in 1..=frames {
            let dimmer = if dimmer_steps { 255 - (f % 200) as u8 } else { 255 };
            let inputs = show.decode(&universes(&*moving, f as f64 / 60.0, dimmer));
            let t = Instant::now();
            let (_, update) = bodies.apply(&camera, 1, w, h, &inputs, composite.clone(), &display);
            apply.push(t.elapsed().as_secs_f64() * 1e3);
            tested += update.pixels_tested;
            let now = bodies.tiles().ok_or("no body tiles")?;
            let t = Instant::now();
            let which: Vec<usize> =
                (0..now.tiles.len()).filter(|&i| now.tiles[i].revision != last.tiles[i].revision).collect();
            if !which.is_empty() {
                bytes += crate::serve::stream::encode_bodies(&now, &which).len();
            }
            encode.push(t.elapsed().as_secs_f64() * 1e3);
            tiles += which.len();
            last = now;
        }
        let n = frames.max(1) as f64;
        rows.push(BodiesRow {
            name: name.to_string(),
            moving: (0..count).filter(|&i| moving(i)).count(),
            frames,
            apply_ms: mean_sd(&apply),
            pixels_tested: tested as f64 / n,
            tiles: tiles as f64 / n,
            bytes: bytes as f64 / n,
            encode_ms: mean_sd(&encode),
        });
    }
    let (layer_build_ms, bodies, visible) = build.unwrap_or((0.0, 0, 0));
    Ok(BodiesReport { size: (w, h), bodies, visible, layer_build_ms, rows })
}

impl BodiesReport {
    /// The report as Markdown.
    pub fn markdown(&self) -> String {
        let (w, h) = self.size;
        let mut s = format!(
            "## Fixture bodies (issue 14 item 5)\n\n{} bodies (tests/replays/chase-44.toml, estimated boxes), {} with \
             a screen rectangle in the picture, {w}×{h}; casting the whole layer (first frame, camera change): {:.1} ms. Per frame at 60 Hz, \
             mean ± sd over the frames; no light buffer is rebuilt in any row.\n\n\
             | scenario | bodies moving | server: LiveBodies::apply ms | pixels ray-tested | stream: tiles | stream: bytes/frame | stream: encode ms |\n\
             |---|---:|---:|---:|---:|---:|---:|\n",
            self.bodies, self.visible, self.layer_build_ms
        );
        for r in &self.rows {
            s += &format!(
                "| {} | {} | {:.2} ± {:.2} | {:.0} | {:.1} | {:.0} | {:.3} ± {:.3} |\n",
                r.name,
                r.moving,
                r.apply_ms.0,
                r.apply_ms.1,
                r.pixels_tested,
                r.tiles,
                r.bytes,
                r.encode_ms.0,
                r.encode_ms.1
            );
        }
        s
    }
}
