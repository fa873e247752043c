//! E1.31 receive rules, sans IO: the node hands in datagrams and `now`, and
//! gets [`SourceEvent`]s plus a [`Disposition`] per packet.
//!
//! - A stream is one source (CID) on one universe. Its sequence numbers are
//!   checked with the (-20, 0] signed 8-bit window (E1.31 6.7.2); a stream
//!   silent for 2.5 s (E131_NETWORK_DATA_LOSS_TIMEOUT) starts afresh, so a
//!   restarted desk's first packet is taken.
//! - Stream_Terminated: the stream leaves the merge now; its slots are ignored.
//! - Preview_Data and START codes other than 0 are ignored (after the
//!   sequence check, which counts every data packet of the stream).
//! - Priority travels with the levels; the merge picks the highest.
//! - Synchronisation (E1.31 11): data with sync address 0 acts now and drops
//!   held data. Data naming sync address S acts now until the first sync
//!   packet for S arrives; after that it is held until the next one. No sync
//!   packet for S in 2.5 s = sync lost: data with Force_Sync set acts now
//!   again, data without it stays held (frozen) until sync resumes. Sync
//!   packets have their own sequence per (CID, S) and are ignored for S = 0.
//!   Held data keeps its source alive in the merge.
//! - Bounded memory: at most `max_streams` streams and `max_sync_addresses`
//!   sync addresses; past that new streams are dropped as "sources exceeded".

use std::collections::HashMap;
use std::net::SocketAddr;
use std::time::Duration;

use tokio::time::Instant;

use super::packet::{self, DataPacket, SacnError, SacnPacket, SyncPacket};
use crate::map::UniverseFilter;
use crate::source::sequence_is_stale;
use crate::source::{
    Disposition, DropReason, EventKind, IgnoreReason, InputUniverse, Levels, SourceEvent, SourceId, SourceName,
};

/// E131_NETWORK_DATA_LOSS_TIMEOUT.
pub const SOURCE_TIMEOUT: Duration = Duration::from_millis(2500);

/// Receiver settings.
#[derive(Clone, Debug)]
pub struct SacnReceiverConfig {
    /// Universes to accept (others are ignored as not patched).
    pub filter: UniverseFilter,
    /// Data loss timeout for streams and for sync.
    pub source_timeout: Duration,
    /// Most (CID, universe) streams tracked.
    pub max_streams: usize,
    /// Most synchronisation addresses tracked.
    pub max_sync_addresses: usize,
}

impl Default for SacnReceiverConfig {
    fn default() -> Self {
        SacnReceiverConfig {
            filter: UniverseFilter::All,
            source_timeout: SOURCE_TIMEOUT,
            max_streams: 1024,
            max_sync_addresses: 64,
        }
    }
}

/// The result of handling one datagram.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SacnHandled {
    /// What happened to the packet.
    pub disposition: Disposition<SacnError>,
    /// The sending source, when the packet parsed.
    pub source: Option<SourceId>,
    /// A synchronisation universe seen for the first time: the node should
    /// join its multicast group (sync packets go there).
    pub join: Option<u16>,
    /// The universe of a data packet (also when it is not patched).
    pub input: Option<InputUniverse>,
}

/// Data waiting for a sync packet.
struct Held {
    levels: Levels,
    priority: u8,
    sync_address: u16,
    force_sync: bool,
    name: SourceName,
}

struct Stream {
    sequence: u8,
    seen: Instant,
    held: Option<Held>,
}

struct SyncAddress {
    /// The last sync packet; `None` until the first one (no holding before it).
    last_sync: Option<Instant>,
    /// The last data or sync packet naming this address: an entry unused for
    /// the data loss timeout is forgotten, so junk or departed desks cannot
    /// fill the table for good.
    used: Instant,
}

/// E1.31 receive state for one socket.
pub struct SacnReceiver {
    config: SacnReceiverConfig,
    streams: HashMap<([u8; 16], u16), Stream>,
    sync_sequences: HashMap<([u8; 16], u16), (u8, Instant)>,
    sync_addresses: HashMap<u16, SyncAddress>,
}

impl SacnReceiver {
    /// A receiver with no streams.
    pub fn new(config: SacnReceiverConfig) -> Self {
        SacnReceiver { config, streams: HashMap::new(), sync_sequences: HashMap::new(), sync_addresses: HashMap::new() }
    }

    /// How many streams are tracked.
    pub fn streams(&self) -> usize {
        self.streams.len()
    }

