//! `footlight run --window` (feature `window`): the live picture in a
//! desktop window, for a machine with a display.
//!
//! The frame clock already produces every frame as 8-bit sRGB in memory (the
//! HTTP preview needs it there), so the window presents that buffer with
//! softbuffer instead of a wgpu surface: it works the same with the CPU or
//! GPU compositor and needs no GPU at all. The winit event loop owns the
//! main thread; the daemon runs on tokio threads and hands frames over a
//! `watch` channel, so a slow window never slows the frame clock.
//!
//! Camera controls (issue 16), the same moves as the page's:
//! drag = orbit, shift-drag or right-drag = pan, wheel = dolly,
//! alt + wheel = field of view; arrow keys orbit, `w`/`s` dolly, `+`/`-`
//! zoom, `1`-`9` jump to the named views in list order. Each move is a
//! camera write to the daemon's [`CameraControl`] (the window is local: no token). The mapping
//! from input to pose is the pure [`control`] (tested in `tests/views.rs`
//! without a display); this file only turns winit events into
//! [`Control`] values. The window itself is not run by any test (CI has
//! no display).

use crate::output::{CameraControl, Control, ControlKey, Frame, PIXELS_PER_LINE, Phase, Pose, control, view_key};
use std::num::NonZeroU32;
use std::rc::Rc;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::watch;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

/// Why the window could not run.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    /// No display server (or winit failed to start).
    #[error("cannot open a window: {0} (is there a display? use the browser preview instead)")]
    EventLoop(String),
}

struct App {
    frames: watch::Receiver<Arc<Frame>>,
    window: Option<Rc<Window>>,
    surface: Option<softbuffer::Surface<Rc<Window>, Rc<Window>>>,
    shown: u64,
    error: Option<String>,
    views: Option<Arc<dyn CameraControl>>,
    /// The pose being edited (taken from the daemon when a move starts).
    pose: Option<Pose>,
    cursor: Option<(f64, f64)>,
    drag: Option<MouseButton>,
    shift: bool,
    alt: bool,
}

impl App {
    fn present(&mut self) {
        let (Some(window), Some(surface)) = (&self.window, &mut self.surface) else { return };
        let frame = self.frames.borrow().clone();
        let size = window.inner_size();
        let (Some(w), Some(h)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height)) else { return };
        if let Err(e) = surface.resize(w, h) {
            self.error = Some(e.to_string());
            return;
        }
        let Ok(mut buffer) = surface.buffer_mut() else { return };
        // Nearest-neighbour scale of the frame into the window, letterboxed.
        let (fw, fh) = (frame.width.max(1) as f32, frame.height.max(1) as f32);
        let scale = (w.get() as f32 / fw).min(h.get() as f32 / fh);
        let (ox, oy) = ((w.get() as f32 - fw * scale) / 2.0, (h.get() as f32 - fh * scale) / 2.0);
        for y in 0..h.get() {
            for x in 0..w.get() {
                let sx = ((x as f32 - ox) / scale).floor();
                let sy = ((y as f32 - oy) / scale).floor();
                let px = if sx >= 0.0 && sy >= 0.0 && sx < fw && sy < fh {
                    let i = ((sy as u32 * frame.width + sx as u32) * 3) as usize;
                    (u32::from(frame.rgb[i]) << 16) | (u32::from(frame.rgb[i + 1]) << 8) | u32::from(frame.rgb[i + 2])
                } else {
                    0
                };
                buffer[(y * w.get() + x) as usize] = px;
            }
        }
        let _ = buffer.present();
        self.shown = frame.number;
    }
}

impl App {
    /// The pose to edit: the daemon's current camera unless a move of ours
    /// is still settling (then our own newest pose).
    fn pose(&mut self) -> Option<Pose> {
        let views = self.views.as_ref()?;
        let status = views.status();
        if self.pose.is_none() || status.phase == Phase::Still {
            self.pose = Some(status.current);
        }
        self.pose
    }

    fn write(&mut self, pose: Pose) {
        let Some(views) = &self.views else { return };
        match views.move_to_pose(pose) {
            Ok(()) => self.pose = Some(pose),
            Err(e) => tracing::debug!("window: camera move ignored: {e}"),
        }
    }

