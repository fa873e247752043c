//! Probes behind "Sixth session of 2026-12-01" in docs/rendering.md. Not
//! part of the build: copy to examples/ (see README.md).
//!
//!   aa_probe count none|one|adaptive  the setup alone, or with one fresh
//!                                     view's pass (run under callgrind)
//!   aa_probe classes                  marked pixels by class, each class's
//!                                     re-shading time; highlight-only pixels
//!                                     at depth 0 (FL_LOOP=1: the specular
//!                                     pair pixels' 9 paths, 1000 times, for perf)
//!   FL_MAT=1 aa_probe classes         re-shading time and error by material
//!   FL_COST=1 aa_probe classes        a cost-aware threshold (FL_ALPHAS, FL_N0,
//!                                     FL_UNIFORM: plain thresholds to compare)
//!   aa_probe illum                    direct + indirect, 1 sample vs adaptive
//!                                     (FL_ROUNDS rounds, FL_FIXTURE=n)
use footlight::bench::mse_display;
use footlight::bench::sweeps::reference_81;
use footlight::fixture::Light;
use footlight::render::gbuffer::{GBuffer, NO_HIT};
use footlight::render::photon::{PhotonSettings, trace_photons};
use footlight::render::view::{Reshading, SampleSet, expand_pixel};
use footlight::render::whitted::direct;
use footlight::render::{AaParams, Display, RecursionLimits, Sampling, View};
use footlight::scene::{Camera, Scene};
use glam::Vec3;
use std::time::Instant;

struct Setup {
    scene: Scene,
    g: GBuffer,
    light: Light,
    kf: Vec3,
    limits: RecursionLimits,
    aa: AaParams,
}

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|x| x.parse().ok())
}

fn list(name: &str) -> Option<Vec<f32>> {
    std::env::var(name).ok().map(|a| a.split(',').map(|x| x.parse().unwrap()).collect())
}

impl Setup {
    fn new() -> Self {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let scene = footlight::scene::load(&root.join("scenes/stage.glb")).unwrap();
        let patch = footlight_mvr::load_patch(&root.join("patch/paper-rig.toml")).unwrap();
        let camera = patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera).unwrap();
        let g = GBuffer::build(&scene, camera, 800, 500);
        let f = &patch.fixtures[env("FL_FIXTURE").unwrap_or(0)];
        let aa = AaParams::new(env("FL_T").unwrap_or(100.0));
        Self { g, light: f.light.clone(), kf: f.k_full(), limits: RecursionLimits::default(), aa, scene }
    }
    fn view(&self, sampling: Sampling) -> View {
        View::from_gbuffer(&self.scene, self.g.clone(), sampling, self.limits)
    }
}

#[inline(never)]
fn pass(s: &Setup, g: GBuffer, sampling: Sampling, aa: Option<AaParams>) -> usize {
    let v = View::from_gbuffer(&s.scene, g, sampling, s.limits);
    v.render_direct(&s.scene, &s.light, aa).1
}

/// The binned base and the anti-aliasing decision, without re-shading.
#[inline(never)]
fn decide(s: &Setup, g: GBuffer) -> usize {
    let v = View::from_gbuffer(&s.scene, g, Sampling::Adaptive, s.limits);
    let (base, _) = v.render_direct(&s.scene, &s.light, None);
    v.aa_decision(&s.scene, &s.light, &base, s.aa).flags.iter().filter(|f| **f).count()
}

fn count(s: Setup, what: &str) {
    let g = s.g.clone();
    match what {
        "none" => println!("{}", g.samples.len()),
        "one" => println!("{}", pass(&s, g, Sampling::One, None)),
        "bins" => println!("{}", pass(&s, g, Sampling::Geometry, None)),
        "decide" => println!("{}", decide(&s, g)),
        _ => println!("{}", pass(&s, g, Sampling::Adaptive, Some(s.aa))),
    }
}

