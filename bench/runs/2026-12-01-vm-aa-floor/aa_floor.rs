//! The probes behind "The floor, measured part by part" in
//! docs/rendering.md (fourth session of 2026-12-01). Not part of the build:
//! copy to examples/ over a tree with variants.diff applied (see README.md).
//!
//!   aa_floor reshade TD TS [TD TS ...]  re-shading time and MSE R with
//!                                       threshold TD on matte, TS on specular pixels
//!   aa_floor parts                      the decision's parts, timed
//!   aa_floor base                       expansion and shading, 1 sample vs bins
//!   aa_floor single                     1-sample pass, base, decision, re-shading
//!                                       (run with RAYON_NUM_THREADS=1 for one thread)
//!   aa_floor bins                       vertices per depth and material
//!   aa_floor borrow                     minor matte bins taken from a neighbour
//!   aa_floor light                      one light's lit curtain pixels, vertices,
//!                                       bins-only and shipped MSE R (FL_FIXTURE=n)
//!   aa_floor recon                      marked pixels filtered from the base (a 3×3
//!                                       weighted mean) instead of re-shaded, by class
//!   aa_floor warm                       re-shading on a fresh view, then again with
//!                                       the 9-sample paths it cached (its shading part)
//!   aa_floor loop1 | loopa              60 fresh views, 1 sample / shipped adaptive
//!                                       (for `perf record` and `perf stat`)
use footlight::bench::mse_display;
use footlight::bench::sweeps::reference_81;
use footlight::fixture::Light;
use footlight::render::gbuffer::{GBuffer, NO_HIT};
use footlight::render::view::{Reshading, SampleSet};
use footlight::render::whitted::direct;
use footlight::render::{AaParams, Display, RecursionLimits, Sampling, View};
use footlight::scene::{Camera, Hit, Scene};
use glam::Vec3;
use std::time::Instant;

struct Setup {
    scene: Scene,
    g: GBuffer,
    limits: RecursionLimits,
    light: Light,
    kf: Vec3,
}

impl Setup {
    fn new() -> Self {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let scene = footlight::scene::load(&root.join("scenes/stage.glb")).unwrap();
        let patch = footlight_mvr::load_patch(&root.join("patch/paper-rig.toml")).unwrap();
        let camera = patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera).unwrap();
        let g = GBuffer::build(&scene, camera, 800, 500);
        // FL_FIXTURE=n: the n-th patch light (0-based; default the bench's first).
        let f = &patch.fixtures[std::env::var("FL_FIXTURE").ok().and_then(|x| x.parse().ok()).unwrap_or(0)];
        Self { g, limits: RecursionLimits::default(), light: f.light.clone(), kf: f.k_full(), scene }
    }
    fn view(&self, s: Sampling) -> View {
        View::from_gbuffer(&self.scene, self.g.clone(), s, self.limits)
    }
    fn reference(&self) -> Vec<Vec3> {
        reference_81(&self.scene, &self.g, &self.light, self.limits).iter().map(|x| *x * self.kf).collect()
    }
    fn mse(&self, dense: &[Vec3], reference: &[Vec3]) -> f64 {
        let out: Vec<Vec3> = dense.iter().map(|x| *x * self.kf).collect();
        mse_display(&out, reference, &Display::default())[0]
    }
    fn specular(&self, i: usize) -> bool {
        let t = self.g.samples[i][4].triangle;
        t != NO_HIT && {
            let m = &self.scene.materials[self.scene.material_of[t as usize] as usize];
            m.k_r.max_element() > 0.0 || m.k_t.max_element() > 0.0
        }
    }
}