    /// Handles one datagram, emitting events through `out`.
    pub fn handle(
        &mut self,
        buf: &[u8],
        _from: SocketAddr,
        now: Instant,
        out: &mut impl FnMut(SourceEvent),
    ) -> SacnHandled {
        let of = |disposition, source| SacnHandled { disposition, source, join: None, input: None };
        match packet::parse(buf) {
            Err(e) => of(Disposition::Malformed(e), None),
            Ok(SacnPacket::Data(d)) => self.data(&d, now, out),
            Ok(SacnPacket::Sync(s)) => of(self.sync(&s, now, out), Some(SourceId::Sacn { cid: s.cid })),
            Ok(SacnPacket::Discovery { cid }) => {
                of(Disposition::Ignored(IgnoreReason::Discovery), Some(SourceId::Sacn { cid }))
            }
        }
    }

    /// How many synchronisation addresses are tracked.
    pub fn sync_addresses(&self) -> usize {
        self.sync_addresses.len()
    }

    /// Whether synchronisation address `address` is tracked (its multicast
    /// group is worth staying in).
    pub fn tracks_sync_address(&self, address: u16) -> bool {
        self.sync_addresses.contains_key(&address)
    }

    fn data(&mut self, d: &DataPacket<'_>, now: Instant, out: &mut impl FnMut(SourceEvent)) -> SacnHandled {
        let source = SourceId::Sacn { cid: d.cid };
        let input = Some(InputUniverse::Sacn(d.universe));
        let handled = |disposition, join| SacnHandled { disposition, source: Some(source), join, input };
        if !self.config.filter.accepts(d.universe) {
            return handled(Disposition::Ignored(IgnoreReason::NotPatched), None);
        }
        // Step 1: the stream and its sequence. A stream silent for the data
        // loss timeout starts afresh, so any sequence number passes.
        let timeout = self.config.source_timeout;
        let key = (d.cid, d.universe);
        match self.streams.get_mut(&key) {
            Some(stream) => {
                let fresh = now.saturating_duration_since(stream.seen) < timeout;
                if fresh && sequence_is_stale(stream.sequence, d.sequence) {
                    return handled(Disposition::Dropped(DropReason::OutOfOrder), None);
                }
                if !fresh {
                    stream.held = None;
                }
                (stream.sequence, stream.seen) = (d.sequence, now);
            }
            None => {
                if self.streams.len() >= self.config.max_streams {
                    self.streams.retain(|_, s| now.saturating_duration_since(s.seen) < timeout);
                    if self.streams.len() >= self.config.max_streams {
                        return handled(Disposition::Dropped(DropReason::SourcesExceeded), None);
                    }
                }
                self.streams.insert(key, Stream { sequence: d.sequence, seen: now, held: None });
            }
        }
        // Step 2: options and START code.
        if d.terminated() {
            self.streams.remove(&key);
            out(SourceEvent { at: now, input: InputUniverse::Sacn(d.universe), source, kind: EventKind::Gone });
            return handled(Disposition::Control, None);
        }
        if d.preview() {
            return handled(Disposition::Ignored(IgnoreReason::Preview), None);
        }
        if d.start_code != 0 {
            return handled(Disposition::Ignored(IgnoreReason::StartCode(d.start_code)), None);
        }
        // Step 3: act now or hold for sync.
        let mut join = None;
        let hold = match d.sync_address {
            0 => false,
            s => {
                if let Some(a) = self.sync_addresses.get_mut(&s) {
                    a.used = now;
                } else {
                    if self.sync_addresses.len() >= self.config.max_sync_addresses {
                        Self::forget_unused(&mut self.sync_addresses, timeout, now);
                    }
                    if self.sync_addresses.len() < self.config.max_sync_addresses {
                        self.sync_addresses.insert(s, SyncAddress { last_sync: None, used: now });
                        join = Some(s);
                    }
                }
                match self.sync_addresses.get(&s).and_then(|a| a.last_sync) {
                    None => false, // never synced (or untracked): act now
                    Some(last) if now.saturating_duration_since(last) < timeout => true,
                    Some(_) => !d.force_sync(), // sync lost: freeze unless Force_Sync
                }
            }
        };
        let stream = self.streams.get_mut(&key).expect("inserted above");
        if hold {
            match &mut stream.held {
                Some(h) => {
                    h.levels.set(d.slots);
                    (h.priority, h.sync_address, h.force_sync) = (d.priority, d.sync_address, d.force_sync());
                    h.name = SourceName::new(d.source_name);
                }
                None => {
                    let levels = Levels::new(d.slots);
                    let (priority, sync_address, force_sync) = (d.priority, d.sync_address, d.force_sync());
                    let name = SourceName::new(d.source_name);
                    stream.held = Some(Held { levels, priority, sync_address, force_sync, name });
                }
            }
            out(SourceEvent { at: now, input: InputUniverse::Sacn(d.universe), source, kind: EventKind::Alive });
            return handled(Disposition::Held, join);
        }
        stream.held = None;
        let kind = EventKind::Levels {
            priority: d.priority,
            timeout: Some(timeout),
            levels: Levels::new(d.slots),
            name: SourceName::new(d.source_name),
        };
        out(SourceEvent { at: now, input: InputUniverse::Sacn(d.universe), source, kind });
        handled(Disposition::Applied, join)
    }

