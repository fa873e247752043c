//! `footlight render`: the still pipeline, from the command's options to the
//! written file. The scene, patch and camera are chosen as `run` chooses
//! them ([`super::inputs`]), the DMX state decoded by the same [`Show`], and
//! the haze density is the live daemon's ([`still_haze`]); the picture
//! itself is [`crate::render::still`]'s.

use super::inputs::{Inputs, choose_camera, load_inputs};
use crate::live::{Decode, Show};
use crate::render::display::{
    Display, HighlightRolloff, balanced, check_finite, white_balance_for, write_exr, write_pfm, write_png,
};
use crate::render::photon::PhotonSettings;
use crate::render::still::{LightJob, StillHaze, render_still_hazy};
use crate::render::{BuildSettings, RecursionLimits, RenderSettings, Sampling};
use crate::scene::{Camera, Scene};
use anyhow::{Context, Result, bail};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// Everything `footlight render` was asked for (its flags, parsed).
#[derive(Clone, Debug)]
pub struct StillOptions {
    /// Scene and patch.
    pub inputs: Inputs,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Maximum Whitted recursion depth.
    pub depth: u32,
    /// Sampling mode.
    pub sampling: Sampling,
    /// Anti-aliasing gradient threshold (the light's relative 0-255 scale).
    pub aa_threshold: f32,
    /// Illuminance (lx) shown as display white.
    pub white_lux: f32,
    /// `--set` levels, `U/ADDR=VALUE` each.
    pub set: Vec<String>,
    /// A DMX recording whose state at `at` seconds is rendered.
    pub dmx: Option<PathBuf>,
    /// Seconds into `dmx`.
    pub at: f64,
    /// Photons stored per light (0: direct light only).
    pub photons: usize,
    /// Photons per radiance estimate.
    pub estimate: usize,
    /// Progressive passes after the photon-map estimate.
    pub refine: u32,
    /// Highlight roll-off of a PNG (`None`: clip at display white).
    pub rolloff: Option<HighlightRolloff>,
    /// Output file (`.png`, `.exr` or `.pfm`).
    pub out: PathBuf,
    /// White balance: auto, none, tungsten or a colour temperature.
    pub white_balance: String,
    /// Replace an existing output file.
    pub force: bool,
    /// Draw the fixture bodies over the picture.
    pub bodies: bool,
}

/// The file formats a still is written in, chosen by the output's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StillFormat {
    /// 8-bit sRGB, exposure and clipping (or roll-off) as on screen.
    Png,
    /// Linear cd/m² times the white balance, float, unclipped (OpenEXR).
    Exr,
    /// Linear as EXR, as a Portable FloatMap.
    Pfm,
}

impl StillFormat {
    /// The format `out`'s extension names (case-insensitive), or an error naming the file.
    pub fn of(out: &Path) -> Result<Self> {
        match out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            Some("pfm") => Ok(Self::Pfm),
            _ => bail!("--out {}: the name must end in .png, .exr or .pfm", out.display()),
        }
    }
}

