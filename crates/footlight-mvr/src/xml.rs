//! Where an XML document is malformed: file, line and column.
//!
//! The serde deserialiser behind the readers reports *what* is wrong but
//! not *where*; a plain pass of quick-xml's pull reader over the text first
//! finds syntax errors (unclosed or mismatched tags, bad attributes, broken
//! UTF-8) with their byte position, turned here into a 1-based line and column.
//!
//! The same pass bounds how deeply elements nest (issue 35). The serde
//! readers after it (quick-xml's for the MVR scene, the `gdtf` crate's for
//! `description.xml`) recurse once per element level, and a stack overflow
//! aborts the process (no `Result`, no unwinding), so a few kilobytes of
//! `<Geometry><Geometry>…` used to kill `footlight run`. This pass keeps
//! only a counter, never recurses, and refuses a document nested deeper than
//! the reader's limit before serde sees it; the limits
//! ([`crate::gdtf::MAX_XML_DEPTH`], [`crate::mvr::MAX_XML_DEPTH`]) are far
//! above real files and far below what a 2 MiB thread stack survives.

use footlight_fixture::PatchError;
use quick_xml::Reader;
use quick_xml::events::Event;
use std::collections::BTreeMap;
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

/// The first element opened past a depth limit, and the deepest nesting seen.
struct TooDeep {
    /// Byte offset of the first element past the limit.
    at: usize,
    /// Its name.
    name: String,
    /// The deepest nesting in the document (counted to the end, or to the
    /// first syntax error after the limit was passed).
    deepest: usize,
}

