//! Art-Net receive rules, sans IO: the node hands in datagrams and `now`, and
//! gets [`SourceEvent`]s plus a [`Disposition`] per packet.
//!
//! - Sources are (IP, Physical). Per Port-Address at most 2 sources merge; a
//!   third is dropped while both others were heard within 10 s (Art-Net 4
//!   merge rules). The merge itself (HTP/LTP) happens in [`crate::Merge`].
//! - Sequence: 0 means "not sequenced" and always passes; otherwise a frame
//!   whose signed 8-bit distance to the last one is in (-20, 0] is dropped
//!   (the sACN rule; Art-Net specifies none). A source silent for 10 s starts
//!   afresh.
//! - ArtSync: start unsynchronised (every ArtDmx goes out now). After an
//!   ArtSync from the IP that sent the last ArtDmx (and while no Port-Address
//!   merges two sources), ArtDmx from that IP is held until the next ArtSync.
//!   4 s without ArtSync: held frames go out and we are unsynchronised again.

use std::collections::HashMap;
use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

use tokio::time::Instant;

use super::packet::{self, ArtDmx, ArtNetError, ArtPacket, ArtPoll};
use crate::map::UniverseFilter;
use crate::source::{Disposition, sequence_is_stale};
use crate::source::{DropReason, EventKind, IgnoreReason, InputUniverse, Levels, SourceEvent, SourceId, SourceName};

/// Art-Net sources merge as if they had sACN priority 100.
pub const PRIORITY: u8 = 100;
/// Art-Net 4: a silent merge source is kept for 10 s.
pub const SOURCE_TIMEOUT: Duration = Duration::from_secs(10);
/// Art-Net 4: back to unsynchronised output 4 s after the last ArtSync.
pub const SYNC_TIMEOUT: Duration = Duration::from_secs(4);

/// Receiver settings.
#[derive(Clone, Debug)]
pub struct ArtNetReceiverConfig {
    /// Port-Addresses to accept (others are ignored as not patched).
    pub filter: UniverseFilter,
    /// How long a silent source counts (merge slot, sequence state).
    pub source_timeout: Duration,
    /// How long synchronous mode lasts without an ArtSync.
    pub sync_timeout: Duration,
    /// Most Port-Addresses tracked at once.
    pub max_ports: usize,
}

impl Default for ArtNetReceiverConfig {
    fn default() -> Self {
        ArtNetReceiverConfig {
            filter: UniverseFilter::All,
            source_timeout: SOURCE_TIMEOUT,
            sync_timeout: SYNC_TIMEOUT,
            max_ports: 1024,
        }
    }
}

/// The result of handling one datagram.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ArtNetHandled {
    /// What happened to the packet.
    pub disposition: Disposition<ArtNetError>,
    /// The sending source, for ArtDmx.
    pub source: Option<SourceId>,
    /// An ArtPoll the node should answer.
    pub poll: Option<ArtPoll>,
    /// The Port-Address of an ArtDmx (also when it is not patched).
    pub input: Option<InputUniverse>,
}

impl ArtNetHandled {
    fn of(disposition: Disposition<ArtNetError>) -> Self {
        ArtNetHandled { disposition, source: None, poll: None, input: None }
    }
}

/// What a reply should say about a port.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PortStatus {
    /// Data arrived within the source timeout.
    pub data: bool,
    /// Two sources are merging.
    pub merging: bool,
    /// Data arrived once, but every source has timed out: the merge holds the
    /// last values.
    pub stale: bool,
}

struct Sender {
    id: SourceId,
    sequence: u8,
    seen: Instant,
}

#[derive(Default)]
struct PortState {
    /// At most two: the Art-Net merge limit.
    senders: Vec<Sender>,
}

struct SyncState {
    ip: IpAddr,
    last: Instant,
}

struct HeldFrame {
    port: u16,
    source: SourceId,
    levels: Levels,
}

/// Art-Net receive state for one socket.
pub struct ArtNetReceiver {
    config: ArtNetReceiverConfig,
    ports: HashMap<u16, PortState>,
    last_dmx_ip: Option<IpAddr>,
    sync: Option<SyncState>,
    /// Frames waiting for ArtSync; reused so holding does not allocate.
    held: Vec<HeldFrame>,
}

