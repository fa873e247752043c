//! The typed status of a DMX input (live or replayed): what feeds each patch
//! universe, who sends it, whether it is fresh or stale, and what arrives on
//! universes the patch does not use.
//!
//! Data comes from the merge stage (every event it applies: levels, "alive"
//! while held for sync, sources leaving and timing out) and from the nodes
//! (data packets their filter drops as not patched). Both write into one
//! [`StatusHandle`] under a mutex held for a few field updates per packet,
//! never across an `.await`; no allocation per packet (sources, universes and
//! unpatched inputs are stored when first seen, bounded). A reader (the HTTP
//! status page) calls [`StatusHandle::snapshot`] and gets [`InputStatus`], a
//! plain `serde::Serialize` value with ages in milliseconds.
//!
//! Unpatched data is also logged: one `warn` per input universe at most
//! every 10 s (and at most [`WARNINGS_PER_PERIOD`] such lines per 10 s in
//! all), naming the universe, the patch universe the default mapping would
//! give it and what to do, e.g. `Art-Net Port-Address 1 (would be patch
//! universe 2 by default) is not patched: 40 packets dropped; route it with
//! [[input]] in the patch`.

use std::collections::BTreeMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use serde::Serialize;
use tokio::time::Instant;

use crate::input::InputPatch;
use crate::map::{UniverseFilter, UniverseMap};
use crate::source::{InputUniverse, Protocol, SourceId, SourceName};
use crate::stats::{Counters, SocketCounters, Stats, StatsHandle};

/// Unpatched input universes tracked one by one; packets on further ones are
/// only counted in [`InputStatus::unpatched_untracked`].
pub const MAX_UNPATCHED: usize = 256;
/// Most "not patched" warnings logged per 10 s in all.
pub const WARNINGS_PER_PERIOD: u32 = 8;
/// How often one input universe is warned about at most.
const WARN_PERIOD: Duration = Duration::from_secs(10);

/// Everything the status page shows about the DMX input.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct InputStatus {
    /// Per patch universe the patch uses (or that received data, when the
    /// input accepts every universe), by number.
    pub universes: Vec<UniverseStatus>,
    /// Input universes whose data no patch universe takes, by protocol and number.
    pub unpatched: Vec<UnpatchedStatus>,
    /// Packets on unpatched input universes past the first [`MAX_UNPATCHED`].
    pub unpatched_untracked: u64,
    /// Packet counters per protocol.
    pub counters: ProtocolCounters,
    /// The UDP sockets' receive buffers and kernel drops.
    pub sockets: SocketStatus,
}

/// The UDP input sockets as the kernel sees them ([`SocketCounters`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SocketStatus {
    /// The Art-Net socket (`None`: Art-Net is off).
    pub artnet: Option<SocketCounters>,
    /// The sACN socket (`None`: sACN is off).
    pub sacn: Option<SocketCounters>,
}

/// Packet counters of each protocol ([`Stats`] totals).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ProtocolCounters {
    /// Art-Net.
    pub artnet: Counters,
    /// sACN.
    pub sacn: Counters,
    /// Enttec USB Pro.
    pub usbpro: Counters,
}

/// Whether a patch universe has live data.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FeedState {
    /// At least one source is live.
    Receiving,
    /// Every source has left or timed out (sACN 2.5 s, Art-Net 10 s); the
    /// merge holds the last values.
    Stale,
    /// No data has arrived yet.
    NoData,
}

/// A universe as a protocol numbers it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct InputRef {
    /// The protocol.
    pub protocol: Protocol,
    /// Art-Net Port-Address (0-32767), sACN universe (1-63999) or USB Pro widget index.
    pub universe: u16,
}

impl From<InputUniverse> for InputRef {
    fn from(input: InputUniverse) -> Self {
        InputRef { protocol: input.protocol(), universe: input.number() }
    }
}

/// One patch universe.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct UniverseStatus {
    /// Patch universe, 1-based.
    pub universe: u16,
    /// The input universes routed to it (the patch's `[[input]]` routes, or
    /// the default rule).
    pub inputs: Vec<InputRef>,
    /// Receiving, stale or no data yet.
    pub state: FeedState,
    /// `state == Stale`: the frame holds its last values.
    pub stale: bool,
    /// Data packets that reached this universe (levels applied or held for sync).
    pub packets: u64,
    /// Milliseconds since the last of them (`None`: none yet).
    pub last_packet_ms: Option<u64>,
    /// The sources merging into it now.
    pub sources: Vec<SourceStatus>,
}

