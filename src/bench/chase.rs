//! "Moving lights keep up" (issue 18), measured through the real daemon:
//! the 44 moving heads of `tests/replays/chase-44.toml` follow a smooth
//! pan/tilt chase sent as Art-Net over loopback, together with 62 more
//! universes of filler, 64 universes at 44 Hz in all (issue 11's load).
//!
//! Reported: each head's direct-light update rate during the chase (median
//! and minimum; target ≥ 15 Hz each at 800×500 on 2 cores), the frame
//! clock's p99 frame interval and composite time under that load, the time
//! from the chase stopping to every head shown at its final position
//! (target < 0.5 s) and to every head converged, and the direct stage's
//! cost against the beam angle (target: roughly proportional to the
//! footprint).

use crate::live::{Daemon, DmxSource, Show};
use crate::render::footprint::{DirectQuality, primary_direct};
use crate::render::photon::PhotonSettings;
use crate::render::{RecursionLimits, Sampling, View};
use crate::scene::{Camera, Scene};
use serde::Serialize;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Heads in the chase patch.
pub const HEADS: usize = 44;
/// Universes sent (2 with the heads, 62 filler).
pub const UNIVERSES: u16 = 64;
/// DMX rate of every universe, Hz.
pub const DMX_HZ: f64 = 44.0;

/// What the chase measured.
#[derive(Clone, Debug, Serialize)]
pub struct ChaseReport {
    /// Picture size.
    pub width: u32,
    /// Picture size.
    pub height: u32,
    /// Chase duration, s.
    pub seconds: f64,
    /// Photons per light (0: direct light only).
    pub photons: usize,
    /// Direct-stage updates per second of each head, median.
    pub direct_hz_median: f64,
    /// … and of the slowest head (no head may starve).
    pub direct_hz_min: f64,
    /// Frame clock p99 frame interval during the chase, ms (60 Hz = 16.7).
    pub frame_interval_p99_ms: f64,
    /// Frames per second the clock reached.
    pub fps: f64,
    /// Composite time of the last frame of the chase, ms.
    pub composite_ms: f64,
    /// From the last DMX packet to every head's final position on screen, ms.
    pub final_position_ms: f64,
    /// From the last DMX packet to every head `ready`, ms (None: not within the limit).
    pub converged_ms: Option<f64>,
    /// Direct stage of one head against its beam angle.
    pub cost_vs_angle: Vec<AngleCost>,
}

/// The direct stage's cost for one beam angle.
#[derive(Clone, Debug, Serialize)]
pub struct AngleCost {
    /// Field angle, degrees.
    pub beam_deg: f32,
    /// Median time of a full-quality direct stage, ms.
    pub ms: f64,
    /// … at moving quality, ms.
    pub moving_ms: f64,
    /// Share of the frame's directly seen vertices evaluated.
    pub vertex_share: f64,
    /// Error of the moving-quality stage against the full one: relative
    /// RMS over the beam's pixels (√(Σ|m−f|²/Σ|f|²)).
    pub moving_rel_rms: f64,
}

/// One head's 16-bit pan and tilt at `t` seconds (the formula the recording
/// `tests/replays/chase-44.pcapng` was generated with, in
/// `crates/footlight-dmx/tests/replays.rs`).
pub fn chase_pan_tilt(head: usize, t: f64) -> (u16, u16) {
    use std::f64::consts::TAU;
    let phase = head as f64 * 0.3;
    let pan = 32768.0 + 6000.0 * (TAU * 0.25 * t + phase).sin();
    let tilt = 32768.0 + 3640.0 + 3000.0 * (TAU * 0.2 * t + phase).sin();
    (pan.round() as u16, tilt.round() as u16)
}

/// The slots of patch universe `u` (1-based) at `t`: heads 16 slots apart.
fn universe_slots(u: u16, t: f64) -> [u8; 512] {
    let mut s = [0u8; 512];
    if u > 2 {
        s.iter_mut().enumerate().for_each(|(i, v)| *v = (i as u8).wrapping_add((t * 10.0) as u8));
        return s;
    }
    for k in 0..HEADS / 2 {
        let (pan, tilt) = chase_pan_tilt(usize::from(u - 1) * (HEADS / 2) + k, t);
        let at = k * 16;
        s[at..at + 2].copy_from_slice(&pan.to_be_bytes());
        s[at + 2..at + 4].copy_from_slice(&tilt.to_be_bytes());
        s[at + 7] = 64;
        s[at + 10] = 255;
        s[at + 11] = 64;
    }
    s
}