/// `footlight render`: loads the inputs, renders the still and writes it;
/// an existing output is kept unless `force`.
pub fn render(args: &StillOptions) -> Result<()> {
    super::check::check_output(&args.out, args.force)?;
    // Checked before anything loads; `auto` is resolved on the loaded rig below.
    white_balance_for(&args.white_balance, None).map_err(|e| anyhow::anyhow!("--white-balance {e}"))?;
    let format = StillFormat::of(&args.out)?;
    let (scene, patch, _) = load_inputs(&args.inputs)?;
    let camera = choose_camera(&scene, &patch);
    let white = white_balance_for(&args.white_balance, patch.rig_white().as_ref())
        .map_err(|e| anyhow::anyhow!("--white-balance {e}"))?;
    tracing::info!("white balance {}: {}", white.setting, white.note);
    let gains = white.gains;
    let show = Show::new(patch)?;
    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        limits: RecursionLimits { max_depth: args.depth, ..RecursionLimits::default() },
        sampling: args.sampling,
        display: Display { white_balance: gains, ..Display::for_white_lux(args.white_lux) },
        build: BuildSettings {
            aa_threshold: args.aa_threshold,
            photons: (args.photons > 0).then(|| PhotonSettings {
                stored: args.photons,
                estimate: args.estimate,
                ..PhotonSettings::default()
            }),
            refine_passes: args.refine,
            edge_samples: true,
            compact: false,
        },
    };
    if args.refine > 0 && args.photons == 0 {
        bail!("--refine {}: refinement needs photons (--photons is 0)", args.refine);
    }
    let universes = still_universes(&show, args.dmx.as_deref(), args.at, &args.set)?;
    // render_still_hazy builds only the lit ones (a dark light adds exactly 0 to eq. 5).
    let jobs = jobs_for(&show, &universes);
    let lit = jobs.iter().filter(|j| j.k != Vec3::ZERO).count();
    if lit < jobs.len() {
        tracing::info!("{lit} of {} lights are lit; the dark ones are not built", jobs.len());
    }
    let haze = still_haze(&show, &scene, &universes);
    let mut still = render_still_hazy(&scene, camera, &jobs, &settings, haze.as_ref())?;
    if args.bodies {
        // Fixture bodies: a layer over the composite, never in the light buffers (issue 14).
        let t = std::time::Instant::now();
        let patch_path = args.inputs.patch_path()?;
        let (layer, bodies, lights, k) = still_bodies(&show, &universes, &patch_path, &scene, &camera, &settings);
        layer.overlay(&camera, &bodies, &lights, &k, &mut still.linear);
        let tested: u64 = (0..bodies.len()).map(|i| layer.footprint_pixels(i)).sum();
        tracing::info!(
            "bodies: {} drawn, {tested} pixel tests ({:.0} per body), {:.1} ms",
            bodies.len(),
            tested as f64 / bodies.len().max(1) as f64,
            t.elapsed().as_secs_f64() * 1e3
        );
    }
    if let Err((i, v)) = check_finite(&still.linear) {
        bail!("composite pixel {i} is {v}: this is a bug, please report it");
    }
    let (w, h) = (settings.width, settings.height);
    let out = &args.out;
    match format {
        StillFormat::Exr => write_exr(out, w, h, &balanced(&still.linear, gains)).map_err(anyhow::Error::msg)?,
        StillFormat::Pfm => write_pfm(out, w, h, &balanced(&still.linear, gains))
            .with_context(|| format!("writing {}", out.display()))?,
        StillFormat::Png => {
            let rgb8 = settings.display.with_rolloff(args.rolloff).to_srgb8(&still.linear);
            write_png(out, w, h, rgb8).with_context(|| format!("writing {}", out.display()))?
        }
    }
    let t = &still.timings;
    tracing::info!(
        "view {:.0} ms, {} light buffers {:.0} ms ({} pixels re-shaded for anti-aliasing), photon maps {:.0} ms, haze {:.0} ms, composite {:.1} ms",
        t.view.as_secs_f64() * 1e3,
        lit,
        t.lights.as_secs_f64() * 1e3,
        still.reshaded,
        t.photons.as_secs_f64() * 1e3,
        t.haze.as_secs_f64() * 1e3,
        t.composite.as_secs_f64() * 1e3
    );
    println!("wrote {}", out.display());
    Ok(())
}

