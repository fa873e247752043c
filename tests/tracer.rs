//! The tracer supervised (issue 33) and within a memory budget (issue 38
//! items 1 and 3): a panicking build marks its light failed and the other
//! lights still build; a dead worker is reported; dark lights queue behind
//! lit ones, are evicted first past the budget, and one that lights is
//! rebuilt at once.

use crate::common::*;
use footlight::live::{Stage, Tracer, TracerSettings};
use footlight::render::{RecursionLimits, Sampling, View};
use footlight::scene::{Camera, Scene, SceneBuilder};
use glam::Vec3;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn small_stage() -> (Arc<Scene>, Camera) {
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.8);
    floor(&mut b, 10.0, 0.0, m);
    (Arc::new(b.build()), Camera::look_at(Vec3::new(0.0, 6.0, 0.01), Vec3::ZERO, 70f32.to_radians()))
}

/// A spot 2 m over the floor at `x`, aimed straight down.
fn spot(x: f32) -> footlight::Light {
    footlight::Light::aimed(
        Vec3::new(x, 2.0, 0.0),
        Vec3::new(x, 0.0, 0.0),
        footlight::Beam::Spot(footlight::fixture::SpotBeam::from_beam_field(30.0, 40.0)),
    )
}

fn settings() -> TracerSettings {
    let mut settings = TracerSettings { threads: 1, ..TracerSettings::default() };
    settings.build.photons = None;
    settings
}

fn tracer(lights: usize, settings: TracerSettings) -> Tracer {
    let (scene, camera) = small_stage();
    let view = View::build(&scene, camera, 48, 48, Sampling::Adaptive, RecursionLimits::default());
    Tracer::new(scene, Arc::new(view), lights, settings)
}

/// Polls `what` (the tracer's worker is a real thread) for at most 60 s.
fn wait_until(what: impl Fn() -> bool, stuck: impl Fn() -> String) {
    let t = Instant::now();
    while !what() {
        assert!(t.elapsed() < Duration::from_secs(60), "{}", stuck());
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn a_panicking_build_marks_its_light_failed_and_the_others_still_build() {
    let tracer = tracer(3, settings());
    tracer.set_names(vec!["Spot A".into(), "Spot B".into(), "Spot C".into()]);
    // Light 1 is built first (brightest lit light first among equal waits:
    // it is requested first), then panics in its next stage.
    tracer.request(0, spot(-1.0), 1.0);
    wait_until(|| tracer.published(0).stage == Stage::Ready, || format!("{:?}", tracer.published(0).stage));
    let before = tracer.published(0);
    tracer.inject_build_panic(0);
    tracer.request(0, spot(1.0), 1.0);
    tracer.request(1, spot(0.0), 1.0);
    tracer.request(2, spot(-2.0), 1.0);
    let done = |i: usize| tracer.published(i).stage == Stage::Ready;
    wait_until(|| done(1) && done(2), || format!("{:?} {:?}", tracer.report(1), tracer.report(2)));
    // Light 0: failed, with its error, and its last picture kept.
    let report = tracer.report(0).expect("light 0");
    let failed = report.failed.as_deref().expect("light 0 failed");
    assert!(failed.contains("panicked") && failed.contains("injected build panic"), "{failed}");
    assert_eq!(tracer.failed().iter().map(|(i, _)| *i).collect::<Vec<_>>(), vec![0]);
    let shown = tracer.published(0);
    assert!(Arc::ptr_eq(&shown.buffer, &before.buffer), "the last published buffer stays");
    assert_eq!(shown.generation, before.generation);
    assert!(tracer.report(1).unwrap().failed.is_none() && tracer.report(2).unwrap().failed.is_none());
    assert!(tracer.worker_error().is_none(), "the worker goes on");
    // The next request of light 0 builds it, and clears the failure.
    tracer.request(0, spot(1.5), 1.0);
    wait_until(|| done(0) && tracer.report(0).unwrap().failed.is_none(), || format!("{:?}", tracer.report(0)));
    assert!(tracer.failed().is_empty());
}

#[test]
fn a_dead_worker_is_reported_not_silent() {
    let tracer = tracer(1, settings());
    assert!(tracer.worker_error().is_none());
    tracer.inject_worker_panic();
    wait_until(|| tracer.worker_error().is_some(), || "the worker's death was not reported".into());
    assert!(tracer.worker_error().unwrap().contains("injected worker panic"), "{:?}", tracer.worker_error());
}

/// Stop cuts a build inside its photon stage (issue 38 item 6): the worker
/// ends with the photon stage of a two-million-photon light unfinished (no
/// photon trace counted, the Whitted buffer still on screen), instead of
/// finishing the stage first.
#[test]
fn stop_cancels_a_build_inside_its_photon_stage() {
    let mut settings = settings();
    settings.build.photons =
        Some(footlight::render::photon::PhotonSettings { stored: 2_000_000, ..Default::default() });
    let tracer = tracer(1, settings);
    tracer.request(0, spot(0.0), 1.0);
    // Whitted published: the photon stage is next (and nothing else is due).
    wait_until(|| tracer.published(0).stage == Stage::Whitted, || format!("{:?}", tracer.published(0).stage));
    std::thread::sleep(Duration::from_millis(20));
    tracer.stop();
    wait_until(|| tracer.worker_finished(), || "the worker did not stop".into());
    assert_eq!(tracer.photon_traces(), 0, "the photon stage was cut, not finished");
    assert_eq!(tracer.published(0).stage, Stage::Whitted);
    assert!(tracer.shutdown(Duration::from_secs(1)), "the worker is joined");
}
