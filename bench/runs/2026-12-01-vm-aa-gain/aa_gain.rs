//! Probe: which pixels hold the error the 9-sample re-shading removes, and
//! which of them the shipped decision finds.
use footlight::bench::sweeps::reference_81;
use footlight::render::gbuffer::{GBuffer, NO_HIT};
use footlight::render::{AaParams, Display, RecursionLimits, Sampling, View};
use footlight::scene::Camera;
use glam::Vec3;

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
    let n = w * h;
    let display = Display::default();
    let s = display.scale();
    let code = |x: Vec3| footlight::render::display::srgb_encode(x * kf * s);
    let reference: Vec<Vec3> = reference_81(&scene, &g, &light, limits).into_iter().map(code).collect();
    let err = |dense: &[Vec3]| -> Vec<f64> {
        dense.iter().zip(&reference).map(|(x, r)| ((code(*x) - *r).x as f64).powi(2)).collect()
    };
    let v = View::from_gbuffer(&scene, g.clone(), Sampling::Adaptive, limits);
    let (base, _) = v.render_direct(&scene, &light, None);
    let (shipped, _) = v.render_direct(&scene, &light, Some(aa));
    let v9 = View::from_gbuffer(&scene, g.clone(), Sampling::Nine, limits);
    let (nine, _) = v9.render_direct(&scene, &light, None);
    let d = v.aa_decision(&scene, &light, &base, aa);
    let (eb, e9, es) = (err(&base), err(&nine), err(&shipped));
    let mse = |e: &[f64]| e.iter().sum::<f64>() / n as f64;
    println!("MSE R: base {:.3e}, nine {:.3e}, shipped {:.3e}", mse(&eb), mse(&e9), mse(&es));
    let gain: Vec<f64> = (0..n).map(|i| eb[i] - e9[i]).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| gain[b].total_cmp(&gain[a]));
    let total_b: f64 = eb.iter().sum();
    let mut acc = 0.0;
    let marks = d.flags.iter().filter(|f| **f).count();
    for (k, &i) in order.iter().enumerate() {
        acc += gain[i];
        let k1 = k + 1;
        if [100, 200, 300, 400, 500, 600, 800, 1000, 1192, 1500, 2000].contains(&k1) {
            let marked = order[..k1].iter().filter(|&&j| d.flags[j]).count();
            println!("oracle top {k1}: MSE {:.3e}; {marked} of them marked", (total_b - acc) / n as f64);
        }
    }
    // The shipped rule's gains: how much of its re-shading pays.
    let mut ship_gain: Vec<f64> = (0..n).filter(|&i| d.flags[i]).map(|i| eb[i] - es[i]).collect();
    ship_gain.sort_by(|a, b| b.total_cmp(a));
    let pos: f64 = ship_gain.iter().filter(|g| **g > 0.0).sum();
    let neg: f64 = ship_gain.iter().filter(|g| **g < 0.0).sum();
    let tiny = ship_gain.iter().filter(|g| g.abs() < 1e-4).count();
    println!("shipped marks {marks}: gain {pos:.3} (+), {neg:.3} (-), {tiny} with |gain| < 1e-4 (code² units/255²)");
    // Missed: top-gain pixels not marked, by class.
    let material = |i: usize| {
        let t = g.samples[i][4].triangle;
        if t == NO_HIT { "miss".to_string() } else { scene.materials[scene.material_of[t as usize] as usize].name.clone() }
    };
    let multi = |i: usize| g.samples[i].iter().any(|x| x.triangle != g.samples[i][0].triangle);
    let mut missed = std::collections::BTreeMap::<String, (usize, f64)>::new();
    let mut missed_gain = 0.0;
    for &i in order.iter().take(1200) {
        if !d.flags[i] {
            missed_gain += gain[i];
            let key = format!("{} multi={}", material(i), multi(i));
            let e = missed.entry(key).or_default();
            e.0 += 1;
            e.1 += gain[i];
        }
    }
    println!("missed among oracle top 1200: gain {missed_gain:.3} (MSE share {:.3e})", missed_gain / n as f64);
    for (k, (c, gsum)) in &missed {
        println!("  {k}: {c} px, gain {gsum:.3}");
    }
    // Marked with little gain, by class.
    let mut idle = std::collections::BTreeMap::<String, (usize, f64)>::new();
    for i in (0..n).filter(|&i| d.flags[i]) {
        let key = format!("{} multi={}", material(i), multi(i));
        let e = idle.entry(key).or_default();
        e.0 += 1;
        e.1 += eb[i] - es[i];
    }
    println!("marked by class (px, gain):");
    for (k, (c, gsum)) in &idle {
        println!("  {k}: {c} px, gain {gsum:.3}");
    }
}
