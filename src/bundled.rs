//! The bundled files (`scenes/`, `patch/`, `tests/data/`, `tests/replays/`)
//! found at run time, never through a path of the build checkout compiled
//! into the binary (issue 33 item 4): a release binary copied to another
//! machine looks where its user says, else beside itself.
//!
//! A relative path is looked up, in order:
//! 1. as given, from the working directory;
//! 2. under `$FOOTLIGHT_DATA` ([`DATA_ENV`]) when it is set (and then
//!    nowhere else: the variable is the user's answer);
//! 3. otherwise under the executable's directory and its ancestors, up to
//!    [`EXE_LEVELS`] levels (`target/release/footlight` finds the checkout
//!    it sits in; `/opt/footlight/bin/footlight` finds `/opt/footlight`).
//!
//! A file found nowhere is an error naming the file and every place looked
//! ([`MissingFile`]).

use std::path::{Path, PathBuf};

/// Environment variable naming the directory that holds the bundled files
/// (the Footlight checkout, or an install's data directory).
pub const DATA_ENV: &str = "FOOTLIGHT_DATA";

/// Levels above the executable's own directory searched for the bundled
/// files when [`DATA_ENV`] is not set (`<checkout>/target/release/footlight`
/// is 2 levels below its checkout).
pub const EXE_LEVELS: usize = 3;

/// A bundled file found nowhere: its name and every directory looked in.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}: not found in {}; run footlight from the Footlight checkout or set {DATA_ENV} to the directory holding it", path.display(), looked(searched))]
pub struct MissingFile {
    /// The relative path asked for.
    pub path: PathBuf,
    /// The directories looked in, in order (the working directory first).
    pub searched: Vec<PathBuf>,
}

/// "the working directory (/x), /y or /z".
fn looked(dirs: &[PathBuf]) -> String {
    let names: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    match names.split_last() {
        None => "the working directory".into(),
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
    }
}

/// The directories a relative bundled path is looked up under, after the
/// working directory: `$FOOTLIGHT_DATA` when set, else the executable's
/// directory and up to [`EXE_LEVELS`] of its ancestors.
pub fn search_dirs() -> Vec<PathBuf> {
    if let Some(dir) = std::env::var_os(DATA_ENV).filter(|d| !d.is_empty()) {
        return vec![PathBuf::from(dir)];
    }
    let Ok(exe) = std::env::current_exe() else { return Vec::new() };
    exe.parent().map(|dir| dir.ancestors().take(EXE_LEVELS + 1).map(Path::to_path_buf).collect()).unwrap_or_default()
}

/// `path` as given when it exists or is absolute, else the first of
/// [`search_dirs`] that holds it.
pub fn find(path: impl AsRef<Path>) -> Result<PathBuf, MissingFile> {
    let path = path.as_ref();
    if path.exists() {
        return Ok(path.to_path_buf());
    }
    if path.is_absolute() {
        return Err(missing(path, Vec::new()));
    }
    let dirs = search_dirs();
    dirs.iter().map(|d| d.join(path)).find(|p| p.exists()).ok_or_else(|| missing(path, dirs))
}

/// The error for `path` after looking under `dirs` (the working directory first).
fn missing(path: &Path, dirs: Vec<PathBuf>) -> MissingFile {
    let cwd = std::env::current_dir().map_or_else(
        |_| PathBuf::from("the working directory"),
        |d| PathBuf::from(format!("the working directory ({})", d.display())),
    );
    let searched = if path.is_absolute() { Vec::new() } else { std::iter::once(cwd).chain(dirs).collect() };
    MissingFile { path: path.to_path_buf(), searched }
}

/// [`find`], or `path` unchanged when it is found nowhere (the loader that
/// opens it then names it): for paths a user gave.
pub fn resolve(path: &Path) -> PathBuf {
    find(path).unwrap_or_else(|_| path.to_path_buf())
}

/// The directory that holds the relative `path` (`patch/fixtures` → the
/// checkout), absolute, for generated patches that name bundled folders.
pub fn root_of(path: impl AsRef<Path>) -> Result<PathBuf, MissingFile> {
    let path = path.as_ref();
    let found = find(path)?;
    let depth = path.components().count();
    let root = found.ancestors().nth(depth).map_or_else(PathBuf::new, Path::to_path_buf);
    if root.as_os_str().is_empty() || root.is_relative() {
        let cwd = std::env::current_dir().unwrap_or_default();
        return Ok(cwd.join(root));
    }
    Ok(root)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_file_names_itself_and_where_it_was_looked_for() {
        let e = find("no/such/bundled-file.toml").unwrap_err();
        let text = e.to_string();
        assert!(text.starts_with("no/such/bundled-file.toml: not found in the working directory ("), "{text}");
        assert!(text.contains(DATA_ENV), "{text}");
        let e = find("/no/such/absolute.toml").unwrap_err();
        assert!(e.searched.is_empty(), "an absolute path is looked for only where it says");
    }

    #[test]
    fn the_root_of_a_relative_path_is_the_directory_holding_it() {
        // The unit tests run in the package directory: `src/lib.rs` is there.
        let root = root_of("src/lib.rs").unwrap();
        assert!(root.is_absolute() && root.join("src/lib.rs").exists(), "{}", root.display());
    }
}
