//! What an import says about itself, once per problem (issue 36 item 3).
//!
//! A festival MVR hangs the same fixture type a hundred times over, each
//! of them made of sixteen cells: a warning said per fixture, per cell or
//! per channel is said thousands of times (a 3,000-cell show printed 3,421
//! lines). Here every warning is said **once per file and problem**, at the
//! XML line of the element concerned, with the number of fixtures (and
//! cells) it concerns; and every fixture type gets one summary line
//! ([`TypeSummary`]): modelled, partly (and why), or not.
//!
//! * [`Tally`]: problems of single fixtures (a GDTF named but missing, not a
//!   light, a break without an address, an unknown mode) grouped by file
//!   and problem; the first fixture's line, a few names and the count.
//! * [`merge_heads`]: a type's warnings of the form `Attr: problem` with
//!   the same problem become one (`ColorAdd_R, ColorAdd_G: problem`), at
//!   the first one's line.
//! * [`count_fixtures`]: a type's warnings get `(48 fixtures, 768 cells)`.
//! * [`dedupe`]: the same message about the same file twice is said once, `(×N)`.
//! * [`summarise`]: one [`TypeSummary`] per fixture type, read from the
//!   type's own warnings (whatever [`crate::fixture_type`] reports), not
//!   from a list kept here.

use footlight_fixture::PatchError;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// The words of the warning [`crate::fixture_type`] gives for attributes it
/// decodes but does not model: `Type: attributes not modelled yet: A (line
/// 40), B (line 57); their channels keep their slots`. [`summarise`] reads
/// the list back from it.
pub const NOT_MODELLED: &str = "attributes not modelled yet";

/// How much of a fixture type Footlight models.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Modelled {
    /// Every channel is modelled and nothing was warned.
    Modelled,
    /// Drawn, with warnings (attributes not modelled, colour not mixed…).
    Partly,
    /// Not drawn: the GDTF is missing or unreadable, or it is not a light.
    Not,
}

impl fmt::Display for Modelled {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Modelled::Modelled => "modelled",
            Modelled::Partly => "partly",
            Modelled::Not => "not modelled",
        })
    }
}

/// One fixture type of a show as `footlight check` sums it up: `Astera AX2
/// PixelBar (48 fixtures, 768 cells): partly — ColorAdd_R, ColorAdd_G: no
/// emitter…; not modelled: ColorMacro1`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct TypeSummary {
    /// `Manufacturer Name` from the GDTF, else the file's name.
    pub name: String,
    /// The GDTF file (an MVR's `GDTFSpec` as resolved, or a path).
    pub file: String,
    /// Fixtures of this type in the show.
    pub fixtures: usize,
    /// Lights they are made of (their cells); equal to `fixtures` when each is one light.
    pub cells: usize,
    /// Modelled, partly or not.
    pub status: Modelled,
    /// Why not fully: each distinct problem of the type, shortened.
    pub reasons: Vec<String>,
    /// Attributes decoded but not modelled (from the type's warning).
    pub not_modelled: Vec<String>,
}

impl fmt::Display for TypeSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ({}", self.name, plural(self.fixtures, "fixture"))?;
        if self.cells > self.fixtures {
            write!(f, ", {} cells", self.cells)?;
        }
        write!(f, "): {}", self.status)?;
        let mut why = self.reasons.clone();
        if !self.not_modelled.is_empty() {
            why.push(format!("not modelled: {}", self.not_modelled.join(", ")));
        }
        if !why.is_empty() {
            write!(f, " — {}", why.join("; "))?;
        }
        Ok(())
    }
}

/// `1 fixture`, `3 fixtures`.
pub fn plural(n: usize, word: &str) -> String {
    if n == 1 { format!("1 {word}") } else { format!("{n} {word}s") }
}

/// Problems of single fixtures, said once per (file, problem) with the
/// first fixture's line, up to [`NAMES_SHOWN`] of their names and their count.
#[derive(Debug, Default)]
pub struct Tally {
    entries: Vec<TallyEntry>,
    index: BTreeMap<(PathBuf, String), usize>,
}