/// One source feeding a patch universe.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct SourceStatus {
    /// The protocol it sends.
    pub protocol: Protocol,
    /// The input universe it sends on.
    pub input: InputRef,
    /// sACN Source Name (`None` for other protocols or an empty name).
    pub name: Option<String>,
    /// sACN CID as a UUID (`8-4-4-4-12` hex digits).
    pub cid: Option<String>,
    /// Art-Net sender IP.
    pub ip: Option<IpAddr>,
    /// Art-Net Physical (the sender's input port).
    pub physical: Option<u8>,
    /// USB Pro widget index.
    pub widget: Option<u8>,
    /// Merge priority (sACN 0-200; Art-Net and USB Pro count as 100).
    pub priority: u8,
    /// Its data packets on this universe.
    pub packets: u64,
    /// Milliseconds since its last one.
    pub last_packet_ms: u64,
}

/// Data on an input universe that no patch universe takes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct UnpatchedStatus {
    /// Protocol and universe number.
    pub input: InputRef,
    /// Data packets dropped.
    pub packets: u64,
    /// Milliseconds since the last.
    pub last_packet_ms: u64,
    /// The patch universe the default mapping gives it (Art-Net N-1, sACN N,
    /// USB Pro widget N-1 → N).
    pub default_patch_universe: Option<u16>,
    /// The patch universe an `[[input]]` route sends it to, when the patch
    /// does not use that universe.
    pub routed_to: Option<u16>,
    /// An `[[input]]` entry blocks it (no warning is logged).
    pub blocked: bool,
}

/// One source as the board keeps it.
struct BoardSource {
    id: SourceId,
    input: InputUniverse,
    priority: u8,
    name: SourceName,
    packets: u64,
    last: Instant,
}

/// One patch universe as the board keeps it.
struct BoardUniverse {
    universe: u16,
    inputs: Vec<InputRef>,
    packets: u64,
    last: Option<Instant>,
    stale: bool,
    sources: Vec<BoardSource>,
}

struct Unpatched {
    packets: u64,
    last: Instant,
    warned: Option<Instant>,
}

/// The mutable state behind a [`StatusHandle`].
#[derive(Default)]
pub(crate) struct Board {
    map: UniverseMap,
    /// The patch universes (when the patch lists none, universes are added as data comes).
    universes: Vec<BoardUniverse>,
    unpatched: BTreeMap<InputUniverse, Unpatched>,
    unpatched_untracked: u64,
    /// Global warning budget: the current 10 s window and warnings in it.
    warn_window: Option<Instant>,
    warnings: u32,
    suppressed: u64,
}

impl Board {
    fn new(patch: &InputPatch) -> Board {
        let mut patched = patch.universes.clone();
        patched.sort_unstable();
        patched.dedup();
        let map = patch.map.clone();
        let universes = patched.iter().map(|&u| Self::empty_universe(&map, u)).collect();
        Board { map, universes, ..Board::default() }
    }

    fn empty_universe(map: &UniverseMap, universe: u16) -> BoardUniverse {
        let inputs = [Protocol::ArtNet, Protocol::Sacn, Protocol::UsbPro]
            .into_iter()
            .flat_map(|p| map.inputs_for(p, universe))
            .map(InputRef::from)
            .collect();
        BoardUniverse { universe, inputs, packets: 0, last: None, stale: false, sources: Vec::new() }
    }

    fn universe_mut(&mut self, universe: u16) -> &mut BoardUniverse {
        let i = match self.universes.binary_search_by_key(&universe, |u| u.universe) {
            Ok(i) => i,
            Err(i) => {
                // Only when every universe is accepted; the merge bounds how many.
                self.universes.insert(i, Self::empty_universe(&self.map, universe));
                i
            }
        };
        &mut self.universes[i]
    }

    /// Levels from `source` reached patch universe `universe`.
    pub(crate) fn levels(
        &mut self,
        universe: u16,
        (source, input): (SourceId, InputUniverse),
        priority: u8,
        name: &SourceName,
        at: Instant,
    ) {
        let u = self.universe_mut(universe);
        (u.packets, u.last, u.stale) = (u.packets + 1, Some(at), false);
        match u.sources.iter_mut().find(|s| s.id == source) {
            Some(s) => {
                (s.input, s.priority, s.packets, s.last) = (input, priority, s.packets + 1, at);
                if s.name != *name {
                    s.name = *name;
                }
            }
            None => u.sources.push(BoardSource { id: source, input, priority, name: *name, packets: 1, last: at }),
        }
    }

