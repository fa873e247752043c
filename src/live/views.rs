//! Walking the stage (issue 16): camera moves, named views, the moving
//! preview and the cache of recent views.
//!
//! The paper fixes the camera (the G-buffer and every light buffer depend on
//! it). Here a camera write ([`Views::move_to`], from the page, the window or
//! a named view) is progressive:
//!
//! 1. **While moving** (a write less than [`ViewSettings::settle`] ago) the
//!    tracer is paused and the frame clock shows [`preview`]: one primary
//!    sample per pixel at reduced resolution, direct light of the lit lights
//!    only, summed with the current k_i in one pass (no per-light buffers).
//!    It goes through the same `Frame` channel, so a dimmer or colour change
//!    shows on the next frame whatever is on screen.
//! 2. **When it stops** the full [`View`] (9-sample G-buffer, Whitted camera
//!    paths) is built on the blocking pool, or taken from the [`ViewCache`],
//!    and swapped into the tracer ([`Tracer::set_view`]), which rebuilds
//!    every light brightest first with its stages published as usual. Photon
//!    maps survive (they do not depend on the camera); only the per-vertex
//!    estimates are redone. The preview stays up until every light has a
//!    buffer for the new view.
//! 3. **Cached views**: the view left behind keeps its `View` and each
//!    light's buffer with the geometry it was built for (LRU, bounded by
//!    bytes). Returning to it publishes those buffers at once for every light
//!    that has not moved meanwhile; the others are rebuilt.
//!
//! Views come from the scene's glTF camera, the patch's `[camera]` and
//! `[[view]]` tables, [`FRAME_VIEW`] (the rig and the stage from a
//! designer's seat, [`frame_rig`]) and views saved from the page (kept in
//! memory only, never written to a file). Poses are position + target +
//! vertical field of view: a glTF camera keeps its roll in [`Pose::up`]
//! (orbiting levels the horizon, as on the page).
//!
//! **A camera that stays on the stage** (issue 37). Every written pose is
//! confined by the scene's [`StageLimits`] (eye and target in the room, the
//! dolly's range, never behind a wall: `scene::camera`'s module doc), so a
//! drag from the page, the window or a named view can never leave the set.
//! The start view orbits about the stage centre: its target is the point
//! of its centre ray nearest the pivot ([`Pose::centred`]), not the
//! surface the ray meets (the back wall, 22 m away on the bundled stage).

use super::daemon::StopSignal;
use super::tracer::{Kept, Tracer};
use crate::Light;
use crate::output::camera::{LimitsStatus, ViewCacheStatus};
use crate::output::{CameraControl, NamedView, Phase, Pose, Stage, ViewSource, ViewStatus, WhiteState};
use crate::render::whitted::{RecursionLimits, expand};
use crate::render::{Display, Sampling, View};
use crate::scene::camera::{Bounds, StageLimits, fov_to_fit, frame_distance};
use crate::scene::{Camera, Scene};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::Notify;
use tokio::time::Instant;

/// Every default of the view machinery, in one place.
#[derive(Clone, Copy, Debug)]
pub struct ViewSettings {
    /// No camera write for this long: the camera has stopped (200 ms).
    pub settle: Duration,
    /// Byte budget of the view cache (views and their light buffers).
    pub cache_bytes: usize,
    /// The moving preview is rendered at 1/`preview_scale` of the picture
    /// size in each direction (2: a quarter of the pixels).
    pub preview_scale: u32,
    /// Views that can be saved from the page (bounds memory and the list).
    pub max_saved: usize,
}

impl Default for ViewSettings {
    fn default() -> Self {
        Self { settle: Duration::from_millis(200), cache_bytes: 1 << 30, preview_scale: 2, max_saved: 64 }
    }
}

/// The name of the view that frames the rig and the stage ([`frame_rig`]).
pub const FRAME_VIEW: &str = "frame the rig";
/// How far [`FRAME_VIEW`] looks down at the stage centre (degrees): a
/// desk at the back of raked stalls, or the front of a circle.
pub const FRAME_PITCH_DEG: f32 = 10.0;
/// Vertical field of view of [`FRAME_VIEW`] (degrees), widened (up to
/// [`FRAME_MAX_FOV_DEG`]) when a wall keeps the eye closer than the framing
/// distance.
pub const FRAME_FOV_DEG: f32 = 50.0;
/// The widest field of view [`FRAME_VIEW`] takes to fit the rig (degrees).
pub const FRAME_MAX_FOV_DEG: f32 = 100.0;
/// How far from the picture's centre to its edge the outermost framed
/// point may sit (a 10 % border).
pub const FRAME_FILL: f32 = 0.9;
/// The picture aspect [`FRAME_VIEW`] is framed for: 1 (square), so the
/// frame holds in every landscape or square picture; a wider picture shows
/// more at the sides.
pub const FRAME_ASPECT: f32 = 1.0;
/// Widest half-angle of a beam's footprint that framing follows (degrees):
/// a flood's edge rays would reach the walls.
const FOOTPRINT_HALF_ANGLE_DEG: f32 = 30.0;

/// How far outside the box of a dark rig's fixtures its focus and footprint
/// hits still count for framing (metres).
const DARK_RIG_REACH_M: f32 = 10.0;

/// The rig as the camera sees it: where the lights hang, where their beams
/// are focused (axis hits) and their footprints' edges (the edge rays'
/// hits). Made from the lit lights, or from every light when none is lit
/// (an MVR show starts black): then their positions and the focus and
/// footprint hits near them only.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Rig {
    /// The lights' positions.
    pub fixtures: Vec<Vec3>,
    /// Each beam axis's first opaque hit (beams into the void left out).
    pub focus: Vec<Vec3>,
    /// Hits of the rays at each footprint's edge (four per light, at its
    /// cut-off up to 30° off the axis).
    pub footprints: Vec<Vec3>,
}

