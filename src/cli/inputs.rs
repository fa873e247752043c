//! What every command loads first: the scene, the patch (TOML or MVR) and
//! the camera, the same for `run`, `render` and `bench`.

use super::check::fixture_summary;
use crate::bundled;
use crate::scene::Camera;
use crate::{Patch, Scene};
use anyhow::Result;
use glam::Vec3;
use std::path::{Path, PathBuf};

/// The scene and patch a command was asked for (`--scene`, `--patch`).
#[derive(Clone, Debug, Default)]
pub struct Inputs {
    /// glTF 2.0 scene; `None`: an MVR patch's own geometry, else the bundled stage.
    pub scene: Option<PathBuf>,
    /// Patch file (TOML or MVR); `None`: [`crate::DEFAULT_PATCH`].
    pub patch: Option<PathBuf>,
}

impl Inputs {
    /// The patch asked for, else the bundled default, as the user would write it.
    pub fn patch(&self) -> &Path {
        self.patch.as_deref().unwrap_or(Path::new(crate::DEFAULT_PATCH))
    }

    /// The patch file to open: the user's (from the working directory, else
    /// where the bundled files are), or the bundled default, which must exist.
    pub fn patch_path(&self) -> Result<PathBuf> {
        match &self.patch {
            Some(p) => Ok(bundled::resolve(p)),
            None => Ok(bundled::find(crate::DEFAULT_PATCH)?),
        }
    }
}

/// The scene, the checked patch and its import status for `/api/status`,
/// each logged once as it loads.
pub fn load_inputs(args: &Inputs) -> Result<(Scene, Patch, crate::output::ImportStatus)> {
    let t = std::time::Instant::now();
    let (scene_path, scene) = load_scene(args)?;
    tracing::info!(
        "{}: {} triangles, {:.1} % specular, {} materials, loaded in {:.0} ms",
        scene_path.display(),
        scene.triangle_count(),
        scene.specular_fraction() * 100.0,
        scene.materials.len(),
        t.elapsed().as_secs_f64() * 1e3
    );
    // A TOML patch, or an MVR show whose fixtures come from its GDTF files.
    let patch_path = args.patch_path()?;
    let checked = footlight_mvr::check_report(&patch_path).map_err(|e| problems(&patch_path, &e))?;
    let import = crate::output::ImportStatus::of(&checked);
    log_import(&patch_path, &checked);
    let patch = checked.patch;
    tracing::info!("{}: {}", patch.path.display(), fixture_summary(&patch, &patch.listing()));
    Ok((scene, patch, import))
}

/// A patch's errors as one error: each on its own line (they are said once
/// per file and problem already), at most 20.
fn problems(path: &Path, errors: &[crate::fixture::PatchError]) -> anyhow::Error {
    const SHOWN: usize = 20;
    let mut lines: Vec<String> = errors.iter().take(SHOWN).map(ToString::to_string).collect();
    match errors.len() {
        0 => lines.push(format!("{}: invalid patch", path.display())),
        n if n > SHOWN => lines.push(format!("… and {} more (`footlight check {}`)", n - SHOWN, path.display())),
        _ => {}
    }
    anyhow::anyhow!(lines.join("\n"))
}

/// What `run` and `render` say of an import at start, once: each fixture
/// type's summary (a missing GDTF, a type partly modelled: a warning) and
/// the warnings, or how many there are and where `footlight check` lists them.
fn log_import(path: &Path, checked: &footlight_mvr::Checked) {
    /// Warnings printed at start before they are only counted.
    const SHOWN: usize = 5;
    for t in &checked.types {
        match t.status {
            footlight_mvr::Modelled::Modelled => tracing::info!("fixture type {t}"),
            _ => tracing::warn!("fixture type {t}"),
        }
    }
    for n in &checked.notes {
        tracing::info!("{n}");
    }
    if checked.warnings.len() <= SHOWN {
        checked.warnings.iter().for_each(|w| tracing::warn!("{w}"));
    } else {
        tracing::warn!(
            "{} import warnings (each said once, with its file and line): `footlight check {}` lists them",
            checked.warnings.len(),
            path.display()
        );
    }
}

/// The scene: `--scene`, else an MVR patch's own geometry (issue 14), else
/// the bundled stage (which must then be found: [`bundled::find`]).
pub fn load_scene(args: &Inputs) -> Result<(PathBuf, Scene)> {
    use crate::scene::mvr_scene::{SceneSource, scene_source};
    let patch = args.patch_path()?;
    let bundled_stage = bundled::find(crate::DEFAULT_SCENE);
    let default = bundled_stage.clone().unwrap_or_else(|_| PathBuf::from(crate::DEFAULT_SCENE));
    let stage = || -> Result<Scene> {
        bundled_stage.clone()?;
        Ok(crate::scene::load(&default)?)
    };
    match scene_source(args.scene.as_deref().map(bundled::resolve).as_deref(), &patch, &default) {
        SceneSource::Gltf(path) if args.scene.is_none() && path == default => Ok((path, stage()?)),
        SceneSource::Gltf(path) => {
            let scene = crate::scene::load(&path)?;
            Ok((path, scene))
        }
        SceneSource::Mvr(path) => {
            let loaded = crate::scene::load_mvr_scene(&path)?;
            if loaded.objects == 0 {
                // A rig without a venue (what a desk exports): light it on the bundled stage.
                tracing::info!(
                    "{}: no scene objects; the bundled stage {} is used (--scene chooses another)",
                    path.display(),
                    default.display()
                );
                return Ok((default.clone(), stage()?));
            }
            for w in &loaded.warnings {
                tracing::warn!("{w}");
            }
            Ok((path, loaded.scene))
        }
    }
}

/// The one camera of `run`, `render` and `bench`: the patch's camera, else
/// the scene's, else (an MVR venue has none) the "frame the rig" view: the
/// lit rig and the stage from a designer's height, instead of a seat level
/// with the deck.
pub fn choose_camera(scene: &Scene, patch: &Patch) -> Camera {
    if let Some(c) = patch.camera.map(|c| Camera::look_at(c.position, c.look_at, c.fov_y)).or(scene.camera) {
        return c;
    }
    let seat = Camera::look_at(Vec3::new(0.0, 1.7, 14.0), Vec3::new(0.0, 1.5, 0.0), 40f32.to_radians());
    let framed = crate::live::views::named_views(&seat, scene, Some(patch))
        .into_iter()
        .find(|v| v.name == crate::live::views::FRAME_VIEW)
        .and_then(|v| v.pose.camera().ok());
    match framed {
        Some(c) => {
            let p = c.position;
            tracing::info!(
                "camera: no camera in the patch or scene; framing the rig from ({:.1}, {:.1}, {:.1}) m",
                p.x,
                p.y,
                p.z
            );
            c
        }
        None => seat,
    }
}