    /// A data packet from `source` is held for sync: it counts, levels do not change.
    pub(crate) fn alive(&mut self, universe: u16, source: SourceId, at: Instant) {
        let u = self.universe_mut(universe);
        (u.packets, u.last) = (u.packets + 1, Some(at));
        if let Some(s) = u.sources.iter_mut().find(|s| s.id == source) {
            (s.packets, s.last) = (s.packets + 1, at);
        }
    }

    /// Sources left `universe`: keep those `remaining` names; `stale` is the frame's flag.
    pub(crate) fn left(&mut self, universe: u16, stale: bool, remaining: impl Iterator<Item = SourceId> + Clone) {
        let u = self.universe_mut(universe);
        u.stale = stale;
        u.sources.retain(|s| remaining.clone().any(|id| id == s.id));
    }

    /// A data packet on `input` that no patch universe takes. Returns the
    /// warning it logged, if any.
    pub(crate) fn not_patched(&mut self, input: InputUniverse, at: Instant) -> Option<String> {
        if !self.unpatched.contains_key(&input) {
            if self.unpatched.len() >= MAX_UNPATCHED {
                self.unpatched_untracked += 1;
                return None;
            }
            self.unpatched.insert(input, Unpatched { packets: 0, last: at, warned: None });
        }
        let entry = self.unpatched.get_mut(&input)?;
        (entry.packets, entry.last) = (entry.packets + 1, at);
        if self.map.is_blocked(input) || entry.warned.is_some_and(|w| at.saturating_duration_since(w) < WARN_PERIOD) {
            return None;
        }
        // The global budget: a flood over many universes logs a few lines, then counts.
        match self.warn_window {
            Some(w) if at.saturating_duration_since(w) < WARN_PERIOD => {}
            _ => (self.warn_window, self.warnings) = (Some(at), 0),
        }
        if self.warnings >= WARNINGS_PER_PERIOD {
            self.suppressed += 1;
            return None;
        }
        self.warnings += 1;
        entry.warned = Some(at);
        let message = unpatched_message(&self.map, input, entry.packets);
        let suppressed = std::mem::take(&mut self.suppressed);
        tracing::warn!(suppressed, "{message}");
        Some(message)
    }

    fn snapshot(&self, now: Instant, stats: &Stats) -> InputStatus {
        let ms = |t: Instant| now.saturating_duration_since(t).as_millis() as u64;
        let universes = self
            .universes
            .iter()
            .map(|u| {
                let state = match (u.last, u.stale) {
                    (None, _) => FeedState::NoData,
                    (Some(_), true) => FeedState::Stale,
                    (Some(_), false) => FeedState::Receiving,
                };
                UniverseStatus {
                    universe: u.universe,
                    inputs: u.inputs.clone(),
                    state,
                    stale: state == FeedState::Stale,
                    packets: u.packets,
                    last_packet_ms: u.last.map(ms),
                    sources: u.sources.iter().map(|s| source_status(s, ms(s.last))).collect(),
                }
            })
            .collect();
        let unpatched = self
            .unpatched
            .iter()
            .map(|(&input, e)| {
                let routed_to = self.map.entry(input).flatten();
                UnpatchedStatus {
                    input: input.into(),
                    packets: e.packets,
                    last_packet_ms: ms(e.last),
                    default_patch_universe: UniverseMap::default_route(input),
                    routed_to,
                    blocked: self.map.is_blocked(input),
                }
            })
            .collect();
        InputStatus {
            universes,
            unpatched,
            unpatched_untracked: self.unpatched_untracked,
            counters: ProtocolCounters { artnet: stats.artnet, sacn: stats.sacn, usbpro: stats.usbpro },
            sockets: SocketStatus { artnet: stats.artnet_socket, sacn: stats.sacn_socket },
        }
    }
}

fn source_status(s: &BoardSource, last_packet_ms: u64) -> SourceStatus {
    let (mut name, mut cid, mut ip, mut physical, mut widget) = (None, None, None, None, None);
    match s.id {
        SourceId::Sacn { cid: c } => {
            let hex: String = c.iter().map(|b| format!("{b:02x}")).collect();
            cid = Some(format!("{}-{}-{}-{}-{}", &hex[..8], &hex[8..12], &hex[12..16], &hex[16..20], &hex[20..]));
            name = (!s.name.is_empty()).then(|| s.name.to_text());
        }
        SourceId::ArtNet { ip: i, physical: p } => (ip, physical) = (Some(i), Some(p)),
        SourceId::UsbPro { widget: w } => widget = Some(w),
    }
    SourceStatus {
        protocol: s.id.protocol(),
        input: s.input.into(),
        name,
        cid,
        ip,
        physical,
        widget,
        priority: s.priority,
        packets: s.packets,
        last_packet_ms,
    }
}