    fn sync(&mut self, s: &SyncPacket, now: Instant, out: &mut impl FnMut(SourceEvent)) -> Disposition<SacnError> {
        let timeout = self.config.source_timeout;
        if s.sync_address == 0 || !self.sync_addresses.contains_key(&s.sync_address) {
            return Disposition::Ignored(IgnoreReason::SyncUnused);
        }
        let key = (s.cid, s.sync_address);
        match self.sync_sequences.get_mut(&key) {
            Some((last, seen)) => {
                if now.saturating_duration_since(*seen) < timeout && sequence_is_stale(*last, s.sequence) {
                    return Disposition::Dropped(DropReason::OutOfOrder);
                }
                (*last, *seen) = (s.sequence, now);
            }
            None => {
                if self.sync_sequences.len() >= self.config.max_streams {
                    self.sync_sequences.retain(|_, (_, seen)| now.saturating_duration_since(*seen) < timeout);
                }
                if self.sync_sequences.len() >= self.config.max_streams {
                    return Disposition::Dropped(DropReason::SourcesExceeded);
                }
                self.sync_sequences.insert(key, (s.sequence, now));
            }
        }
        if let Some(a) = self.sync_addresses.get_mut(&s.sync_address) {
            (a.last_sync, a.used) = (Some(now), now);
        }
        Self::release(&mut self.streams, timeout, now, out, |h| h.sync_address == s.sync_address);
        Disposition::Control
    }

    /// Emits and clears the held data that `which` selects. (A function over
    /// the stream table, so callers can borrow the other fields in `which`.)
    fn release(
        streams: &mut HashMap<([u8; 16], u16), Stream>,
        timeout: Duration,
        now: Instant,
        out: &mut impl FnMut(SourceEvent),
        which: impl Fn(&Held) -> bool,
    ) {
        for (&(cid, universe), stream) in streams.iter_mut() {
            if let Some(h) = stream.held.take_if(|h| which(h)) {
                let kind =
                    EventKind::Levels { priority: h.priority, timeout: Some(timeout), levels: h.levels, name: h.name };
                let source = SourceId::Sacn { cid };
                out(SourceEvent { at: now, input: InputUniverse::Sacn(universe), source, kind });
            }
        }
    }

    /// Timers: on sync loss, releases held data that has Force_Sync; forgets
    /// streams silent for the data loss timeout. Call at least every 100 ms.
    pub fn tick(&mut self, now: Instant, out: &mut impl FnMut(SourceEvent)) {
        let timeout = self.config.source_timeout;
        let addresses = &self.sync_addresses;
        let lost = |a: &SyncAddress| a.last_sync.is_some_and(|t| now.saturating_duration_since(t) >= timeout);
        Self::release(&mut self.streams, timeout, now, out, |h| {
            h.force_sync && addresses.get(&h.sync_address).is_some_and(lost)
        });
        self.streams.retain(|_, s| now.saturating_duration_since(s.seen) < timeout);
        self.sync_sequences.retain(|_, (_, seen)| now.saturating_duration_since(*seen) < timeout);
        Self::forget_unused(&mut self.sync_addresses, timeout, now);
    }

    /// Forgets sync addresses no data or sync packet named for `timeout`.
    /// Held data of a departed address cannot be stranded: the stream holding
    /// it names the address in every packet, and a silent stream expires with it.
    fn forget_unused(addresses: &mut HashMap<u16, SyncAddress>, timeout: Duration, now: Instant) {
        addresses.retain(|_, a| now.saturating_duration_since(a.used) < timeout);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sacn::packet::{DataSpec, OPTION_FORCE_SYNC, OPTION_PREVIEW, OPTION_TERMINATED, build_data, build_sync};

    const FROM: SocketAddr = SocketAddr::new(std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST), 5568);

