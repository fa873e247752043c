//! The camera and display controls of the live picture: what the page
//! (`serve::control`) and the window write, as the
//! [`CameraControl`] trait the daemon's camera (`live::views::Views`)
//! implements, and the values they exchange: [`Pose`], [`NamedView`],
//! [`ViewStatus`], [`WhiteState`].
//!
//! The mapping from a device's input to the next pose is the pure
//! [`control`] ([`Control`], [`ControlKey`], [`view_key`]): the window
//! turns winit events into [`Control`] values, the page's `camera.js` does
//! the same arithmetic (tested in `tests/views.rs` without a display).

use super::status::Stage;
use crate::render::Display;
use crate::render::display::WhiteChoice;
use crate::scene::camera::StageLimits;
use crate::scene::{Camera, Scene};
use footlight_fixture::patch::RigWhite;
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// The camera and display writes of the preview (HTTP) and the window, and
/// what they read back. The daemon's camera (`live::views::Views`)
/// implements it; a server without a daemon has none (its camera routes
/// answer 404).
pub trait CameraControl: Send + Sync {
    /// A camera write as a pose, confined to the stage; refused (with the
    /// reason) when the pose is unusable.
    fn move_to_pose(&self, pose: Pose) -> Result<(), String>;
    /// Moves to the named view (one write, settled at once); an unknown
    /// name is refused.
    fn go_to(&self, name: &str) -> Result<(), String>;
    /// Saves the current camera under `name` (in memory only).
    fn save(&self, name: &str) -> Result<NamedView, String>;
    /// Every named view, in list order (the window's `1`-`9` keys).
    fn list(&self) -> Vec<NamedView>;
    /// The camera's status (`view` in `/api/status`).
    fn status(&self) -> ViewStatus;
    /// Shows from the next frame on with `display` (exposure, white
    /// balance, roll-off): uniforms only, no rebuild.
    fn set_display(&self, display: Display);
    /// Records the white balance in force and the rig's white.
    fn set_white(&self, choice: WhiteChoice, rig: Option<RigWhite>);
    /// The white balance in force and the rig's white.
    fn white(&self) -> WhiteState;
}

/// A camera as a user writes it: eye, target, vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// Eye position, metres.
    pub position: [f32; 3],
    /// Point looked at, metres.
    pub target: [f32; 3],
    /// Vertical field of view, degrees.
    pub fov_y: f32,
    /// The camera's up direction (roll), when it is not the level one
    /// (world +Y projected onto the picture plane): a glTF camera keeps its
    /// full orientation this way. Omitted in JSON for a level camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<[f32; 3]>,
}

impl Pose {
    /// The camera of this pose, or why it is unusable.
    pub fn camera(&self) -> Result<Camera, String> {
        let (p, t) = (Vec3::from_array(self.position), Vec3::from_array(self.target));
        if !p.is_finite() || !t.is_finite() {
            return Err("camera position and target must be finite numbers".into());
        }
        if p.distance(t) < 1e-4 {
            return Err("camera target must differ from its position".into());
        }
        if !(self.fov_y.is_finite() && self.fov_y > 0.0 && self.fov_y < 179.0) {
            return Err(format!("camera fov_y {} must be between 0 and 179 degrees", self.fov_y));
        }
        let Some(up) = self.up else { return Ok(Camera::look_at(p, t, self.fov_y.to_radians())) };
        let up = Vec3::from_array(up);
        let forward = (t - p).normalize();
        // Gram-Schmidt: the part of `up` across the viewing direction.
        let across = forward.cross(up);
        let right = across
            .try_normalize()
            .filter(|_| up.is_finite() && across.length() >= 1e-3 * up.length())
            .ok_or_else(|| "camera up must be a finite direction not along the viewing direction".to_string())?;
        let basis = glam::Mat3::from_cols(right, right.cross(forward), -forward);
        Ok(Camera::from_rotation(p, glam::Quat::from_mat3(&basis).normalize(), self.fov_y.to_radians()))
    }

    /// The up vector to write for `camera`: `None` when it is the level one
    /// [`Camera::look_at`] gives (within 1e-5), else the camera's own.
    fn roll_of(camera: &Camera) -> Option<[f32; 3]> {
        let forward = -camera.basis.z_axis;
        let level = Camera::look_at(camera.position, camera.position + forward, camera.yfov);
        (!level.basis.y_axis.abs_diff_eq(camera.basis.y_axis, 1e-5)).then(|| camera.basis.y_axis.to_array())
    }