impl ArtNetReceiver {
    /// A receiver in unsynchronised mode with no sources.
    pub fn new(config: ArtNetReceiverConfig) -> Self {
        ArtNetReceiver { config, ports: HashMap::new(), last_dmx_ip: None, sync: None, held: Vec::new() }
    }

    /// Whether ArtSync currently holds ArtDmx.
    pub fn synchronous(&self) -> bool {
        self.sync.is_some()
    }

    /// Handles one datagram from `from`, emitting events through `out`.
    pub fn handle(
        &mut self,
        buf: &[u8],
        from: SocketAddr,
        now: Instant,
        out: &mut impl FnMut(SourceEvent),
    ) -> ArtNetHandled {
        match packet::parse(buf) {
            Err(e) => ArtNetHandled::of(Disposition::Malformed(e)),
            Ok(ArtPacket::Dmx(dmx)) => self.dmx(&dmx, from.ip(), now, out),
            Ok(ArtPacket::Poll(poll)) => ArtNetHandled { poll: Some(poll), ..ArtNetHandled::of(Disposition::Control) },
            Ok(ArtPacket::Sync) => ArtNetHandled::of(self.artsync(from.ip(), now, out)),
            Ok(ArtPacket::Unsupported { opcode }) => {
                tracing::debug!(opcode = format_args!("{opcode:#06x}"), %from, "Art-Net OpCode not served");
                ArtNetHandled::of(Disposition::Ignored(IgnoreReason::Unsupported(opcode)))
            }
        }
    }

    fn dmx(&mut self, dmx: &ArtDmx<'_>, ip: IpAddr, now: Instant, out: &mut impl FnMut(SourceEvent)) -> ArtNetHandled {
        let source = SourceId::ArtNet { ip, physical: dmx.physical };
        let port = dmx.port_address;
        let input = Some(InputUniverse::ArtNet(port));
        let handled = |d| ArtNetHandled { source: Some(source), input, ..ArtNetHandled::of(d) };
        if !self.config.filter.accepts(port) {
            return handled(Disposition::Ignored(IgnoreReason::NotPatched));
        }
        // Step 1: find the sender among the port's (at most two) live sources.
        let timeout = self.config.source_timeout;
        if !self.ports.contains_key(&port) && self.ports.len() >= self.config.max_ports {
            self.ports.retain(|_, p| p.senders.iter().any(|s| now.saturating_duration_since(s.seen) < timeout));
            if self.ports.len() >= self.config.max_ports {
                return handled(Disposition::Dropped(DropReason::SourcesExceeded));
            }
        }
        let state = self.ports.entry(port).or_default();
        state.senders.retain(|s| now.saturating_duration_since(s.seen) < timeout);
        let sender = match state.senders.iter_mut().position(|s| s.id == source) {
            Some(i) => &mut state.senders[i],
            None if state.senders.len() >= 2 => return handled(Disposition::Dropped(DropReason::SourcesExceeded)),
            None => {
                state.senders.push(Sender { id: source, sequence: 0, seen: now });
                state.senders.last_mut().expect("just pushed")
            }
        };
        // Step 2: sequence (0 = off on either side).
        if dmx.sequence != 0 && sender.sequence != 0 && sequence_is_stale(sender.sequence, dmx.sequence) {
            return handled(Disposition::Dropped(DropReason::OutOfOrder));
        }
        sender.sequence = dmx.sequence;
        sender.seen = now;
        self.last_dmx_ip = Some(ip);
        // Step 3: hold for ArtSync, or emit now.
        if let Some((sync_ip, last)) = self.sync.as_ref().map(|s| (s.ip, s.last)) {
            if now.saturating_duration_since(last) >= self.config.sync_timeout {
                self.leave_sync(now, out);
            } else if sync_ip == ip {
                match self.held.iter_mut().find(|h| h.port == port && h.source == source) {
                    Some(h) => h.levels.set(dmx.data),
                    None => self.held.push(HeldFrame { port, source, levels: Levels::new(dmx.data) }),
                }
                out(SourceEvent { at: now, input: InputUniverse::ArtNet(port), source, kind: EventKind::Alive });
                return handled(Disposition::Held);
            }
        }
        out(self.levels_event(port, source, Levels::new(dmx.data), now));
        handled(Disposition::Applied)
    }

