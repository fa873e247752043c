//! `footlight bench`: which section runs, at what size, on which inputs.
//! Full-size figures are [`PICTURE_SIZE`], CI-sized ones
//! [`QUICK_SIZE`]; the bundled test files are found at run time
//! ([`crate::bundled`]).

use super::inputs::{Inputs, choose_camera, load_inputs};
use crate::bench;
use crate::render::{PICTURE_SIZE, QUICK_SIZE};
use anyhow::{Context, Result};
use std::path::PathBuf;
use std::sync::Arc;

/// One section run alone, or the whole bench.
#[derive(Clone, Debug, PartialEq)]
pub enum BenchSection {
    /// Every section, written as a report.
    All,
    /// "Walking the stage" (issue 16), printed as Markdown.
    Walk,
    /// The haze section (issue 15; the whole picture: issue 34 item 5);
    /// `spp` overrides the whole picture's reference samples.
    Haze {
        /// Samples per pixel of the whole hazy picture's reference.
        spp: Option<u32>,
    },
    /// The accuracy round (issue 13): these parts (empty: all).
    Accuracy(Vec<bench::accuracy::Part>),
    /// Gobos, shutters, prism, frost (issue 14).
    Gate,
    /// The pixel-bar rig of the 150-fixture MVR (issue 14).
    Pixels,
    /// Fixture bodies (issue 14 item 5).
    Bodies,
    /// Error against time (issue 34): ours and the reference path tracer
    /// against a converged reference; `spp` overrides the reference's samples.
    Converge {
        /// Samples per pixel of the whole-picture reference.
        spp: Option<u32>,
    },
    /// The festival targets (issue 38): picture size and per-phase deadline
    /// (`None`: the festival's own defaults).
    Festival {
        /// Picture size.
        size: Option<(u32, u32)>,
        /// Deadline of each phase in seconds.
        seconds: Option<f64>,
    },
}

/// Everything `footlight bench` was asked for.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Scene and patch (`None` patch: the paper's rig).
    pub inputs: Inputs,
    /// CI-sized run ([`QUICK_SIZE`], one repetition).
    pub quick: bool,
    /// Output folder (default [`bench::default_out_dir`]).
    pub out: Option<PathBuf>,
    /// The section to run.
    pub section: BenchSection,
}

/// A section's picture: [`PICTURE_SIZE`], or [`QUICK_SIZE`] with `quick`.
fn sized(quick: bool) -> (u32, u32) {
    if quick { QUICK_SIZE } else { PICTURE_SIZE }
}

/// Runs the section asked for and prints (or writes) its report.
pub fn bench(mut args: BenchOptions) -> Result<()> {
    if let BenchSection::Festival { size, seconds } = args.section {
        let mut cfg = bench::festival::FestivalConfig::new(args.quick);
        if let Some(p) = &args.inputs.patch {
            cfg.show = crate::bundled::resolve(p);
        }
        (cfg.width, cfg.height) = size.unwrap_or((cfg.width, cfg.height));
        cfg.seconds = seconds.unwrap_or(cfg.seconds);
        let out = args.out.unwrap_or_else(bench::default_out_dir);
        let report = bench::festival::run(&cfg).map_err(|e| anyhow::anyhow!("festival: {e}"))?;
        report.write(&out)?;
        print!("{}", report.lines());
        println!("report written to {}", out.display());
        return Ok(());
    }
    if let BenchSection::Converge { spp } = args.section {
        let mut cfg = bench::error_time::ErrorTimeConfig::new(args.quick);
        cfg.reference_spp = spp.unwrap_or(cfg.reference_spp);
        let out = args.out.unwrap_or_else(bench::default_out_dir);
        let report = bench::error_time::run(&cfg).map_err(|e| anyhow::anyhow!("error against time: {e}"))?;
        report.write(&out)?;
        print!("{}", report.markdown());
        println!("report written to {}", out.display());
        return Ok(());
    }
    // The paper's figures are measured on the paper's rig.
    args.inputs.patch.get_or_insert_with(|| PathBuf::from(crate::PAPER_PATCH));
    let (scene, patch, _) = load_inputs(&args.inputs)?;
    let camera = choose_camera(&scene, &patch);
    let quick = args.quick;
    let size = sized(quick);
    let scene_path = || -> Result<PathBuf> {
        Ok(match &args.inputs.scene {
            Some(p) => crate::bundled::resolve(p),
            None => crate::bundled::find(crate::DEFAULT_SCENE)?,
        })
    };
    match &args.section {
        BenchSection::Walk => {
            let (seconds, photons) =
                if quick { (1.0, 0) } else { (5.0, crate::render::photon::PhotonSettings::default().stored) };
            let walk = bench::walk::run(&Arc::new(scene), &patch, camera, size, seconds, photons)
                .map_err(|e| anyhow::anyhow!("walking the stage: {e}"))?;
            println!("{}", walk.markdown());
        }
        BenchSection::Haze { spp } => {
            let scene = Arc::new(scene);
            let light = patch.fixtures.first().map(|f| f.light.clone()).context("the patch has no fixtures")?;
            let (repeats, paths, moves) = if quick { (1, 20_000, 2) } else { (3, 200_000, 10) };
            let rig = (!quick).then(bench::haze::rig_lights);
            let mut report = bench::haze::run(&scene, camera, size.0, size.1, &light, repeats, paths, rig.as_deref())
                .context("haze: the scene has no volume for the haze box")?;
            report.moved = bench::haze::moved_beam(&scene, camera, size, 2, &light, moves);
            report.whole = Some(
                bench::haze_whole::run(&bench::haze_whole::WholeHazeConfig {
                    reference_spp: spp.unwrap_or(bench::haze_whole::WholeHazeConfig::new(quick).reference_spp),
                    ..bench::haze_whole::WholeHazeConfig::new(quick)
                })
                .map_err(|e| anyhow::anyhow!("whole haze: {e}"))?,
            );
            println!("{}", report.lines());
        }
        BenchSection::Accuracy(parts) => {
            let repeats = if quick { 1 } else { 3 };
            let report = bench::accuracy::run(&scene, &scene_path()?, &patch, camera, size, repeats, parts)
                .map_err(|e| anyhow::anyhow!("accuracy section: {e}"))?;
            println!("{}", report.markdown());
        }
        BenchSection::Gate => {
            let gate_patch = crate::bundled::find("tests/data/gate-patch.toml")?;
            let rows = bench::gate::run(&scene, camera, size, &gate_patch).map_err(|e| anyhow::anyhow!("gate: {e}"))?;
            println!("{}", bench::gate::markdown(&rows, size));
        }
        BenchSection::Pixels => {
            let show = crate::bundled::find(bench::SHOW150)?;
            let report = bench::mvr::pixels(&Arc::new(scene), camera, size, &show)
                .map_err(|e| anyhow::anyhow!("pixel bars: {e}"))?;
            print!("{}", report.lines());
        }
        BenchSection::Bodies => {
            let frames = if quick { 30 } else { 240 };
            let report = bench::bodies::run(&Arc::new(scene), camera, size, frames)
                .map_err(|e| anyhow::anyhow!("fixture bodies: {e}"))?;
            println!("{}", report.markdown());
        }
        BenchSection::All | BenchSection::Festival { .. } | BenchSection::Converge { .. } => {
            let out = args.out.clone().unwrap_or_else(bench::default_out_dir);
            let config = bench::BenchConfig::new(quick, scene_path()?);
            let report = bench::run(&scene, &patch, camera, &config, &out)?;
            println!("{}", report.summary());
            println!("report written to {}", out.display());
        }
    }
    Ok(())
}