    /// The pose of `camera` with its target on the surface the picture's
    /// centre shows (what orbiting turns around), 10 m ahead when the
    /// centre ray hits nothing.
    pub fn focused(scene: &Scene, camera: &Camera) -> Self {
        let forward = -camera.basis.z_axis;
        let t = scene.accel.intersect(camera.position, forward, f32::INFINITY).map_or(10.0, |h| h.t);
        let t = if t.is_finite() && t > 0.05 { t } else { 10.0 };
        Self { target: (camera.position + forward * t).to_array(), ..Self::of(camera) }
    }

    /// The pose of `camera` with its target the point of the centre ray
    /// nearest `pivot` (the stage centre, what orbiting then turns around):
    /// the picture is the camera's own, and an orbit swings about the
    /// stage, not about the wall behind it. A pivot behind the eye (or
    /// nearer than [`crate::scene::camera::MIN_DISTANCE`] along the ray)
    /// falls back to [`Pose::focused`].
    pub fn centred(scene: &Scene, camera: &Camera, pivot: Vec3) -> Self {
        let forward = -camera.basis.z_axis;
        let t = (pivot - camera.position).dot(forward);
        if !(t.is_finite() && t >= crate::scene::camera::MIN_DISTANCE) {
            return Self::focused(scene, camera);
        }
        Self { target: (camera.position + forward * t).to_array(), ..Self::of(camera) }
    }

    /// The pose of `camera` (target one metre ahead of the eye).
    pub fn of(camera: &Camera) -> Self {
        let forward = -camera.basis.z_axis;
        Self {
            position: camera.position.to_array(),
            target: (camera.position + forward).to_array(),
            fov_y: camera.yfov.to_degrees(),
            up: Self::roll_of(camera),
        }
    }
}

impl Pose {
    /// Turns the eye around the target: `yaw` about world +Y, `pitch` up
    /// (radians); the distance to the target is kept and the pitch stays
    /// within ±86° so the view never flips over the pole. A rolled camera
    /// (a glTF camera's [`Pose::up`]) comes out level. A NaN angle leaves
    /// the pose as it was.
    pub fn orbit(&self, yaw: f32, pitch: f32) -> Self {
        let (p, t) = (Vec3::from_array(self.position), Vec3::from_array(self.target));
        let off = p - t;
        let r = off.length();
        if r.is_nan() || r <= 0.0 || !yaw.is_finite() || !pitch.is_finite() {
            return *self;
        }
        let limit = 1.5f32;
        let (y0, p0) = (off.x.atan2(off.z), (off.y / r).clamp(-1.0, 1.0).asin());
        let (y1, p1) = (y0 - yaw, (p0 + pitch).clamp(-limit, limit));
        let o = Vec3::new(r * p1.cos() * y1.sin(), r * p1.sin(), r * p1.cos() * y1.cos());
        // A turntable about world +Y: the horizon is levelled (roll dropped),
        // as the page's orbit does.
        Self { position: (t + o).to_array(), up: None, ..*self }
    }

    /// Moves eye and target together by `right` and `up` metres in the
    /// camera's own axes.
    pub fn pan(&self, right: f32, up: f32) -> Self {
        let (p, t) = (Vec3::from_array(self.position), Vec3::from_array(self.target));
        let Ok(camera) = self.camera() else { return *self };
        let shift = camera.basis.x_axis * right + camera.basis.y_axis * up;
        if !shift.is_finite() {
            return *self;
        }
        Self { position: (p + shift).to_array(), target: (t + shift).to_array(), ..*self }
    }

    /// Scales the eye's distance to the target by `factor` (kept within 0.2-500 m).
    pub fn dolly(&self, factor: f32) -> Self {
        let (p, t) = (Vec3::from_array(self.position), Vec3::from_array(self.target));
        let off = p - t;
        let r = (off.length() * factor).clamp(0.2, 500.0);
        match off.try_normalize() {
            Some(dir) if r.is_finite() => Self { position: (t + dir * r).to_array(), ..*self },
            _ => *self,
        }
    }

    /// Scales the field of view by `factor` (kept within 5-120°).
    pub fn zoom(&self, factor: f32) -> Self {
        let fov = self.fov_y * factor;
        if fov.is_finite() { Self { fov_y: fov.clamp(5.0, 120.0), ..*self } } else { *self }
    }
}

