//! `[[view]]`: named camera views of the stage (issue 16).
//!
//! ```toml
//! [[view]]
//! name = "director"            # unique among the views
//! position = [0.0, 1.6, 14.0]  # eye, metres
//! target = [0.0, 1.5, 0.0]     # point looked at, distinct from position
//! fov_y = 35.0                 # vertical field of view, degrees (default 40)
//! ```
//!
//! The live preview lists these beside the scene's glTF camera and the
//! patch's `[camera]`, and moves the camera to one on request. This crate
//! only reads and checks the table, with `file:line` on every error.

use super::file::{DEFAULT_FOV_Y, PatchFile};
use crate::error::{PatchError, line_of};
use glam::Vec3;
use serde::Deserialize;
use std::path::Path;
use toml::Spanned;

/// One `[[view]]` as written (first stage).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewFile {
    /// The name shown in the list (1-64 characters, unique).
    pub name: Spanned<String>,
    /// Eye position in metres.
    pub position: Spanned<[f32; 3]>,
    /// Point looked at.
    pub target: Spanned<[f32; 3]>,
    /// Vertical field of view in degrees (default [`DEFAULT_FOV_Y`]).
    pub fov_y: Option<Spanned<f32>>,
}

/// A validated `[[view]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSpec {
    /// Its name.
    pub name: String,
    /// Eye position.
    pub position: Vec3,
    /// Point looked at (distinct from `position`).
    pub target: Vec3,
    /// Vertical field of view in radians.
    pub fov_y: f32,
    /// Line in the patch file.
    pub line: usize,
}

/// Checks every `[[view]]`, pushing one error per bad key (at its line).
pub(super) fn build_views(path: &Path, text: &str, file: &PatchFile, errors: &mut Vec<PatchError>) -> Vec<ViewSpec> {
    let mut out: Vec<ViewSpec> = Vec::new();
    for v in &file.view {
        let line = line_of(text, v.span().start);
        let v = v.get_ref();
        let mut err = |span: std::ops::Range<usize>, msg: String| {
            errors.push(PatchError::new(path, line_of(text, span.start), msg));
        };
        let name = v.name.get_ref().trim().to_string();
        if name.is_empty() || name.chars().count() > 64 || name.chars().any(char::is_control) {
            err(v.name.span(), format!("view name {:?} must be 1-64 printable characters", v.name.get_ref()));
            continue;
        }
        if let Some(first) = out.iter().find(|o| o.name == name) {
            err(v.name.span(), format!("view {name:?} is defined twice (first at line {})", first.line));
            continue;
        }
        let (p, t) = (Vec3::from(*v.position.get_ref()), Vec3::from(*v.target.get_ref()));
        if !p.is_finite() {
            err(v.position.span(), format!("view {name:?}: position must be three finite numbers"));
            continue;
        }
        if !t.is_finite() || p.distance(t) < 1e-4 {
            err(v.target.span(), format!("view {name:?}: target must be three finite numbers, distinct from position"));
            continue;
        }
        let fov_y = v.fov_y.as_ref().map_or(DEFAULT_FOV_Y, |f| *f.get_ref());
        if !(fov_y > 0.0 && fov_y < 179.0) {
            let span = v.fov_y.as_ref().map_or(0..0, |f| f.span());
            err(span, format!("view {name:?}: fov_y {fov_y} must be between 0 and 179 degrees"));
            continue;
        }
        out.push(ViewSpec { name, position: p, target: t, fov_y: fov_y.to_radians(), line });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<ViewSpec>, Vec<PatchError>> {
        let file: PatchFile = toml::from_str(text).expect("toml");
        let mut errors = Vec::new();
        let views = build_views(Path::new("p.toml"), text, &file, &mut errors);
        if errors.is_empty() { Ok(views) } else { Err(errors) }
    }

    #[test]
    fn views_parse_with_default_fov_and_their_lines() {
        let text = "[[view]]\nname = \"desk\"\nposition = [0.0, 2.0, 10.0]\ntarget = [0.0, 1.0, 0.0]\n\n\
                    [[view]]\nname = \"balcony\"\nposition = [0.0, 6.0, 12.0]\ntarget = [0.0, 0.0, 0.0]\nfov_y = 30.0\n";
        let v = parse(text).expect("valid");
        assert_eq!(v.len(), 2);
        assert_eq!((v[0].name.as_str(), v[0].line), ("desk", 1));
        assert!((v[0].fov_y - 40f32.to_radians()).abs() < 1e-6);
        assert_eq!((v[1].name.as_str(), v[1].line), ("balcony", 6));
        assert_eq!(v[1].position, Vec3::new(0.0, 6.0, 12.0));
        assert!((v[1].fov_y - 30f32.to_radians()).abs() < 1e-6);
    }

    #[test]
    fn bad_views_are_refused_at_the_keys_line() {
        let good = "[[view]]\nname = \"a\"\nposition = [0.0, 2.0, 10.0]\ntarget = [0.0, 1.0, 0.0]\nfov_y = 40.0\n";
        for (text, line, needle) in [
            (good.replace("name = \"a\"", "name = \"\""), 2, "1-64"),
            (good.replace("target = [0.0, 1.0, 0.0]", "target = [0.0, 2.0, 10.0]"), 4, "distinct"),
            (good.replace("position = [0.0, 2.0, 10.0]", "position = [0.0, inf, 10.0]"), 3, "finite"),
            (good.replace("fov_y = 40.0", "fov_y = 180.0"), 5, "fov_y"),
            (format!("{good}\n{good}"), 8, "defined twice (first at line 1)"),
        ] {
            let e = parse(&text).expect_err(needle);
            assert_eq!(e.len(), 1, "{text}: {e:?}");
            assert_eq!(e[0].line, line, "{text}: {}", e[0]);
            assert!(e[0].to_string().contains(needle), "{}", e[0]);
        }
        // Unknown keys are refused by the first stage (a typo is not ignored).
        assert!(
            toml::from_str::<PatchFile>(
                "[[view]]\nname = \"a\"\nposition = [0.0, 2.0, 1.0]\ntarget = [0.0, 0.0, 0.0]\nfov = 3.0\n"
            )
            .is_err()
        );
    }
}
