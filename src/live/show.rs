//! [`Show`]: the one owner of everything between the merged DMX and the
//! fixtures (DESIGN.md "Owners").
//!
//! ```text
//! patch ──> Show ──┬─ input_patch(): [[input]] routes as the DMX crate's UniverseMap,
//!                  │  the universes to join (sACN) and announce (ArtPollReply),
//!                  │  LTP masks — used by live input, record, replay and render --dmx
//!                  ├─ input_universe(protocol, n): the one protocol → input mapping
//!                  │  (routes, and the status's unpatched inputs; a USB Pro widget past 255 is an error)
//!                  ├─ decode(slots): every fixture's state, tracer light and k_i (eq. 4)
//!                  └─ change(old, new): the fixture crate's one rule (composite or geometry),
//!                     applied by the frame clock to every light each frame
//! ```
//!
//! The DMX it decodes is read in place through [`DmxSlots`]: the daemon
//! hands it the DMX crate's merged frames (with their `stale` flags), stills
//! hand it a [`footlight_fixture::Universes`]; nothing is copied per packet
//! or per frame.

use crate::Patch;
use crate::fixture::{Change, DmxSlots, FixtureState, classify};
use crate::live::clock::{Decode, LightInput};
use crate::output::{LightLabel, LightPatch};
use footlight_dmx::{InputPatch, InputUniverse, Protocol, SlotMask, UniverseMap};
use footlight_fixture::patch::InputProtocol;
use std::sync::{Arc, Mutex};

/// The show: the patch plus how DMX reaches it.
pub struct Show {
    patch: Arc<Patch>,
    input: InputPatch,
    /// Per fixture, what its last state decoded to ([`Decode::decode_at`]):
    /// a fixture whose state has not changed since (a held look: most of a
    /// festival rig's 3,687 emitters, most of the time) is not decoded
    /// again. Its light, k_i and k_i at full are pure functions of its
    /// state, and working them out (the beam's solid angle for Î, the
    /// colour mix, the gels) was most of the frame clock's time on the
    /// festival show: a profile of a held look put 66 % of the daemon's CPU
    /// on the clock and 28 % on the builds.
    decoded: Mutex<Vec<Option<LightInput>>>,
}

/// Why a protocol universe cannot be an input of the DMX crate
/// ([`Show::input_universe`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RouteError {
    /// A USB Pro input is a widget index 0-255, not a DMX universe number.
    #[error(
        "USB Pro widget index {universe} is outside 0-255 (a USB Pro input's `universe` is the widget's \
         index, the one --usbpro opens is 0; give the patch universe it feeds as patch_universe)"
    )]
    UsbProWidget {
        /// The index asked for.
        universe: u16,
    },
}

/// Why a patch cannot be shown ([`Show::new`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ShowError {
    /// An `[[input]]` route names an input no DMX node can receive.
    #[error("{} line {line}: [[input]]: {source}", path.display())]
    Route {
        /// The patch file.
        path: std::path::PathBuf,
        /// The route's line in it.
        line: usize,
        /// What is wrong with it.
        source: RouteError,
    },
}

