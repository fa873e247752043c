//! Probe: re-shading rules over the marked pixels, judged by error and by
//! the vertices they expand (each sample's path shaded once).
use footlight::bench::sweeps::reference_81;
use footlight::render::display::srgb8;
use footlight::render::gbuffer::{GBuffer, NO_HIT};
use footlight::render::view::expand_sample;
use footlight::render::whitted::direct;
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
    let (w, h) = (800usize, 500usize);
    let n = w * h;
    let display = Display::default();
    let s = display.scale();
    let code = |x: Vec3| footlight::render::display::srgb_encode(x * kf * s);
    let reference: Vec<Vec3> = reference_81(&scene, &g, &light, limits).into_iter().map(code).collect();
    let mse = |dense: &[Vec3]| -> f64 {
        dense.iter().zip(&reference).map(|(x, r)| ((code(*x) - *r).x as f64).powi(2)).sum::<f64>() / n as f64
    };
    let v = View::from_gbuffer(&scene, g.clone(), Sampling::Adaptive, limits);
    let (base, _) = v.render_direct(&scene, &light, None);
    let ts: Vec<f32> = std::env::var("FL_TS").ok().map_or(vec![100.0], |x| x.split(',').map(|y| y.parse().unwrap()).collect());
    let material = |i: usize| {
        let t = g.samples[i][4].triangle;
        if t == NO_HIT { "miss".to_string() } else { scene.materials[scene.material_of[t as usize] as usize].name.clone() }
    };
    for t in ts {
        let aa = AaParams::new(t);
        let d = v.aa_decision(&scene, &light, &base, aa);
        let level = d.level.unwrap();
        let rel = |x: Vec3| srgb8(x / level);
        let marked: Vec<usize> = (0..n).filter(|&i| d.flags[i]).collect();
        // Per marked pixel: each sample's value and vertex count.
        struct P {
            i: usize,
            sv: [Vec3; 9],
            nv: [usize; 9],
            whole: bool,
            dev: f32,
            basev: usize,
        }
        let mut out = Vec::new();
        let ps: Vec<P> = marked
            .iter()
            .map(|&i| {
                let mut sv = [Vec3::ZERO; 9];
                let mut nv = [0; 9];
                for k in 0..9 {
                    out.clear();
                    expand_sample(&scene, &g, g.samples[i][k], 1.0 / 9.0, limits, &mut out);
                    nv[k] = out.len();
                    sv[k] = out.iter().map(|x| x.weight * direct(&scene, &light, x)).sum();
                }
                let own = rel(base[i]);
                let dev = [0, 2, 6, 8]
                    .iter()
                    .map(|&k| {
                        let c = rel(sv[k] * 9.0);
                        (0..3).map(|j| (f32::from(c[j]) - f32::from(own[j])).abs()).fold(0.0, f32::max)
                    })
                    .fold(0.0, f32::max);
                P { i, sv, nv, whole: d.highlights.contains(&i), dev, basev: v.shading.pixel(i).len() }
            })
            .collect();
        let corners = |p: &P| [0, 2, 6, 8].iter().map(|&k| p.nv[k]).sum::<usize>();
        let all = |p: &P| p.nv.iter().sum::<usize>();
        // Rule: full when dev > full_at, interpolate when dev > interp_at, else base.
        let run = |full_at: f32, interp_at: f32, name: &str| {
            let mut dense = base.clone();
            let mut cost = 0usize;
            let mut fulls = 0;
            for p in &ps {
                let c4: Vec3 = [0, 2, 6, 8].iter().map(|&k| p.sv[k]).sum();
                if p.whole || p.dev > full_at {
                    dense[p.i] = p.sv.iter().sum();
                    cost += all(p);
                    fulls += 1;
                } else if p.dev > interp_at {
                    // midpoints from their corners, centre from the base
                    dense[p.i] = 2.0 * c4 + base[p.i] / 9.0;
                    cost += corners(p);
                } else {
                    cost += corners(p);
                }
            }
            println!("T {t} {name}: full {fulls}, vertices {cost}, MSE R {:.3e}", mse(&dense));
        };
        println!("T {t}: marked {}, base vertices of marked {}", ps.len(), ps.iter().map(|p| p.basev).sum::<usize>());
        run(10.0, 1e9, "shipped (full > 10)");
        for fa in [20.0, 30.0, 50.0, 80.0] {
            run(fa, 1e9, &format!("full > {fa}, else base"));
            run(fa, 10.0, &format!("full > {fa}, interp > 10"));
        }
        run(1e9, 10.0, "interp > 10 only");
        for cmax in [8usize, 12, 16, 24] {
            for hi in [1e9f32, 100.0, 60.0] {
                let mut dense = base.clone();
                let mut cost = 0usize;
                let mut fulls = 0;
                for p in &ps {
                    let c4: Vec3 = [0, 2, 6, 8].iter().map(|&k| p.sv[k]).sum();
                    cost += corners(p);
                    if p.whole || (p.dev > 10.0 && (corners(p) <= cmax || p.dev > hi)) {
                        dense[p.i] = p.sv.iter().sum();
                        cost += all(p) - corners(p);
                        fulls += 1;
                    } else if p.dev > 10.0 {
                        dense[p.i] = 2.0 * c4 + base[p.i] / 9.0;
                    }
                }
                println!("T {t} cost-aware: corners' vertices <= {cmax} or dev > {hi}: full {fulls}, vertices {cost}, MSE R {:.3e}", mse(&dense));
            }
        }
        // by material: gain and cost of the full re-shades (shipped rule)
        let mut by = std::collections::BTreeMap::<String, (usize, usize, f64)>::new();
        for p in ps.iter().filter(|p| p.whole || p.dev > 10.0) {
            let e = by.entry(material(p.i)).or_default();
            let nine: Vec3 = p.sv.iter().sum();
            let eb = ((code(base[p.i]) - reference[p.i]).x as f64).powi(2);
            let e9 = ((code(nine) - reference[p.i]).x as f64).powi(2);
            e.0 += 1;
            e.1 += all(p);
            e.2 += eb - e9;
        }
        for (m, (c, cost, gain)) in by {
            println!("  full {m}: {c} px, {cost} vertices, gain {:.3e} MSE", gain / n as f64);
        }
    }
}