fn fastest(n: usize, mut f: impl FnMut() -> f64) -> f64 {
    (0..n).map(|_| f()).fold(f64::INFINITY, f64::min)
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let s = Setup::new();
    let (scene, light) = (&s.scene, &s.light);
    let aa = AaParams::new(std::env::var("FL_T").ok().and_then(|x| x.parse().ok()).unwrap_or(100.0));
    match args[0].as_str() {
        "reshade" => {
            let reference = s.reference();
            let t: Vec<f32> = args[1..].iter().map(|a| a.parse().unwrap()).collect();
            for pair in t.chunks(2) {
                let (mut err, mut n) = (0.0, (0, 0));
                let time = fastest(7, || {
                    let v = s.view(Sampling::Adaptive);
                    let (mut dense, _) = v.render_direct(scene, light, None);
                    let dd = v.aa_decision(scene, light, &dense, AaParams::new(pair[0]));
                    let ds = v.aa_decision(scene, light, &dense, AaParams::new(pair[1]));
                    let flags: Vec<bool> = (0..dense.len())
                        .map(|i| dd.highlights.contains(&i) || if s.specular(i) { ds.flags[i] } else { dd.flags[i] })
                        .collect();
                    let count =
                        |spec: bool| flags.iter().enumerate().filter(|(i, f)| **f && s.specular(*i) == spec).count();
                    n = (count(false), count(true));
                    let t = Instant::now();
                    v.reshade(
                        scene,
                        light,
                        &mut dense,
                        Reshading { flags: &flags, whole: &dd.highlights, corners_first: dd.level },
                    );
                    let elapsed = ms(t);
                    err = s.mse(&dense, &reference);
                    elapsed
                });
                println!(
                    "matte {} specular {}: {} + {} px, re-shading {time:.2} ms, MSE R {err:.3e}",
                    pair[0], pair[1], n.0, n.1
                );
            }
        }
        "parts" => {
            let v = s.view(Sampling::Adaptive);
            let (dense, _) = v.render_direct(scene, light, None);
            let (w, h) = (800, 500);
            let (reference, window) = footlight::render::view::reference_in_window(&dense, w, h).unwrap();
            println!("lit window {window:?}");
            let time = |name: &str, f: &dyn Fn()| {
                println!(
                    "{name}: {:.3} ms",
                    fastest(200, || {
                        let t = Instant::now();
                        f();
                        ms(t)
                    })
                );
            };
            time("row spans", &|| {
                std::hint::black_box(footlight::render::view::row_spans(&dense, w));
            });
            time("reference level + window", &|| {
                std::hint::black_box(footlight::render::view::reference_in_window(&dense, w, h));
            });
            time("pairs (with their own level)", &|| {
                std::hint::black_box(v.gradient_pairs(scene, &dense, aa));
            });
            time("highlight pixels", &|| {
                std::hint::black_box(v.glint_pixels(scene, light, &dense, reference, 100.0));
            });
            time("whole decision", &|| {
                std::hint::black_box(v.aa_decision(scene, light, &dense, aa));
            });
        }
        "base" => {
            let (v1, vb) = (s.view(Sampling::One), s.view(Sampling::Adaptive));
            let mut best = [f64::INFINITY; 4];
            for _ in 0..30 {
                for (k, set) in [SampleSet::Centre, SampleSet::Binned].into_iter().enumerate() {
                    let t = Instant::now();
                    std::hint::black_box(View::expand_all(scene, &s.g, set, s.limits));
                    best[k] = best[k].min(ms(t));
                }
                for (k, v) in [&v1, &vb].into_iter().enumerate() {
                    let t = Instant::now();
                    std::hint::black_box(v.render_direct(scene, light, None));
                    best[2 + k] = best[2 + k].min(ms(t));
                }
            }
            let ratio = (best[1] + best[3]) / (best[0] + best[2]) * 100.0;
            println!(
                "expansion {:.2} / {:.2} ms, shading {:.2} / {:.2} ms (1 sample / bins): bins {ratio:.1} %",
                best[0], best[1], best[2], best[3]
            );
        }
        "single" => {
            let v0 = s.view(Sampling::Adaptive);
            let (dense0, _) = v0.render_direct(scene, light, None);
            let mut best = [f64::INFINITY; 4];
            for _ in 0..15 {
                for (k, sampling) in [Sampling::One, Sampling::Adaptive].into_iter().enumerate() {
                    let g = s.g.clone();
                    let t = Instant::now();
                    let v = View::from_gbuffer(scene, g, sampling, s.limits);
                    std::hint::black_box(v.render_direct(scene, light, None));
                    best[k] = best[k].min(ms(t));
                }
                let v = s.view(Sampling::Adaptive);
                let mut dense = dense0.clone();
                let t = Instant::now();
                let decision = v.aa_decision(scene, light, &dense, aa);
                best[2] = best[2].min(ms(t));
                let t = Instant::now();
                v.reshade(scene, light, &mut dense, decision.reshading());
                best[3] = best[3].min(ms(t));
            }
            let pct = |x: f64| x / best[0] * 100.0;
            println!(
                "1 sample {:.2} ms; bins {:.2} ms ({:.1} %); decision {:.2} ms ({:.1} %); re-shading {:.2} ms ({:.1} %)",
                best[0],
                best[1],
                pct(best[1]),
                best[2],
                pct(best[2]),
                best[3],
                pct(best[3])
            );
        }
        "bins" => {
            for sampling in [Sampling::One, Sampling::Adaptive] {
                let v = s.view(sampling);
                let (mut single, mut multi) = ([0usize; 6], [0usize; 6]);
                let mut by = std::collections::BTreeMap::new();
                for i in 0..800 * 500 {
                    let several = s.g.bins(i).len() > 1;
                    for x in v.shading.pixel(i) {
                        *by.entry(scene.materials[x.material as usize].name.clone()).or_insert(0usize) += 1;
                        let d = (x.depth as usize).min(5);
                        if several { multi[d] += 1 } else { single[d] += 1 }
                    }
                }
                println!(
                    "{sampling:?}: {} vertices; by depth, one bin {single:?}, several {multi:?}",
                    v.shading.vertex_count()
                );
                println!("  {by:?}");
            }
        }
        "borrow" => borrow(&s),
        "recon" => recon(&s),
        "loop1" | "loopa" => {
            let (sampling, a) = if args[0] == "loop1" { (Sampling::One, None) } else { (Sampling::Adaptive, Some(aa)) };
            let mut best = f64::INFINITY;
            for _ in 0..60 {
                let g = s.g.clone();
                let t = Instant::now();
                let v = View::from_gbuffer(scene, g, sampling, s.limits);
                std::hint::black_box(v.render_direct(scene, light, a));
                best = best.min(ms(t));
            }
            println!("{} fastest {best:.2} ms", args[0]);
        }
        "warm" => {
            let v0 = s.view(Sampling::Adaptive);
            let (dense0, _) = v0.render_direct(scene, light, None);
            let mut best = [f64::INFINITY; 2];
            for _ in 0..15 {
                let v = s.view(Sampling::Adaptive);
                let decision = v.aa_decision(scene, light, &dense0, aa);
                for k in 0..2 {
                    let mut dense = dense0.clone();
                    let t = Instant::now();
                    v.reshade(scene, light, &mut dense, decision.reshading());
                    best[k] = best[k].min(ms(t));
                }
            }
            println!("re-shading cold {:.2} ms, warm cache {:.2} ms", best[0], best[1]);
        }
        "light" => {
            let reference = s.reference();
            let v = s.view(Sampling::Adaptive);
            let (base, _) = v.render_direct(scene, light, None);
            let (shipped, n) = v.render_direct(scene, light, Some(aa));
            let on_curtain = |i: usize| {
                let t = s.g.samples[i][4].triangle;
                t != NO_HIT && scene.materials[scene.material_of[t as usize] as usize].name.contains("curtain")
            };
            let curtain = (0..base.len()).filter(|&i| base[i].max_element() > 0.0 && on_curtain(i)).count();
            println!(
                "lit curtain px {curtain}; vertices {}; bins only MSE R {:.3e}; shipped {:.3e} ({n} re-shaded)",
                v.shading.vertex_count(),
                s.mse(&base, &reference),
                s.mse(&shipped, &reference)
            );
        }
        other => panic!("unknown probe {other}"),
    }
}