/// The DMX state a still shows: a recording at `at` seconds (through the
/// show's routes), then `set` levels (`U/ADDR=VALUE`; a universe they touch
/// starts from the patch's look). A universe with neither keeps the look.
pub fn still_universes(show: &Show, dmx: Option<&Path>, at: f64, set: &[String]) -> Result<crate::fixture::Universes> {
    let mut universes = crate::fixture::Universes::new();
    if let Some(path) = dmx {
        let recording = footlight_dmx::Recording::open(path)?;
        for frame in footlight_dmx::state_at(&recording, std::time::Duration::from_secs_f64(at), show.input_patch())? {
            universes.set(frame.universe, &frame.slots);
        }
    }
    let patch = show.patch();
    for item in set {
        let (lhs, value) =
            item.split_once('=').with_context(|| format!("--set {item:?}: expected U/ADDR=VALUE, e.g. 1/1=255"))?;
        let (u, a) = lhs.split_once('/').with_context(|| format!("--set {item:?}: expected U/ADDR=VALUE"))?;
        let u: u16 = u.trim().parse().with_context(|| format!("--set {item:?}: universe must be a number from 1"))?;
        let a: u16 = a.trim().parse().with_context(|| format!("--set {item:?}: address must be 1-512"))?;
        let v: u8 = value.trim().parse().with_context(|| format!("--set {item:?}: value must be 0-255"))?;
        if u == 0 || !(1..=512).contains(&a) {
            bail!("--set {item:?}: universe counts from 1 and the address is 1-512");
        }
        if universes.get(u).is_none() {
            universes.set(u, patch.look_universes.get(u).unwrap_or(&[0; 512]));
        }
        universes.set_slot(u, a, v);
    }
    Ok(universes)
}

/// Every light's job for a DMX state: its tracer light, k_i at full and
/// now (eq. 4) and its fixture id, in patch order.
pub fn jobs_for(show: &Show, universes: &crate::fixture::Universes) -> Vec<LightJob> {
    // One input per patch fixture, in patch order (`Show::decode`).
    show.decode(universes)
        .into_iter()
        .zip(&show.patch().fixtures)
        .map(|(i, f)| LightJob { light: i.light, k_full: i.k_full, k: i.k, fixture: Some(f.id) })
        .collect()
}

/// The still's haze: the patch's `[haze]` at the density the live daemon
/// shows for the same DMX ([`Show`]'s [`Decode::haze_density`], the one
/// rule: the hazer channel's slot / 255, from the patch's look when no
/// frame of its universe is given, so `density = 50` is 128/255 in both),
/// at refined quality; `None` without `[haze]` or a volume to fill.
pub fn still_haze(show: &Show, scene: &Scene, universes: &crate::fixture::Universes) -> Option<StillHaze> {
    let spec = show.patch().haze.as_ref()?;
    let medium = crate::render::media::Medium::from_spec(spec, scene);
    if medium.is_none() {
        tracing::warn!("[haze] has no box and the scene has no volume: no haze");
    }
    Some(StillHaze {
        medium: medium?,
        density: show.haze_density(universes)?,
        quality: crate::render::media::HazeQuality::REFINED,
    })
}

/// The body layer of a still: every light's body at its decoded pan/tilt
/// (GDTF models for an MVR patch, estimated boxes otherwise), with the
/// lights and k_i that glow in their lenses.
#[allow(clippy::type_complexity)]
pub fn still_bodies(
    show: &Show,
    universes: &crate::fixture::Universes,
    patch: &Path,
    scene: &Scene,
    camera: &Camera,
    settings: &RenderSettings,
) -> (crate::render::bodies::BodyLayer, Vec<crate::render::bodies::Body>, Vec<crate::Light>, Vec<Vec3>) {
    use crate::render::bodies::{BodyLayer, body_models};
    let inputs = show.decode(universes);
    let names: Vec<String> = show.patch().fixtures.iter().map(|f| f.name.clone()).collect();
    let (models, warnings) = body_models(patch, &names, &show.fixture_ids());
    for w in warnings {
        tracing::warn!("{w}");
    }
    let bodies: Vec<_> = models
        .iter()
        .map(|m| {
            let i = &inputs[m.driver];
            m.pose(&i.light, i.state.pan, i.state.tilt)
        })
        .collect();
    let layer = BodyLayer::build(scene, camera, settings.width, settings.height, &bodies);
    let lights = inputs.iter().map(|i| i.light.clone()).collect();
    let k = inputs.iter().map(|i| i.k).collect();
    (layer, bodies, lights, k)
}
