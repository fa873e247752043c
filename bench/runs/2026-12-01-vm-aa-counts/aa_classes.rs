//! Probe (not shipped): the marked pixels by class, each class's re-shading
//! time, and highlight-only pixels re-shaded at depth 0 only.
use footlight::bench::mse_display;
use footlight::bench::sweeps::reference_81;
use footlight::fixture::Light;
use footlight::render::gbuffer::{GBuffer, NO_HIT};
use footlight::render::view::{Reshading, SampleSet, expand_pixel};
use footlight::render::whitted::direct;
use footlight::render::{AaParams, Display, RecursionLimits, Sampling, View};
use footlight::scene::Camera;
use glam::Vec3;
use std::time::Instant;

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = footlight::scene::load(&root.join("scenes/stage.glb")).unwrap();
    let patch = footlight_mvr::load_patch(&root.join("patch/paper-rig.toml")).unwrap();
    let camera = patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera).unwrap();
    let g = GBuffer::build(&scene, camera, 800, 500);
    let f = &patch.fixtures[0];
    let light: Light = f.light.clone();
    let kf = f.k_full();
    let limits = RecursionLimits::default();
    let t: f32 = std::env::var("FL_T").ok().and_then(|x| x.parse().ok()).unwrap_or(100.0);
    let aa = AaParams::new(t);
    let reference: Vec<Vec3> = reference_81(&scene, &g, &light, limits).iter().map(|x| *x * kf).collect();
    let mse = |dense: &[Vec3]| {
        let out: Vec<Vec3> = dense.iter().map(|x| *x * kf).collect();
        mse_display(&out, &reference, &Display::default())[0]
    };
    let specular = |i: usize| {
        let t = g.samples[i][4].triangle;
        t != NO_HIT && {
            let m = &scene.materials[scene.material_of[t as usize] as usize];
            m.k_r.max_element() > 0.0 || m.k_t.max_element() > 0.0
        }
    };
    let v0 = View::from_gbuffer(&scene, g.clone(), Sampling::Adaptive, limits);
    let (base, _) = v0.render_direct(&scene, &light, None);
    let d = v0.aa_decision(&scene, &light, &base, aa);
    let pairflags = v0.gradient_flags(&scene, &base, aa);
    let n = base.len();
    let hl_only: Vec<usize> = d.highlights.iter().copied().filter(|&i| !pairflags[i]).collect();
    let hl_pair: Vec<usize> = d.highlights.iter().copied().filter(|&i| pairflags[i]).collect();
    let pair_spec = (0..n).filter(|&i| pairflags[i] && specular(i) && !d.highlights.contains(&i)).count();
    let pair_matte = (0..n).filter(|&i| pairflags[i] && !specular(i) && !d.highlights.contains(&i)).count();
    println!(
        "threshold {t}: marked {}, highlight-only {}, highlight+pair {}, pair specular {pair_spec}, pair matte {pair_matte}",
        d.flags.iter().filter(|f| **f).count(),
        hl_only.len(),
        hl_pair.len()
    );
    if std::env::var("FL_LOOP").is_ok() {
        let spec: Vec<usize> = (0..n).filter(|&i| pairflags[i] && specular(i)).collect();
        let mut out = Vec::new();
        let t0 = Instant::now();
        let mut acc = Vec3::ZERO;
        let mut verts = 0;
        for _ in 0..1000 {
            for &i in &spec {
                out.clear();
                expand_pixel(&scene, &g, i, SampleSet::All, limits, &mut out);
                verts += out.len();
                acc += out.iter().map(|x| x.weight * direct(&scene, &light, x)).sum::<Vec3>();
            }
        }
        println!(
            "{} px x200: {:.1} ms per pass, {} vertices per pass {acc}",
            spec.len(),
            t0.elapsed().as_secs_f64() * 1e3 / 1000.0,
            verts / 1000
        );
        return;
    }
    // Shipped, for the error.
    let mut shipped = base.clone();
    v0.reshade(&scene, &light, &mut shipped, d.reshading());
    println!("shipped MSE R {:.4e}", mse(&shipped));
    if std::env::var("FL_COST").is_ok() {
        // Per pixel: the largest threshold at which a pair still marks it.
        let mut level = vec![0.0f32; n];
        let mut th = t;
        while th <= 1000.0 {
            let f = v0.gradient_flags(&scene, &base, AaParams::new(th));
            for i in 0..n {
                if f[i] {
                    level[i] = th;
                }
            }
            th += 10.0;
        }
        let verts: Vec<usize> = (0..n).map(|i| v0.shading.pixel(i).len()).collect();
        let alphas: Vec<f32> = std::env::var("FL_ALPHAS").ok().map(|a| a.split(',').map(|x| x.parse().unwrap()).collect()).unwrap_or(vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        let n0: f32 = std::env::var("FL_N0").ok().and_then(|x| x.parse().ok()).unwrap_or(2.0);
        let uniform: Vec<f32> = std::env::var("FL_UNIFORM").ok().map(|a| a.split(',').map(|x| x.parse().unwrap()).collect()).unwrap_or_default();
        let rules: Vec<(f32, f32)> = alphas.iter().map(|&a| (a, t)).chain(uniform.iter().map(|&u| (0.0, u))).collect();
        for (alpha, t) in rules {
            print!("threshold {t} ");
            let flags: Vec<bool> = (0..n)
                .map(|i| d.highlights.contains(&i) || (level[i] > 0.0 && level[i] >= t * (verts[i] as f32 / n0).max(1.0).powf(alpha)))
                .collect();
            let mut best = f64::INFINITY;
            let mut err = 0.0;
            for _ in 0..25 {
                let v = View::from_gbuffer(&scene, g.clone(), Sampling::Adaptive, limits);
                let mut dense = base.clone();
                let t0 = Instant::now();
                v.reshade(&scene, &light, &mut dense, Reshading { flags: &flags, whole: &d.highlights, corners_first: d.level });
                best = best.min(t0.elapsed().as_secs_f64() * 1e3);
                err = mse(&dense);
            }
            let vsum: usize = (0..n).filter(|&i| flags[i]).map(|i| verts[i]).sum();
            println!("alpha {alpha} n0 {n0}: {} px ({vsum} base vertices), {best:.2} ms, MSE R {err:.4e}", flags.iter().filter(|f| **f).count());
        }
        return;
    }
    if std::env::var("FL_MAT").is_ok() {
        let name = |i: usize| {
            let t = g.samples[i][4].triangle;
            if t == NO_HIT {
                "miss".to_string()
            } else {
                scene.materials[scene.material_of[t as usize] as usize].name.clone()
            }
        };
        let mut names: Vec<String> = (0..n).filter(|&i| d.flags[i]).map(name).collect();
        names.sort();
        names.dedup();
        for m in names {
            let pick: Vec<bool> = (0..n).map(|i| d.flags[i] && name(i) == m).collect();
            let rest: Vec<bool> = (0..n).map(|i| d.flags[i] && !pick[i]).collect();
            let mut without = base.clone();
            v0.reshade(
                &scene,
                &light,
                &mut without,
                Reshading { flags: &rest, whole: &d.highlights, corners_first: d.level },
            );
            let mut best = f64::INFINITY;
            for _ in 0..9 {
                let v = View::from_gbuffer(&scene, g.clone(), Sampling::Adaptive, limits);
                let mut dense = base.clone();
                let t0 = Instant::now();
                v.reshade(
                    &scene,
                    &light,
                    &mut dense,
                    Reshading { flags: &pick, whole: &d.highlights, corners_first: d.level },
                );
                best = best.min(t0.elapsed().as_secs_f64() * 1e3);
            }
            println!(
                "{m}: {} px, {best:.2} ms alone; MSE R without them {:.4e}",
                pick.iter().filter(|f| **f).count(),
                mse(&without)
            );
        }
        return;
    }
    // Classes timed alone on fresh views.
    let classes: [(&str, Box<dyn Fn(usize) -> bool>); 3] = [
        ("highlight-only", Box::new(|i| d.highlights.contains(&i) && !pairflags[i])),
        ("pair specular", Box::new(|i| d.flags[i] && !(d.highlights.contains(&i) && !pairflags[i]) && specular(i))),
        ("pair matte", Box::new(|i| d.flags[i] && !(d.highlights.contains(&i) && !pairflags[i]) && !specular(i))),
    ];
    for (name, pick) in &classes {
        let flags: Vec<bool> = (0..n).map(|i| d.flags[i] && pick(i)).collect();
        let mut best = f64::INFINITY;
        for _ in 0..9 {
            let v = View::from_gbuffer(&scene, g.clone(), Sampling::Adaptive, limits);
            let mut dense = base.clone();
            let t0 = Instant::now();
            v.reshade(
                &scene,
                &light,
                &mut dense,
                Reshading { flags: &flags, whole: &d.highlights, corners_first: d.level },
            );
            best = best.min(t0.elapsed().as_secs_f64() * 1e3);
        }
        println!("{name}: {} px, {best:.2} ms", flags.iter().filter(|f| **f).count());
    }
    // Highlight-only pixels at depth 0: 9 primary vertices, base's deeper vertices.
    let depth0 = RecursionLimits { max_depth: 0, ..limits };
    let alt = |i: usize, out: &mut Vec<footlight::render::whitted::ShadingVertex>| {
        out.clear();
        expand_pixel(&scene, &g, i, SampleSet::All, depth0, out);
        let near: Vec3 = out.iter().map(|x| x.weight * direct(&scene, &light, x)).sum();
        let deep: Vec3 =
            v0.shading.pixel(i).iter().filter(|x| x.depth > 0).map(|x| x.weight * direct(&scene, &light, x)).sum();
        near + deep
    };
    let mut best = f64::INFINITY;
    let mut out = Vec::new();
    let mut values = Vec::new();
    for _ in 0..9 {
        let t0 = Instant::now();
        values = hl_only.iter().map(|&i| alt(i, &mut out)).collect::<Vec<_>>();
        best = best.min(t0.elapsed().as_secs_f64() * 1e3);
    }
    let mut mixed = shipped.clone();
    for (&i, v) in hl_only.iter().zip(&values) {
        mixed[i] = *v;
    }
    println!("highlight-only at depth 0 (one thread): {best:.2} ms, MSE R {:.4e}", mse(&mixed));
}