fn illum(s: &Setup) {
    let (scene, light) = (&s.scene, &s.light);
    let t0 = Instant::now();
    let maps = trace_photons(scene, light, &PhotonSettings::default());
    println!("photon maps {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
    // [direct, indirect] for 1 sample, then adaptive; the direct timer holds
    // the G-buffer's copy in both.
    let mut all: Vec<[f64; 4]> = Vec::new();
    for _ in 0..env("FL_ROUNDS").unwrap_or(9) {
        let mut r = [0.0; 4];
        for (k, (sampling, a)) in [(Sampling::One, None), (Sampling::Adaptive, Some(s.aa))].into_iter().enumerate() {
            let t = Instant::now();
            let v = s.view(sampling);
            std::hint::black_box(v.render_direct(scene, light, a));
            r[2 * k] = t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let e = v.vertex_irradiance(scene, &maps);
            std::hint::black_box(v.render_vertex_irradiance(scene, &e));
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

fn classes(s: &Setup) {
    let (scene, light, g, aa) = (&s.scene, &s.light, &s.g, s.aa);
    let reference: Vec<Vec3> = reference_81(scene, g, light, s.limits).iter().map(|x| *x * s.kf).collect();
    let mse = |dense: &[Vec3]| {
        let out: Vec<Vec3> = dense.iter().map(|x| *x * s.kf).collect();
        mse_display(&out, &reference, &Display::default())[0]
    };
    let material = |i: usize| {
        let t = g.samples[i][4].triangle;
        (t != NO_HIT).then(|| &scene.materials[scene.material_of[t as usize] as usize])
    };
    let specular = |i: usize| material(i).is_some_and(|m| m.k_r.max_element() > 0.0 || m.k_t.max_element() > 0.0);
    let v0 = s.view(Sampling::Adaptive);
    let (base, _) = v0.render_direct(scene, light, None);
    let d = v0.aa_decision(scene, light, &base, aa);
    let pairflags = v0.gradient_flags(scene, &base, aa);
    let n = base.len();
    let highlight_only = |i: usize| d.highlights.contains(&i) && !pairflags[i];
    // `flags` re-shaded on fresh views: the fastest of `rounds`, and the picture.
    let reshade = |flags: &[bool], rounds: usize| {
        let mut best = f64::INFINITY;
        let mut dense = base.clone();
        for _ in 0..rounds {
            let v = s.view(Sampling::Adaptive);
            dense.copy_from_slice(&base);
            let t0 = Instant::now();
            v.reshade(scene, light, &mut dense, Reshading { flags, whole: &d.highlights, corners_first: d.level });
            best = best.min(t0.elapsed().as_secs_f64() * 1e3);
        }
        (best, dense)
    };
    let pixels = |flags: &[bool]| flags.iter().filter(|f| **f).count();
    println!(
        "threshold {}: marked {}, highlight-only {}, highlight+pair {}, pair specular {}, pair matte {}",
        aa.threshold,
        pixels(&d.flags),
        (0..n).filter(|&i| highlight_only(i)).count(),
        d.highlights.iter().filter(|&&i| pairflags[i]).count(),
        (0..n).filter(|&i| pairflags[i] && specular(i) && !d.highlights.contains(&i)).count(),
        (0..n).filter(|&i| pairflags[i] && !specular(i) && !d.highlights.contains(&i)).count(),
    );
    if std::env::var("FL_LOOP").is_ok() {
        let spec: Vec<usize> = (0..n).filter(|&i| pairflags[i] && specular(i)).collect();
        let (mut out, mut verts, mut acc) = (Vec::new(), 0, Vec3::ZERO);
        let t0 = Instant::now();
        for _ in 0..1000 {
            for &i in &spec {
                out.clear();
                expand_pixel(scene, g, i, SampleSet::All, s.limits, &mut out);
                verts += out.len();
                acc += out.iter().map(|x| x.weight * direct(scene, light, x)).sum::<Vec3>();
            }
        }
        let per = t0.elapsed().as_secs_f64() * 1e3 / 1000.0;
        println!("{} px x1000: {per:.1} ms per pass, {} vertices per pass {acc}", spec.len(), verts / 1000);
        return;
    }
    let mut shipped = base.clone();
    v0.reshade(scene, light, &mut shipped, d.reshading());
    println!("shipped MSE R {:.4e}", mse(&shipped));
    if std::env::var("FL_COST").is_ok() {
        // Per pixel: the largest threshold at which a pair still marks it.
        let mut level = vec![0.0f32; n];
        let mut th = aa.threshold;
        while th <= 1000.0 {
            for (l, f) in level.iter_mut().zip(v0.gradient_flags(scene, &base, AaParams::new(th))) {
                if f {
                    *l = th;
                }
            }
            th += 10.0;
        }
        let verts: Vec<usize> = (0..n).map(|i| v0.shading.pixel(i).len()).collect();
        let n0: f32 = env("FL_N0").unwrap_or(2.0);
        let alphas = list("FL_ALPHAS").unwrap_or(vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        let uniform = list("FL_UNIFORM").unwrap_or_default();
        let rules = alphas.iter().map(|&a| (a, aa.threshold)).chain(uniform.iter().map(|&u| (0.0, u)));
        for (alpha, t) in rules {
            let cut = |i: usize| t * (verts[i] as f32 / n0).max(1.0).powf(alpha);
            let flags: Vec<bool> =
                (0..n).map(|i| d.highlights.contains(&i) || (level[i] > 0.0 && level[i] >= cut(i))).collect();
            let (best, dense) = reshade(&flags, 25);
            let vsum: usize = (0..n).filter(|&i| flags[i]).map(|i| verts[i]).sum();
            println!(
                "threshold {t} alpha {alpha} n0 {n0}: {} px ({vsum} base vertices), {best:.2} ms, MSE R {:.4e}",
                pixels(&flags),
                mse(&dense)
            );
        }
        return;
    }
    if std::env::var("FL_MAT").is_ok() {
        let name = |i: usize| material(i).map_or_else(|| "miss".to_string(), |m| m.name.clone());
        let mut names: Vec<String> = (0..n).filter(|&i| d.flags[i]).map(name).collect();
        names.sort();
        names.dedup();
        for m in names {
            let pick: Vec<bool> = (0..n).map(|i| d.flags[i] && name(i) == m).collect();
            let rest: Vec<bool> = (0..n).map(|i| d.flags[i] && !pick[i]).collect();
            let (_, without) = reshade(&rest, 1);
            let (best, _) = reshade(&pick, 9);
            println!("{m}: {} px, {best:.2} ms alone; MSE R without them {:.4e}", pixels(&pick), mse(&without));
        }
        return;
    }
    let classes: [(&str, &dyn Fn(usize) -> bool); 3] = [
        ("highlight-only", &|i| highlight_only(i)),
        ("pair specular", &|i| !highlight_only(i) && specular(i)),
        ("pair matte", &|i| !highlight_only(i) && !specular(i)),
    ];
    for (name, pick) in classes {
        let flags: Vec<bool> = (0..n).map(|i| d.flags[i] && pick(i)).collect();
        println!("{name}: {} px, {:.2} ms", pixels(&flags), reshade(&flags, 9).0);
    }
    // Highlight-only pixels at depth 0: 9 primary vertices, the base's deeper vertices.
    let depth0 = RecursionLimits { max_depth: 0, ..s.limits };
    let mut out = Vec::new();
    let mut mixed = shipped;
    let t0 = Instant::now();
    for i in (0..n).filter(|&i| highlight_only(i)) {
        out.clear();
        expand_pixel(scene, g, i, SampleSet::All, depth0, &mut out);
        let near: Vec3 = out.iter().map(|x| x.weight * direct(scene, light, x)).sum();
        let deep: Vec3 =
            v0.shading.pixel(i).iter().filter(|x| x.depth > 0).map(|x| x.weight * direct(scene, light, x)).sum();
        mixed[i] = near + deep;
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    println!("highlight-only at depth 0 (one thread): {ms:.2} ms, MSE R {:.4e}", mse(&mixed));
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let s = Setup::new();
    match args.first().map(String::as_str) {
        Some("count") => count(s, args.get(1).map_or("adaptive", String::as_str)),
        Some("illum") => illum(&s),
        _ => classes(&s),
    }
}
