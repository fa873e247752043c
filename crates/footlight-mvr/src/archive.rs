//! Opening MVR and GDTF archives (zip) without trusting them.
//!
//! Both formats are zip files (DIN SPEC 15800). Before any byte is
//! inflated, every entry is checked: a name with a `..` component, an
//! absolute name (`/x`, `\x`, `C:x`), more than [`MAX_TOTAL`] bytes
//! uncompressed in all, or an entry of more than [`RATIO_FLOOR`] bytes that
//! inflates more than [`MAX_RATIO`]:1 is refused with an error naming the
//! archive and the entry. Entries are then read with a cap at their
//! declared size, so a header that lies about its size cannot inflate more.
//! Nothing is ever written to disk: the archive's files live in memory.
//!
//! The `zip` crate (well kept, pure Rust with zlib-rs) does the inflating;
//! this module only adds the checks.

use footlight_fixture::PatchError;
use std::collections::BTreeMap;
use std::io::{Cursor, Read};
use std::path::{Path, PathBuf};

/// Most bytes all entries of one archive may inflate to (1 GiB).
pub const MAX_TOTAL: u64 = 1 << 30;
/// Largest inflated/compressed ratio of one entry.
pub const MAX_RATIO: u64 = 100;
/// Entries up to this size (1 MiB) are exempt from the ratio test: small
/// text files legitimately compress more than 100:1.
pub const RATIO_FLOOR: u64 = 1 << 20;

/// The files of one archive, read into memory, by their names in the zip.
#[derive(Clone, Debug)]
pub struct Archive {
    /// Where it came from (for messages).
    pub path: PathBuf,
    files: BTreeMap<String, Vec<u8>>,
}

/// The limits an archive is checked against (the defaults are the module's constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Most bytes all entries may inflate to.
    pub max_total: u64,
    /// Largest inflated/compressed ratio of one entry above `ratio_floor` bytes.
    pub max_ratio: u64,
    /// Entries up to this many bytes skip the ratio test.
    pub ratio_floor: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self { max_total: MAX_TOTAL, max_ratio: MAX_RATIO, ratio_floor: RATIO_FLOOR }
    }
}

impl Archive {
    /// Reads and checks the archive at `path`.
    pub fn open(path: &Path) -> Result<Self, PatchError> {
        let bytes = std::fs::read(path).map_err(|e| PatchError::new(path, 0, format!("cannot read: {e}")))?;
        Self::from_bytes(path, bytes, Limits::default())
    }

    /// Checks and reads an archive held in memory; `path` names it in messages.
    pub fn from_bytes(path: &Path, bytes: Vec<u8>, limits: Limits) -> Result<Self, PatchError> {
        let err = |m: String| PatchError::new(path, 0, m);
        let mut zip = zip::ZipArchive::new(Cursor::new(bytes))
            .map_err(|e| err(format!("not a readable zip archive ({e}); MVR and GDTF files are zip files")))?;
        let mut total: u64 = 0;
        let mut sizes = Vec::with_capacity(zip.len());
        for i in 0..zip.len() {
            let f = zip.by_index_raw(i).map_err(|e| err(format!("zip entry {i} is unreadable: {e}")))?;
            let name = f.name().to_string();
            if let Some(why) = unsafe_name(&name) {
                return Err(err(format!(
                    "refused: entry {name:?} {why}; the archive may try to write outside its folder"
                )));
            }
            if f.encrypted() {
                return Err(err(format!("refused: entry {name:?} is encrypted")));
            }
            let (size, packed) = (f.size(), f.compressed_size());
            total = total.saturating_add(size);
            if total > limits.max_total {
                return Err(err(format!(
                    "refused: the entries inflate to more than {} bytes (at {name:?}); a zip bomb or not an MVR/GDTF file",
                    limits.max_total
                )));
            }
            if size > limits.ratio_floor && size / packed.max(1) > limits.max_ratio {
                return Err(err(format!(
                    "refused: entry {name:?} inflates {size} bytes from {packed} (more than {}:1); a zip bomb or not an MVR/GDTF file",
                    limits.max_ratio
                )));
            }
            sizes.push((name, size, f.is_dir()));
        }
        let mut files = BTreeMap::new();
        for (i, (name, size, dir)) in sizes.into_iter().enumerate() {
            if dir {
                continue;
            }
            let f = zip.by_index(i).map_err(|e| err(format!("entry {name:?}: {e}")))?;
            let mut data = Vec::with_capacity(size.min(1 << 24) as usize);
            f.take(size + 1).read_to_end(&mut data).map_err(|e| err(format!("entry {name:?}: {e}")))?;
            if data.len() as u64 != size {
                return Err(err(format!(
                    "refused: entry {name:?} inflates to {} bytes, not the {size} its header declares",
                    data.len()
                )));
            }
            files.insert(name, data);
        }
        Ok(Self { path: path.to_path_buf(), files })
    }

    /// The file named `name`: the exact name first, then ignoring ASCII case
    /// and a leading `./` (exporters differ).
    pub fn get(&self, name: &str) -> Option<&[u8]> {
        if let Some(d) = self.files.get(name) {
            return Some(d);
        }
        let want = name.trim_start_matches("./");
        self.files
            .iter()
            .find(|(k, _)| k.trim_start_matches("./").eq_ignore_ascii_case(want))
            .map(|(_, v)| v.as_slice())
    }

    /// Names of the files, sorted.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.files.keys().map(String::as_str)
    }

    /// A label for a file inside the archive in messages: `archive/entry`.
    pub fn label(&self, entry: &str) -> PathBuf {
        self.path.join(entry)
    }
}

/// Why an entry name is unsafe, if it is.
pub fn unsafe_name(name: &str) -> Option<&'static str> {
    let n = name.replace('\\', "/");
    if n.starts_with('/') {
        return Some("has an absolute path");
    }
    let b = n.as_bytes();
    if b.len() >= 2 && b[1] == b':' && b[0].is_ascii_alphabetic() {
        return Some("has an absolute (drive-letter) path");
    }
    if n.split('/').any(|c| c == "..") {
        return Some("has a `..` path component");
    }
    if n.contains('\0') {
        return Some("has a NUL byte in its name");
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert!(unsafe_name("../x").is_some());
        assert!(unsafe_name("a/../../x").is_some());
        assert!(unsafe_name("a\\..\\x").is_some());
        assert!(unsafe_name("/etc/passwd").is_some());
        assert!(unsafe_name("C:\\x").is_some());
        assert!(unsafe_name("wheels/gobo..png").is_none());
        assert!(unsafe_name("models/gltf/Head.glb").is_none());
    }
}
