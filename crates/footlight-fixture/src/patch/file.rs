//! The patch file as written: plain serde structs (first stage). The
//! schema is `docs/patch-format.md`. Values that a later check may reject
//! keep their span, so the error points at the key's own line.

use serde::Deserialize;
use std::collections::BTreeMap;
use toml::Spanned;

/// The whole patch file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatchFile {
    /// Folder of fixture-type files, relative to the patch (default `fixtures`).
    pub fixtures: Option<Spanned<String>>,
    /// Gel library, relative to the patch (default `gels.toml`).
    pub gels: Option<Spanned<String>>,
    /// Optional camera overriding the scene's.
    pub camera: Option<Spanned<CameraFile>>,
    /// An MVR show (relative to the patch) whose fixtures this patch uses;
    /// the file then adds `[haze]`, `[[view]]`, `[camera]`, `[[input]]` and
    /// `[look]` to it and has no `[[fixture]]` of its own.
    pub show: Option<Spanned<String>>,
    /// Fixture instances.
    #[serde(default)]
    pub fixture: Vec<Spanned<FixtureFile>>,
    /// The default look: DMX values by fixture id and attribute, or by `"U/ADDR"`.
    pub look: Option<Spanned<BTreeMap<String, Spanned<toml::Value>>>>,
    /// Protocol universe → patch universe overrides.
    #[serde(default)]
    pub input: Vec<Spanned<InputFile>>,
    /// The haze medium (`[haze]`, see `patch/haze.rs`).
    pub haze: Option<Spanned<super::haze::HazeFile>>,
    /// Named camera views (`[[view]]`, see `patch/views.rs`).
    #[serde(default)]
    pub view: Vec<Spanned<super::views::ViewFile>>,
}

/// `[camera]`: eye position, target and vertical field of view.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    /// Eye position in metres.
    pub position: Spanned<[f32; 3]>,
    /// Point looked at.
    pub look_at: Spanned<[f32; 3]>,
    /// Vertical field of view in degrees (default [`DEFAULT_FOV_Y`]).
    pub fov_y: Option<Spanned<f32>>,
}

/// The camera's vertical field of view when `fov_y` is not given, degrees.
pub const DEFAULT_FOV_Y: f32 = 40.0;

/// One `[[fixture]]` entry as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixtureFile {
    /// Fixture id as the desk shows it (unique in the patch).
    pub id: Spanned<u32>,
    /// Human-readable name.
    #[serde(default)]
    pub name: Option<String>,
    /// Fixture type: a file stem in the fixtures folder, or the built-in `"spot"`.
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    /// DMX mode of the fixture type.
    pub mode: Option<Spanned<String>>,
    /// Patch universe, counted from 1 as desks show it.
    pub universe: Option<Spanned<i64>>,
    /// Start address 1-512.
    pub address: Option<Spanned<i64>>,
    /// A fixed gel (id in the gel library).
    pub gel: Option<Spanned<String>>,
    /// Scroller string for this instance (gel ids), replacing the type's.
    pub frames: Option<Spanned<Vec<String>>>,
    /// Position in metres (stage coordinates, +Y up).
    pub position: Spanned<[f32; 3]>,
    /// Point the beam aims at (a moving head: at pan 0, tilt 0).
    pub aim: Option<Spanned<[f32; 3]>>,
    /// Orientation quaternion [x, y, z, w] (a moving head: its body; identity hangs it).
    pub rotation: Option<Spanned<[f32; 4]>>,
    /// Manual field angle (degrees) for a zoom without a DMX channel.
    pub zoom: Option<Spanned<f32>>,
    /// Manual focus 0..1.
    pub focus: Option<Spanned<f32>>,
    /// Manual iris fraction.
    pub iris: Option<Spanned<f32>>,
    /// Manual pan, degrees.
    pub pan: Option<Spanned<f32>>,
    /// Manual tilt, degrees.
    pub tilt: Option<Spanned<f32>>,
    /// Built-in spot: full beam angle (50 % of peak), degrees.
    pub beam_angle: Option<Spanned<f32>>,
    /// Built-in spot: full field angle (10 % of peak), degrees.
    pub field_angle: Option<Spanned<f32>>,
    /// Built-in spot: Î in candela.
    pub intensity: Option<Spanned<f32>>,
    /// Built-in spot: linear RGB colour at full.
    pub colour: Option<Spanned<[f32; 3]>>,
    /// Built-in spot: dimmer level v of the default look.
    pub level: Option<Spanned<f32>>,
}

/// One `[[input]]` entry.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputFile {
    /// `"sacn"`, `"artnet"` or `"usbpro"`.
    pub protocol: Spanned<String>,
    /// sACN universe (1-63999), Art-Net Port-Address (0-32767) or USB Pro widget index (0-255).
    pub universe: Spanned<i64>,
    /// The patch universe it feeds (1-63999).
    pub patch_universe: Option<Spanned<i64>>,
    /// Feed nothing (stop the default route).
    #[serde(default)]
    pub block: bool,
}