/// Minor matte bins of multi-bin pixels take the value of a neighbouring
/// single-bin pixel on the same surface instead of their own shading.
fn borrow(s: &Setup) {
    let (scene, light, g) = (&s.scene, &s.light, &s.g);
    let (w, h) = (800usize, 500usize);
    let reference = s.reference();
    let v = s.view(Sampling::Adaptive);
    let (dense, _) = v.render_direct(scene, light, None);
    let material = |t: u32| &scene.materials[scene.material_of[t as usize] as usize];
    let shades = |t: u32| material(t).diffuse.max_element() > 0.0 || material(t).specular.max_element() > 0.0;
    let terminal = |t: u32| material(t).k_r.max_element() <= 0.0 && material(t).k_t.max_element() <= 0.0;
    let surface = |t: u32, u: f32, vv: f32| scene.surface(&Hit { triangle: t, t: 0.0, u, v: vv });
    let mut out = dense.clone();
    let mut borrowed = 0;
    for i in 0..w * h {
        let bins = g.bins(i);
        if bins.len() < 2 {
            continue;
        }
        // The pixel's vertices, one group per shaded bin (each starts at depth 0).
        let verts = v.shading.pixel(i);
        let starts: Vec<usize> = (0..verts.len()).filter(|&k| verts[k].depth == 0).chain([verts.len()]).collect();
        let shaded: Vec<_> = bins.iter().filter(|b| b.triangle != NO_HIT && shades(b.triangle)).collect();
        assert_eq!(shaded.len() + 1, starts.len());
        let centre = g.samples[i][4].triangle;
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        let mut value = Vec3::ZERO;
        for (k, b) in shaded.iter().enumerate() {
            let group = &verts[starts[k]..starts[k + 1]];
            let own = group.iter().map(|vx| vx.weight * direct(scene, light, vx)).sum::<Vec3>();
            if b.triangle == centre || !terminal(b.triangle) || group.len() != 1 {
                value += own;
                continue;
            }
            let sp = surface(b.triangle, b.u, b.v);
            let lender = (-1i64..=1)
                .flat_map(|dy| (-1i64..=1).map(move |dx| (x + dx, y + dy)))
                .filter(|&(qx, qy)| (qx, qy) != (x, y) && qx >= 0 && qy >= 0 && qx < w as i64 && qy < h as i64)
                .map(|(qx, qy)| qy as usize * w + qx as usize)
                .filter_map(|q| {
                    let qb = g.bins(q);
                    let ok = qb.len() == 1
                        && qb[0].triangle != NO_HIT
                        && scene.material_of[qb[0].triangle as usize] == scene.material_of[b.triangle as usize];
                    let qs = ok.then(|| surface(qb[0].triangle, qb[0].u, qb[0].v))?;
                    (qs.shading_normal.dot(sp.shading_normal) >= 0.99).then(|| (qs.position.distance(sp.position), q))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            match lender {
                Some((_, q)) => {
                    value += b.weight * dense[q];
                    borrowed += 1;
                }
                None => value += own,
            }
        }
        out[i] = value;
    }
    println!(
        "borrowed bins {borrowed}; base MSE R {:.3e} -> {:.3e}",
        s.mse(&dense, &reference),
        s.mse(&out, &reference)
    );
    for t in [100.0f32, 120.0, 150.0] {
        for (name, base) in [("own bins", &dense), ("borrowed", &out)] {
            let v2 = s.view(Sampling::Adaptive);
            let mut d = base.clone();
            let decision = v2.aa_decision(scene, light, &d, AaParams::new(t));
            let n = v2.reshade(scene, light, &mut d, decision.reshading());
            println!("threshold {t}, {name}: {n} re-shaded, MSE R {:.3e}", s.mse(&d, &reference));
        }
    }
}

/// Image-space reconstruction of marked pixels (probe): which subsets must be
/// re-shaded and which can be filtered from the base.
fn recon(s: &Setup) {
    let (scene, light) = (&s.scene, &s.light);
    let (w, h) = (800usize, 500usize);
    let reference = s.reference();
    let v = s.view(Sampling::Adaptive);
    let (base, _) = v.render_direct(scene, light, None);
    let th: f32 = std::env::var("FL_T").ok().and_then(|x| x.parse().ok()).unwrap_or(100.0);
    let d = v.aa_decision(scene, light, &base, AaParams::new(th));
    let flags = d.flags.clone();
    let marked: Vec<usize> = (0..w * h).filter(|&i| flags[i]).collect();
    let spec: Vec<bool> = (0..w * h).map(|i| s.specular(i)).collect();
    // Full 9-sample value of every marked pixel (shipped re-shading).
    let mut nine = base.clone();
    v.reshade(scene, light, &mut nine, Reshading { flags: &flags, whole: &d.highlights, corners_first: d.level });
    println!("marked {} (specular {}), highlights {}", marked.len(), marked.iter().filter(|&&i| spec[i]).count(), d.highlights.len());
    println!("bins only {:.3e}; shipped {:.3e}", s.mse(&base, &reference), s.mse(&nine, &reference));
    let tent = |img: &[Vec3], i: usize, wc: f32, we: f32, wd: f32| -> Vec3 {
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        let mut acc = Vec3::ZERO;
        let mut wsum = 0.0;
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (qx, qy) = (x + dx, y + dy);
                if qx < 0 || qy < 0 || qx >= w as i64 || qy >= h as i64 { continue; }
                let q = qy as usize * w + qx as usize;
                let wt = match dx.abs() + dy.abs() { 0 => wc, 1 => we, _ => wd };
                acc += wt * img[q];
                wsum += wt;
            }
        }
        acc / wsum
    };
    let cases: [(&str, fn(bool, bool) -> u8); 5] = [
        ("highlights 9, rest base", |hl, _| if hl { 2 } else { 0 }),
        ("highlights 9, rest filtered", |hl, _| if hl { 2 } else { 1 }),
        ("highlights+matte 9, specular filtered", |hl, sp| if hl || !sp { 2 } else { 1 }),
        ("highlights+specular 9, matte filtered", |hl, sp| if hl || sp { 2 } else { 1 }),
        ("highlights+matte 9, specular base", |hl, sp| if hl || !sp { 2 } else { 0 }),
    ];
    for (wc, we, wd) in [(4.0, 2.0, 1.0), (1.0, 1.0, 1.0), (2.0, 1.0, 0.0), (8.0, 2.0, 1.0)] {
        for (name, rule) in cases {
            let mut out = base.clone();
            let mut n9 = 0;
            for &i in &marked {
                match rule(d.highlights.contains(&i), spec[i]) {
                    2 => { out[i] = nine[i]; n9 += 1; }
                    1 => out[i] = tent(&base, i, wc, we, wd),
                    _ => {}
                }
            }
            println!("tent {wc}/{we}/{wd} {name}: {n9} at 9 samples, MSE R {:.3e}", s.mse(&out, &reference));
        }
    }
}
