//! Which input universe feeds which patch universe.
//!
//! Patch universes count from 1, as desks show them (DESIGN.md "Universes").
//! By default sACN universe N, Art-Net Port-Address N-1 and USB Pro widget N-1
//! all feed patch universe N. The patch's `[[input]]` table fills this map
//! ([`UniverseMap::route`], [`UniverseMap::block`]); [`UniverseMap::empty`]
//! starts without defaults. The rules:
//!
//! 1. An input with an explicit entry goes where the entry says (a route), or
//!    nowhere (a block).
//! 2. A patch universe that at least one route targets is fed by its routes
//!    only: the default inputs of that patch universe (of every protocol) no
//!    longer feed it. So routing Art-Net Port-Address 1 to patch universe 1
//!    takes Port-Address 0 and sACN universe 1 off patch universe 1, as a user
//!    expects when the desk starts its universes elsewhere.
//! 3. Every other input follows the default rule.
//!
//! ```
//! use footlight_dmx::{InputUniverse, UniverseMap};
//! let mut map = UniverseMap::default();
//! assert_eq!(map.patch_universe(InputUniverse::ArtNet(0)), Some(1));
//! map.route(InputUniverse::Sacn(101), 2); // the desk's universe 101 drives patch universe 2
//! assert_eq!(map.patch_universe(InputUniverse::Sacn(101)), Some(2));
//! assert_eq!(map.patch_universe(InputUniverse::Sacn(2)), None); // 2 is routed explicitly now
//! ```

use std::collections::{BTreeMap, BTreeSet};

use crate::source::{InputUniverse, Protocol};

/// Highest sACN data universe (E1.31: 1-63999).
pub const SACN_MAX_UNIVERSE: u16 = 63999;
/// Highest Art-Net 15-bit Port-Address.
pub const ARTNET_MAX_PORT_ADDRESS: u16 = 0x7FFF;

/// The input → patch universe table.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UniverseMap {
    /// Whether inputs without an explicit entry use the default rule.
    defaults: bool,
    /// Explicit entries: `Some(patch)` routes, `None` blocks.
    routes: BTreeMap<InputUniverse, Option<u16>>,
    /// Patch universes some route targets (rule 2: no defaults feed them).
    /// Derived from `routes` after every change.
    routed: BTreeSet<u16>,
}

impl Default for UniverseMap {
    fn default() -> Self {
        UniverseMap { defaults: true, routes: BTreeMap::new(), routed: BTreeSet::new() }
    }
}

impl UniverseMap {
    /// A map with no routes at all (not even the defaults).
    pub fn empty() -> Self {
        UniverseMap { defaults: false, ..UniverseMap::default() }
    }

    fn update_routed(&mut self) {
        self.routed = self.routes.values().filter_map(|p| *p).collect();
    }

    /// The default rule: Art-Net Port-Address N-1, sACN universe N and USB Pro
    /// widget N-1 feed patch universe N.
    pub fn default_route(input: InputUniverse) -> Option<u16> {
        match input {
            InputUniverse::ArtNet(pa) if pa <= ARTNET_MAX_PORT_ADDRESS => Some(pa + 1),
            InputUniverse::Sacn(u) if (1..=SACN_MAX_UNIVERSE).contains(&u) => Some(u),
            InputUniverse::UsbPro(w) => Some(u16::from(w) + 1),
            _ => None,
        }
    }

    /// Routes `input` to patch universe `patch` (1-based; 0 blocks). From
    /// then on only routes feed `patch` (see the module docs).
    pub fn route(&mut self, input: InputUniverse, patch: u16) -> &mut Self {
        self.routes.insert(input, (patch != 0).then_some(patch));
        self.update_routed();
        self
    }

    /// Stops `input` from feeding any patch universe.
    pub fn block(&mut self, input: InputUniverse) -> &mut Self {
        self.routes.insert(input, None);
        self.update_routed();
        self
    }

    /// The explicit entry of `input`: `Some(Some(patch))` routed,
    /// `Some(None)` blocked, `None` no entry (the default rule applies).
    pub fn entry(&self, input: InputUniverse) -> Option<Option<u16>> {
        self.routes.get(&input).copied()
    }