/// Runs the chase for `seconds` at `width`×`height`.
pub fn run(
    scene: &Arc<Scene>,
    camera: Camera,
    (width, height): (u32, u32),
    seconds: f64,
    photons: usize,
) -> Result<ChaseReport, String> {
    let path = crate::bundled::find("tests/replays/chase-44.toml").map_err(|e| e.to_string())?;
    let patch = crate::Patch::load(&path).map_err(|e| e.to_string())?;
    let show = Arc::new(Show::new(patch).map_err(|e| e.to_string())?);
    let mut config = super::harness::config(width, height);
    config.tracer.build.photons =
        (photons > 0).then(|| PhotonSettings { stored: photons, ..PhotonSettings::default() });
    let cost_vs_angle = angle_costs(scene, camera, width, height);
    let rt = super::harness::runtime()?;
    let daemon = Daemon::new(scene.clone(), show, camera, config).input(DmxSource::Network {
        artnet: Some(footlight_dmx::artnet::ArtNetConfig {
            bind: "127.0.0.1:0".parse().map_err(|e| format!("{e}"))?,
            ..Default::default()
        }),
        sacn: None,
        usbpro: None,
    });
    let running = super::harness::Running::start(rt, daemon)?;
    let handle = running.handle.clone();
    let target = handle.dmx.and_then(|d| d.artnet).ok_or("no Art-Net socket")?;
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    // The chase: 64 universes at 44 Hz, paced by the clock, bounded in time.
    let start = Instant::now();
    let mut frame = 0u32;
    while start.elapsed().as_secs_f64() < seconds {
        let t = f64::from(frame) / DMX_HZ;
        for u in 1..=UNIVERSES {
            let packet =
                footlight_dmx::artnet::packet::build_dmx((frame % 255 + 1) as u8, 0, u - 1, &universe_slots(u, t));
            sock.send_to(&packet, target).map_err(|e| e.to_string())?;
        }
        frame += 1;
        let next = Duration::from_secs_f64(f64::from(frame) / DMX_HZ);
        if let Some(wait) = next.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
    }
    let sent_for = start.elapsed().as_secs_f64();
    let stopped = Instant::now();
    let during = (handle.status)();
    let mut rates: Vec<f64> =
        during.lights.iter().map(|l| l.build.as_ref().map_or(0.0, |b| b.direct_updates as f64 / sent_for)).collect();
    rates.sort_by(f64::total_cmp);
    // Every head at its final position: nothing waits any more.
    let final_position_ms = loop {
        let s = (handle.status)();
        let done = s.lights.iter().all(|l| l.build.as_ref().is_some_and(|b| b.pending_ms.is_none()));
        if done {
            break stopped.elapsed().as_secs_f64() * 1e3;
        }
        if stopped.elapsed() > Duration::from_secs(120) {
            break f64::NAN;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    let limit = Duration::from_secs(if photons > 0 { 180 } else { 60 });
    let converged_ms = loop {
        let s = (handle.status)();
        if s.lights.iter().all(|l| l.build.as_ref().is_some_and(|b| b.stage == crate::output::Stage::Ready)) {
            break Some(stopped.elapsed().as_secs_f64() * 1e3);
        }
        if stopped.elapsed() > limit {
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    running.stop()?;
    Ok(ChaseReport {
        width,
        height,
        seconds: sent_for,
        photons,
        direct_hz_median: rates.get(rates.len() / 2).copied().unwrap_or(0.0),
        direct_hz_min: rates.first().copied().unwrap_or(0.0),
        frame_interval_p99_ms: during.clock.frame_interval_p99_ms,
        fps: during.clock.fps,
        composite_ms: during.clock.composite_ms,
        final_position_ms,
        converged_ms,
        cost_vs_angle,
    })
}

/// The direct stage of a head over the stage centre at 5°, 18° and 40°.
fn angle_costs(scene: &Scene, camera: Camera, width: u32, height: u32) -> Vec<AngleCost> {
    let view = View::build(scene, camera, width, height, Sampling::Adaptive, RecursionLimits::default());
    let frame_vertices = view.shading.vertices().iter().filter(|v| v.depth == 0).count().max(1);
    let bounds = view.tile_bounds();
    [5.0f32, 18.0, 40.0]
        .into_iter()
        .map(|deg| {
            let beam = crate::Beam::Spot(crate::fixture::SpotBeam::from_beam_field(deg * 0.75, deg));
            let light = crate::Light::aimed(glam::Vec3::new(0.5, 6.5, -1.0), glam::Vec3::new(0.5, 0.0, 0.5), beam);
            let time = |quality| {
                let mut ms = Vec::new();
                let mut last = None;
                for _ in 0..15 {
                    let t = Instant::now();
                    let built = primary_direct(scene, &view, bounds, &light, quality);
                    ms.push(t.elapsed().as_secs_f64() * 1e3);
                    last = Some(built);
                }
                ms.sort_by(f64::total_cmp);
                (ms[ms.len() / 2], last)
            };
            let (full_ms, full) = time(DirectQuality::Full);
            let (moving_ms, moving) = time(DirectQuality::Moving);
            let (Some((full, stats)), Some((moving, _))) = (full, moving) else {
                return AngleCost {
                    beam_deg: deg,
                    ms: full_ms,
                    moving_ms,
                    vertex_share: 0.0,
                    moving_rel_rms: f64::NAN,
                };
            };
            let (f, m) = (full.to_dense(), moving.to_dense());
            let err: f64 = f.iter().zip(&m).map(|(a, b)| f64::from((*a - *b).length_squared())).sum();
            let norm: f64 = f.iter().map(|a| f64::from(a.length_squared())).sum();
            AngleCost {
                beam_deg: deg,
                ms: full_ms,
                moving_ms,
                vertex_share: stats.vertices as f64 / frame_vertices as f64,
                moving_rel_rms: if norm > 0.0 { (err / norm).sqrt() } else { 0.0 },
            }
        })
        .collect()
}

impl ChaseReport {
    /// Markdown section for report.md.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "\n## Moving lights keep up (issue 18)\n\n{HEADS} moving heads (18°) in a pan/tilt chase over Art-Net on loopback, \
             {UNIVERSES} universes at {DMX_HZ} Hz, {:.1} s, {}×{}, {} photons per light, through the daemon.\n\n\
             | measurement | value | target |\n|---|---:|---:|\n\
             | direct-light updates per head, median | {:.1} Hz | ≥ 15 Hz |\n\
             | direct-light updates, slowest head | {:.1} Hz | ≥ 15 Hz |\n\
             | frame clock p99 frame interval | {:.1} ms | 16.7 ms at 60 Hz |\n\
             | frame rate | {:.1} fps | 60 |\n\
             | composite time | {:.2} ms | |\n\
             | chase stop → every head at its final position | {:.0} ms | < 500 ms |\n\
             | chase stop → every head converged | {} | |\n\n\
             | beam (field angle) | direct stage, full | moving quality | vertices evaluated | moving-quality error (rel. RMS vs full) |\n|---:|---:|---:|---:|---:|\n",
            self.seconds,
            self.width,
            self.height,
            self.photons,
            self.direct_hz_median,
            self.direct_hz_min,
            self.frame_interval_p99_ms,
            self.fps,
            self.composite_ms,
            self.final_position_ms,
            self.converged_ms.map_or("not within the limit".to_string(), |ms| format!("{ms:.0} ms")),
        );
        for a in &self.cost_vs_angle {
            s += &format!(
                "| {}° | {:.2} ms | {:.2} ms | {:.2} % | {:.3} |\n",
                a.beam_deg,
                a.ms,
                a.moving_ms,
                a.vertex_share * 100.0,
                a.moving_rel_rms
            );
        }
        s
    }

    /// Lines for the terminal summary.
    pub fn lines(&self) -> String {
        format!(
            "  chase: {HEADS} heads, direct updates median {:.1} Hz, min {:.1} Hz; p99 frame {:.1} ms; final position {:.0} ms\n",
            self.direct_hz_median, self.direct_hz_min, self.frame_interval_p99_ms, self.final_position_ms
        )
    }
}
