//! The tracer supervised (issue 33) and within a memory budget (issue 38
//! items 1 and 3): a panicking build marks its light failed and the other
//! lights still build; a dead worker is reported; dark lights queue behind
//! lit ones, are evicted first past the budget, and one that lights is
//! rebuilt at once.

use crate::common::*;
use footlight::live::{Tracer, TracerSettings};
use footlight::output::Stage;
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

/// A panic outside any build restarts the worker (counted, its message
/// kept) and the lights go on building; panics past the restart limit end
/// it for good, reported instead of silent.
#[test]
fn a_panicking_worker_restarts_then_is_reported_not_silent() {
    let tracer = tracer(1, settings());
    assert!(tracer.worker_error().is_none());
    tracer.inject_worker_panic();
    wait_until(|| tracer.worker_restarts().0 == 1, || "the worker was not restarted".into());
    assert!(tracer.worker_restarts().1.unwrap().contains("injected worker panic"));
    assert!(tracer.worker_error().is_none(), "restarted, not dead");
    tracer.request(0, spot(0.0), 1.0);
    wait_until(|| tracer.published(0).stage == Stage::Ready, || format!("{:?}", tracer.published(0).stage));
    for n in 2..=3 {
        tracer.inject_worker_panic();
        wait_until(
            || tracer.worker_restarts().0 >= n || tracer.worker_error().is_some(),
            || format!("panic {n} went unnoticed"),
        );
    }
    wait_until(|| tracer.worker_error().is_some(), || "the worker's death was not reported".into());
    assert!(tracer.worker_error().unwrap().contains("injected worker panic"), "{:?}", tracer.worker_error());
    assert_eq!(tracer.worker_restarts().0, 2, "two restarts, then the limit");
    wait_until(|| tracer.worker_finished(), || "the dead worker's thread did not end".into());
}

/// The daemon's supervision task (issue 33): it ends with the light
/// builder's error once the worker died for good (the daemon then stops
/// with that error), and with Ok when the daemon stops first.
#[test]
fn the_daemons_supervision_task_reports_a_dead_light_builder() {
    use footlight::live::daemon::{stop_signal, supervise_tracer};
    let rt = tokio::runtime::Builder::new_current_thread().enable_time().start_paused(true).build().unwrap();
    let alive = Arc::new(tracer(1, settings()));
    let (tx, stop) = stop_signal();
    tx.send(true).unwrap();
    let (task, result) = rt.block_on(supervise_tracer(alive.clone(), stop));
    assert_eq!((task, result), ("light builder", Ok(())));
    let dying = Arc::new(tracer(1, settings()));
    for n in 1..=3 {
        dying.inject_worker_panic();
        wait_until(|| dying.worker_restarts().0 >= n || dying.worker_error().is_some(), || format!("panic {n}"));
    }
    wait_until(|| dying.worker_error().is_some(), || "the worker did not die".into());
    let (_tx, stop) = stop_signal();
    let (task, result) = rt.block_on(supervise_tracer(dying, stop));
    assert_eq!(task, "light builder");
    assert!(result.as_ref().is_err_and(|e| e.contains("injected worker panic")), "{result:?}");
}