    /// Height of the picture on screen, pixels (pan scale).
    fn height(&self) -> f32 {
        self.window.as_ref().map_or(500, |w| w.inner_size().height.max(1)) as f32
    }

    /// Applies one control input ([`control`], the same arithmetic as the page).
    fn apply(&mut self, input: Control) {
        if let Some(pose) = self.pose() {
            self.write(control(&pose, input));
        }
    }

    fn camera_event(&mut self, event: &WindowEvent) {
        match event {
            WindowEvent::ModifiersChanged(m) => {
                self.shift = m.state().shift_key();
                self.alt = m.state().alt_key();
            }
            WindowEvent::MouseInput { state, button, .. } => {
                self.drag = (*state == ElementState::Pressed).then_some(*button);
            }
            WindowEvent::CursorMoved { position, .. } => {
                let now = (position.x, position.y);
                let last = self.cursor.replace(now);
                if let (Some(button), Some((lx, ly))) = (self.drag, last) {
                    let (dx, dy) = ((now.0 - lx) as f32, (now.1 - ly) as f32);
                    let pan = button == MouseButton::Right || self.shift;
                    self.apply(Control::Drag { dx, dy, pan, height: self.height() });
                }
            }
            WindowEvent::MouseWheel { delta, .. } => {
                // winit: positive y scrolls up (away from the user); the
                // control takes the browser's convention (positive = towards).
                let pixels = match delta {
                    MouseScrollDelta::LineDelta(_, y) => -*y * PIXELS_PER_LINE,
                    MouseScrollDelta::PixelDelta(p) => -p.y as f32,
                };
                self.apply(Control::Wheel { pixels, fov: self.alt });
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                let key = match &event.logical_key {
                    Key::Named(NamedKey::ArrowLeft) => Some(ControlKey::Left),
                    Key::Named(NamedKey::ArrowRight) => Some(ControlKey::Right),
                    Key::Named(NamedKey::ArrowUp) => Some(ControlKey::Up),
                    Key::Named(NamedKey::ArrowDown) => Some(ControlKey::Down),
                    Key::Character(c) => {
                        if let (Some(n), Some(views)) = (view_key(c), &self.views)
                            && let Some(v) = views.list().get(n)
                            && views.go_to(&v.name).is_ok()
                        {
                            self.pose = Some(v.pose);
                        }
                        ControlKey::from_char(c)
                    }
                    _ => None,
                };
                if let Some(key) = key {
                    self.apply(Control::Key(key));
                }
            }
            _ => {}
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let attrs = Window::default_attributes()
            .with_title("Footlight")
            .with_inner_size(winit::dpi::LogicalSize::new(self.frames.borrow().width, self.frames.borrow().height));
        let made = event_loop.create_window(attrs).map_err(|e| e.to_string()).and_then(|w| {
            let w = Rc::new(w);
            let context = softbuffer::Context::new(w.clone()).map_err(|e| e.to_string())?;
            let surface = softbuffer::Surface::new(&context, w.clone()).map_err(|e| e.to_string())?;
            Ok((w, surface))
        });
        match made {
            Ok((w, s)) => {
                self.window = Some(w);
                self.surface = Some(s);
            }
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::RedrawRequested | WindowEvent::Resized(_) => self.present(),
            other => self.camera_event(&other),
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.frames.borrow().number != self.shown
            && let Some(w) = &self.window
        {
            w.request_redraw();
        }
        event_loop.set_control_flow(ControlFlow::WaitUntil(Instant::now() + Duration::from_millis(8)));
    }
}

/// Shows `frames` in a window until it is closed, with camera controls
/// writing to `views`. Must run on the main thread.
pub fn show(frames: watch::Receiver<Arc<Frame>>, views: Option<Arc<dyn CameraControl>>) -> Result<(), WindowError> {
    let event_loop = EventLoop::new().map_err(|e| WindowError::EventLoop(e.to_string()))?;
    let mut app = App {
        frames,
        window: None,
        surface: None,
        shown: u64::MAX,
        error: None,
        views,
        pose: None,
        cursor: None,
        drag: None,
        shift: false,
        alt: false,
    };
    event_loop.run_app(&mut app).map_err(|e| WindowError::EventLoop(e.to_string()))?;
    match app.error {
        Some(e) => Err(WindowError::EventLoop(e)),
        None => Ok(()),
    }
}
