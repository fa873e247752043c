//! Where an XML document is malformed: file, line and column.
//!
//! The serde deserialiser behind the readers reports *what* is wrong but
//! not *where*; a plain pass of quick-xml's pull reader over the text first
//! finds syntax errors (unclosed or mismatched tags, bad attributes, broken
//! UTF-8) with their byte position, turned here into a 1-based line and column.

use footlight_fixture::PatchError;
use quick_xml::Reader;
use quick_xml::events::Event;
use std::path::Path;

/// The text of an XML file, or an error at the line and column of the first
/// invalid UTF-8 byte.
pub fn utf8<'a>(label: &Path, bytes: &'a [u8]) -> Result<&'a str, PatchError> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    std::str::from_utf8(bytes).map_err(|e| {
        let (line, col) = line_col(bytes, e.valid_up_to());
        PatchError::new(label, line, format!("column {col}: not UTF-8 text (MVR and GDTF XML is UTF-8)"))
    })
}

/// Checks that `text` is well-formed XML with one root element named `root`.
pub fn well_formed(label: &Path, text: &str, root: &str) -> Result<(), PatchError> {
    let mut reader = Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    let mut depth = 0usize;
    let mut seen_root = false;
    loop {
        let at = reader.buffer_position() as usize;
        match reader.read_event() {
            Ok(Event::Start(e)) => {
                if depth == 0 {
                    check_root(label, text, at, e.name().as_ref(), root, &mut seen_root)?;
                }
                depth += 1;
                check_attributes(label, text, at, &e)?;
            }
            Ok(Event::Empty(e)) => {
                if depth == 0 {
                    check_root(label, text, at, e.name().as_ref(), root, &mut seen_root)?;
                }
                check_attributes(label, text, at, &e)?;
            }
            Ok(Event::End(_)) => depth = depth.saturating_sub(1),
            Ok(Event::Eof) => {
                if depth > 0 {
                    let (line, col) = line_col(text.as_bytes(), text.len());
                    return Err(PatchError::new(label, line, format!("column {col}: the file ends inside an element")));
                }
                if !seen_root {
                    return Err(PatchError::new(label, 1, format!("column 1: no <{root}> element")));
                }
                return Ok(());
            }
            Ok(_) => {}
            Err(e) => {
                let (line, col) = line_col(text.as_bytes(), reader.error_position() as usize);
                return Err(PatchError::new(label, line, format!("column {col}: malformed XML: {e}")));
            }
        }
    }
}

fn check_root(label: &Path, text: &str, at: usize, name: &[u8], root: &str, seen: &mut bool) -> Result<(), PatchError> {
    let (line, col) = line_col(text.as_bytes(), at);
    if *seen {
        return Err(PatchError::new(label, line, format!("column {col}: a second root element")));
    }
    *seen = true;
    if name != root.as_bytes() {
        let got = String::from_utf8_lossy(name);
        return Err(PatchError::new(label, line, format!("column {col}: root element <{got}>, expected <{root}>")));
    }
    Ok(())
}

fn check_attributes(
    label: &Path,
    text: &str,
    at: usize,
    e: &quick_xml::events::BytesStart<'_>,
) -> Result<(), PatchError> {
    for a in e.attributes() {
        let a = a.map_err(|err| {
            let (line, col) = line_col(text.as_bytes(), at);
            PatchError::new(label, line, format!("column {col}: malformed attribute: {err}"))
        })?;
        if let Err(err) = a.normalized_value(quick_xml::XmlVersion::Implicit1_0) {
            let (line, col) = line_col(text.as_bytes(), at);
            return Err(PatchError::new(label, line, format!("column {col}: bad escape in an attribute: {err}")));
        }
    }
    Ok(())
}

/// 1-based line and column (in characters) of byte offset `at`.
pub fn line_col(bytes: &[u8], at: usize) -> (usize, usize) {
    let at = at.min(bytes.len());
    let before = &bytes[..at];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let start = before.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
    let col = String::from_utf8_lossy(&before[start..]).chars().count() + 1;
    (line, col)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions() {
        let p = Path::new("x.xml");
        assert!(well_formed(p, "<a><b/></a>", "a").is_ok());
        let e = well_formed(p, "<a>\n  <b></c>\n</a>", "a").unwrap_err();
        assert_eq!(e.line, 2, "{e}");
        assert!(e.message.starts_with("column "), "{e}");
        let e = well_formed(p, "<a>\n<b>", "a").unwrap_err();
        assert_eq!(e.line, 2, "{e}");
        let e = well_formed(p, "<z/>", "a").unwrap_err();
        assert!(e.message.contains("expected <a>"), "{e}");
        assert_eq!(line_col(b"ab\ncd", 4), (2, 2));
        let e = utf8(p, b"<a>\n\xff</a>").unwrap_err();
        assert_eq!((e.line, e.message.starts_with("column 1")), (2, true), "{e}");
    }
}
