//! The numerical stress matrix: scenes and settings at the edges of what a
//! user can feed Footlight, each rendered through the whole pipeline
//! (G-buffer, Whitted, photon maps, composite). Every image must be finite
//! and non-negative, and bounded by the analytic maximum where one exists.
//! `footlight bench` reports the table; `tests/stress.rs` runs it small.

use crate::fixture::{Beam, Light, SpotBeam};
use crate::render::photon::PhotonSettings;
use crate::render::{BuildSettings, Cancel, LightBuffer, LightBuild, RecursionLimits, Sampling, View, composite};
use crate::scene::{Camera, Material, Scene, SceneBuilder};
use glam::Vec3;
use serde::Serialize;
use std::f32::consts::PI;

/// One case of the matrix and its outcome.
#[derive(Clone, Debug, Serialize)]
pub struct StressCase {
    /// What was stressed.
    pub name: String,
    /// All checks passed.
    pub ok: bool,
    /// Largest composite value (cd/m²).
    pub max_value: f32,
    /// Analytic upper bound, where one exists.
    pub bound: Option<f32>,
    /// What was checked, or what failed.
    pub detail: String,
}

const W: u32 = 48;
const H: u32 = 32;

/// A light and its k_i.
type Lit = (Light, Vec3);

/// Renders `lights` (direct + photon-mapped indirect with `photons` stored)
/// and returns the composite or the first bad buffer.
fn render(scene: &Scene, camera: Camera, lights: &[Lit], photons: usize) -> Result<Vec<Vec3>, String> {
    let view = View::build(scene, camera, W, H, Sampling::Adaptive, RecursionLimits::default());
    let mut buffers = Vec::new();
    let settings = BuildSettings {
        photons: Some(PhotonSettings { stored: photons, seed: 17, ..PhotonSettings::default() }),
        refine_passes: 0,
        ..BuildSettings::default()
    };
    for (i, (light, _)) in lights.iter().enumerate() {
        let mut build = LightBuild::new(light.clone(), i, settings, Cancel::never());
        let b = build
            .run_to_end(scene, &view)
            .map_err(|e| format!("light {i}: {e}"))?
            .ok_or_else(|| format!("light {i}: no buffer"))?;
        if let Some(maps) = build.maps() {
            for p in maps.global.photons.iter().chain(&maps.caustic.photons) {
                if !p.power.is_finite() || p.power.min_element() < 0.0 || !p.position.is_finite() {
                    return Err(format!("light {i}: photon {p:?} is not finite"));
                }
            }
        }
        buffers.push(b);
    }
    let refs: Vec<&LightBuffer> = buffers.iter().collect();
    let k: Vec<Vec3> = lights.iter().map(|l| l.1).collect();
    let img = composite(&refs, &k, W, H);
    match crate::render::display::check_finite(&img) {
        Ok(()) => Ok(img),
        Err((i, v)) => Err(format!("composite pixel {i} = {v}")),
    }
}

/// The composite of `light` (k = 1000 cd, white) over `scene` in a haze of
/// σ_s `sigma_s` (σ_a 0, g 0.7) filling the scene's box up to 2.5 m, with
/// the beam's in-scattering and both extinctions ([`crate::render::media`]).
fn hazy(scene: &Scene, camera: Camera, light: &Light, sigma_s: f32) -> Result<Vec<Vec3>, String> {
    use crate::render::media::{HazeQuality, HazeView, Medium, render_inscatter, resolve};
    let view = View::build(scene, camera, W, H, Sampling::Adaptive, RecursionLimits::default());
    let medium = Medium::new(sigma_s, 0.0, 0.7, Vec3::new(-5.0, -0.01, -5.0), Vec3::new(5.0, 2.5, 5.0))
        .map_err(|e| e.to_string())?;
    let hv = HazeView::new(scene, &view.gbuffer);
    let (surface, _) = view.render_light(scene, light, None);
    let haze = render_inscatter(scene, &hv, light, &medium, HazeQuality::REFINED);
    let buffer = resolve(&hv, &medium, light.position, &surface, Some(&haze), 1.0);
    buffer.check().map_err(|e| format!("{e:?}"))?;
    let img = composite(&[&buffer], &[Vec3::splat(1000.0)], W, H);
    match crate::render::display::check_finite(&img) {
        Ok(()) => Ok(img),
        Err((i, v)) => Err(format!("composite pixel {i} = {v}")),
    }
}