    fn data(cid: u8, seq: u8, options: u8, sync: u16, slots: &[u8]) -> Vec<u8> {
        build_data(&DataSpec {
            cid: [cid; 16],
            source_name: "t",
            priority: 100,
            sync_address: sync,
            sequence: seq,
            options,
            universe: 1,
            start_code: 0,
            slots,
        })
    }

    fn run(rx: &mut SacnReceiver, buf: &[u8], now: Instant) -> (Disposition<SacnError>, Vec<SourceEvent>) {
        let mut events = Vec::new();
        let h = rx.handle(buf, FROM, now, &mut |e| events.push(e));
        (h.disposition, events)
    }

    fn values(events: &[SourceEvent]) -> Vec<u8> {
        events
            .iter()
            .filter_map(|e| match &e.kind {
                EventKind::Levels { levels, .. } => Some(levels.as_slice()[0]),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn first_packet_of_a_new_source_passes_whatever_its_sequence() {
        let t = Instant::now();
        let mut rx = SacnReceiver::new(SacnReceiverConfig::default());
        assert_eq!(run(&mut rx, &data(1, 200, 0, 0, &[1]), t).0, Disposition::Applied);
        assert_eq!(run(&mut rx, &data(2, 0, 0, 0, &[1]), t).0, Disposition::Applied);
        assert_eq!(rx.streams(), 2);
    }

    #[test]
    fn termination_preview_and_start_codes() {
        let t = Instant::now();
        let mut rx = SacnReceiver::new(SacnReceiverConfig::default());
        assert_eq!(
            run(&mut rx, &data(1, 1, OPTION_PREVIEW, 0, &[1]), t).0,
            Disposition::Ignored(IgnoreReason::Preview)
        );
        let (d, e) = run(&mut rx, &data(1, 2, OPTION_TERMINATED, 0, &[1]), t);
        assert_eq!(d, Disposition::Control);
        assert!(matches!(e[0].kind, EventKind::Gone));
        assert_eq!(rx.streams(), 0);
        let mut dd = data(1, 3, 0, 0, &[1]);
        dd[125] = 0xDD;
        assert_eq!(run(&mut rx, &dd, t).0, Disposition::Ignored(IgnoreReason::StartCode(0xDD)));
    }

    #[test]
    fn sync_holds_after_the_first_sync_packet_only() {
        let t = Instant::now();
        let ms = |n| t + Duration::from_millis(n);
        let mut rx = SacnReceiver::new(SacnReceiverConfig::default());
        // Before any sync packet for 7000: act now.
        let (d, e) = run(&mut rx, &data(1, 1, 0, 7000, &[10]), t);
        assert_eq!((d, values(&e)), (Disposition::Applied, vec![10]));
        assert_eq!(run(&mut rx, &build_sync(&[9; 16], 1, 0), t).0, Disposition::Ignored(IgnoreReason::SyncUnused));
        assert_eq!(run(&mut rx, &build_sync(&[9; 16], 1, 7000), ms(1)).0, Disposition::Control);
        let (d, e) = run(&mut rx, &data(1, 2, 0, 7000, &[20]), ms(2));
        assert_eq!((d, values(&e)), (Disposition::Held, vec![]));
        run(&mut rx, &data(1, 3, 0, 7000, &[21]), ms(3));
        let (_, e) = run(&mut rx, &build_sync(&[9; 16], 2, 7000), ms(4));
        assert_eq!(values(&e), vec![21]);
        // A stale sync packet is dropped by its own sequence.
        assert_eq!(run(&mut rx, &build_sync(&[9; 16], 1, 7000), ms(5)).0, Disposition::Dropped(DropReason::OutOfOrder));
        // Sync address 0 acts now and drops held data.
        run(&mut rx, &data(1, 4, 0, 7000, &[30]), ms(6));
        let (d, e) = run(&mut rx, &data(1, 5, 0, 0, &[31]), ms(7));
        assert_eq!((d, values(&e)), (Disposition::Applied, vec![31]));
        let (_, e) = run(&mut rx, &build_sync(&[9; 16], 3, 7000), ms(8));
        assert_eq!(values(&e), Vec::<u8>::new());
    }

    #[test]
    fn sync_loss_releases_force_sync_and_freezes_the_rest() {
        let t = Instant::now();
        let ms = |n| t + Duration::from_millis(n);
        let mut rx = SacnReceiver::new(SacnReceiverConfig::default());
        run(&mut rx, &data(1, 1, 0, 7000, &[1]), t);
        run(&mut rx, &data(2, 1, 0, 7000, &[1]), t);
        run(&mut rx, &build_sync(&[9; 16], 1, 7000), t);
        run(&mut rx, &data(1, 2, OPTION_FORCE_SYNC, 7000, &[50]), ms(100));
        run(&mut rx, &data(2, 2, 0, 7000, &[60]), ms(100));
        let mut e = Vec::new();
        rx.tick(ms(2499), &mut |ev| e.push(ev));
        assert!(values(&e).is_empty());
        rx.tick(ms(2500), &mut |ev| e.push(ev));
        assert_eq!(values(&e), vec![50], "Force_Sync data goes out on sync loss, the other stays frozen");
        let (d, _) = run(&mut rx, &data(1, 3, OPTION_FORCE_SYNC, 7000, &[51]), ms(2600));
        assert_eq!(d, Disposition::Applied);
        let (d, _) = run(&mut rx, &data(2, 3, 0, 7000, &[61]), ms(2600));
        assert_eq!(d, Disposition::Held);
        let (_, e) = run(&mut rx, &build_sync(&[9; 16], 2, 7000), ms(2700));
        assert_eq!(values(&e), vec![61]);
    }

    #[test]
    fn sync_addresses_expire_so_a_new_desk_synchronises_after_junk() {
        let t = Instant::now();
        let ms = |n| t + Duration::from_millis(n);
        let mut rx = SacnReceiver::new(SacnReceiverConfig::default());
        // 64 junk sync addresses fill the table.
        for (i, s) in (1000..1064u16).enumerate() {
            let d = data(1, i as u8, 0, s, &[1]);
            assert_eq!(run(&mut rx, &d, t).0, Disposition::Applied);
        }
        assert_eq!(rx.sync_addresses(), 64);
        // A new desk with sync address 7000 while the table is full: not tracked,
        // its sync packet is unused and its data is never held (no synchronisation).
        assert_eq!(run(&mut rx, &data(2, 1, 0, 7000, &[10]), ms(1000)).0, Disposition::Applied);
        assert!(!rx.tracks_sync_address(7000));
        assert_eq!(
            run(&mut rx, &build_sync(&[9; 16], 1, 7000), ms(1001)).0,
            Disposition::Ignored(IgnoreReason::SyncUnused)
        );
        assert_eq!(run(&mut rx, &data(2, 2, 0, 7000, &[11]), ms(1002)).0, Disposition::Applied);
        // Nothing names the junk addresses for 2.5 s: the timer forgets them.
        rx.tick(ms(2499), &mut |_| {});
        assert_eq!(rx.sync_addresses(), 64);
        rx.tick(ms(2500), &mut |_| {});
        assert_eq!(rx.sync_addresses(), 0);
        // Now the desk synchronises: first data tracks 7000, the sync packet
        // starts holding, data waits for the next sync packet.
        assert_eq!(run(&mut rx, &data(2, 3, 0, 7000, &[12]), ms(2600)).0, Disposition::Applied);
        assert!(rx.tracks_sync_address(7000));
        assert_eq!(run(&mut rx, &build_sync(&[9; 16], 2, 7000), ms(2610)).0, Disposition::Control);
        let (d, e) = run(&mut rx, &data(2, 4, 0, 7000, &[13]), ms(2620));
        assert_eq!((d, values(&e)), (Disposition::Held, vec![]));
        let (_, e) = run(&mut rx, &build_sync(&[9; 16], 3, 7000), ms(2630));
        assert_eq!(values(&e), vec![13]);
        // A full table also makes room by itself when a new address arrives
        // after the old ones went unused (no tick in between).
        for (i, s) in (2000..2063u16).enumerate() {
            run(&mut rx, &data(3, i as u8, 0, s, &[1]), ms(3000));
        }
        assert_eq!(rx.sync_addresses(), 64);
        assert_eq!(run(&mut rx, &data(4, 1, 0, 7100, &[1]), ms(5600)).0, Disposition::Applied);
        assert!(rx.tracks_sync_address(7100));
    }

    #[test]
    fn data_carries_the_source_name() {
        let t = Instant::now();
        let mut rx = SacnReceiver::new(SacnReceiverConfig::default());
        let (_, e) = run(&mut rx, &data(1, 1, 0, 0, &[5]), t);
        match &e[0].kind {
            EventKind::Levels { name, .. } => assert_eq!(name.to_text(), "t"),
            other => panic!("{other:?}"),
        }
    }
}
