//! Probe: how much of the 9-sample re-shading traces paths deeper than any
//! lit vertex of the pixel's base neighbourhood.
use footlight::bench::mse_display;
use footlight::bench::sweeps::reference_81;
use footlight::render::gbuffer::GBuffer;
use footlight::render::view::{SampleSet, expand_pixel};
use footlight::render::whitted::direct;
use footlight::render::{AaParams, Display, RecursionLimits, Sampling, View};
use footlight::scene::Camera;
use glam::Vec3;
use std::time::Instant;

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|x| x.parse().ok())
}

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = footlight::scene::load(&root.join("scenes/stage.glb")).unwrap();
    let patch = footlight_mvr::load_patch(&root.join("patch/paper-rig.toml")).unwrap();
    let camera = patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera).unwrap();
    let g = GBuffer::build(&scene, camera, 800, 500);
    let f = &patch.fixtures[env("FL_FIXTURE").unwrap_or(0)];
    let light = f.light.clone();
    let kf = f.k_full();
    let limits = RecursionLimits::default();
    let aa = AaParams::new(env("FL_T").unwrap_or(100.0));
    let (w, h) = (800usize, 500usize);
    let reference: Vec<Vec3> = reference_81(&scene, &g, &light, limits).iter().map(|x| *x * kf).collect();
    let mse = |dense: &[Vec3]| {
        let out: Vec<Vec3> = dense.iter().map(|x| *x * kf).collect();
        mse_display(&out, &reference, &Display::default())[0]
    };
    let v0 = View::from_gbuffer(&scene, g.clone(), Sampling::Adaptive, limits);
    let (base, _) = v0.render_direct(&scene, &light, None);
    let (shipped, _) = v0.render_direct(&scene, &light, Some(aa));
    let d = v0.aa_decision(&scene, &light, &base, aa);
    // Deepest lit depth per pixel (-1: nothing lit).
    let deepest: Vec<i32> = (0..w * h)
        .map(|i| {
            v0.shading
                .pixel(i)
                .iter()
                .filter(|v| direct(&scene, &light, v) != Vec3::ZERO)
                .map(|v| v.depth as i32)
                .max()
                .unwrap_or(-1)
        })
        .collect();
    let radius: i32 = env("FL_R").unwrap_or(1);
    let k_of = |i: usize| {
        let (x, y) = ((i % w) as i32, (i / w) as i32);
        let mut k = -1;
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                let (a, b) = (x + dx, y + dy);
                if a >= 0 && b >= 0 && (a as usize) < w && (b as usize) < h {
                    k = k.max(deepest[b as usize * w + a as usize]);
                }
            }
        }
        k
    };
    let flagged: Vec<usize> = (0..w * h).filter(|&i| d.flags[i]).collect();
    println!("marked {}, shipped MSE R {:.4e}", flagged.len(), mse(&shipped));
    let mut hist = [0usize; 8];
    for &i in &flagged {
        hist[(k_of(i) + 1) as usize] += 1;
    }
    println!("k histogram (-1..6): {hist:?}");
    for prune in [false, true] {
        let mut best = f64::INFINITY;
        let mut dense = base.clone();
        let mut verts = 0;
        for _ in 0..9 {
            dense.copy_from_slice(&base);
            verts = 0;
            let mut out = Vec::new();
            let t0 = Instant::now();
            for &i in &flagged {
                let mut l = limits;
                if prune {
                    l.max_depth = k_of(i).max(0) as u32;
                }
                out.clear();
                expand_pixel(&scene, &g, i, SampleSet::All, l, &mut out);
                verts += out.len();
                dense[i] = out.iter().map(|x| x.weight * direct(&scene, &light, x)).sum();
            }
            best = best.min(t0.elapsed().as_secs_f64() * 1e3);
        }
        println!("all 9, prune {prune}: {verts} vertices, {best:.2} ms (one thread), MSE R {:.4e}", mse(&dense));
    }
}
