//! The patch as a desk programmer reads it: one line per fixture (its
//! cells folded) with its type, mode and DMX address, for `footlight check`
//! and the daemon's start-up log.

use super::{FixtureModel, Patch};
use std::fmt;

/// One fixture of a patch: a run of lights under one id (an MVR fixture's
/// cells), or a single light.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ListedFixture {
    /// Fixture id as the patch gives it.
    pub id: u32,
    /// The fixture's name (a cell's fixture name, not `"fixture / cell"`).
    pub name: String,
    /// Fixture type name (`spot` for the built-in spot).
    pub type_name: String,
    /// DMX mode name (`None` for the built-in spot).
    pub mode: Option<String>,
    /// Lights it is made of (1, or its cells).
    pub lights: usize,
    /// Patch universe and start address (`None`: not patched).
    pub dmx: Option<(u16, u16)>,
    /// Slots from the start address (the widest of its cells' modes).
    pub footprint: u16,
}

impl fmt::Display for ListedFixture {
    /// `  12  Name  type (mode)  1/7-12`, cells counted when there are several.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match &self.mode {
            Some(m) => format!("{} ({m})", self.type_name),
            None => self.type_name.clone(),
        };
        let cells = if self.lights > 1 { format!(", {} cells", self.lights) } else { String::new() };
        let dmx = match self.dmx {
            Some((u, a)) if self.footprint > 1 => {
                format!("{u}/{a}-{}", u32::from(a) + u32::from(self.footprint) - 1)
            }
            Some((u, a)) => format!("{u}/{a}"),
            None => "not patched".to_string(),
        };
        write!(f, "{:>5}  {}  [{kind}{cells}]  DMX {dmx}", self.id, self.name)
    }
}

impl Patch {
    /// The fixtures in patch order, each with its cells folded: consecutive
    /// lights with the same id are one fixture (the MVR import emits a
    /// fixture's cells one after another under its id).
    pub fn listing(&self) -> Vec<ListedFixture> {
        let mut out: Vec<ListedFixture> = Vec::new();
        for f in &self.fixtures {
            let footprint = f.footprint().min(super::BREAK_STRIDE);
            if let Some(last) = out.last_mut()
                && last.id == f.id
                && f.cell.is_some()
            {
                last.lights += 1;
                last.footprint = last.footprint.max(footprint);
                continue;
            }
            let type_name = match &f.model {
                FixtureModel::Builtin(_) => "spot".to_string(),
                FixtureModel::Typed(t) => t.fixture_type.name.clone(),
            };
            let mode = f.mode_name().map(str::to_string);
            let name = f.cell.as_ref().map_or_else(|| f.name.clone(), |c| c.fixture_name.clone());
            out.push(ListedFixture { id: f.id, name, type_name, mode, lights: 1, dmx: f.dmx, footprint });
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn fixtures_are_listed_with_type_mode_and_address_range() {
        let text = r#"
[[fixture]]
id = 3
name = "Front"
type = "spot"
position = [0.0, 6.0, 6.0]
aim = [0.0, 0.0, 0.0]
intensity = 1000.0
universe = 2
address = 10

[[fixture]]
id = 4
type = "spot"
position = [1.0, 6.0, 6.0]
aim = [0.0, 0.0, 0.0]
intensity = 1000.0
"#;
        let patch = Patch::parse(Path::new("/x/p.toml"), text).unwrap();
        let list = patch.listing();
        assert_eq!(list.len(), 2);
        assert_eq!(list[0].to_string(), "    3  Front  [spot]  DMX 2/10");
        assert_eq!(list[1].dmx, None);
        assert!(list[1].to_string().ends_with("DMX not patched"), "{}", list[1]);
    }
}