#[derive(Debug)]
struct TallyEntry {
    path: PathBuf,
    line: usize,
    problem: String,
    names: Vec<String>,
    count: usize,
}

/// Fixture names a grouped message shows before `and N more`.
pub const NAMES_SHOWN: usize = 4;

impl Tally {
    /// Counts `fixture` (its name as shown, e.g. `Spot 3 (id 12)`) under
    /// `problem` of `path`; `line` is kept from the first fixture.
    pub fn add(&mut self, path: &Path, line: usize, problem: impl Into<String>, fixture: impl Into<String>) {
        let problem = problem.into();
        let key = (path.to_path_buf(), problem.clone());
        let i = *self.index.entry(key).or_insert_with(|| {
            self.entries.push(TallyEntry { path: path.to_path_buf(), line, problem, names: Vec::new(), count: 0 });
            self.entries.len() - 1
        });
        let e = &mut self.entries[i];
        e.count += 1;
        if e.names.len() < NAMES_SHOWN {
            e.names.push(fixture.into());
        }
    }

    /// True when nothing was counted.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// One message per problem, in the order first seen: `problem: A, B, C,
    /// D and 44 more (48 fixtures)`.
    pub fn into_errors(self) -> Vec<PatchError> {
        self.messages(|problem, names, count| format!("{problem}: {names}{count}"))
    }

    /// One message per problem, the fixtures first (how errors about
    /// fixtures read): `fixture "A" (id 1): problem`, `fixtures "A" (id 1),
    /// "B" (id 2) and 46 more (48 fixtures): problem`.
    pub fn into_errors_named_first(self) -> Vec<PatchError> {
        self.messages(|problem, names, count| {
            let s = if count.is_empty() { "" } else { "s" };
            format!("fixture{s} {names}{count}: {problem}")
        })
    }

    fn messages(self, say: impl Fn(&str, &str, &str) -> String) -> Vec<PatchError> {
        self.entries
            .into_iter()
            .map(|e| {
                let more = e.count - e.names.len();
                let names =
                    if more > 0 { format!("{} and {more} more", e.names.join(", ")) } else { e.names.join(", ") };
                let count = if e.count > 1 { format!(" ({})", plural(e.count, "fixture")) } else { String::new() };
                PatchError::new(&e.path, e.line, say(&e.problem, &names, &count))
            })
            .collect()
    }
}

/// `Attr: problem` warnings of the same file with the same problem, merged
/// into one: `Attr1, Attr2: problem` at the first one's line (a pixel bar's
/// ColorAdd_R, _G, _B and _W said once). Other warnings pass unchanged, in order.
pub fn merge_heads(warnings: Vec<PatchError>) -> Vec<PatchError> {
    let mut out: Vec<PatchError> = Vec::new();
    let mut heads: Vec<Vec<String>> = Vec::new();
    let mut at: BTreeMap<(PathBuf, String), usize> = BTreeMap::new();
    for w in warnings {
        let split = w.message.split_once(": ").filter(|(h, _)| !h.is_empty() && !h.contains(' '));
        let Some((head, rest)) = split.map(|(h, r)| (h.to_string(), r.to_string())) else {
            out.push(w);
            heads.push(Vec::new());
            continue;
        };
        match at.get(&(w.path.clone(), rest.clone())) {
            Some(&i) => {
                if !heads[i].contains(&head) {
                    heads[i].push(head);
                }
            }
            None => {
                at.insert((w.path.clone(), rest), out.len());
                out.push(w);
                heads.push(vec![head]);
            }
        }
    }
    for (w, h) in out.iter_mut().zip(heads) {
        if h.len() > 1 {
            let rest = w.message.split_once(": ").map(|(_, r)| r.to_string()).unwrap_or_default();
            w.message = format!("{}: {rest}", h.join(", "));
        }
    }
    out
}