    /// Whether some route targets patch universe `patch` (its default inputs
    /// then no longer feed it).
    pub fn is_routed(&self, patch: u16) -> bool {
        self.routed.contains(&patch)
    }

    /// Whether `input` has an explicit `block` entry.
    pub fn is_blocked(&self, input: InputUniverse) -> bool {
        self.routes.get(&input).is_some_and(Option::is_none)
    }

    /// The explicit entries: `(input, Some(patch universe))` for a route,
    /// `(input, None)` for a block, in input order.
    pub fn entries(&self) -> impl Iterator<Item = (InputUniverse, Option<u16>)> + '_ {
        self.routes.iter().map(|(i, p)| (*i, *p))
    }

    /// The patch universe `input` feeds, if any.
    pub fn patch_universe(&self, input: InputUniverse) -> Option<u16> {
        match self.routes.get(&input) {
            Some(route) => *route,
            None if self.defaults => Self::default_route(input).filter(|p| !self.routed.contains(p)),
            None => None,
        }
    }

    /// The inputs of `protocol` that feed patch universe `patch`.
    pub fn inputs_for(&self, protocol: Protocol, patch: u16) -> Vec<InputUniverse> {
        let mut inputs: Vec<InputUniverse> = self
            .routes
            .iter()
            .filter(|(i, p)| i.protocol() == protocol && **p == Some(patch))
            .map(|(i, _)| *i)
            .collect();
        if self.defaults && patch >= 1 && !self.routed.contains(&patch) {
            let default = match protocol {
                Protocol::ArtNet => InputUniverse::ArtNet(patch - 1),
                Protocol::Sacn => InputUniverse::Sacn(patch),
                Protocol::UsbPro => match u8::try_from(patch - 1) {
                    Ok(w) => InputUniverse::UsbPro(w),
                    Err(_) => return inputs,
                },
            };
            if !self.routes.contains_key(&default) && Self::default_route(default) == Some(patch) {
                inputs.push(default);
            }
        }
        inputs.sort();
        inputs
    }

    /// The protocol universe numbers (Art-Net Port-Addresses, sACN
    /// universes, USB Pro widget indices) of `protocol` that feed any of
    /// `patch_universes`, sorted, without duplicates: the sACN groups to join
    /// and the Art-Net Port-Addresses to announce.
    pub fn input_universes(&self, protocol: Protocol, patch_universes: &[u16]) -> Vec<u16> {
        let mut v: Vec<u16> = (patch_universes.iter())
            .flat_map(|&u| self.inputs_for(protocol, u))
            .map(|i| match i {
                InputUniverse::ArtNet(n) | InputUniverse::Sacn(n) => n,
                InputUniverse::UsbPro(w) => u16::from(w),
            })
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The filter a receiver uses to drop universes early: those feeding one of
    /// `patch_universes`, or every mapped universe when that list is empty.
    pub fn filter(&self, protocol: Protocol, patch_universes: &[u16]) -> UniverseFilter {
        if patch_universes.is_empty() {
            return UniverseFilter::All;
        }
        let mut bits = Box::new([0u64; 1024]);
        for &p in patch_universes {
            for input in self.inputs_for(protocol, p) {
                let n = match input {
                    InputUniverse::ArtNet(n) | InputUniverse::Sacn(n) => n,
                    InputUniverse::UsbPro(w) => u16::from(w),
                };
                bits[usize::from(n) / 64] |= 1 << (n % 64);
            }
        }
        UniverseFilter::Only(bits)
    }
}

/// Which protocol universe numbers a receiver accepts (a 65536-bit set).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum UniverseFilter {
    /// Every universe.
    All,
    /// Only the universes whose bit is set.
    Only(Box<[u64; 1024]>),
}

impl UniverseFilter {
    /// A filter accepting exactly `universes`.
    pub fn only(universes: impl IntoIterator<Item = u16>) -> Self {
        let mut bits = Box::new([0u64; 1024]);
        for n in universes {
            bits[usize::from(n) / 64] |= 1 << (n % 64);
        }
        UniverseFilter::Only(bits)
    }

    /// Whether universe `n` passes.
    pub fn accepts(&self, n: u16) -> bool {
        match self {
            UniverseFilter::All => true,
            UniverseFilter::Only(bits) => bits[usize::from(n) / 64] & (1 << (n % 64)) != 0,
        }
    }

