//! [`Show`]: the one owner of everything between the merged DMX and the
//! fixtures (DESIGN.md "Owners").
//!
//! ```text
//! patch ──> Show ──┬─ input_patch(): [[input]] routes as the DMX crate's UniverseMap,
//!                  │  the universes to join (sACN) and announce (ArtPollReply),
//!                  │  LTP masks — used by live input, record, replay and render --dmx
//!                  ├─ decode(slots): every fixture's state, tracer light and k_i (eq. 4)
//!                  └─ change(old, new): the fixture crate's one rule (composite or geometry)
//! ```
//!
//! The DMX it decodes is read in place through [`DmxSlots`]: the daemon
//! hands it the DMX crate's merged frames (with their `stale` flags), stills
//! hand it a [`footlight_fixture::Universes`]; nothing is copied per packet
//! or per frame.

use crate::Patch;
use crate::fixture::{Change, DmxSlots, FixtureState, classify};
use crate::live::clock::{Decode, LightInput, LightLabel};
use footlight_dmx::{InputPatch, InputUniverse, SlotMask, UniverseMap};
use footlight_fixture::patch::InputProtocol;
use std::sync::Arc;

/// The show: the patch plus how DMX reaches it.
pub struct Show {
    patch: Arc<Patch>,
    input: InputPatch,
}

impl Show {
    /// The show of `patch`: its `[[input]]` routes (inputs without a route
    /// keep the default rule: sACN N and Art-Net Port-Address N−1 feed patch
    /// universe N), the patched universes and the LTP slots.
    pub fn new(patch: Patch) -> Self {
        let mut map = UniverseMap::default();
        for route in &patch.inputs {
            let input = match route.protocol {
                InputProtocol::Sacn => InputUniverse::Sacn(route.universe),
                InputProtocol::ArtNet => InputUniverse::ArtNet(route.universe),
                InputProtocol::UsbPro => InputUniverse::UsbPro(u8::try_from(route.universe).unwrap_or(u8::MAX)),
            };
            match route.patch_universe {
                Some(u) => map.route(input, u),
                None => map.block(input),
            };
        }
        // Fixtures' universes (every DMX break's), and the hazer channel's (it drives the haze density).
        let hazer = patch.haze.as_ref().and_then(|h| h.dmx.map(|(u, _)| u));
        let mut universes: Vec<u16> = patch.fixtures.iter().flat_map(|f| f.universes()).chain(hazer).collect();
        universes.sort_unstable();
        universes.dedup();
        let ltp = patch.ltp_addresses().into_iter().map(|(u, addrs)| (u, SlotMask::from_addresses(addrs))).collect();
        let input = InputPatch { map, universes, ltp, ..InputPatch::default() };
        Self { patch: Arc::new(patch), input }
    }

    /// The patch.
    pub fn patch(&self) -> &Arc<Patch> {
        &self.patch
    }

    /// What the DMX input needs: routes, universes to join and announce,
    /// LTP masks. Live input, `record`, `replay` and `render --dmx` all take it.
    pub fn input_patch(&self) -> &InputPatch {
        &self.input
    }

    /// Patch universes that carry fixtures, ascending (at least one: an
    /// empty patch listens to universe 1).
    pub fn universes(&self) -> Vec<u16> {
        if self.input.universes.is_empty() { vec![1] } else { self.input.universes.clone() }
    }

    /// Fixture ids as the patch names them, in light order (for logs and status).
    pub fn fixture_ids(&self) -> Vec<u32> {
        self.patch.fixtures.iter().map(|f| f.id).collect()
    }

    /// Every light's patch data for the status, in light order: its
    /// fixture (a cell's fixture), DMX address, mode and position.
    pub fn light_patches(&self) -> Vec<LightPatch> {
        self.patch.fixtures.iter().map(LightPatch::of).collect()
    }

    /// The DMX slots of light `index`'s footprint, for the status page.
    pub fn fixture_slots(&self, index: usize, universes: &dyn DmxSlots) -> Vec<u8> {
        let Some(f) = self.patch.fixtures.get(index) else { return Vec::new() };
        let Some((u, addr)) = f.dmx else { return Vec::new() };
        let slots = universes.slots(u).or_else(|| self.patch.look_universes.get(u));
        let start = usize::from(addr.max(1)) - 1;
        let end = (start + usize::from(f.footprint())).min(512);
        slots.map(|sl| sl[start.min(end)..end].to_vec()).unwrap_or_default()
    }

