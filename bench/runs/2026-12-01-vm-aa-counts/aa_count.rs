//! Probe (not shipped): instruction counts under callgrind of one fresh
//! view's 1-sample pass and adaptive pass (`--toggle-collect=aa_count::pass*`).
use footlight::fixture::Light;
use footlight::render::gbuffer::GBuffer;
use footlight::render::{AaParams, RecursionLimits, Sampling, View};
use footlight::scene::{Camera, Scene};

#[inline(never)]
fn pass_one(scene: &Scene, g: GBuffer, light: &Light) -> usize {
    let v = View::from_gbuffer(scene, g, Sampling::One, RecursionLimits::default());
    v.render_direct(scene, light, None).0.len()
}

#[inline(never)]
fn pass_adaptive(scene: &Scene, g: GBuffer, light: &Light, aa: AaParams) -> usize {
    let v = View::from_gbuffer(scene, g, Sampling::Adaptive, RecursionLimits::default());
    v.render_direct(scene, light, Some(aa)).1
}

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = footlight::scene::load(&root.join("scenes/stage.glb")).unwrap();
    let patch = footlight_mvr::load_patch(&root.join("patch/paper-rig.toml")).unwrap();
    let camera = patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera).unwrap();
    let g = GBuffer::build(&scene, camera, 800, 500);
    let light = patch.fixtures[0].light.clone();
    let aa = AaParams::new(std::env::var("FL_T").ok().and_then(|x| x.parse().ok()).unwrap_or(100.0));
    match std::env::args().nth(1).as_deref() {
        Some("one") => println!("{}", pass_one(&scene, g, &light)),
        Some("none") => println!("{}", g.samples.len()),
        _ => println!("{}", pass_adaptive(&scene, g, &light, aa)),
    }
}