fn case(
    name: &str,
    result: Result<Vec<Vec3>, String>,
    bound: Option<f32>,
    expect: impl Fn(&[Vec3]) -> Result<(), String>,
) -> StressCase {
    match result {
        Err(detail) => StressCase { name: name.into(), ok: false, max_value: f32::NAN, bound, detail },
        Ok(img) => {
            let max_value = img.iter().map(|p| p.max_element()).fold(0.0, f32::max);
            let mut problems = Vec::new();
            if let Some(b) = bound
                && max_value > b
            {
                problems.push(format!("max {max_value:e} above the analytic bound {b:e}"));
            }
            if let Err(e) = expect(&img) {
                problems.push(e);
            }
            let ok = problems.is_empty();
            let detail = if ok { "finite, non-negative, within bound".to_string() } else { problems.join("; ") };
            StressCase { name: name.into(), ok, max_value, bound, detail }
        }
    }
}

fn plane(scale: f32, rho: f32) -> (SceneBuilder, u32) {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::lambert("plane", Vec3::splat(rho)));
    let s = 5.0 * scale;
    b.add_quad(Vec3::new(-s, 0.0, s), Vec3::new(s, 0.0, s), Vec3::new(s, 0.0, -s), Vec3::new(-s, 0.0, -s), m);
    (b, m)
}

fn omni(p: Vec3) -> Light {
    Light::aimed(p, p + Vec3::NEG_Y, Beam::Spot(SpotBeam::from_beam_field(360.0, 360.0)))
}

fn cube(b: &mut SceneBuilder, min: Vec3, max: Vec3, m: u32) {
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(if x { max.x } else { min.x }, if y { max.y } else { min.y }, if z { max.z } else { min.z })
    };
    for (a, bb, cc, d) in [
        (c(false, false, true), c(true, false, true), c(true, true, true), c(false, true, true)),
        (c(true, false, false), c(false, false, false), c(false, true, false), c(true, true, false)),
        (c(true, false, true), c(true, false, false), c(true, true, false), c(true, true, true)),
        (c(false, false, false), c(false, false, true), c(false, true, true), c(false, true, false)),
        (c(false, true, true), c(true, true, true), c(true, true, false), c(false, true, false)),
        (c(false, false, false), c(true, false, false), c(true, false, true), c(false, false, true)),
    ] {
        b.add_quad(a, bb, cc, d, m);
    }
}

/// Bound for a Lambert plane of albedo ρ lit by point lights: the largest
/// luminance is ρ/π · I / h² (directly below each light), summed.
fn plane_bound(rho: f32, lights: &[(f32, f32)]) -> f32 {
    lights.iter().map(|(i, h)| rho / PI * i / (h * h)).sum::<f32>() * 1.001
}

fn all_black(img: &[Vec3]) -> Result<(), String> {
    if img.iter().all(|p| *p == Vec3::ZERO) { Ok(()) } else { Err("expected a black image".into()) }
}

fn some_light(img: &[Vec3]) -> Result<(), String> {
    if img.iter().any(|p| p.max_element() > 0.0) { Ok(()) } else { Err("expected some light".into()) }
}