/// Checks that `text` is well-formed XML with one root element named
/// `root`, whose elements nest at most `max_depth` deep (the root is level
/// 1, an empty element `<x/>` counts as a level). Too deep is an error at
/// the line of the first element past the limit, naming the limit and the
/// document's deepest nesting; nothing here recurses.
pub fn well_formed(label: &Path, text: &str, root: &str, max_depth: usize) -> Result<(), PatchError> {
    let mut reader = Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    let mut depth = 0usize;
    let mut seen_root = false;
    let mut too_deep: Option<TooDeep> = None;
    loop {
        let at = reader.buffer_position() as usize;
        let event = reader.read_event();
        // Nesting first: once past the limit only the deepest level is
        // still counted, and the first syntax error ends the count.
        match &event {
            Ok(Event::Start(e) | Event::Empty(e)) => {
                let level = depth + 1;
                if level > max_depth {
                    let name = || String::from_utf8_lossy(e.name().as_ref()).into_owned();
                    let t = too_deep.get_or_insert_with(|| TooDeep { at, name: name(), deepest: level });
                    t.deepest = t.deepest.max(level);
                }
            }
            Err(_) | Ok(Event::Eof) => {
                if let Some(t) = &too_deep {
                    let (line, col) = line_col(text.as_bytes(), t.at);
                    return Err(PatchError::new(
                        label,
                        line,
                        format!(
                            "column {col}: elements nested {} deep (limit {max_depth}; <{}> here is the first \
                             past it); refused before parsing, as a hostile or broken file",
                            t.deepest, t.name
                        ),
                    ));
                }
            }
            _ => {}
        }
        if too_deep.is_some() {
            match event {
                Ok(Event::Start(_)) => depth += 1,
                Ok(Event::End(_)) => depth = depth.saturating_sub(1),
                _ => {}
            }
            continue;
        }
        match event {
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

/// Where elements start in an XML text, by a name they carry: the 1-based
/// line of the first `<Element attribute="value">` for each indexed
/// attribute (a GDTF's `<LogicalChannel Attribute="Gobo2">`, `<Attribute
/// Name="Gobo2">`, `<DMXMode Name="Standard">`; an MVR's `<Fixture
/// uuid="…">`), so a warning about a named thing can give the line a
/// designer opens the file at. Built in one pass of the pull reader (no
/// recursion; the text was checked by [`well_formed`] first); an element
/// past a syntax error is simply not indexed.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LineIndex {
    /// (element, attribute, value) → line of its first occurrence.
    lines: BTreeMap<(String, String, String), usize>,
    /// Line of the first element of each name.
    elements: BTreeMap<String, usize>,
    /// (attribute, value) → line of the first element of any name carrying it.
    values: BTreeMap<(String, String), usize>,
}

impl LineIndex {
    /// Indexes every element of `text` by the values of the attributes named in `attributes`.
    pub fn new(text: &str, attributes: &[&str]) -> Self {
        let mut out = Self::default();
        let mut reader = Reader::from_str(text);
        let bytes = text.as_bytes();
        // Lines counted incrementally: each byte is looked at once.
        let (mut counted_to, mut line) = (0usize, 1usize);
        loop {
            let at = reader.buffer_position() as usize;
            let e = match reader.read_event() {
                Ok(Event::Start(e) | Event::Empty(e)) => e,
                Ok(Event::Eof) | Err(_) => break,
                Ok(_) => continue,
            };
            // The element starts at its '<', after any whitespace the position may include.
            let start = at + bytes[at.min(bytes.len())..].iter().position(|&b| b == b'<').unwrap_or(0);
            line += bytes[counted_to.min(start)..start].iter().filter(|&&b| b == b'\n').count();
            counted_to = counted_to.max(start);
            let name = String::from_utf8_lossy(e.name().as_ref()).into_owned();
            for a in e.attributes().flatten() {
                let key = a.key.as_ref();
                if attributes.iter().any(|w| w.as_bytes() == key)
                    && let Ok(v) = a.normalized_value(quick_xml::XmlVersion::Implicit1_0)
                {
                    let (key, v) = (String::from_utf8_lossy(key).into_owned(), v.into_owned());
                    out.values.entry((key.clone(), v.clone())).or_insert(line);
                    out.lines.entry((name.clone(), key, v)).or_insert(line);
                }
            }
            out.elements.entry(name).or_insert(line);
        }
        out
    }

    /// Line of the first `<element attribute="value">`.
    pub fn line(&self, element: &str, attribute: &str, value: &str) -> Option<usize> {
        self.lines.get(&(element.to_string(), attribute.to_string(), value.to_string())).copied()
    }

    /// Line of the first element of any name with `attribute="value"`.
    pub fn any(&self, attribute: &str, value: &str) -> Option<usize> {
        self.values.get(&(attribute.to_string(), value.to_string())).copied()
    }

    /// Line of the first element named `element`.
    pub fn element(&self, element: &str) -> Option<usize> {
        self.elements.get(element).copied()
    }
}

/// The value of `attribute` on the first `<element>` of `text` (e.g. a
/// GDTF's `FixtureType` `Name`), without parsing the rest.
pub fn first_attribute(text: &str, element: &str, attribute: &str) -> Option<String> {
    let mut reader = Reader::from_str(text);
    loop {
        match reader.read_event() {
            Ok(Event::Start(e) | Event::Empty(e)) if e.name().as_ref() == element.as_bytes() => {
                let a = e.attributes().flatten().find(|a| a.key.as_ref() == attribute.as_bytes())?;
                return a.normalized_value(quick_xml::XmlVersion::Implicit1_0).ok().map(|v| v.into_owned());
            }
            Ok(Event::Eof) | Err(_) => return None,
            Ok(_) => {}
        }
    }
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
        assert!(well_formed(p, "<a><b/></a>", "a", 8).is_ok());
        let e = well_formed(p, "<a>\n  <b></c>\n</a>", "a", 8).unwrap_err();
        assert_eq!(e.line, 2, "{e}");
        assert!(e.message.starts_with("column "), "{e}");
        let e = well_formed(p, "<a>\n<b>", "a", 8).unwrap_err();
        assert_eq!(e.line, 2, "{e}");
        let e = well_formed(p, "<z/>", "a", 8).unwrap_err();
        assert!(e.message.contains("expected <a>"), "{e}");
        assert_eq!(line_col(b"ab\ncd", 4), (2, 2));
        let e = utf8(p, b"<a>\n\xff</a>").unwrap_err();
        assert_eq!((e.line, e.message.starts_with("column 1")), (2, true), "{e}");
    }

    #[test]
    fn named_elements_have_their_lines() {
        let text = "<GDTF>\n  <Attribute Name=\"Gobo2\"/>\n  <DMXMode Name=\"Std\">\n    <LogicalChannel Attribute=\"Gobo2\">\n    </LogicalChannel>\n    <LogicalChannel Attribute=\"Gobo2\"/>\n  </DMXMode>\n</GDTF>\n";
        let ix = LineIndex::new(text, &["Name", "Attribute"]);
        assert_eq!(ix.line("Attribute", "Name", "Gobo2"), Some(2));
        assert_eq!(ix.line("DMXMode", "Name", "Std"), Some(3));
        assert_eq!(ix.line("LogicalChannel", "Attribute", "Gobo2"), Some(4), "the first one");
        assert_eq!(ix.line("LogicalChannel", "Attribute", "Dimmer"), None);
        assert_eq!(ix.element("GDTF"), Some(1));
        assert_eq!(ix.any("Attribute", "Gobo2"), Some(4));
        assert_eq!(first_attribute(text, "DMXMode", "Name").as_deref(), Some("Std"));
    }

    /// `<a>` + `<b>` × (n − 1), then their end tags: n levels.
    fn nested(n: usize, leaf: &str) -> String {
        format!("<a>\n{}{leaf}{}</a>", "<b>".repeat(n - 1), "</b>".repeat(n - 1))
    }

    #[test]
    fn nesting_is_bounded_before_parsing() {
        let p = Path::new("x.xml");
        // Exactly at the limit passes; an empty element counts as a level.
        assert!(well_formed(p, &nested(4, ""), "a", 4).is_ok());
        assert!(well_formed(p, &nested(3, "<c/>"), "a", 4).is_ok());
        let e = well_formed(p, &nested(4, "<c/>"), "a", 4).unwrap_err();
        assert!(e.message.contains("nested 5 deep (limit 4; <c> here"), "{e}");
        // The line of the first element past the limit; the deepest level counted to the end.
        let e = well_formed(p, &nested(10_002, ""), "a", 256).unwrap_err();
        assert_eq!(e.line, 2, "{e}");
        assert!(e.message.contains("nested 10002 deep (limit 256; <b> here is the first past it)"), "{e}");
        // A syntax error after the limit is passed still reports the depth.
        let e = well_formed(p, "<a><b><b></x>", "a", 2).unwrap_err();
        assert!(e.message.contains("nested 3 deep (limit 2"), "{e}");
        // A syntax error before it is reported as one.
        let e = well_formed(p, "<a></x><b><b><b>", "a", 2).unwrap_err();
        assert!(e.message.contains("malformed XML"), "{e}");
    }
}