impl Rig {
    /// The rig of `lights` (each light with its k_i) over `scene`: the lit
    /// ones (k_i luminance above 0), or all when none is lit.
    pub fn of(scene: &Scene, lights: &[(&Light, Vec3)]) -> Self {
        let luminance = |k: Vec3| k.dot(Vec3::new(0.2126, 0.7152, 0.0722));
        let lit: Vec<&Light> = lights.iter().filter(|(_, k)| luminance(*k) > 0.0).map(|(l, _)| *l).collect();
        let dark = lit.is_empty();
        let chosen: Vec<&Light> = if dark { lights.iter().map(|(l, _)| *l).collect() } else { lit };
        let mut rig = Self::default();
        for light in chosen.into_iter().filter(|l| l.position.is_finite()) {
            rig.add(scene, light);
        }
        // A dark rig (an MVR show before its look): where it hangs and what
        // it lights near itself. Beams at rest that reach far across an
        // open-air venue (a blinder tilted at the field) would pull the
        // camera 100 m back, so their hits are left out.
        let bounds = rig
            .fixtures
            .iter()
            .fold(None, |b: Option<(Vec3, Vec3)>, p| Some(b.map_or((*p, *p), |(lo, hi)| (lo.min(*p), hi.max(*p)))));
        if let (true, Some((lo, hi))) = (dark, bounds) {
            let near = |p: &Vec3| p.clamp(lo, hi).distance(*p) <= DARK_RIG_REACH_M;
            rig.focus.retain(near);
            rig.footprints.retain(near);
        }
        rig
    }

    /// Adds `light`: its position, its axis's hit and its footprint's edge hits.
    fn add(&mut self, scene: &Scene, light: &Light) {
        self.fixtures.push(light.position);
        self.focus.extend(crate::scene::camera::focus_point(scene, light.position, light.axis()));
        let half = light.beam.cos_cutoff().clamp(-1.0, 1.0).acos().min(FOOTPRINT_HALF_ANGLE_DEG.to_radians());
        for side in [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y] {
            let edge = light.rotation * glam::Quat::from_axis_angle(side.cross(Vec3::NEG_Z), half) * Vec3::NEG_Z;
            self.footprints.extend(crate::scene::camera::focus_point(scene, light.position, edge));
        }
    }

    /// True when there are no lights.
    pub fn is_empty(&self) -> bool {
        self.fixtures.is_empty()
    }
}

/// [`FRAME_VIEW`]: a level camera looking at `limits.pivot` (the stage
/// centre, so an orbit from it turns about the stage) from
/// [`FRAME_PITCH_DEG`] above, in the plan direction `start` looks (the
/// audience's side), as far back as the lit stage (the focus points and
/// footprints of `rig`), the pivot and the fixtures no nearer the audience
/// than all that they light need to fit a [`FRAME_FOV_DEG`] picture
/// ([`frame_distance`]): a front-of-house bar over the seats hangs behind
/// the designer and is left out. Without a rig, the corners of the scene's
/// `bounds` instead. The eye may sit outside the scene's bounds (in an
/// open house, in front of the set; the room then grows to hold it, as it
/// holds every named view's eye), but never behind a wall
/// ([`crate::scene::camera::behind_wall`]): if one kept it nearer, the
/// field of view widens to fit ([`fov_to_fit`], at most
/// [`FRAME_MAX_FOV_DEG`]).
pub fn frame_rig(scene: &Scene, rig: &Rig, bounds: &Bounds, start: &Camera, limits: &StageLimits) -> Pose {
    let pivot = limits.pivot;
    // The audience's side: where the start camera looks, in plan.
    let plan = {
        let f = -start.basis.z_axis;
        Vec3::new(f.x, 0.0, f.z).try_normalize().unwrap_or(Vec3::NEG_Z)
    };
    // What is lit, and the fixtures no nearer the audience than all of it
    // (a front-of-house bar hangs over the seats, behind the designer).
    let mut points: Vec<Vec3> = rig.focus.iter().chain(&rig.footprints).copied().collect();
    let downstage = points.iter().map(|p| (*p - pivot).dot(plan)).fold(0.0, f32::min);
    points.extend(rig.fixtures.iter().filter(|f| (**f - pivot).dot(plan) >= downstage));
    if points.is_empty() {
        points = (0..8)
            .map(|i| {
                let pick = |bit: usize, lo: f32, hi: f32| if i & bit == 0 { lo } else { hi };
                let (a, b) = (bounds.min, bounds.max);
                Vec3::new(pick(1, a.x, b.x), pick(2, a.y, b.y), pick(4, a.z, b.z))
            })
            .collect();
    }
    points.push(pivot);
    let pitch = FRAME_PITCH_DEG.to_radians();
    let forward = plan * pitch.cos() - Vec3::Y * pitch.sin();
    let fov = FRAME_FOV_DEG.to_radians();
    let s = frame_distance(&points, pivot, forward, fov, FRAME_ASPECT, FRAME_FILL).max(limits.min_distance);
    let (eye, fov) = match crate::scene::camera::behind_wall(scene, pivot, pivot - forward * s) {
        Some(t) => {
            let eye = pivot - forward * (t - crate::scene::camera::WALL_MARGIN).max(limits.min_distance);
            (eye, fov_to_fit(&points, eye, pivot, FRAME_ASPECT, FRAME_FILL).clamp(fov, FRAME_MAX_FOV_DEG.to_radians()))
        }
        None => (pivot - forward * s, fov),
    };
    Pose { position: eye.to_array(), target: pivot.to_array(), fov_y: fov.to_degrees(), up: None }
}

/// The walking limits of `scene` with these named views: the pivot from
/// the [`FRAME_VIEW`] view's target when the list has one (it is the stage
/// centre), else from the scene's bounds ([`crate::scene::camera::stage_centre`]);
/// the room holds every named view's eye and `start`'s. `None` for an empty
/// scene (nothing to stay in).
pub fn stage_limits(scene: &Scene, start: &Camera, named: &[NamedView]) -> Option<StageLimits> {
    let bounds = Bounds::of_scene(scene)?;
    let pivot = named
        .iter()
        .find(|v| v.source == ViewSource::Rig)
        .map(|v| Vec3::from_array(v.pose.target))
        .unwrap_or_else(|| crate::scene::camera::stage_centre(scene, &bounds, &[]));
    let eyes: Vec<Vec3> =
        named.iter().map(|v| Vec3::from_array(v.pose.position)).chain(std::iter::once(start.position)).collect();
    Some(StageLimits::new(bounds, &eyes, pivot))
}