/// The warning for data on `input` that no patch universe takes.
pub fn unpatched_message(map: &UniverseMap, input: InputUniverse, packets: u64) -> String {
    let dropped = format!("{packets} packet{} dropped", if packets == 1 { "" } else { "s" });
    let default = UniverseMap::default_route(input);
    match (map.entry(input), default) {
        (Some(Some(p)), _) => format!(
            "{input} is routed to patch universe {p}, which no fixture in the patch uses: {dropped}; \
             patch fixtures on universe {p} or change the [[input]] route"
        ),
        (Some(None), _) => format!("{input} is blocked by an [[input]] entry: {dropped}"),
        (None, Some(d)) if map.is_routed(d) => format!(
            "{input} (patch universe {d} by default, but [[input]] routes feed universe {d}) is not patched: \
             {dropped}; route it with [[input]] in the patch"
        ),
        (None, Some(d)) => format!(
            "{input} (would be patch universe {d} by default) is not patched: {dropped}; \
             route it with [[input]] in the patch"
        ),
        (None, None) => format!("{input} is not patched: {dropped}; route it with [[input]] in the patch"),
    }
}

/// A shared handle to the status and the packet counters of one input (live
/// or replay). Cheap to clone; survives [`crate::DmxInput::run`] consuming
/// the input. Two handles are equal when they share the same state.
#[derive(Clone, Default)]
pub struct StatusHandle {
    board: Arc<Mutex<Board>>,
    stats: StatsHandle,
}

impl std::fmt::Debug for StatusHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StatusHandle").finish_non_exhaustive()
    }
}

impl PartialEq for StatusHandle {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.board, &other.board)
    }
}

impl StatusHandle {
    /// An empty status (no patch universes until an input or replay configures it).
    pub fn new() -> Self {
        Self::default()
    }

    /// The packet counters behind this status.
    pub fn stats(&self) -> StatsHandle {
        self.stats.clone()
    }

    /// The status now.
    pub fn snapshot(&self) -> InputStatus {
        self.snapshot_at(Instant::now())
    }

    /// The status with ages measured at `now`.
    pub fn snapshot_at(&self, now: Instant) -> InputStatus {
        let stats = self.stats.snapshot();
        self.lock().snapshot(now, &stats)
    }

    /// Starts over for `patch`: every counter zero, the patch universes listed
    /// with no data.
    pub(crate) fn configure(&self, patch: &InputPatch) {
        *self.lock() = Board::new(patch);
        *self.stats.lock() = Stats::default();
    }

    /// Counts a data packet on an unpatched input universe (and warns, rate-limited).
    pub(crate) fn not_patched(&self, input: InputUniverse, at: Instant) {
        self.lock().not_patched(input, at);
    }