    fn levels_event(&self, port: u16, source: SourceId, levels: Levels, now: Instant) -> SourceEvent {
        let timeout = Some(self.config.source_timeout);
        let kind = EventKind::Levels { priority: PRIORITY, timeout, levels, name: SourceName::default() };
        SourceEvent { at: now, input: InputUniverse::ArtNet(port), source, kind }
    }

    fn artsync(&mut self, ip: IpAddr, now: Instant, out: &mut impl FnMut(SourceEvent)) -> Disposition<ArtNetError> {
        if self.last_dmx_ip != Some(ip) || self.merging(now) {
            return Disposition::Ignored(IgnoreReason::SyncNotApplicable);
        }
        self.release(now, out);
        self.sync = Some(SyncState { ip, last: now });
        Disposition::Control
    }

    fn release(&mut self, now: Instant, out: &mut impl FnMut(SourceEvent)) {
        let held = std::mem::take(&mut self.held);
        for h in &held {
            out(self.levels_event(h.port, h.source, h.levels.clone(), now));
        }
        self.held = held;
        self.held.clear();
    }

    fn leave_sync(&mut self, now: Instant, out: &mut impl FnMut(SourceEvent)) {
        tracing::debug!("no ArtSync for {:?}: back to unsynchronised output", self.config.sync_timeout);
        self.release(now, out);
        self.sync = None;
    }

    /// Timers: leaves synchronous mode (releasing held frames) 4 s after the
    /// last ArtSync. Call at least every 100 ms or at [`Self::next_deadline`].
    pub fn tick(&mut self, now: Instant, out: &mut impl FnMut(SourceEvent)) {
        if let Some(sync) = &self.sync
            && now.saturating_duration_since(sync.last) >= self.config.sync_timeout
        {
            self.leave_sync(now, out);
        }
    }