/// The named views of a scene and patch: the start view, [`FRAME_VIEW`],
/// the glTF camera, the patch's `[camera]` and its `[[view]]` entries, in
/// that order. The stage centre comes from the patch's default look
/// ([`Rig::of`]: its lit lights' focus points, or every light's when none
/// is lit), else from the scene's bounds; the start view and the glTF
/// camera orbit about it ([`Pose::centred`]).
pub fn named_views(start: &Camera, scene: &Scene, patch: Option<&crate::Patch>) -> Vec<NamedView> {
    let rig = patch.map_or_else(Rig::default, |p| {
        let lights = p.lights();
        let k = p.default_k();
        Rig::of(scene, &lights.iter().zip(k).collect::<Vec<_>>())
    });
    let bounds = Bounds::of_scene(scene);
    let pivot = bounds.map(|b| crate::scene::camera::stage_centre(scene, &b, &rig.focus));
    let centred = |camera: &Camera| match pivot {
        Some(p) => Pose::centred(scene, camera, p),
        None => Pose::focused(scene, camera),
    };
    let mut out = vec![NamedView { name: "start".into(), pose: centred(start), source: ViewSource::Start }];
    if let Some(c) = &scene.camera {
        out.push(NamedView { name: "scene camera".into(), pose: centred(c), source: ViewSource::Scene });
    }
    if let Some(p) = patch {
        if let Some(c) = &p.camera {
            let pose = Pose {
                position: c.position.to_array(),
                target: c.look_at.to_array(),
                fov_y: c.fov_y.to_degrees(),
                up: None,
            };
            out.push(NamedView { name: "patch camera".into(), pose, source: ViewSource::Patch });
        }
        for v in &p.views {
            let pose = Pose {
                position: v.position.to_array(),
                target: v.target.to_array(),
                fov_y: v.fov_y.to_degrees(),
                up: None,
            };
            out.retain(|o| o.name != v.name);
            out.push(NamedView { name: v.name.clone(), pose, source: ViewSource::Patch });
        }
    }
    // The frame view, second in the list (key `2` in the window); a patch
    // view of the same name replaces it.
    if let (Some(bounds), Some(pivot)) = (bounds, pivot)
        && !out.iter().any(|v| v.name == FRAME_VIEW)
    {
        let eyes: Vec<Vec3> = out.iter().map(|v| Vec3::from_array(v.pose.position)).collect();
        let limits = StageLimits::new(bounds, &eyes, pivot);
        let pose = frame_rig(scene, &rig, &bounds, start, &limits);
        out.insert(1, NamedView { name: FRAME_VIEW.into(), pose, source: ViewSource::Rig });
    }
    out
}

/// One cached view: its `View` and what each light showed in it.
struct CacheEntry {
    camera: Camera,
    view: Arc<View>,
    kept: Vec<Option<Kept>>,
    bytes: usize,
    last_used: u64,
}

/// LRU cache of views left behind, bounded by bytes (the view's G-buffer
/// and camera paths plus the light buffers it keeps). The key is the camera,
/// matched by [`same_camera`] (a pose that went through JSON or degrees and
/// back differs from the original in the last bits only).
pub struct ViewCache {
    entries: Vec<CacheEntry>,
    budget: usize,
    clock: u64,
    hits: u64,
    misses: u64,
}

impl ViewCache {
    /// An empty cache of at most `budget` bytes.
    pub fn new(budget: usize) -> Self {
        Self { entries: Vec::new(), budget, clock: 0, hits: 0, misses: 0 }
    }

    /// Takes the entry for exactly `camera` out (it becomes the current view).
    pub fn take(&mut self, camera: &Camera) -> Option<(Arc<View>, Vec<Option<Kept>>)> {
        match self.entries.iter().position(|e| same_camera(&e.camera, camera)) {
            Some(i) => {
                self.hits += 1;
                let e = self.entries.swap_remove(i);
                Some((e.view, e.kept))
            }
            None => {
                self.misses += 1;
                None
            }
        }
    }