    pub(crate) fn lock(&self) -> MutexGuard<'_, Board> {
        self.board.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The patch universes a filter accepts, for the merge stage: `All` when the
/// patch lists none.
pub(crate) fn patched_filter(patch: &InputPatch) -> UniverseFilter {
    if patch.universes.is_empty() { UniverseFilter::All } else { UniverseFilter::only(patch.universes.iter().copied()) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::Ipv4Addr;

    fn patch() -> InputPatch {
        let mut map = UniverseMap::default();
        map.route(InputUniverse::ArtNet(1), 1).route(InputUniverse::Sacn(101), 2).block(InputUniverse::Sacn(7));
        InputPatch { map, universes: vec![1, 2], ..InputPatch::default() }
    }

    #[test]
    fn messages_name_the_universe_and_the_default_patch_universe() {
        let p = patch();
        let msg = |i, n| unpatched_message(&p.map, i, n);
        assert_eq!(
            msg(InputUniverse::ArtNet(5), 40),
            "Art-Net Port-Address 5 (would be patch universe 6 by default) is not patched: 40 packets dropped; \
             route it with [[input]] in the patch"
        );
        assert!(msg(InputUniverse::ArtNet(0), 1).starts_with(
            "Art-Net Port-Address 0 (patch universe 1 by default, but [[input]] routes feed universe 1) is not \
             patched: 1 packet dropped"
        ));
        let mut routed = p.clone();
        routed.map.route(InputUniverse::Sacn(300), 9);
        assert!(
            unpatched_message(&routed.map, InputUniverse::Sacn(300), 2)
                .starts_with("sACN universe 300 is routed to patch universe 9, which no fixture in the patch uses")
        );
    }

    #[test]
    fn warnings_are_rate_limited_per_universe_and_overall() {
        let t = Instant::now();
        let s = |n| t + Duration::from_secs(n);
        let mut b = Board::new(&patch());
        assert!(b.not_patched(InputUniverse::ArtNet(5), t).unwrap().contains("1 packet dropped"));
        for _ in 0..39 {
            assert_eq!(b.not_patched(InputUniverse::ArtNet(5), s(1)), None);
        }
        let again = b.not_patched(InputUniverse::ArtNet(5), s(10)).expect("10 s later");
        assert!(again.contains("41 packets dropped"), "{again}");
        // A blocked universe is counted, never warned about.
        assert_eq!(b.not_patched(InputUniverse::Sacn(7), s(10)), None);
        // A flood over many universes: at most WARNINGS_PER_PERIOD lines per 10 s.
        let warned = (100..400u16).filter(|&n| b.not_patched(InputUniverse::Sacn(n), s(20)).is_some()).count();
        assert_eq!(warned, WARNINGS_PER_PERIOD as usize);
        assert_eq!(b.unpatched.len(), MAX_UNPATCHED);
        let status = b.snapshot(s(21), &Stats::default());
        assert_eq!(status.unpatched_untracked, 300 - (MAX_UNPATCHED as u64 - 2));
        let art5 = &status.unpatched[0];
        assert_eq!(art5.input, InputRef { protocol: Protocol::ArtNet, universe: 5 });
        assert_eq!((art5.packets, art5.last_packet_ms, art5.default_patch_universe), (41, 11_000, Some(6)));
        let blocked = status.unpatched.iter().find(|u| u.input.universe == 7).unwrap();
        assert!(blocked.blocked && blocked.routed_to.is_none());
    }

    #[test]
    fn universes_list_routes_sources_and_staleness() {
        let t = Instant::now();
        let mut b = Board::new(&patch());
        let status = b.snapshot(t, &Stats::default());
        let inputs: Vec<Vec<InputRef>> = status.universes.iter().map(|u| u.inputs.clone()).collect();
        assert_eq!(
            inputs,
            vec![
                vec![InputRef { protocol: Protocol::ArtNet, universe: 1 }],
                vec![InputRef { protocol: Protocol::Sacn, universe: 101 }],
            ]
        );
        assert!(status.universes.iter().all(|u| u.state == FeedState::NoData && u.last_packet_ms.is_none()));
        let art = SourceId::ArtNet { ip: Ipv4Addr::new(10, 0, 0, 9).into(), physical: 2 };
        let sacn = SourceId::Sacn { cid: [0xAB; 16] };
        b.levels(1, (art, InputUniverse::ArtNet(1)), 100, &SourceName::default(), t);
        b.levels(2, (sacn, InputUniverse::Sacn(101)), 150, &SourceName::new(b"Desk\0junk"), t);
        b.alive(2, sacn, t + Duration::from_millis(500));
        let status = b.snapshot(t + Duration::from_millis(700), &Stats::default());
        let (u1, u2) = (&status.universes[0], &status.universes[1]);
        assert_eq!((u1.state, u1.packets, u1.last_packet_ms), (FeedState::Receiving, 1, Some(700)));
        assert_eq!(u1.sources[0].ip, Some(Ipv4Addr::new(10, 0, 0, 9).into()));
        assert_eq!(u1.sources[0].physical, Some(2));
        assert_eq!((u2.packets, u2.last_packet_ms), (2, Some(200)));
        let s = &u2.sources[0];
        assert_eq!((s.name.as_deref(), s.priority, s.packets), (Some("Desk"), 150, 2));
        assert_eq!(s.cid.as_deref(), Some("abababab-abab-abab-abab-abababababab"));
        b.left(2, true, std::iter::empty());
        let status = b.snapshot(t + Duration::from_secs(3), &Stats::default());
        assert_eq!((status.universes[1].state, status.universes[1].stale), (FeedState::Stale, true));
        assert!(status.universes[1].sources.is_empty());
        let json = serde_json::to_value(&status).unwrap();
        assert_eq!(json["universes"][1]["state"], "stale");
        assert_eq!(json["universes"][0]["sources"][0]["protocol"], "artnet");
        assert_eq!(json["universes"][0]["inputs"][0]["universe"], 1);
    }
}