    /// When [`Self::tick`] next has work.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.sync.as_ref().map(|s| s.last + self.config.sync_timeout)
    }

    /// Whether any Port-Address has two live sources.
    pub fn merging(&self, now: Instant) -> bool {
        self.ports.keys().any(|&p| self.port_status(p, now).merging)
    }

    /// The reply status of a Port-Address.
    pub fn port_status(&self, port: u16, now: Instant) -> PortStatus {
        let Some(state) = self.ports.get(&port) else { return PortStatus::default() };
        let live = state.senders.iter().filter(|s| now.saturating_duration_since(s.seen) < self.config.source_timeout);
        let n = live.count();
        PortStatus { data: n > 0, merging: n > 1, stale: n == 0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::artnet::packet::{build_dmx, build_sync};

    fn addr(last: u8) -> SocketAddr {
        SocketAddr::from(([10, 0, 0, last], 6454))
    }

    fn run(
        rx: &mut ArtNetReceiver,
        buf: &[u8],
        from: u8,
        now: Instant,
    ) -> (Disposition<ArtNetError>, Vec<SourceEvent>) {
        let mut events = Vec::new();
        let h = rx.handle(buf, addr(from), now, &mut |e| events.push(e));
        (h.disposition, events)
    }

    fn value(e: &SourceEvent) -> Option<u8> {
        match &e.kind {
            EventKind::Levels { levels, .. } => Some(levels.as_slice()[0]),
            _ => None,
        }
    }

    #[test]
    fn sequence_zero_always_passes_and_window_drops_stale() {
        let t = Instant::now();
        let mut rx = ArtNetReceiver::new(ArtNetReceiverConfig::default());
        assert_eq!(run(&mut rx, &build_dmx(10, 0, 0, &[1]), 1, t).0, Disposition::Applied);
        assert_eq!(run(&mut rx, &build_dmx(9, 0, 0, &[2]), 1, t).0, Disposition::Dropped(DropReason::OutOfOrder));
        assert_eq!(run(&mut rx, &build_dmx(10, 0, 0, &[2]), 1, t).0, Disposition::Dropped(DropReason::OutOfOrder));
        assert_eq!(run(&mut rx, &build_dmx(0, 0, 0, &[3]), 1, t).0, Disposition::Applied);
        assert_eq!(run(&mut rx, &build_dmx(5, 0, 0, &[4]), 1, t).0, Disposition::Applied);
        assert_eq!(run(&mut rx, &build_dmx(255, 0, 0, &[4]), 1, t).0, Disposition::Dropped(DropReason::OutOfOrder));
        // Wrap 250 → 1 (senders skip 0).
        for seq in [100, 200, 250] {
            assert_eq!(run(&mut rx, &build_dmx(seq, 0, 0, &[4]), 1, t).0, Disposition::Applied);
        }
        assert_eq!(run(&mut rx, &build_dmx(1, 0, 0, &[5]), 1, t).0, Disposition::Applied);
    }

    #[test]
    fn third_sender_is_dropped_until_one_times_out() {
        let t = Instant::now();
        let mut rx = ArtNetReceiver::new(ArtNetReceiverConfig::default());
        let p = build_dmx(0, 0, 3, &[1]);
        assert_eq!(run(&mut rx, &p, 1, t).0, Disposition::Applied);
        assert_eq!(run(&mut rx, &p, 2, t).0, Disposition::Applied);
        assert!(rx.port_status(3, t).merging);
        assert_eq!(run(&mut rx, &p, 3, t).0, Disposition::Dropped(DropReason::SourcesExceeded));
        let later = t + Duration::from_secs(10);
        assert_eq!(run(&mut rx, &p, 3, later).0, Disposition::Applied);
    }

    #[test]
    fn artsync_holds_releases_and_falls_back_after_4s() {
        let t0 = Instant::now();
        let mut rx = ArtNetReceiver::new(ArtNetReceiverConfig::default());
        let (_, e) = run(&mut rx, &build_dmx(0, 0, 0, &[10]), 1, t0);
        assert_eq!(value(&e[0]), Some(10));
        // ArtSync from another IP than the ArtDmx sender: ignored.
        assert_eq!(run(&mut rx, &build_sync(), 2, t0).0, Disposition::Ignored(IgnoreReason::SyncNotApplicable));
        assert_eq!(run(&mut rx, &build_sync(), 1, t0).0, Disposition::Control);
        let (d, e) = run(&mut rx, &build_dmx(0, 0, 0, &[20]), 1, t0);
        assert_eq!(d, Disposition::Held);
        assert!(matches!(e[0].kind, EventKind::Alive));
        let (_, e) = run(&mut rx, &build_dmx(0, 0, 0, &[21]), 1, t0);
        assert_eq!(e.len(), 1);
        let (_, e) = run(&mut rx, &build_sync(), 1, t0 + Duration::from_millis(20));
        assert_eq!(e.iter().filter_map(value).collect::<Vec<_>>(), vec![21]);
        // Held again, then no ArtSync for 4 s: released by the timer.
        run(&mut rx, &build_dmx(0, 0, 0, &[30]), 1, t0 + Duration::from_millis(40));
        let mut e = Vec::new();
        rx.tick(t0 + Duration::from_millis(4019), &mut |ev| e.push(ev));
        assert!(e.is_empty());
        rx.tick(t0 + Duration::from_millis(4020), &mut |ev| e.push(ev));
        assert_eq!(e.iter().filter_map(value).collect::<Vec<_>>(), vec![30]);
        assert!(!rx.synchronous());
        let (d, _) = run(&mut rx, &build_dmx(0, 0, 0, &[40]), 1, t0 + Duration::from_secs(5));
        assert_eq!(d, Disposition::Applied);
    }

    #[test]
    fn artsync_is_ignored_while_merging() {
        let t = Instant::now();
        let mut rx = ArtNetReceiver::new(ArtNetReceiverConfig::default());
        run(&mut rx, &build_dmx(0, 0, 0, &[1]), 2, t);
        run(&mut rx, &build_dmx(0, 0, 0, &[1]), 1, t);
        assert_eq!(run(&mut rx, &build_sync(), 1, t).0, Disposition::Ignored(IgnoreReason::SyncNotApplicable));
    }

    #[test]
    fn unpatched_port_addresses_are_ignored() {
        let t = Instant::now();
        let config = ArtNetReceiverConfig { filter: UniverseFilter::only([0]), ..Default::default() };
        let mut rx = ArtNetReceiver::new(config);
        assert_eq!(run(&mut rx, &build_dmx(0, 0, 1, &[1]), 1, t).0, Disposition::Ignored(IgnoreReason::NotPatched));
        assert_eq!(run(&mut rx, &build_dmx(0, 0, 0, &[1]), 1, t).0, Disposition::Applied);
    }
}