    /// Keeps a view left behind; the least recently used go past the budget.
    pub fn insert(&mut self, camera: Camera, view: Arc<View>, kept: Vec<Option<Kept>>) {
        let mut seen = std::collections::HashSet::new();
        let buffers: usize =
            kept.iter().flatten().filter(|k| seen.insert(Arc::as_ptr(&k.buffer))).map(|k| k.buffer.bytes()).sum();
        let bytes = view.bytes() + buffers;
        self.entries.retain(|e| !same_camera(&e.camera, &camera));
        if bytes > self.budget {
            return;
        }
        self.clock += 1;
        self.entries.push(CacheEntry { camera, view, kept, bytes, last_used: self.clock });
        while self.bytes() > self.budget {
            let Some(oldest) = self.entries.iter().enumerate().min_by_key(|(_, e)| e.last_used).map(|(i, _)| i) else {
                break;
            };
            self.entries.swap_remove(oldest);
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.entries.iter().map(|e| e.bytes).sum()
    }

    /// Views held.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Returns to a cached view so far.
    pub fn hits(&self) -> u64 {
        self.hits
    }

    /// View changes that had to build their view.
    pub fn misses(&self) -> u64 {
        self.misses
    }
}

struct State {
    /// The latest written camera.
    target: Camera,
    /// Its pose as written (the target orbiting turns around).
    pose: Pose,
    /// The camera of the tracer's view.
    active: Camera,
    name: Option<String>,
    last_write: Option<Instant>,
    writes: u64,
    phase: Phase,
    named: Vec<NamedView>,
    cache: ViewCache,
    last_switch_ms: Option<f64>,
    last_restored: usize,
}

/// The camera of a running daemon: writes, named views, the settle loop
/// ([`Views::run`]) and the moving preview ([`Views::preview_camera`]).
pub struct Views {
    scene: Arc<Scene>,
    tracer: Arc<Tracer>,
    width: u32,
    height: u32,
    limits: RecursionLimits,
    settings: ViewSettings,
    /// Where a written pose may go ([`StageLimits`]; `None`: an empty scene).
    stage: Option<StageLimits>,
    state: Mutex<State>,
    wake: Notify,
    /// Display settings written over HTTP (`POST /api/display`), taken by
    /// the frame clock on its next tick ([`Views::take_display`]).
    display: Mutex<Option<Display>>,
    /// The white balance in force and the rig's white (`auto`), for `/api/display`.
    white: Mutex<WhiteState>,
}

impl Views {
    /// The views of `tracer`, whose view was built from `start`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: Arc<Scene>,
        tracer: Arc<Tracer>,
        start: Camera,
        named: Vec<NamedView>,
        limits: RecursionLimits,
        settings: ViewSettings,
    ) -> Self {
        let view = tracer.view();
        let (width, height) = (view.width(), view.height());
        let stage = stage_limits(&scene, &start, &named);
        let pose = stage.map_or_else(|| Pose::focused(&scene, &start), |l| Pose::centred(&scene, &start, l.pivot));
        Self {
            scene,
            tracer,
            width,
            height,
            limits,
            settings,
            stage,
            state: Mutex::new(State {
                target: start,
                pose,
                active: start,
                name: Some("start".into()),
                last_write: None,
                writes: 0,
                phase: Phase::Still,
                named,
                cache: ViewCache::new(settings.cache_bytes),
                last_switch_ms: None,
                last_restored: 0,
            }),
            wake: Notify::new(),
            display: Mutex::new(None),
            white: Mutex::new(WhiteState {
                choice: crate::render::display::WhiteChoice::of_gains(Display::default().white_balance),
                rig: None,
            }),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().expect("views lock")
    }

    /// The settings.
    pub fn settings(&self) -> &ViewSettings {
        &self.settings
    }

    /// The walking limits (`None`: an empty scene).
    pub fn stage_limits(&self) -> Option<&StageLimits> {
        self.stage.as_ref()
    }

    /// `pose` confined to the stage ([`StageLimits::confine`]: in the room,
    /// the dolly's range, never behind a wall); its field of view and roll
    /// are kept (the roll is dropped only if the confined eye looks along
    /// it). An unusable pose is refused.
    pub fn confine(&self, pose: Pose) -> Result<Pose, String> {
        pose.camera()?;
        let Some(stage) = &self.stage else { return Ok(pose) };
        let c = stage.confine(&self.scene, Vec3::from_array(pose.position), Vec3::from_array(pose.target));
        if !c.moved {
            return Ok(pose);
        }
        let moved = Pose { position: c.eye.to_array(), target: c.target.to_array(), ..pose };
        match moved.camera() {
            Ok(_) => Ok(moved),
            Err(_) => Ok(Pose { up: None, ..moved }),
        }
    }

    /// A camera write: the preview follows it at once; the full view is
    /// built once no write came for [`ViewSettings::settle`]. The camera is
    /// confined to the stage ([`Views::confine`]).
    pub fn move_to(&self, camera: Camera) {
        let pose = match &self.stage {
            Some(stage) => Pose::centred(&self.scene, &camera, stage.pivot),
            None => Pose::focused(&self.scene, &camera),
        };
        if self.move_to_pose(pose).is_err() {
            self.write(camera, pose);
        }
    }

    fn write(&self, camera: Camera, pose: Pose) {
        let mut st = self.lock();
        st.target = camera;
        st.pose = pose;
        st.name = None;
        st.last_write = Some(Instant::now());
        st.writes += 1;
        st.phase = Phase::Moving;
        drop(st);
        self.tracer.set_paused(true);
        self.wake.notify_one();
    }

    /// The camera the moving preview shows, or `None` when the tracer's
    /// buffers are the picture: while moving or building, and after a view
    /// change until every light has a buffer for the new view.
    pub fn preview_camera(&self) -> Option<Camera> {
        let st = self.lock();
        match st.phase {
            Phase::Moving | Phase::Building => Some(st.target),
            Phase::Still => (self.tracer.view_generation() > 0 && self.tracer.any_queued()).then_some(st.active),
        }
    }

    /// The display settings written since the last call, if any (the frame clock).
    pub fn take_display(&self) -> Option<Display> {
        self.display.lock().unwrap_or_else(|e| e.into_inner()).take()
    }

    /// The moving preview for `camera` with `lights` (geometry and k_i), in
    /// the tracer's haze at `density` (0-1 of the patch's; `None` or 0: clear).
    pub fn preview(
        &self,
        camera: &Camera,
        lights: &[(&Light, Vec3)],
        display: &Display,
        density: Option<f32>,
    ) -> Vec<u8> {
        let haze = self.tracer.medium().zip(density);
        let (w, h, scale) = (self.width, self.height, self.settings.preview_scale);
        let linear = preview_in_haze(&self.scene, camera, w, h, scale, lights, haze.as_ref().map(|(m, d)| (m, *d)));
        if let Err((i, v)) = crate::render::display::check_finite(&linear) {
            tracing::error!("moving preview: pixel {i} is {v} (a bug)");
        }
        display.to_srgb8(&linear)
    }

    /// The settle loop: once no write came for the settle time, the view of
    /// the latest camera is taken from the cache or built off the async
    /// workers, and swapped into the tracer. Returns when `stop` fires.
    pub async fn run(self: Arc<Self>, stop: StopSignal) -> (&'static str, Result<(), String>) {
        let stopped = stop.fired();
        tokio::pin!(stopped);
        loop {
            let due = {
                let st = self.lock();
                match (st.phase, st.last_write) {
                    (Phase::Moving, Some(t)) => Some(t + self.settings.settle),
                    _ => None,
                }
            };
            let sleep = async {
                match due {
                    Some(t) => tokio::time::sleep_until(t).await,
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                _ = &mut stopped => return ("views", Ok(())),
                _ = self.wake.notified() => continue,
                _ = sleep => {}
            }
            if let Err(e) = self.settle().await {
                return ("views", Err(e));
            }
        }
    }

    /// One settle step: builds or restores the view of the latest camera if
    /// it has been still for the settle time.
    async fn settle(self: &Arc<Self>) -> Result<(), String> {
        let stopped_at = Instant::now();
        let (camera, writes) = {
            let mut st = self.lock();
            let still = st.last_write.is_some_and(|t| t + self.settings.settle <= Instant::now());
            if st.phase != Phase::Moving || !still {
                return Ok(());
            }
            if same_camera(&st.target, &st.active) {
                // Back where it started before settling: nothing to build.
                st.phase = Phase::Still;
                drop(st);
                self.tracer.set_paused(false);
                return Ok(());
            }
            st.phase = Phase::Building;
            (st.target, st.writes)
        };
        let cached = self.lock().cache.take(&camera);
        let (view, kept) = match cached {
            Some(hit) => hit,
            None => {
                let (scene, w, h, limits) = (self.scene.clone(), self.width, self.height, self.limits);
                let view = tokio::task::spawn_blocking(move || {
                    Arc::new(View::build(&scene, camera, w, h, Sampling::Adaptive, limits))
                })
                .await
                .map_err(|e| format!("building the view failed: {e}"))?;
                (view, Vec::new())
            }
        };
        let mut st = self.lock();
        if st.writes != writes {
            // The camera moved on while building: keep the view for later.
            st.cache.insert(camera, view, kept);
            if st.phase == Phase::Building {
                st.phase = Phase::Moving;
            }
            return Ok(());
        }
        let old_camera = st.active;
        let old_view = self.tracer.view();
        let (old, restored) = self.tracer.set_view(view, &kept);
        st.cache.insert(old_camera, old_view, old);
        st.active = camera;
        st.phase = Phase::Still;
        st.last_restored = restored;
        st.last_switch_ms = Some(stopped_at.elapsed().as_secs_f64() * 1e3);
        drop(st);
        self.tracer.set_paused(false);
        tracing::info!("view changed: {restored} of {} lights restored from the view cache", self.tracer.len());
        Ok(())
    }
}

impl CameraControl for Views {
    /// A camera write as a pose (the page's and the window's moves keep
    /// their orbit target this way), confined to the stage
    /// ([`Views::confine`]); refused when the pose is unusable.
    fn move_to_pose(&self, pose: Pose) -> Result<(), String> {
        let pose = self.confine(pose)?;
        self.write(pose.camera()?, pose);
        Ok(())
    }

    /// Moves to the named view. A jump is one write, not a drag: it is
    /// settled at once (no [`ViewSettings::settle`] wait), so a cached view
    /// is back on the next frame.
    fn go_to(&self, name: &str) -> Result<(), String> {
        let pose = self.lock().named.iter().find(|v| v.name == name).map(|v| v.pose);
        let Some(pose) = pose else { return Err(format!("no view named {name:?}")) };
        self.move_to_pose(pose)?;
        let mut st = self.lock();
        st.name = Some(name.to_string());
        let now = Instant::now();
        st.last_write = Some(now.checked_sub(self.settings.settle).unwrap_or(now));
        drop(st);
        self.wake.notify_one();
        Ok(())
    }

    /// Saves the current camera as `name` (in memory; a saved view of the
    /// same name is replaced, a scene or patch view is not).
    fn save(&self, name: &str) -> Result<NamedView, String> {
        let name = name.trim();
        if name.is_empty() || name.chars().count() > 64 || name.chars().any(char::is_control) {
            return Err("a view name is 1-64 printable characters".into());
        }
        let mut st = self.lock();
        if st.named.iter().any(|v| v.name == name && v.source != ViewSource::Saved) {
            return Err(format!("{name:?} is a scene or patch view; choose another name"));
        }
        st.named.retain(|v| v.name != name);
        if st.named.iter().filter(|v| v.source == ViewSource::Saved).count() >= self.settings.max_saved {
            return Err(format!("at most {} saved views", self.settings.max_saved));
        }
        let view = NamedView { name: name.to_string(), pose: st.pose, source: ViewSource::Saved };
        st.named.push(view.clone());
        st.name = Some(name.to_string());
        Ok(view)
    }

    /// Every named view.
    fn list(&self) -> Vec<NamedView> {
        self.lock().named.clone()
    }

    /// Asks the frame clock to show from its next frame on with `display`
    /// (exposure, white balance, roll-off): uniforms only, no rebuild.
    fn set_display(&self, display: Display) {
        *self.display.lock().unwrap_or_else(|e| e.into_inner()) = Some(display);
    }

    /// Records the white balance in force and the rig's white (the daemon at
    /// start, `POST /api/display` on a change).
    fn set_white(&self, choice: crate::render::display::WhiteChoice, rig: Option<footlight_fixture::patch::RigWhite>) {
        *self.white.lock().unwrap_or_else(|e| e.into_inner()) = WhiteState { choice, rig };
    }

    /// The white balance in force and the rig's white.
    fn white(&self) -> WhiteState {
        self.white.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// `view` in `/api/status`.
    fn status(&self) -> ViewStatus {
        let st = self.lock();
        let stage = (0..self.tracer.len())
            .filter_map(|i| self.tracer.report(i))
            .map(|r| r.stage)
            .min_by_key(|s| stage_rank(*s))
            .unwrap_or(Stage::Ready);
        ViewStatus {
            current: st.pose,
            name: st.name.clone(),
            phase: st.phase,
            stage,
            writes: st.writes,
            last_switch_ms: st.last_switch_ms,
            last_restored: st.last_restored,
            cache: ViewCacheStatus {
                entries: st.cache.len(),
                bytes: st.cache.bytes(),
                budget_bytes: self.settings.cache_bytes,
                hits: st.cache.hits(),
                misses: st.cache.misses(),
            },
            limits: self.stage.as_ref().map(LimitsStatus::from),
        }
    }
}

/// True when two cameras see the same picture up to float rounding: eye
/// within 1e-5 m, basis vectors within 1e-5, field of view within 1e-6 rad.
pub fn same_camera(a: &Camera, b: &Camera) -> bool {
    a.position.abs_diff_eq(b.position, 1e-5) && a.basis.abs_diff_eq(b.basis, 1e-5) && (a.yfov - b.yfov).abs() <= 1e-6
}

/// Orders stages from least to most advanced.
fn stage_rank(s: Stage) -> u32 {
    match s {
        Stage::Queued => 0,
        Stage::Direct => 1,
        Stage::Whitted => 2,
        Stage::Photons => 3,
        Stage::Refining(n) => 4 + n.min(1 << 20),
        Stage::Ready => u32::MAX,
    }
}

/// The moving preview, linear cd/m² at `width`×`height`: one primary ray
/// per pixel of a 1/`scale` image (the pixel centre), direct light of each
/// of `lights` at the surface it hits (the same `direct` term as every
/// buffer, eq. 1 without recursion), summed with its k_i in one pass, then
/// replicated to full size. No mirrors, glass, anti-aliasing or indirect
/// light: it only has to follow the camera.
pub fn preview(
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    scale: u32,
    lights: &[(&Light, Vec3)],
) -> Vec<Vec3> {
    preview_in_haze(scene, camera, width, height, scale, lights, None)
}

/// Samples per ray of the preview's beams (the live tracer's coarse stage,
/// [`HazeQuality::COARSE`](crate::render::media::HazeQuality::COARSE)).
pub const PREVIEW_HAZE_SAMPLES: u32 = crate::render::media::HazeQuality::COARSE.samples;

/// The preview's beam grid: every 4th pixel of the reduced image in x and
/// y (1/8 of the picture at the default preview scale 2), chosen so that
/// six beams cost about what the surfaces cost (`footlight bench
/// --walk-only --patch patch/haze-rig.toml`; docs/live.md).
pub const PREVIEW_HAZE_STEP: u32 = 4;

/// As [`preview`], in `haze` = (the medium at 100 %, density 0-1): each
/// surface term dimmed by e^(−d κ_s) (camera and light paths through the
/// box, as `render::media::resolve`), plus each light's single scattering
/// d σ_s a0 e^(−d κ) along the ray ([`integrate_ray`](crate::render::media::integrate_ray),
/// equiangular, [`PREVIEW_HAZE_SAMPLES`] samples), traced only inside the
/// beam's screen bounds (`single::beam_screen_bounds`) on every
/// [`PREVIEW_HAZE_STEP`]-th pixel of the reduced image in x and y, and
/// interpolated bilinearly. A clear medium or d = 0 is exactly [`preview`].
pub fn preview_in_haze(
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    scale: u32,
    lights: &[(&Light, Vec3)],
    haze: Option<(&crate::render::media::Medium, f32)>,
) -> Vec<Vec3> {
    let haze = haze
        .map(|(m, d)| (m, crate::render::media::medium::clean_density(d)))
        .filter(|(m, d)| *d > 0.0 && !m.is_clear());
    let Some((medium, d)) = haze else { return preview_clear(scene, camera, width, height, scale, lights) };
    use crate::render::media::single::{HazeView, beam_screen_bounds, integrate_ray};
    let scale = scale.max(1);
    let (sw, sh) = (width.div_ceil(scale).max(1), height.div_ceil(scale).max(1));
    let lit: Vec<(&Light, Vec3)> = lights.iter().copied().filter(|(_, k)| k.max_element() > 0.0).collect();
    let n = (sw * sh) as usize;
    let dirs: Vec<Vec3> = (0..n)
        .map(|i| camera.direction((i % sw as usize) as f32 + 0.5, (i / sw as usize) as f32 + 0.5, sw, sh))
        .collect();
    let hits: Vec<_> = dirs.par_iter().map(|dir| scene.accel.intersect(camera.position, *dir, f32::INFINITY)).collect();
    let t_hit: Vec<f32> = hits.iter().map(|h| h.as_ref().map_or(f32::INFINITY, |h| h.t)).collect();
    let (sigma_t, sigma_tl, sigma_s) = (medium.sigma_t(), medium.sigma_t_light(), medium.sigma_s);
    let cam = camera.position;
    // Surfaces, each light's term dimmed along its camera and light paths.
    let mut small = vec![Vec3::ZERO; n];
    small.par_chunks_mut(sw as usize).enumerate().for_each(|(y, row)| {
        let mut vertices = Vec::new();
        for (x, out) in row.iter_mut().enumerate() {
            let i = y * sw as usize + x;
            let Some(hit) = &hits[i] else { continue };
            let p = cam + dirs[i] * hit.t;
            let cam_path = sigma_t * medium.length_inside(cam, p);
            *out = shade_surface(scene, hit, dirs[i], &lit, &mut vertices, |light| {
                (-d * (cam_path + sigma_tl * medium.length_inside(p, light.position))).exp()
            });
        }
    });
    // Beams: on a grid of every PREVIEW_HAZE_STEP-th pixel of the reduced
    // image (the ray through each block's centre), inside each beam's
    // bounds, interpolated bilinearly back.
    let hv = HazeView::from_rays(*camera, sw, sh, dirs, t_hit);
    let bounds: Vec<Option<(usize, usize, usize, usize)>> =
        lit.iter().map(|(light, _)| beam_screen_bounds(&hv, light, medium)).collect();
    let step = PREVIEW_HAZE_STEP as usize;
    let (gw, gh) = ((sw as usize).div_ceil(step), (sh as usize).div_ceil(step));
    let mut grid = vec![Vec3::ZERO; gw * gh];
    grid.par_chunks_mut(gw).enumerate().for_each(|(gy, row)| {
        for (gx, out) in row.iter_mut().enumerate() {
            let (x, y) = (gx * step, gy * step);
            let mut ray = None;
            for ((light, k), b) in lit.iter().zip(&bounds) {
                // The bounds hold the whole beam; a block whose interpolation
                // reaches into them (one block either side) is traced.
                let Some((x0, y0, x1, y1)) = *b else { continue };
                if x + 2 * step <= x0 || x >= x1 + step || y + 2 * step <= y0 || y >= y1 + step {
                    continue;
                }
                let (dir, t) = *ray.get_or_insert_with(|| {
                    let c = step as f32 / 2.0;
                    let dir = camera.direction(x as f32 + c, y as f32 + c, sw, sh);
                    (dir, scene.accel.intersect(cam, dir, f32::INFINITY).map_or(f32::INFINITY, |h| h.t))
                });
                let a = integrate_ray(scene, medium, light, cam, dir, t, PREVIEW_HAZE_SAMPLES);
                if a.a0 > 0.0 && a.a0.is_finite() {
                    *out += *k * (d * sigma_s * a.a0 * (-d * a.kappa()).exp());
                }
            }
        }
    });
    let axis = |p: usize, n: usize| {
        let f = ((p as f32 + 0.5) / step as f32 - 0.5).max(0.0);
        let a = (f as usize).min(n - 1);
        (a, (a + 1).min(n - 1), f - a as f32)
    };
    small.par_chunks_mut(sw as usize).enumerate().for_each(|(y, row)| {
        let (ya, yb, fy) = axis(y, gh);
        for (x, v) in row.iter_mut().enumerate() {
            let (xa, xb, fx) = axis(x, gw);
            let top = grid[ya * gw + xa] * (1.0 - fx) + grid[ya * gw + xb] * fx;
            let bottom = grid[yb * gw + xa] * (1.0 - fx) + grid[yb * gw + xb] * fx;
            *v += top * (1.0 - fy) + bottom * fy;
        }
    });
    upscale(&small, sw, sh, width, height, scale)
}

/// One preview pixel's surface: the direct light of each of `lit` (with
/// its k_i) at the directly seen point of `hit` along `dir`, no recursion,
/// each light's term times `dim(light)` (the haze's transmittance, 1 in
/// clear air). `vertices` is scratch.
fn shade_surface(
    scene: &Scene,
    hit: &crate::scene::Hit,
    dir: Vec3,
    lit: &[(&Light, Vec3)],
    vertices: &mut Vec<crate::render::whitted::ShadingVertex>,
    dim: impl Fn(&Light) -> f32,
) -> Vec3 {
    let primary = RecursionLimits { max_depth: 0, ..RecursionLimits::default() };
    vertices.clear();
    expand(scene, scene.surface(hit), dir, Vec3::ONE, primary, vertices);
    vertices
        .iter()
        .map(|v| {
            lit.iter()
                .map(|(light, k)| *k * v.weight * crate::render::whitted::direct(scene, light, v) * dim(light))
                .sum::<Vec3>()
        })
        .sum()
}

/// Replicates the reduced `sw`×`sh` picture to `width`×`height`.
fn upscale(small: &[Vec3], sw: u32, sh: u32, width: u32, height: u32, scale: u32) -> Vec<Vec3> {
    let mut full = vec![Vec3::ZERO; (width * height) as usize];
    full.par_chunks_mut(width.max(1) as usize).enumerate().for_each(|(y, row)| {
        let sy = (y as u32 / scale).min(sh - 1);
        for (x, out) in row.iter_mut().enumerate() {
            *out = small[(sy * sw + (x as u32 / scale).min(sw - 1)) as usize];
        }
    });
    full
}

/// [`preview`] without haze.
fn preview_clear(
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    scale: u32,
    lights: &[(&Light, Vec3)],
) -> Vec<Vec3> {
    let scale = scale.max(1);
    let (sw, sh) = (width.div_ceil(scale).max(1), height.div_ceil(scale).max(1));
    let lit: Vec<(&Light, Vec3)> = lights.iter().copied().filter(|(_, k)| k.max_element() > 0.0).collect();
    let mut small = vec![Vec3::ZERO; (sw * sh) as usize];
    small.par_chunks_mut(sw as usize).enumerate().for_each(|(y, row)| {
        let mut vertices = Vec::new();
        for (x, out) in row.iter_mut().enumerate() {
            let dir = camera.direction(x as f32 + 0.5, y as f32 + 0.5, sw, sh);
            let Some(hit) = scene.accel.intersect(camera.position, dir, f32::INFINITY) else { continue };
            *out = shade_surface(scene, &hit, dir, &lit, &mut vertices, |_| 1.0);
        }
    });
    upscale(&small, sw, sh, width, height, scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> Pose {
        Pose { position: [0.0, 5.0, 6.0], target: [0.0, 1.0, 0.0], fov_y: 40.0, up: None }
    }

    fn dist(p: &Pose) -> f32 {
        Vec3::from_array(p.position).distance(Vec3::from_array(p.target))
    }

    #[test]
    fn orbit_keeps_the_distance_and_a_full_turn_comes_back() {
        let p = pose();
        let mut q = p;
        for _ in 0..8 {
            q = q.orbit(std::f32::consts::FRAC_PI_4, 0.0);
            assert!((dist(&q) - dist(&p)).abs() < 1e-4);
        }
        assert!(Vec3::from_array(q.position).abs_diff_eq(Vec3::from_array(p.position), 1e-4), "{q:?}");
        // A quarter turn to the left puts the eye on the −X side (yaw about +Y).
        let side = p.orbit(std::f32::consts::FRAC_PI_2, 0.0);
        assert!((side.position[0] + 6.0).abs() < 1e-4 && side.position[2].abs() < 1e-4, "{side:?}");
        // Pitch stops short of the pole: the camera stays well defined.
        let top = p.orbit(0.0, 10.0);
        assert!(top.camera().unwrap().basis.is_finite());
        assert!(top.position[1] < 1.0 + dist(&p));
    }

    #[test]
    fn pan_moves_eye_and_target_together_sideways_and_dolly_and_zoom_stay_in_range() {
        let p = pose();
        let q = p.pan(1.0, 0.0);
        let shift = Vec3::from_array(q.position) - Vec3::from_array(p.position);
        assert!((shift - Vec3::X).length() < 1e-5, "right of a camera looking down −Z is +X: {shift}");
        assert_eq!(Vec3::from_array(q.target) - Vec3::from_array(p.target), shift);
        assert!((dist(&p.dolly(0.5)) - 0.5 * dist(&p)).abs() < 1e-4);
        assert!((dist(&p.dolly(1e-9)) - 0.2).abs() < 1e-5);
        assert_eq!(p.zoom(100.0).fov_y, 120.0);
        assert_eq!(p.zoom(f32::NAN), p);
    }

    /// A 20 m deck at y = 0 (one-sided, facing up).
    fn deck() -> Scene {
        let mut b = crate::scene::SceneBuilder::new();
        let m = b.add_material(crate::scene::Material::lambert("deck", Vec3::splat(0.5)));
        let (a, c) = (-10.0, 10.0);
        b.add_quad(Vec3::new(a, 0.0, c), Vec3::new(c, 0.0, c), Vec3::new(c, 0.0, a), Vec3::new(a, 0.0, a), m);
        b.build()
    }

    fn spot(from: Vec3, at: Vec3) -> Light {
        Light::aimed(from, at, crate::Beam::Spot(crate::fixture::SpotBeam::from_beam_field(20.0, 30.0)))
    }

    #[test]
    fn centred_targets_the_point_of_the_centre_ray_nearest_the_pivot() {
        let scene = deck();
        let camera = Camera::look_at(Vec3::new(0.0, 2.0, 10.0), Vec3::new(0.0, 2.0, 0.0), 0.7);
        // The ray is x = 0, y = 2: the nearest point to (1, 1, −2) is (0, 2, −2).
        let p = Pose::centred(&scene, &camera, Vec3::new(1.0, 1.0, -2.0));
        assert!(Vec3::from_array(p.target).abs_diff_eq(Vec3::new(0.0, 2.0, -2.0), 1e-5), "{p:?}");
        assert!(same_camera(&p.camera().unwrap(), &camera), "the picture is the camera's own");
        // A pivot behind the eye: the surface the centre ray meets (here none: 10 m ahead).
        let behind = Pose::centred(&scene, &camera, Vec3::new(0.0, 1.0, 20.0));
        assert_eq!(behind, Pose::focused(&scene, &camera));
    }

    #[test]
    fn the_frame_view_holds_the_lit_rig_and_its_footprints_from_a_designers_pitch() {
        let scene = deck();
        let lights = [
            spot(Vec3::new(-4.0, 6.0, 3.0), Vec3::new(-1.0, 0.0, -1.0)),
            spot(Vec3::new(4.0, 6.0, 3.0), Vec3::new(1.0, 0.0, -1.0)),
            spot(Vec3::new(0.0, 7.0, -6.0), Vec3::new(0.0, 0.0, -2.0)),
            // Dark, far off stage right: not framed while others are lit.
            spot(Vec3::new(-9.0, 6.0, 9.0), Vec3::new(-9.0, 0.0, 9.0)),
        ];
        let k = [Vec3::splat(100.0), Vec3::splat(100.0), Vec3::splat(50.0), Vec3::ZERO];
        let with_k: Vec<(&Light, Vec3)> = lights.iter().zip(k).collect();
        let rig = Rig::of(&scene, &with_k);
        assert_eq!(rig.fixtures.len(), 3, "the lit lights only");
        assert_eq!(rig.focus.len(), 3);
        assert_eq!(rig.footprints.len(), 12, "four edge hits per light");
        // All dark: every light.
        let dark: Vec<(&Light, Vec3)> = lights.iter().map(|l| (l, Vec3::ZERO)).collect();
        let dark_rig = Rig::of(&scene, &dark);
        assert_eq!(dark_rig.fixtures.len(), 4);
        assert_eq!(dark_rig.footprints.len(), 14, "the edge hits (two miss the deck), all near the rig");
        assert_eq!(dark_rig.focus.len(), 4, "every focus within 10 m of the rig");
        // A dark light aimed 40 m off (a blinder at the field) leaves its focus out.
        let far = spot(Vec3::new(0.0, 6.0, 3.0), Vec3::new(0.0, 0.0, 60.0));
        let far_deck = {
            let mut b = crate::scene::SceneBuilder::new();
            let m = b.add_material(crate::scene::Material::lambert("field", Vec3::splat(0.5)));
            b.add_quad(
                Vec3::new(-80.0, 0.0, 80.0),
                Vec3::new(80.0, 0.0, 80.0),
                Vec3::new(80.0, 0.0, -80.0),
                Vec3::new(-80.0, 0.0, -80.0),
                m,
            );
            b.build()
        };
        let mut with_far = dark.clone();
        with_far.push((&far, Vec3::ZERO));
        let focus = Rig::of(&far_deck, &with_far).focus;
        assert_eq!(focus.len(), 4, "{focus:?}");
        assert!(focus.iter().all(|p| p.z < 20.0), "{focus:?}");

        let bounds = Bounds::of_scene(&scene).unwrap();
        let pivot = crate::scene::camera::stage_centre(&scene, &bounds, &rig.focus);
        let start = Camera::look_at(Vec3::new(3.0, 1.7, 14.0), Vec3::new(3.0, 1.7, 0.0), 0.7);
        let limits = StageLimits::new(bounds, &[start.position], pivot);
        let pose = frame_rig(&scene, &rig, &bounds, &start, &limits);
        let cam = pose.camera().unwrap();
        assert_eq!(Vec3::from_array(pose.target), pivot, "it looks at the stage centre");
        // Looking the way the start camera looks (−Z), 10° down.
        let forward = -cam.basis.z_axis;
        assert!((forward.y + FRAME_PITCH_DEG.to_radians().sin()).abs() < 1e-5 && forward.x.abs() < 1e-5, "{forward}");
        assert_eq!(pose.fov_y, FRAME_FOV_DEG, "nothing in the way: the plain field");
        let tan = (pose.fov_y.to_radians() / 2.0).tan();
        let mut worst = 0.0f32;
        // The lit stage, and the fixtures no nearer the audience (+Z here)
        // than all of it: the upstage one; the two at z = 3 hang over the seats.
        let lit: Vec<Vec3> = rig.focus.iter().chain(&rig.footprints).copied().collect();
        let front = lit.iter().map(|p| p.z).fold(pivot.z, f32::max);
        let hung: Vec<Vec3> = rig.fixtures.iter().copied().filter(|f| f.z <= front).collect();
        assert_eq!(hung, [Vec3::new(0.0, 7.0, -6.0)]);
        for p in lit.iter().chain(&hung) {
            let local = cam.basis.transpose() * (*p - cam.position);
            let (u, v) = (local.x / -local.z / (tan * FRAME_ASPECT), local.y / -local.z / tan);
            worst = worst.max(u.abs()).max(v.abs());
            assert!(-local.z > 0.0 && u.abs() <= FRAME_FILL + 1e-4 && v.abs() <= FRAME_FILL + 1e-4, "{p}: ({u}, {v})");
        }
        assert!((worst - FRAME_FILL).abs() < 1e-3, "the frame is tight: {worst}");

        // In the list: second, after the start view, which orbits the same pivot.
        let patchless = named_views(&start, &scene, None);
        assert_eq!(patchless.iter().map(|v| v.name.as_str()).collect::<Vec<_>>(), ["start", FRAME_VIEW]);
        assert_eq!(patchless[1].source, ViewSource::Rig);
    }

    #[test]
    fn poses_round_trip_through_cameras() {
        let c = pose().camera().unwrap();
        assert!(same_camera(&Pose::of(&c).camera().unwrap(), &c));
        assert!(Pose { fov_y: 0.0, ..pose() }.camera().is_err());
        assert!(Pose { target: [0.0, 5.0, 6.0], ..pose() }.camera().is_err());
        assert!(Pose { position: [f32::NAN, 0.0, 0.0], ..pose() }.camera().is_err());
    }
}