    /// The accepted universes, when the filter is a list.
    pub fn universes(&self) -> Option<Vec<u16>> {
        match self {
            UniverseFilter::All => None,
            UniverseFilter::Only(_) => Some((0..=u16::MAX).filter(|&n| self.accepts(n)).collect()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_follow_design_md() {
        let map = UniverseMap::default();
        assert_eq!(map.patch_universe(InputUniverse::ArtNet(0)), Some(1));
        assert_eq!(map.patch_universe(InputUniverse::ArtNet(0x7FFF)), Some(0x8000));
        assert_eq!(map.patch_universe(InputUniverse::ArtNet(0x8000)), None);
        assert_eq!(map.patch_universe(InputUniverse::Sacn(1)), Some(1));
        assert_eq!(map.patch_universe(InputUniverse::Sacn(0)), None);
        assert_eq!(map.patch_universe(InputUniverse::Sacn(64000)), None);
        assert_eq!(map.patch_universe(InputUniverse::UsbPro(0)), Some(1));
        assert_eq!(map.inputs_for(Protocol::ArtNet, 3), vec![InputUniverse::ArtNet(2)]);
        assert_eq!(map.inputs_for(Protocol::Sacn, 3), vec![InputUniverse::Sacn(3)]);
    }

    #[test]
    fn overrides_replace_and_block_defaults() {
        let mut map = UniverseMap::default();
        map.route(InputUniverse::Sacn(101), 1).block(InputUniverse::Sacn(1));
        assert_eq!(map.patch_universe(InputUniverse::Sacn(1)), None);
        assert_eq!(map.inputs_for(Protocol::Sacn, 1), vec![InputUniverse::Sacn(101)]);
        let f = map.filter(Protocol::Sacn, &[1]);
        assert!(f.accepts(101) && !f.accepts(1));
        assert_eq!(f.universes(), Some(vec![101]));
        let empty = UniverseMap::empty();
        assert_eq!(empty.patch_universe(InputUniverse::ArtNet(0)), None);
        assert!(empty.filter(Protocol::ArtNet, &[1]).universes().unwrap().is_empty());
        assert!(map.filter(Protocol::Sacn, &[]).accepts(4000));
    }

    #[test]
    fn a_routed_patch_universe_takes_only_its_routes() {
        // The brief's example: Art-Net Port-Address 1 → patch 1, sACN 101 → patch 2.
        let mut map = UniverseMap::default();
        map.route(InputUniverse::ArtNet(1), 1).route(InputUniverse::Sacn(101), 2);
        assert_eq!(map.patch_universe(InputUniverse::ArtNet(1)), Some(1));
        assert_eq!(map.patch_universe(InputUniverse::Sacn(101)), Some(2));
        // The defaults of patch universes 1 and 2 no longer feed them ...
        assert_eq!(map.patch_universe(InputUniverse::ArtNet(0)), None);
        assert_eq!(map.patch_universe(InputUniverse::Sacn(1)), None);
        assert_eq!(map.patch_universe(InputUniverse::Sacn(2)), None);
        assert_eq!(map.patch_universe(InputUniverse::UsbPro(0)), None);
        // ... while other universes keep theirs.
        assert_eq!(map.patch_universe(InputUniverse::ArtNet(2)), Some(3));
        assert_eq!(map.patch_universe(InputUniverse::Sacn(3)), Some(3));
        assert_eq!(map.input_universes(Protocol::ArtNet, &[1, 2]), vec![1]);
        assert_eq!(map.input_universes(Protocol::Sacn, &[1, 2]), vec![101]);
        assert_eq!(map.input_universes(Protocol::Sacn, &[1, 2, 3]), vec![3, 101]);
        assert!(!map.is_blocked(InputUniverse::ArtNet(0)));
        map.block(InputUniverse::ArtNet(0));
        assert!(map.is_blocked(InputUniverse::ArtNet(0)));
        // Re-routing updates the derived set: patch 1 has no route now, so its defaults return.
        map.route(InputUniverse::ArtNet(1), 5);
        assert_eq!(map.patch_universe(InputUniverse::Sacn(1)), Some(1));
        assert_eq!(map.patch_universe(InputUniverse::ArtNet(0)), None, "still blocked explicitly");
        assert_eq!(map.entries().count(), 3);
    }
}