/// The same message about the same file said once; a repeated one ends in `(×N)`.
pub fn dedupe(warnings: Vec<PatchError>) -> Vec<PatchError> {
    let mut out: Vec<PatchError> = Vec::new();
    let mut count: Vec<usize> = Vec::new();
    let mut at: BTreeMap<(PathBuf, String), usize> = BTreeMap::new();
    for w in warnings {
        match at.get(&(w.path.clone(), w.message.clone())) {
            Some(&i) => count[i] += 1,
            None => {
                at.insert((w.path.clone(), w.message.clone()), out.len());
                out.push(w);
                count.push(1);
            }
        }
    }
    for (w, n) in out.iter_mut().zip(count) {
        if n > 1 {
            w.message = format!("{} (×{n})", w.message);
        }
    }
    out
}

/// Appends `(48 fixtures, 768 cells)` to each warning about a fixture
/// type's file: `types` maps the type's file label (its warnings' path is
/// that label or below it) to its fixtures and cells.
pub fn count_fixtures(warnings: &mut [PatchError], types: &BTreeMap<PathBuf, (usize, usize)>) {
    for w in warnings.iter_mut() {
        let Some((_, &(fixtures, cells))) = types.iter().find(|(label, _)| w.path.starts_with(label)) else {
            continue;
        };
        w.message = format!("{} ({})", w.message, fixtures_and_cells(fixtures, cells));
    }
}

/// `1 fixture`, `48 fixtures, 768 cells`.
pub fn fixtures_and_cells(fixtures: usize, cells: usize) -> String {
    if cells > fixtures {
        format!("{}, {cells} cells", plural(fixtures, "fixture"))
    } else {
        plural(fixtures, "fixture")
    }
}

/// The part of a type's warning the summary shows: the message without the
/// file's own type name in front.
fn short(message: &str, type_name: &str) -> String {
    message.strip_prefix(type_name).and_then(|r| r.strip_prefix(": ")).unwrap_or(message).trim().to_string()
}

/// The attributes of a [`NOT_MODELLED`] warning, their `(line N)` dropped.
fn not_modelled_list(message: &str) -> Option<Vec<String>> {
    let rest = message.split(NOT_MODELLED).nth(1)?;
    let rest = rest.trim_start_matches([':', ' ']);
    let list = rest.split("; ").next().unwrap_or(rest);
    Some(
        list.split(", ")
            .map(|a| a.split(" (line").next().unwrap_or(a).trim().to_string())
            .filter(|a| !a.is_empty())
            .collect(),
    )
}