    /// What a state change of a fixture costs: the fixture crate's rule.
    pub fn change(old: &FixtureState, new: &FixtureState) -> Change {
        classify(old, new)
    }
}

/// Where a light is patched and hung, as a desk shows it (the status's
/// per-light patch fields, [`Show::light_patches`]; docs/live.md).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct LightPatch {
    /// The fixture's own name: for a cell, its fixture's (the light's
    /// `name` is `"fixture / cell"`); else the light's name.
    pub fixture_name: Option<String>,
    /// 1-based number of the cell within its fixture, when the fixture is
    /// several lights (an MVR pixel bar's pixels); `None` for a one-light
    /// fixture. A fixture's cells are consecutive lights under one id.
    pub cell: Option<u32>,
    /// Patch universe of the start address; `None` when unpatched.
    pub universe: Option<u16>,
    /// Start address, 1-512; `None` when unpatched.
    pub address: Option<u16>,
    /// `universe.address` as desks write it (`"2.17"`); `None` when unpatched.
    pub dmx_address: Option<String>,
    /// Channels the fixture's mode uses from its start address.
    pub footprint: Option<u16>,
    /// The DMX mode's name (GDTF and library types); `None` for the built-in spot.
    pub mode: Option<String>,
    /// Where the fixture hangs, metres to the millimetre, stage axes (y up):
    /// the patch's `position`, an MVR fixture's origin (shared by its cells).
    pub position: Option<[f64; 3]>,
}

impl LightPatch {
    /// The patch data of one fixture instance.
    fn of(f: &footlight_fixture::Fixture) -> Self {
        let fixture_name = f.cell.as_ref().map_or_else(|| f.name.clone(), |c| c.fixture_name.clone());
        Self {
            fixture_name: Some(fixture_name),
            cell: f.cell.as_ref().map(|c| c.number),
            universe: f.dmx.map(|(u, _)| u),
            address: f.dmx.map(|(_, a)| a),
            dmx_address: f.dmx.map(|(u, a)| format!("{u}.{a}")),
            footprint: Some(f.footprint()),
            mode: f.mode_name().map(str::to_string),
            position: Some(f.position.to_array().map(|v| (f64::from(v) * 1000.0).round() / 1000.0)),
        }
    }
}

/// Reads the DMX crate's merged frames in place (the live daemon's input).
pub struct LiveSlots<'a>(pub &'a footlight_dmx::Universes);

impl DmxSlots for LiveSlots<'_> {
    fn slots(&self, universe: u16) -> Option<&[u8; 512]> {
        self.0.get(universe).map(|f| &f.slots)
    }
}

impl Decode for Show {
    fn len(&self) -> usize {
        self.patch.fixtures.len()
    }

    fn decode(&self, universes: &dyn DmxSlots) -> Vec<LightInput> {
        self.patch
            .fixtures
            .iter()
            .map(|f| {
                let state = f.decode_universes(universes);
                LightInput { light: f.light_of(&state), k: f.k_of(&state), k_full: f.k_full_of(&state), state }
            })
            .collect()
    }

    fn decode_at(&self, universes: &dyn DmxSlots, t_seconds: f64) -> Vec<LightInput> {
        self.patch
            .fixtures
            .iter()
            .map(|f| {
                let mut state = f.decode_universes(universes);
                if state.spins()
                    && let footlight_fixture::FixtureModel::Typed(t) = &f.model
                {
                    state = t.fixture_type.state_at(&state, t_seconds);
                }
                LightInput { light: f.light_of(&state), k: f.k_of(&state), k_full: f.k_full_of(&state), state }
            })
            .collect()
    }

    fn labels(&self) -> Vec<LightLabel> {
        self.patch.fixtures.iter().map(|f| LightLabel { fixture: Some(f.id), name: f.name.clone() }).collect()
    }

    fn slots_of(&self, index: usize, universes: &dyn DmxSlots) -> Vec<u8> {
        self.fixture_slots(index, universes)
    }

    fn haze_density(&self, universes: &dyn DmxSlots) -> Option<f32> {
        let spec = self.patch.haze.as_ref()?;
        let slots = spec.dmx.and_then(|(u, _)| universes.slots(u).or_else(|| self.patch.look_universes.get(u)));
        Some(slots.map_or(spec.density, |sl| spec.density_from_slots(sl)))
    }
}