/// Runs every case; `photons` is the photon count per light (small for tests).
pub fn run_matrix(photons: usize) -> Vec<StressCase> {
    let mut out = Vec::new();
    let rho = 0.5;
    let down = |scale: f32| Camera::look_at(Vec3::new(0.0, 4.0, 3.0) * scale, Vec3::ZERO, 0.9);

    for (name, scale) in [("scene scale 1 mm", 1e-3f32), ("scene scale 1 km", 1e3)] {
        let (b, _) = plane(scale, rho);
        let h = 2.0 * scale;
        let r =
            render(&b.build(), down(scale), &[(omni(Vec3::new(0.3, 2.0, -0.2) * scale), Vec3::splat(1000.0))], photons);
        out.push(case(name, r, Some(plane_bound(rho, &[(1000.0, h)])), some_light));
    }
    // Haze at optical depths from 0.2 to 1e30 across the box (issue 34):
    // the picture's energy falls with σ_s once σ_s passes 1/L, and never
    // exceeds the clear picture's at depth ≥ 40.
    {
        let (b, _) = plane(1.0, rho);
        let scene = b.build();
        let light =
            Light::aimed(Vec3::new(0.0, 2.0, 0.0), Vec3::ZERO, Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0)));
        let camera = Camera::look_at(Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 0.8, 0.0), 0.9);
        let energy = |img: &[Vec3]| img.iter().map(|p| f64::from(p.element_sum())).sum::<f64>();
        let clear = hazy(&scene, camera, &light, 0.0);
        let clear_energy = clear.as_deref().map_or(f64::NAN, energy);
        let mut last = f64::INFINITY;
        for sigma_s in [0.05f32, 10.0, 1e4, 1e30] {
            let r = hazy(&scene, camera, &light, sigma_s);
            let this = r.as_deref().map_or(f64::NAN, energy);
            let dense = sigma_s >= 10.0;
            out.push(case(
                &format!("haze σ_s {sigma_s:e} /m (optical depth up to {:e})", sigma_s * 5.0),
                r,
                None,
                |_| {
                    if dense && !(this <= last * (1.0 + 1e-6) && this <= clear_energy) {
                        Err(format!("energy {this:e} after {last:e} (clear {clear_energy:e})"))
                    } else {
                        Ok(())
                    }
                },
            ));
            if dense {
                last = this;
            }
        }
    }
    {
        let (b, _) = plane(4.0, rho);
        let h = 1e-3;
        let r = render(&b.build(), down(1.0), &[(omni(Vec3::new(8.0, h, 0.0)), Vec3::splat(1000.0))], photons);
        out.push(case(
            "grazing light (1 mm above the plane, 8 m away)",
            r,
            Some(plane_bound(rho, &[(1000.0, h)])),
            |_| Ok(()),
        ));
        let (b, _) = plane(4.0, rho);
        let cam = Camera::look_at(Vec3::new(0.0, 1e-4, 15.0), Vec3::new(0.0, 1e-4, 0.0), 0.9);
        let r = render(&b.build(), cam, &[(omni(Vec3::new(0.0, 2.0, 0.0)), Vec3::splat(1000.0))], photons);
        out.push(case("grazing camera (0.1 mm above the plane)", r, Some(plane_bound(rho, &[(1000.0, 2.0)])), |_| {
            Ok(())
        }));
    }
    {
        let (mut b, m) = plane(1.0, rho);
        b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::X * 2.0], None, m);
        b.add_triangle([Vec3::Y; 3], None, m);
        b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1e-9, 0.0)], None, m);
        b.add_triangle([Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::NAN, 0.0)], None, m);
        let r = render(&b.build(), down(1.0), &[(omni(Vec3::new(0.0, 2.0, 0.0)), Vec3::splat(1000.0))], photons);
        out.push(case("zero-area, sliver and NaN triangles", r, Some(plane_bound(rho, &[(1000.0, 2.0)])), some_light));
    }
    {
        let (mut b, _) = plane(1.0, rho);
        let mirror = b.add_material(Material::from_pbr("chrome", Vec3::splat(0.9), 1.0, 0.0, 0.0, 1.5));
        let s = 5.0;
        b.add_quad(Vec3::new(-s, 0.0, s), Vec3::new(s, 0.0, s), Vec3::new(s, 0.0, -s), Vec3::new(-s, 0.0, -s), mirror);
        let r = render(&b.build(), down(1.0), &[(omni(Vec3::new(0.0, 2.0, 0.0)), Vec3::splat(1000.0))], photons);
        out.push(case("coincident faces (diffuse and mirror in one plane)", r, None, |_| Ok(())));
    }
    {
        let (mut b, m) = plane(1.0, rho);
        cube(&mut b, Vec3::new(-0.5, 0.5, -0.5), Vec3::new(0.5, 1.5, 0.5), m);
        let r = render(&b.build(), down(1.0), &[(omni(Vec3::new(0.0, 1.0, 0.0)), Vec3::splat(1000.0))], photons);
        out.push(case("light inside a closed box", r, Some(0.0), all_black));
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::lambert("box", Vec3::splat(0.8)));
        cube(&mut b, Vec3::splat(-1.0), Vec3::splat(1.0), m);
        let cam = Camera::look_at(Vec3::new(0.3, 0.2, 0.5), Vec3::ZERO, 1.2);
        let r = render(&b.build(), cam, &[(omni(Vec3::new(0.0, 0.5, 0.0)), Vec3::splat(1000.0))], photons);
        out.push(case("camera and light inside a closed box", r, None, some_light));
    }
    {
        let (b, _) = plane(1.0, rho);
        let r = render(&b.build(), down(1.0), &[(omni(Vec3::ZERO), Vec3::splat(1000.0))], photons);
        out.push(case("light exactly on the surface", r, None, |_| Ok(())));
    }
    {
        let (b, _) = plane(1.0, rho);
        let scene = b.build();
        let narrow =
            Light::aimed(Vec3::new(0.0, 2.0, 0.0), Vec3::ZERO, Beam::Spot(SpotBeam::from_beam_field(1e-3, 2e-3)));
        let wide =
            Light::aimed(Vec3::new(0.0, 2.0, 0.0), Vec3::ZERO, Beam::Spot(SpotBeam::from_beam_field(360.0, 360.0)));
        let r = render(&scene, down(1.0), &[(narrow, Vec3::splat(1e6)), (wide, Vec3::splat(1000.0))], photons);
        out.push(case(
            "extreme beams (0.001° and 360°)",
            r,
            Some(plane_bound(rho, &[(1e6, 2.0), (1000.0, 2.0)])),
            some_light,
        ));
    }
    {
        let (b, _) = plane(1.0, rho);
        let scene = b.build();
        let l = omni(Vec3::new(0.0, 2.0, 0.0));
        out.push(case(
            "dimmer 0",
            render(&scene, down(1.0), &[(l.clone(), Vec3::ZERO)], photons),
            Some(0.0),
            all_black,
        ));
        out.push(case(
            "dimmer full",
            render(&scene, down(1.0), &[(l.clone(), Vec3::splat(1000.0))], photons),
            Some(plane_bound(rho, &[(1000.0, 2.0)])),
            some_light,
        ));
        // Gels from spectra: zero and full transmission (photometry, eq. 4).
        use footlight_photometry::{Lamp, Sampled, colour_exact};
        let lamp = Lamp::tungsten();
        let opaque = colour_exact(&lamp, 1.0, Some(&Sampled::constant(0.0))) * 1000.0;
        let clear = colour_exact(&lamp, 1.0, Some(&Sampled::constant(1.0))) * 1000.0;
        let open = colour_exact(&lamp, 1.0, None) * 1000.0;
        out.push(case(
            "gel with zero transmission",
            render(&scene, down(1.0), &[(l.clone(), opaque)], photons),
            Some(0.0),
            all_black,
        ));
        let full = render(&scene, down(1.0), &[(l.clone(), clear)], photons);
        out.push(case(
            "gel with full transmission",
            full,
            Some(plane_bound(rho, &[(open.max_element(), 2.0)])),
            |_| {
                if (clear - open).abs().max_element() <= 1e-3 * open.max_element() {
                    Ok(())
                } else {
                    Err(format!("clear gel changed k: {clear} vs {open}"))
                }
            },
        ));
        out.push(case(
            "huge intensity (1e9 cd)",
            render(&scene, down(1.0), &[(l.clone(), Vec3::splat(1e9))], photons),
            Some(plane_bound(rho, &[(1e9, 2.0)])),
            some_light,
        ));
        for n in [0usize, 1] {
            out.push(case(
                &format!("{n} photon(s)"),
                render(&scene, down(1.0), &[(l.clone(), Vec3::splat(1000.0))], n),
                Some(plane_bound(rho, &[(1000.0, 2.0)])),
                some_light,
            ));
        }
        // Real fixture types at absurd settings: zoom, iris, focus, pan and
        // tilt far outside their ranges, through the patch's state → light → k.
        let parsed = crate::bundled::root_of("patch/fixtures").map_err(|e| e.to_string()).and_then(|root| {
            let root = root.display();
            let text = format!(
                "fixtures = \"{root}/patch/fixtures\"\ngels = \"{root}/patch/gels.toml\"\n\
                 [[fixture]]\nid = 1\ntype = \"generic-moving-spot\"\nmode = \"standard\"\nuniverse = 1\naddress = 1\nposition = [0.0, 3.0, 0.0]\n\
                 [[fixture]]\nid = 2\ntype = \"strand-castor\"\nmode = \"1ch\"\nuniverse = 1\naddress = 40\nposition = [1.0, 3.0, 1.0]\naim = [0.0, 0.0, 0.0]\n\
                 [[fixture]]\nid = 3\ntype = \"niethammer-hpz-115-d\"\nmode = \"1ch\"\nuniverse = 1\naddress = 41\nposition = [-1.0, 3.0, 1.0]\naim = [0.0, 0.0, 0.0]\n"
        );
            crate::Patch::parse(std::path::Path::new("stress-patch.toml"), &text).map_err(|e| e.to_string())
        });
        match parsed {
            Err(e) => out.push(StressCase {
                name: "extreme zoom, iris, focus, pan and tilt".into(),
                ok: false,
                max_value: f32::NAN,
                bound: None,
                detail: e.to_string(),
            }),
            Ok(patch) => {
                let mut lights = Vec::new();
                for f in &patch.fixtures {
                    for (zoom, iris, focus, pan) in
                        [(0.0, 0.0, 0.0, -1e4), (1e4, 1.0, 1.0, 1e4), (f32::NAN, f32::NAN, f32::NAN, f32::NAN)]
                    {
                        let state = footlight_fixture::FixtureState {
                            v: 1.0,
                            zoom,
                            iris,
                            focus,
                            pan,
                            tilt: pan,
                            ..footlight_fixture::FixtureState::default()
                        };
                        lights.push((f.light_of(&state), f.k_of(&state)));
                    }
                }
                let finite_k =
                    lights.iter().all(|(l, k)| k.is_finite() && l.position.is_finite() && l.rotation.is_finite());
                let r = if finite_k {
                    render(&scene, down(1.0), &lights, photons.min(2_000))
                } else {
                    Err("non-finite k or light from a fixture state".into())
                };
                out.push(case("extreme zoom, iris, focus, pan and tilt (fixture types)", r, None, some_light));
            }
        }
        let many: Vec<Lit> = (0..128)
            .map(|i| {
                let a = i as f32 * 0.37;
                (omni(Vec3::new(3.0 * a.cos(), 1.0 + (i % 7) as f32 * 0.5, 3.0 * a.sin())), Vec3::splat(1000.0))
            })
            .collect();
        let bound = plane_bound(rho, &many.iter().map(|(l, k)| (k.x, l.position.y)).collect::<Vec<_>>());
        out.push(case(
            "128 lights at full",
            render(&scene, down(1.0), &many, photons.min(500)),
            Some(bound),
            some_light,
        ));
    }
    out
}