/// One fixture type's summary from its warnings: `label` is the type's
/// file label (its warnings are at that path or below it), `type_name` the
/// name its warnings start with. No warnings: modelled; otherwise partly,
/// each distinct problem (without the type's name) and the [`NOT_MODELLED`]
/// attributes listed.
pub fn summarise(
    name: String,
    file: String,
    label: &Path,
    type_name: &str,
    fixtures: usize,
    cells: usize,
    warnings: &[PatchError],
) -> TypeSummary {
    let mut reasons: Vec<String> = Vec::new();
    let mut not_modelled: Vec<String> = Vec::new();
    for w in warnings.iter().filter(|w| w.path.starts_with(label)) {
        match not_modelled_list(&w.message) {
            Some(list) => {
                not_modelled.extend(list.into_iter().filter(|a| !not_modelled.contains(a)).collect::<Vec<_>>())
            }
            None => {
                let s = short(&w.message, type_name);
                if !reasons.contains(&s) {
                    reasons.push(s);
                }
            }
        }
    }
    let status = if reasons.is_empty() && not_modelled.is_empty() { Modelled::Modelled } else { Modelled::Partly };
    TypeSummary { name, file, fixtures, cells, status, reasons, not_modelled }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(path: &str, line: usize, m: &str) -> PatchError {
        PatchError::new(Path::new(path), line, m)
    }

    #[test]
    fn fixture_problems_are_said_once_with_a_count() {
        let mut t = Tally::default();
        for k in 1..=6 {
            t.add(Path::new("s.mvr/G.xml"), 10 + k, "GDTF file \"X.gdtf\" is missing", format!("Bar {k}"));
        }
        t.add(Path::new("s.mvr/G.xml"), 40, "not a light", "Hazer 1");
        let e = t.into_errors();
        assert_eq!(e.len(), 2);
        assert_eq!(e[0].line, 11, "the first fixture's line");
        assert_eq!(e[0].message, "GDTF file \"X.gdtf\" is missing: Bar 1, Bar 2, Bar 3, Bar 4 and 2 more (6 fixtures)");
        assert_eq!(e[1].message, "not a light: Hazer 1");
        let mut t = Tally::default();
        t.add(Path::new("s.mvr/G.xml"), 7, "no mode \"M\"", "\"Spot 1\" (id 1)");
        t.add(Path::new("s.mvr/G.xml"), 9, "x.gdtf:2: broken", "\"Spot 2\" (id 2)");
        t.add(Path::new("s.mvr/G.xml"), 11, "x.gdtf:2: broken", "\"Spot 3\" (id 3)");
        let e = t.into_errors_named_first();
        assert_eq!(e[0].message, "fixture \"Spot 1\" (id 1): no mode \"M\"");
        assert_eq!(
            (e[1].line, e[1].message.as_str()),
            (9, "fixtures \"Spot 2\" (id 2), \"Spot 3\" (id 3) (2 fixtures): x.gdtf:2: broken")
        );
    }

    #[test]
    fn attribute_warnings_with_one_problem_merge() {
        let m = merge_heads(vec![
            w("a.gdtf/description.xml", 40, "ColorAdd_R: no emitter; decoded"),
            w("a.gdtf/description.xml", 47, "ColorAdd_G: no emitter; decoded"),
            w("b.gdtf/description.xml", 9, "ColorAdd_R: no emitter; decoded"),
            w("a.gdtf/description.xml", 3, "BeamAngle 0 is not in (0, 180]; 25 used"),
        ]);
        assert_eq!(m.len(), 3);
        assert_eq!((m[0].line, m[0].message.as_str()), (40, "ColorAdd_R, ColorAdd_G: no emitter; decoded"));
        assert_eq!(m[1].message, "ColorAdd_R: no emitter; decoded");
        let d = dedupe(vec![w("x", 1, "a"), w("x", 2, "a"), w("y", 1, "a")]);
        assert_eq!(d.iter().map(|e| e.message.as_str()).collect::<Vec<_>>(), ["a (×2)", "a"]);
    }

    #[test]
    fn a_type_is_summed_up_from_its_warnings() {
        let label = Path::new("s.mvr/Astera@AX2.gdtf");
        let ws = [
            w("s.mvr/Astera@AX2.gdtf/description.xml", 40, "ColorAdd_R, ColorAdd_G: no emitter; decoded but not mixed"),
            w(
                "s.mvr/Astera@AX2.gdtf/description.xml",
                52,
                "AX2: attributes not modelled yet: ColorMacro1 (line 52), Gobo2 (line 60); their channels keep their slots",
            ),
            w("s.mvr/Other.gdtf/description.xml", 1, "Other: not counted"),
        ];
        let s = summarise("Astera AX2".into(), "Astera@AX2.gdtf".into(), label, "AX2", 48, 768, &ws);
        assert_eq!(s.status, Modelled::Partly);
        assert_eq!(s.not_modelled, ["ColorMacro1", "Gobo2"]);
        assert_eq!(
            s.to_string(),
            "Astera AX2 (48 fixtures, 768 cells): partly — ColorAdd_R, ColorAdd_G: no emitter; decoded but not mixed; \
             not modelled: ColorMacro1, Gobo2"
        );
        let ok = summarise("Footlight Spot".into(), "Spot.gdtf".into(), Path::new("Spot.gdtf"), "Spot", 1, 1, &ws);
        assert_eq!(ok.to_string(), "Footlight Spot (1 fixture): modelled");
        let mut c = vec![ws[0].clone(), ws[2].clone()];
        count_fixtures(&mut c, &BTreeMap::from([(label.to_path_buf(), (48, 768))]));
        assert!(c[0].message.ends_with("(48 fixtures, 768 cells)") && !c[1].message.contains("fixtures"), "{c:?}");
    }
}