/// Radians of orbit per pixel of drag (the page's `camera.js` uses 0.008 too).
pub const ORBIT_PER_PIXEL: f32 = 0.008;
/// Radians of orbit per arrow-key press.
pub const ORBIT_PER_KEY: f32 = 0.05;
/// Wheel: the factor on distance (or field of view) is exp(pixels × this),
/// the exponent kept within ±1 per event (as the page's wheel handler).
pub const WHEEL_PER_PIXEL: f32 = 0.001;
/// Pixels of one wheel notch ("line"), the browsers' usual `deltaY`.
pub const PIXELS_PER_LINE: f32 = 100.0;

/// A camera control input, device-independent: what the window's mouse and
/// keys (and the page's pointer and wheel events) ask for. [`control`]
/// turns it into the next pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Control {
    /// A drag by `dx`, `dy` pixels (x right, y down) on a picture
    /// `height` pixels tall: orbit, or pan when `pan` (shift / right button).
    Drag {
        /// Pixels right.
        dx: f32,
        /// Pixels down.
        dy: f32,
        /// Pan instead of orbit.
        pan: bool,
        /// Height of the picture on screen, pixels (pan: one pixel of drag
        /// moves the target by one pixel's width at its distance).
        height: f32,
    },
    /// A wheel turn of `pixels` (browser convention: positive = towards the
    /// user, away from the stage): dolly, or field of view when `fov` (alt).
    Wheel {
        /// Pixels scrolled (a notch is [`PIXELS_PER_LINE`]).
        pixels: f32,
        /// Change the field of view instead of the distance.
        fov: bool,
    },
    /// A key press.
    Key(ControlKey),
}

/// The keys of the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlKey {
    /// Arrow left: orbit left.
    Left,
    /// Arrow right: orbit right.
    Right,
    /// Arrow up: orbit up.
    Up,
    /// Arrow down: orbit down.
    Down,
    /// `w`: dolly in (×0.9).
    DollyIn,
    /// `s`: dolly out (×1.1).
    DollyOut,
    /// `+`/`=`: narrower field of view (×0.9).
    ZoomIn,
    /// `-`: wider field of view (×1.1).
    ZoomOut,
}

impl ControlKey {
    /// The key for a typed character (`w`, `s`, `+`, `=`, `-`).
    pub fn from_char(c: &str) -> Option<Self> {
        match c {
            "w" | "W" => Some(Self::DollyIn),
            "s" | "S" => Some(Self::DollyOut),
            "+" | "=" => Some(Self::ZoomIn),
            "-" => Some(Self::ZoomOut),
            _ => None,
        }
    }
}

/// The named view a digit key jumps to: `1`-`9` are the list's first nine
/// views (index 0-8); `None` for anything else.
pub fn view_key(c: &str) -> Option<usize> {
    match c.as_bytes() {
        [d @ b'1'..=b'9'] => Some(usize::from(d - b'1')),
        _ => None,
    }
}

/// The pose after `input`: the window's controls as a pure function (the
/// page's `camera.js` does the same arithmetic). Limits: pitch within ±86°,
/// distance 0.2-500 m, field of view 5-120°; a non-finite input (NaN or
/// infinite pixels, a zero-height picture) leaves the pose unchanged.
pub fn control(pose: &Pose, input: Control) -> Pose {
    match input {
        Control::Drag { dx, dy, pan, height } => {
            if !(dx.is_finite() && dy.is_finite()) {
                return *pose;
            }
            if pan {
                if !(height.is_finite() && height >= 1.0) {
                    return *pose;
                }
                let d = Vec3::from_array(pose.position).distance(Vec3::from_array(pose.target));
                let scale = 2.0 * d * (pose.fov_y.to_radians() / 2.0).tan() / height;
                pose.pan(-dx * scale, dy * scale)
            } else {
                pose.orbit(dx * ORBIT_PER_PIXEL, dy * ORBIT_PER_PIXEL)
            }
        }
        Control::Wheel { pixels, fov } => {
            if !pixels.is_finite() {
                return *pose;
            }
            let f = (pixels * WHEEL_PER_PIXEL).clamp(-1.0, 1.0).exp();
            if fov { pose.zoom(f) } else { pose.dolly(f) }
        }
        Control::Key(key) => match key {
            ControlKey::Left => pose.orbit(-ORBIT_PER_KEY, 0.0),
            ControlKey::Right => pose.orbit(ORBIT_PER_KEY, 0.0),
            ControlKey::Up => pose.orbit(0.0, ORBIT_PER_KEY),
            ControlKey::Down => pose.orbit(0.0, -ORBIT_PER_KEY),
            ControlKey::DollyIn => pose.dolly(0.9),
            ControlKey::DollyOut => pose.dolly(1.1),
            ControlKey::ZoomIn => pose.zoom(0.9),
            ControlKey::ZoomOut => pose.zoom(1.1),
        },
    }
}

