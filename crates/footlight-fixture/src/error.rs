//! The one error shape of every file Footlight reads for the patch: the
//! patch itself, fixture-type files and photometric files. It always names
//! `file:line` and says what to change (DESIGN.md "One schema").

use std::path::{Path, PathBuf};

/// An error in a patch, fixture-type or photometric file, with the file and
/// 1-based line it refers to.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}:{line}: {message}", path.display())]
pub struct PatchError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line number (0 when the file could not be read at all).
    pub line: usize,
    /// What is wrong and what to do about it.
    pub message: String,
}

impl PatchError {
    /// An error at `line` of `path`.
    pub fn new(path: &Path, line: usize, message: impl Into<String>) -> Self {
        Self { path: path.to_path_buf(), line, message: message.into() }
    }
}

/// 1-based line number of byte offset `at` in `text`.
pub(crate) fn line_of(text: &str, at: usize) -> usize {
    text.as_bytes()[..at.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1
}

/// The error of a TOML file that serde could not read.
pub(crate) fn toml_error(path: &Path, text: &str, e: &toml::de::Error) -> PatchError {
    PatchError::new(path, e.span().map(|s| line_of(text, s.start)).unwrap_or(0), e.message().trim().to_string())
}