/// Scheduling rule 6 (issue 38: moved heads while the rig builds): a
/// photon stage in progress yields to a lit light's new request, whose
/// direct stage is published before any photon stage finished; the
/// yielded build is kept and its photon stage runs again, this time to the
/// end even when another light moves meanwhile (a build yields once).
#[test]
fn a_photon_stage_yields_once_to_a_lit_light_that_moves() {
    let mut settings = TracerSettings { settle: Duration::ZERO, ..settings() };
    settings.build.photons = Some(footlight::render::photon::PhotonSettings { stored: 600_000, ..Default::default() });
    settings.build.refine_passes = 0;
    let tracer = tracer(3, settings);
    tracer.request(0, spot(-1.0), 1.0);
    // Whitted published: the 600,000-photon stage is next and nothing else is due.
    wait_until(|| tracer.published(0).stage == Stage::Whitted, || format!("{:?}", tracer.published(0).stage));
    std::thread::sleep(Duration::from_millis(20));
    tracer.request(1, spot(0.5), 1.0);
    wait_until(|| tracer.published(1).stage != Stage::Queued, || "no direct stage for the moved light".into());
    assert_eq!(tracer.photon_traces(), 0, "the photon stage yielded before it finished");
    assert_eq!(tracer.photon_yields(), 1);
    assert_eq!(tracer.published(0).stage, Stage::Whitted, "the yielded light keeps its picture");
    // Light 1's own photon stage may yield to light 2; light 0's retry may not.
    wait_until(|| tracer.published(1).stage == Stage::Ready, || format!("{:?}", tracer.published(1).stage));
    tracer.request(2, spot(1.5), 1.0);
    wait_until(
        || (0..3).all(|i| tracer.published(i).stage == Stage::Ready),
        || format!("{:?}", (0..3).map(|i| tracer.published(i).stage).collect::<Vec<_>>()),
    );
    assert_eq!(tracer.photon_yields(), 1, "light 0's second photon stage did not yield to light 2");
    assert_eq!(tracer.photon_traces(), 3, "every light traced its photons once to the end");
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

/// Issue 38 items 1 and 3: dark lights queue behind lit ones, and past the
/// memory budget the dark lights' buffers go first (least recently lit
/// first), the lit ones stay, used bytes end within the budget, and an
/// evicted light that lights is rebuilt at once.
#[test]
fn dark_lights_wait_for_lit_ones_and_are_evicted_first_past_the_memory_budget() {
    // Settled at once: a lit light's later stages are due right after its
    // direct stage (with the default 150 ms, dark lights use that idle time).
    let tracer = tracer(6, TracerSettings { settle: Duration::ZERO, ..settings() });
    // Lights 0, 2, 4 dark; 1, 3, 5 lit. The dark ones are requested first (they wait longest).
    let x = |i: usize| -2.5 + i as f32;
    // All queued at once (paused meanwhile, so the worker sees the whole queue).
    tracer.set_paused(true);
    for i in [0, 2, 4, 1, 3, 5] {
        tracer.request(i, spot(x(i)), if i % 2 == 1 { 1.0 } else { 0.0 });
    }
    tracer.set_paused(false);
    let ready = |i: usize| tracer.published(i).stage == Stage::Ready;
    wait_until(|| (0..6).all(ready), || format!("{:?}", (0..6).map(|i| tracer.published(i).stage).collect::<Vec<_>>()));
    // (a) Every publish of a lit light (direct and Whitted) came before the first of any dark light.
    let lit_last = [1, 3, 5].iter().map(|&i| tracer.publish_order(i).1.unwrap()).max().unwrap();
    let dark_first = [0, 2, 4].iter().map(|&i| tracer.publish_order(i).0.unwrap()).min().unwrap();
    assert!(lit_last < dark_first, "lit lights' last publish {lit_last}, dark lights' first {dark_first}");

    // Light 4 was lit a moment ago, 0 and 2 never: 4 is evicted last.
    tracer.set_priority(4, 1.0);
    tracer.set_priority(4, 0.0);
    let all = tracer.memory();
    assert!(!all.over_budget && all.evicted_lights == 0, "{all:?}");
    let per_light = all.buffers_bytes / 6;
    assert!(per_light > 0 && all.caches_bytes > 0, "{all:?}");
    // (b) A budget that holds the lit lights and about one more buffer.
    let budget = all.lit_bytes + per_light + per_light / 2;
    tracer.set_memory_budget(budget);
    let after = tracer.memory();
    assert!(after.used_bytes <= budget, "{after:?}");
    assert!(!after.over_budget);
    assert!(tracer.evicted(0) && tracer.evicted(2), "never-lit dark lights go first");
    for i in [1, 3, 5] {
        assert!(!tracer.evicted(i) && ready(i), "lit light {i} kept");
    }
    assert_eq!(tracer.published(0).stage, Stage::Queued);
    assert!(!tracer.any_queued(), "an evicted dark light does not hold the moving preview");
    // The evicted light 0 lights: rebuilt (or restored) at once, and the budget holds again.
    tracer.set_priority(0, 1.0);
    assert!(!tracer.evicted(0));
    wait_until(|| ready(0), || format!("{:?}", tracer.published(0).stage));
    let relit = tracer.memory();
    assert!(relit.used_bytes <= budget || relit.over_budget, "{relit:?}");
    assert!(!tracer.evicted(0) && (1..6).step_by(2).all(|i| !tracer.evicted(i)));
    // Lit lights alone over the budget: said, nothing lit evicted, the tracer goes on.
    tracer.set_memory_budget(1 << 20);
    tracer.set_memory_budget(relit.lit_bytes / 2);
    let over = tracer.memory();
    assert!(over.over_budget, "{over:?}");
    assert!([0, 1, 3, 5].iter().all(|&i| !tracer.evicted(i) && ready(i)));
    tracer.request(1, spot(0.3), 1.0);
    wait_until(|| ready(1), || format!("{:?}", tracer.published(1).stage));
}

#[test]
fn memory_budgets_parse_bytes_suffixes_and_percentages() {
    use footlight::memory::parse_budget;
    let gib = 1u64 << 30;
    assert_eq!(parse_budget("4G", None), Ok(4 * gib));
    assert_eq!(parse_budget("512M", None), Ok(512 << 20));
    assert_eq!(parse_budget("1.5GiB", None), Ok(3 * gib / 2));
    assert_eq!(parse_budget("2097152", None), Ok(2 << 20));
    assert_eq!(parse_budget("25%", Some(16 * gib)), Ok(4 * gib));
    assert_eq!(parse_budget("50%", None), Ok(footlight::memory::FALLBACK_BUDGET));
    assert!(parse_budget("0%", Some(gib)).is_err() && parse_budget("101%", Some(gib)).is_err());
    assert!(parse_budget("lots", None).is_err() && parse_budget("100K", None).is_err());
}

/// Issue 38 item 4, both ways: a stage that starts while the frame clock is
/// quiet runs with the quiet threads added, and once a tick took longer
/// than `quiet_tick` the stages within `quiet_hold` run on the build
/// threads alone (the clock has its core back). A short tick does not make
/// the clock busy. The pool a stage runs on never changes its picture: the
/// buffers are bit for bit those of a tracer with no quiet threads.
#[test]
fn stages_take_the_clocks_core_only_while_the_clock_is_quiet() {
    let quiet = TracerSettings {
        quiet_threads: 1,
        quiet_tick: Duration::from_millis(8),
        quiet_hold: Duration::from_secs(3600),
        ..settings()
    };
    let a = tracer(2, quiet);
    let b = tracer(2, TracerSettings { quiet_threads: 0, ..settings() });
    let ready = |t: &Tracer, i: usize| t.published(i).stage == Stage::Ready;
    for t in [&a, &b] {
        t.request(0, spot(-1.0), 1.0);
        wait_until(|| ready(t, 0), || format!("{:?}", t.report(0)));
    }
    let quiet_stages = a.quiet_stages();
    assert!(quiet_stages >= 2, "direct and Whitted stages with the quiet threads: {quiet_stages}");
    assert_eq!(b.quiet_stages(), 0, "no quiet threads, no quiet stages");
    assert_eq!(a.published(0).buffer.to_dense(), b.published(0).buffer.to_dense(), "same picture on more threads");

    // A short tick leaves the clock quiet.
    a.clock_tick(Duration::from_millis(5));
    a.request(1, spot(1.0), 1.0);
    wait_until(|| ready(&a, 1), || format!("{:?}", a.report(1)));
    let after_short = a.quiet_stages();
    assert!(after_short >= quiet_stages + 2, "still quiet after a 5 ms tick: {after_short}");

    // A long tick (a broad cue's composite): no stage takes the clock's core.
    a.clock_tick(Duration::from_millis(30));
    a.request(0, spot(0.5), 1.0);
    a.request(1, spot(-0.5), 1.0);
    wait_until(|| ready(&a, 0) && ready(&a, 1), || format!("{:?} {:?}", a.report(0), a.report(1)));
    assert_eq!(a.quiet_stages(), after_short, "busy clock: the build threads alone");
    b.request(0, spot(0.5), 1.0);
    wait_until(|| ready(&b, 0), || format!("{:?}", b.report(0)));
    assert_eq!(a.published(0).buffer.to_dense(), b.published(0).buffer.to_dense(), "same picture either way");
}