/// Where a named view comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewSource {
    /// The view the daemon started with.
    Start,
    /// The scene's glTF camera.
    Scene,
    /// The patch's `[camera]` or a `[[view]]` entry.
    Patch,
    /// Saved from the page (in memory only).
    Saved,
    /// Made from the rig and the stage (`live::views::FRAME_VIEW`).
    Rig,
}

/// A named view.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NamedView {
    /// The name shown in the list.
    pub name: String,
    /// The camera.
    pub pose: Pose,
    /// Where it comes from.
    pub source: ViewSource,
}

/// What the camera is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// The tracer's view is the camera's.
    Still,
    /// Camera writes arrive: the moving preview is shown.
    Moving,
    /// The camera stopped; its full view is being built.
    Building,
}

/// `view` in `/api/status` (documented in docs/live.md).
#[derive(Clone, Debug, Serialize)]
pub struct ViewStatus {
    /// The camera now (the latest write).
    pub current: Pose,
    /// The named view chosen last, unless the camera moved since.
    pub name: Option<String>,
    /// Still, moving or building.
    pub phase: Phase,
    /// The least advanced stage of any light for the current view.
    pub stage: Stage,
    /// Camera writes accepted since start.
    pub writes: u64,
    /// Time from the camera stopping to its full view in the tracer, ms (last change).
    pub last_switch_ms: Option<f64>,
    /// Lights whose buffers came back from the cache on the last change.
    pub last_restored: usize,
    /// The view cache.
    pub cache: ViewCacheStatus,
    /// Where the camera may go (`None`: an empty scene, no limits).
    pub limits: Option<LimitsStatus>,
}

impl Default for ViewStatus {
    /// A still camera at the origin looking down −Z (45°), nothing to
    /// build, no limits: the status of a preview server run without a
    /// camera control (the tests).
    fn default() -> Self {
        Self {
            current: Pose { position: [0.0; 3], target: [0.0, 0.0, -1.0], fov_y: 45.0, up: None },
            name: None,
            phase: Phase::Still,
            stage: Stage::Ready,
            writes: 0,
            last_switch_ms: None,
            last_restored: 0,
            cache: ViewCacheStatus::default(),
            limits: None,
        }
    }
}

/// The walking limits in the status ([`StageLimits`]): the page keeps its
/// dolly within the distance range.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct LimitsStatus {
    /// The stage centre (m).
    pub pivot: [f32; 3],
    /// The room's lowest corner (m).
    pub room_min: [f32; 3],
    /// The room's highest corner (m).
    pub room_max: [f32; 3],
    /// Nearest the eye comes to the target (m).
    pub min_distance: f32,
    /// Farthest the eye goes from the target (m).
    pub max_distance: f32,
}

impl From<&StageLimits> for LimitsStatus {
    fn from(l: &StageLimits) -> Self {
        Self {
            pivot: l.pivot.to_array(),
            room_min: l.room.min.to_array(),
            room_max: l.room.max.to_array(),
            min_distance: l.min_distance,
            max_distance: l.max_distance,
        }
    }
}

/// The view cache in the status.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ViewCacheStatus {
    /// Views kept.
    pub entries: usize,
    /// Bytes they hold.
    pub bytes: usize,
    /// The budget.
    pub budget_bytes: usize,
    /// Returns to a cached view.
    pub hits: u64,
    /// View changes that built their view.
    pub misses: u64,
}

/// The white balance in force ([`CameraControl::white`]) and the rig's white that
/// `auto` resolves to.
#[derive(Clone, Debug)]
pub struct WhiteState {
    /// The setting and its gains.
    pub choice: WhiteChoice,
    /// The rig's white at full (`None`: no lamp in the patch).
    pub rig: Option<RigWhite>,
}