impl Show {
    /// The show of `patch`: its `[[input]]` routes (inputs without a route
    /// keep the default rule: sACN N and Art-Net Port-Address N−1 feed patch
    /// universe N), the patched universes and the LTP slots. A route the
    /// DMX input cannot take (a USB Pro widget index past 255) is an error
    /// naming the patch file and line, never a different input in silence.
    pub fn new(patch: Patch) -> Result<Self, ShowError> {
        let mut map = UniverseMap::default();
        for route in &patch.inputs {
            let input = Self::input_universe(protocol_of(route.protocol), route.universe)
                .map_err(|source| ShowError::Route { path: patch.path.clone(), line: route.line, source })?;
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
        let decoded = Mutex::new(vec![None; patch.fixtures.len()]);
        Ok(Self { patch: Arc::new(patch), input, decoded })
    }

    /// The input universe `universe` of `protocol` names as the DMX crate
    /// keys it: the one mapping from a protocol and its number to an input,
    /// for the patch's `[[input]]` routes and for the status's unpatched
    /// inputs alike. A USB Pro widget index past 255 is an error.
    pub fn input_universe(protocol: Protocol, universe: u16) -> Result<InputUniverse, RouteError> {
        Ok(match protocol {
            Protocol::Sacn => InputUniverse::Sacn(universe),
            Protocol::ArtNet => InputUniverse::ArtNet(universe),
            Protocol::UsbPro => {
                InputUniverse::UsbPro(u8::try_from(universe).map_err(|_| RouteError::UsbProWidget { universe })?)
            }
        })
    }

    /// Every fixture's [`LightInput`] from the DMX `universes` (at frame
    /// time `t_seconds`: spinning gobos, prisms and wheels turned), each
    /// worked out again only when its state changed since the last call
    /// (the memo `decoded`; equal states decode to equal inputs).
    fn decode_states(&self, universes: &dyn DmxSlots, t_seconds: Option<f64>) -> Vec<LightInput> {
        let mut memo = self.decoded.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        self.patch
            .fixtures
            .iter()
            .zip(memo.iter_mut())
            .map(|(f, last)| {
                let mut state = f.decode_universes(universes);
                if let Some(t) = t_seconds
                    && state.spins()
                    && let footlight_fixture::FixtureModel::Typed(typed) = &f.model
                {
                    state = typed.fixture_type.state_at(&state, t);
                }
                match last {
                    Some(input) if input.state == state => input.clone(),
                    _ => {
                        let input = LightInput {
                            light: f.light_of(&state),
                            k: f.k_of(&state),
                            k_full: f.k_full_of(&state),
                            state,
                        };
                        *last = Some(input.clone());
                        input
                    }
                }
            })
            .collect()
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

    /// What a state change of a fixture costs: the fixture crate's rule,
    /// the one the frame clock applies to every light each frame (a
    /// geometry change asks the tracer for a rebuild; anything else is a
    /// new k_i, a composite).
    pub fn change(old: &FixtureState, new: &FixtureState) -> Change {
        classify(old, new)
    }
}

/// The DMX crate's protocol of a patch route's protocol.
fn protocol_of(p: InputProtocol) -> Protocol {
    match p {
        InputProtocol::Sacn => Protocol::Sacn,
        InputProtocol::ArtNet => Protocol::ArtNet,
        InputProtocol::UsbPro => Protocol::UsbPro,
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
        self.decode_states(universes, None)
    }

    fn decode_at(&self, universes: &dyn DmxSlots, t_seconds: f64) -> Vec<LightInput> {
        self.decode_states(universes, Some(t_seconds))
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

#[cfg(test)]
mod tests {
    use super::*;
    use footlight_fixture::patch::InputRoute;
    use std::path::Path;

    /// One spot on universe 1.
    const SPOT: &str = "[[fixture]]\nid = 1\ntype = \"spot\"\nposition = [0.0, 6.0, 6.0]\naim = [0.0, 0.0, 0.0]\n\
                        intensity = 1000.0\nuniverse = 1\naddress = 1\n";

    /// The memo of decoded states gives what a fresh decode gives: over a
    /// run of frames (held, changed, back, with spinning time) every
    /// fixture's input equals that of a show that decodes it for the first
    /// time.
    #[test]
    fn decoding_from_the_memo_equals_decoding_afresh() {
        let path = crate::bundled::find(crate::DEFAULT_PATCH).expect("the default patch");
        let patch = Patch::load(&path).expect("the default patch loads");
        let show = Show::new(patch.clone()).expect("show");
        let n = patch.fixtures.len();
        let frame = |seed: u8| {
            let mut u = crate::fixture::Universes::new();
            for a in 1..=512u16 {
                u.set_slot(1, a, (a as u8).wrapping_mul(37).wrapping_add(seed));
            }
            u
        };
        for (i, seed) in [0u8, 0, 1, 1, 0, 200].into_iter().enumerate() {
            let u = frame(seed);
            let t = i as f64 * 0.37;
            let fresh = Show::new(patch.clone()).expect("show").decode_at(&u, t);
            assert_eq!(show.decode_at(&u, t), fresh, "frame {i}");
            assert_eq!(fresh.len(), n);
        }
    }

    /// The one-spot patch with these `[[input]]` routes (text).
    fn patch(routes: &str) -> Result<Patch, footlight_fixture::PatchError> {
        Patch::parse(Path::new("rig.toml"), &format!("{SPOT}{routes}"))
    }

    #[test]
    fn one_mapping_from_a_protocol_number_to_an_input() {
        assert_eq!(Show::input_universe(Protocol::Sacn, 7), Ok(InputUniverse::Sacn(7)));
        assert_eq!(Show::input_universe(Protocol::ArtNet, 0), Ok(InputUniverse::ArtNet(0)));
        assert_eq!(Show::input_universe(Protocol::UsbPro, 255), Ok(InputUniverse::UsbPro(255)));
        // Past a widget index: an error, never widget 255 in silence.
        assert_eq!(Show::input_universe(Protocol::UsbPro, 256), Err(RouteError::UsbProWidget { universe: 256 }));
    }

    #[test]
    fn a_usb_pro_route_past_widget_255_is_an_error_naming_the_patch_and_line() {
        // The patch file refuses it itself (the parser's range check) ...
        let e = patch("\n[[input]]\nprotocol = \"usbpro\"\nuniverse = 300\npatch_universe = 1\n")
            .expect_err("widget 300 is refused");
        assert!(e.to_string().contains("USB Pro widget index 300"), "{e}");
        // ... and a patch built in code with such a route is refused by Show
        // (it used to be routed as widget 255).
        let mut p = patch("").expect("the spot alone parses");
        p.inputs.push(InputRoute { protocol: InputProtocol::UsbPro, universe: 300, patch_universe: Some(1), line: 12 });
        let e = Show::new(p).err().expect("widget 300 is an error");
        assert_eq!(
            e,
            ShowError::Route { path: "rig.toml".into(), line: 12, source: RouteError::UsbProWidget { universe: 300 } }
        );
        let said = e.to_string();
        assert!(said.starts_with("rig.toml line 12: [[input]]: USB Pro widget index 300 is outside 0-255"), "{said}");
        // Widget 255 and the other protocols route as written.
        let show = Show::new(
            patch(
                "\n[[input]]\nprotocol = \"usbpro\"\nuniverse = 255\npatch_universe = 1\n\n\
             [[input]]\nprotocol = \"artnet\"\nuniverse = 4\nblock = true\n",
            )
            .expect("valid routes"),
        )
        .expect("valid routes");
        let map = &show.input_patch().map;
        assert_eq!(map.patch_universe(InputUniverse::UsbPro(255)), Some(1));
        assert_eq!(map.entry(InputUniverse::ArtNet(4)), Some(None));
    }
}
