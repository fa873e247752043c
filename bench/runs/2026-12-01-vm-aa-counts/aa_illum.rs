//! Probe (not shipped): one light's illumination (direct + indirect at the
//! paper's photon settings), 1 sample against adaptive AA, fresh views.
use footlight::render::gbuffer::GBuffer;
use footlight::render::photon::{PhotonSettings, trace_photons};
use footlight::render::{AaParams, RecursionLimits, Sampling, View};
use footlight::scene::Camera;
use std::time::Instant;

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = footlight::scene::load(&root.join("scenes/stage.glb")).unwrap();
    let patch = footlight_mvr::load_patch(&root.join("patch/paper-rig.toml")).unwrap();
    let camera = patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera).unwrap();
    let g = GBuffer::build(&scene, camera, 800, 500);
    let fx: usize = std::env::var("FL_FIXTURE").ok().and_then(|x| x.parse().ok()).unwrap_or(0);
    let light = patch.fixtures[fx].light.clone();
    let limits = RecursionLimits::default();
    let t0 = Instant::now();
    let maps = trace_photons(&scene, &light, &PhotonSettings::default());
    println!("photon maps {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
    let aa = AaParams::new(std::env::var("FL_T").ok().and_then(|x| x.parse().ok()).unwrap_or(100.0));
    let rounds: usize = std::env::var("FL_ROUNDS").ok().and_then(|x| x.parse().ok()).unwrap_or(9);
    // [direct, indirect] for 1 sample and adaptive
    let mut all: Vec<[f64; 4]> = Vec::new();
    for _ in 0..rounds {
        let mut r = [0.0; 4];
        for (k, (sampling, a)) in [(Sampling::One, None), (Sampling::Adaptive, Some(aa))].into_iter().enumerate() {
            let t = Instant::now();
            let v = View::from_gbuffer(&scene, g.clone(), sampling, limits);
            std::hint::black_box(v.render_direct(&scene, &light, a));
            r[2 * k] = t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let e = v.vertex_irradiance(&scene, &maps);
            std::hint::black_box(v.render_vertex_irradiance(&scene, &e));
            r[2 * k + 1] = t.elapsed().as_secs_f64() * 1e3;
        }
        all.push(r);
    }
    let min = |k: usize| all.iter().map(|r| r[k]).fold(f64::INFINITY, f64::min);
    let (d1, i1, da, ia) = (min(0), min(1), min(2), min(3));
    println!("1 sample: direct {d1:.1} ms, indirect {i1:.1} ms; adaptive: direct {da:.1} ms, indirect {ia:.1} ms");
    println!(
        "direct only {:.1} %, indirect only {:.1} %, illumination {:.1} %",
        da / d1 * 100.0,
        ia / i1 * 100.0,
        (da + ia) / (d1 + i1) * 100.0
    );
    let mut per: Vec<f64> = all.iter().map(|r| (r[2] + r[3]) / (r[0] + r[1]) * 100.0).collect();
    per.sort_by(f64::total_cmp);
    println!("illumination round by round: {per:.1?}");
}
