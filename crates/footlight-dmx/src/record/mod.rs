//! Record what arrives to pcapng; replay pcap/pcapng captures through the
//! same receivers and merge.
//!
//! Recording taps the nodes: every datagram as received (valid or not, with
//! its arrival time) and every USB Pro level frame, written as an ArtDmx
//! (Port-Address = widget index) in a synthetic IPv4/UDP packet from
//! 0.0.0.0:6454 to 255.255.255.255:6454 with the packet comment
//! `footlight-dmx usbpro widget=N`. Wireshark and tshark open the file.
//!
//! Replay reads our files and captures made by tcpdump/Wireshark (Ethernet,
//! Linux cooked, loopback or raw-IP link types; IPv4 UDP), recognises Art-Net
//! and sACN by their headers (any port), and feeds them through
//! [`ArtNetReceiver`]/[`SacnReceiver`] and [`Merge`](crate::Merge) with the
//! recorded clock: `now` = replay start + (packet time - time 0), where time 0
//! is the first DMX data packet of a patched universe after routing
//! ([`Recording::start_for`]; OLA's leading ArtPoll/ArtPollReply do not count). USB Pro frames (by their comment) re-enter as the widget's source.
//! [`replay`] paces packets in real time (or `speed` times faster);
//! [`state_at`] computes the merged universes at a time without waiting.

mod pcapng;
mod reader;

use std::collections::BTreeMap;
use std::fs::File;
use std::future::Future;
use std::io::{BufReader, BufWriter};
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tokio::sync::mpsc;
use tokio::time::Instant;

pub use pcapng::PcapngWriter;
pub use reader::{CaptureError, CaptureReader, Datagram, Frame, link, udp_datagram};

use crate::artnet::{self, ArtNetReceiver, ArtNetReceiverConfig};
use crate::error::Error;
use crate::input::{DmxInput, InputConfig, InputPatch, MergeStage};
use crate::map::UniverseMap;
use crate::merge::UniverseFrame;
use crate::net::TICK;
use crate::sacn::{self, SacnReceiver, SacnReceiverConfig};
use crate::source::{
    Disposition, EventKind, IgnoreReason, InputUniverse, Levels, Protocol, SourceEvent, SourceId, SourceName,
};
use crate::stats::{Stats, StatsHandle};
use crate::status::{self, StatusHandle};
use crate::usbpro::receiver::{self as usb, ReceiveMode};

/// Latest time `state_at` looks at (a century; keeps `Instant` arithmetic in range).
const MAX_STATE_AT: Duration = Duration::from_secs(100 * 365 * 24 * 3600);

/// Comment prefix that marks a synthetic ArtDmx as a USB Pro frame; the
/// widget index follows, then ` changes-only` for label 9 mode.
const USB_COMMENT: &str = "footlight-dmx usbpro widget=";
const USB_CHANGES_ONLY: &str = " changes-only";

/// One packet for the recorder.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Captured {
    /// Arrival time.
    pub at: Instant,
    /// Sender.
    pub from: SocketAddr,
    /// Our socket (0.0.0.0 when bound to the wildcard).
    pub to: SocketAddr,
    /// UDP payload.
    pub payload: Vec<u8>,
    /// The pcapng packet comment (marks USB Pro frames).
    pub comment: Option<String>,
}

/// The nodes' side of a recording: a bounded queue that never blocks input
/// (a full queue loses the packet and counts it).
#[derive(Clone, Debug)]
pub struct Tap {
    tx: mpsc::Sender<Captured>,
    lost: Arc<AtomicU64>,
}

/// The recorder's side of a [`Tap`].
#[derive(Debug)]
pub struct Captures {
    rx: mpsc::Receiver<Captured>,
    lost: Arc<AtomicU64>,
}

impl Captures {
    /// The next packet; `None` once every tap is dropped (all nodes stopped).
    pub async fn recv(&mut self) -> Option<Captured> {
        self.rx.recv().await
    }

    /// [`Self::recv`] for a blocking thread.
    pub fn blocking_recv(&mut self) -> Option<Captured> {
        self.rx.blocking_recv()
    }

    /// Packets lost because the recorder fell behind.
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }
}

impl Tap {
    /// A tap and the receiving end the recorder reads.
    pub fn new(capacity: usize) -> (Tap, Captures) {
        let (tx, rx) = mpsc::channel(capacity.max(1));
        let lost = Arc::new(AtomicU64::new(0));
        (Tap { tx, lost: Arc::clone(&lost) }, Captures { rx, lost })
    }

    fn push(&self, captured: Captured) {
        if self.tx.try_send(captured).is_err() {
            self.lost.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Captures a datagram.
    pub fn datagram(&self, at: Instant, from: SocketAddr, to: SocketAddr, payload: &[u8]) {
        self.push(Captured { at, from, to, payload: payload.to_vec(), comment: None });
    }

    /// Captures a USB Pro level frame as an ArtDmx.
    pub fn usb_frame(&self, at: Instant, widget: u8, mode: ReceiveMode, levels: &Levels) {
        // ArtDmx carries at least 2 slots.
        let data = &levels.slots()[..levels.len().max(2)];
        let payload = artnet::packet::build_dmx(0, 0, u16::from(widget), data);
        let from = SocketAddr::from(([0, 0, 0, 0], artnet::PORT));
        let to = SocketAddr::from(([255, 255, 255, 255], artnet::PORT));
        let mode = if mode == ReceiveMode::ChangesOnly { USB_CHANGES_ONLY } else { "" };
        self.push(Captured { at, from, to, payload, comment: Some(format!("{USB_COMMENT}{widget}{mode}")) });
    }
}

/// What a recording wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RecordSummary {
    /// Packets written.
    pub packets: u64,
    /// Packets lost because the writer fell behind.
    pub lost: u64,
    /// From the first to the last packet written.
    pub duration: Duration,
}

fn v4(addr: SocketAddr) -> SocketAddrV4 {
    match addr {
        SocketAddr::V4(a) => a,
        SocketAddr::V6(a) => SocketAddrV4::new(a.ip().to_ipv4_mapped().unwrap_or(Ipv4Addr::UNSPECIFIED), a.port()),
    }
}

/// Records every packet the configured inputs receive to a pcapng file at
/// `out`, until `shutdown` resolves. Binds like [`DmxInput::bind`].
pub async fn record(
    out: &Path,
    config: InputConfig,
    shutdown: impl Future<Output = ()>,
) -> Result<RecordSummary, Error> {
    record_input(out, DmxInput::bind(config).await?, shutdown).await
}

/// [`record()`] with an input bound by the caller, who may subscribe to its
/// frames and counters first (to show them while recording).
pub async fn record_input(
    out: &Path,
    mut input: DmxInput,
    shutdown: impl Future<Output = ()>,
) -> Result<RecordSummary, Error> {
    let file_err = |source| Error::File { path: out.to_path_buf(), source };
    let captures = input.capture(8192);
    let file = File::create(out).map_err(file_err)?;
    let writer = PcapngWriter::new(BufWriter::new(file)).map_err(file_err)?;
    let clock = (Instant::now(), SystemTime::now());
    tracing::info!(path = %out.display(), "recording DMX input");
    let writing = tokio::task::spawn_blocking(move || write_captures(writer, captures, clock));
    input.run(shutdown).await?;
    let summary = writing.await.map_err(|e| file_err(std::io::Error::other(e)))?.map_err(file_err)?;
    tracing::info!(path = %out.display(), packets = summary.packets, lost = summary.lost, "recording closed");
    Ok(summary)
}

/// The writer thread: drains the tap until every node has dropped it.
fn write_captures(
    mut writer: PcapngWriter<BufWriter<File>>,
    mut captures: Captures,
    (instant0, wall0): (Instant, SystemTime),
) -> std::io::Result<RecordSummary> {
    let wall0 = wall0.duration_since(UNIX_EPOCH).unwrap_or_default();
    let mut summary = RecordSummary::default();
    let (mut first, mut last_flush) = (None, std::time::Instant::now());
    while let Some(c) = captures.blocking_recv() {
        // Wall time = start time + (arrival - start) on the monotonic clock.
        let ts =
            (wall0 + c.at.saturating_duration_since(instant0)).saturating_sub(instant0.saturating_duration_since(c.at));
        writer.write_udp(ts, v4(c.from), v4(c.to), &c.payload, c.comment.as_deref())?;
        summary.packets += 1;
        summary.duration = ts.saturating_sub(*first.get_or_insert(ts));
        if last_flush.elapsed() >= Duration::from_secs(1) {
            writer.flush()?;
            last_flush = std::time::Instant::now();
        }
    }
    writer.flush()?;
    summary.lost = captures.lost();
    Ok(summary)
}

/// A capture file to replay.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Recording {
    path: PathBuf,
    dmx_packets: usize,
    /// First and last DMX data packet (any universe).
    first: Option<Duration>,
    last: Option<Duration>,
    /// Per input universe: its first DMX data packet and how many it holds.
    inputs: BTreeMap<InputUniverse, (Duration, u64)>,
    /// More input universes than [`MAX_SCANNED_INPUTS`] held data.
    inputs_overflow: bool,
}

/// Input universes [`Recording::open`] notes one by one.
const MAX_SCANNED_INPUTS: usize = 4096;

/// What a UDP payload is.
fn classify(payload: &[u8]) -> Option<Protocol> {
    if payload.starts_with(artnet::packet::ID) {
        Some(Protocol::ArtNet)
    } else if payload.len() >= 16 && payload[..2] == [0x00, 0x10] && &payload[4..16] == sacn::packet::ACN_ID {
        Some(Protocol::Sacn)
    } else {
        None
    }
}

/// The widget of a USB Pro frame recorded as ArtDmx (by its packet comment),
/// and whether it was in changes-only mode.
fn usb_widget(comment: Option<&str>) -> Option<(u8, bool)> {
    let rest = comment?.strip_prefix(USB_COMMENT)?;
    let (widget, changes_only) = match rest.strip_suffix(USB_CHANGES_ONLY) {
        Some(w) => (w, true),
        None => (rest, false),
    };
    widget.parse::<u8>().ok().map(|w| (w, changes_only))
}

/// The input universe of a DMX *data* packet: an ArtDmx, or E1.31 data with
/// START code 0 (not preview, not a termination). Control packets (ArtPoll,
/// ArtPollReply, ArtTodRequest, ArtSync, E1.31 sync and discovery, …) are not data.
pub fn dmx_data_input(payload: &[u8], comment: Option<&str>) -> Option<InputUniverse> {
    match classify(payload)? {
        Protocol::ArtNet => match artnet::packet::parse(payload) {
            Ok(artnet::ArtPacket::Dmx(d)) => Some(match usb_widget(comment) {
                Some((widget, _)) => InputUniverse::UsbPro(widget),
                None => InputUniverse::ArtNet(d.port_address),
            }),
            _ => None,
        },
        Protocol::Sacn => match sacn::packet::parse(payload) {
            Ok(sacn::SacnPacket::Data(d)) if d.start_code == 0 && !d.preview() && !d.terminated() => {
                Some(InputUniverse::Sacn(d.universe))
            }
            _ => None,
        },
        Protocol::UsbPro => None,
    }
}

impl Recording {
    /// Opens a pcap or pcapng file and scans it once (streaming) for its DMX
    /// data packets, their input universes and time span.
    pub fn open(path: impl AsRef<Path>) -> Result<Recording, Error> {
        let path = path.as_ref().to_path_buf();
        let mut recording = Recording {
            path,
            dmx_packets: 0,
            first: None,
            last: None,
            inputs: BTreeMap::new(),
            inputs_overflow: false,
        };
        let mut reader = recording.reader()?;
        while let Some(frame) = reader.next_frame().map_err(|e| recording.capture_error(e))? {
            let Some(d) = udp_datagram(&frame) else { continue };
            let Some(input) = dmx_data_input(d.payload, frame.comment) else { continue };
            recording.dmx_packets += 1;
            recording.first.get_or_insert(frame.timestamp);
            recording.last = Some(frame.timestamp);
            let full = recording.inputs.len() >= MAX_SCANNED_INPUTS;
            match recording.inputs.get_mut(&input) {
                Some((_, n)) => *n += 1,
                None if full => recording.inputs_overflow = true,
                None => {
                    recording.inputs.insert(input, (frame.timestamp, 1));
                }
            }
        }
        Ok(recording)
    }

    fn capture_error(&self, source: CaptureError) -> Error {
        Error::Capture { path: self.path.clone(), source }
    }

    fn reader(&self) -> Result<CaptureReader<BufReader<File>>, Error> {
        let file = File::open(&self.path).map_err(|source| Error::File { path: self.path.clone(), source })?;
        CaptureReader::new(BufReader::new(file)).map_err(|e| self.capture_error(e))
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// DMX data packets in the file (ArtDmx, E1.31 data with START code 0).
    pub fn dmx_packets(&self) -> usize {
        self.dmx_packets
    }

    /// The input universes holding DMX data, with their packet counts (the
    /// first 4096 universes).
    pub fn inputs(&self) -> impl Iterator<Item = (InputUniverse, u64)> + '_ {
        self.inputs.iter().map(|(i, (_, n))| (*i, *n))
    }

    /// From the first to the last DMX data packet.
    pub fn duration(&self) -> Duration {
        match (self.first, self.last) {
            (Some(a), Some(b)) => b.saturating_sub(a),
            _ => Duration::ZERO,
        }
    }

    /// Wall-clock time of the first DMX data packet.
    pub fn started_at(&self) -> Option<SystemTime> {
        self.first.map(|d| UNIX_EPOCH + d)
    }

    /// Time 0 of a replay with `patch`: the capture time of the first DMX data
    /// packet of a patched universe (after routing). Fails, naming the input
    /// universes the file holds, when none of its data reaches the patch.
    pub fn start_for(&self, patch: &InputPatch) -> Result<Duration, Error> {
        let patched = status::patched_filter(patch);
        let takes = |input: InputUniverse| patch.map.patch_universe(input).is_some_and(|u| patched.accepts(u));
        let found = self.inputs.iter().filter(|(i, _)| takes(**i)).map(|(_, (first, _))| *first).min();
        if let Some(first) = found {
            return Ok(first);
        }
        if self.inputs_overflow {
            // Universes past the scan's list: look through the file.
            let mut reader = self.reader()?;
            while let Some(frame) = reader.next_frame().map_err(|e| self.capture_error(e))? {
                let input = udp_datagram(&frame).and_then(|d| dmx_data_input(d.payload, frame.comment));
                if input.is_some_and(takes) {
                    return Ok(frame.timestamp);
                }
            }
        }
        Err(Error::NoPatchedDmx { path: self.path.clone(), holds: self.holds(patch) })
    }

    /// "holds …" text for [`Error::NoPatchedDmx`].
    fn holds(&self, patch: &InputPatch) -> String {
        if self.inputs.is_empty() {
            return "it holds no DMX data at all (no ArtDmx, no E1.31 data with START code 0)".into();
        }
        let mut list: Vec<String> = self
            .inputs
            .iter()
            .take(8)
            .map(|(i, (_, n))| {
                let default = UniverseMap::default_route(*i).map(|p| format!(", patch universe {p} by default"));
                let plural = if *n == 1 { "" } else { "s" };
                format!("{i} ({n} packet{plural}{})", default.unwrap_or_default())
            })
            .collect();
        if self.inputs.len() > 8 || self.inputs_overflow {
            list.push(format!("and {} more", self.inputs.len().saturating_sub(8).max(1)));
        }
        let patched = if patch.universes.is_empty() {
            "any patch universe".to_string()
        } else {
            let u: Vec<String> = patch.universes.iter().map(u16::to_string).collect();
            format!("patch universes {}", u.join(", "))
        };
        format!(
            "none of its DMX reaches {patched}; it holds {}; route them with [[input]] in the patch",
            list.join(", ")
        )
    }
}

/// How to replay.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplayOptions {
    /// 1.0 = real time, 2.0 = twice as fast, `f64::INFINITY` = no waiting.
    pub speed: f64,
    /// Start this far into the recording (the state there is sent first).
    pub start: Duration,
    /// Mapping, universes (empty: all) and merge policy.
    pub patch: InputPatch,
    /// Where the replay reports its status and counters, as a live input
    /// does (reset when the replay starts). Keep a clone to read it.
    pub status: StatusHandle,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions { speed: 1.0, start: Duration::ZERO, patch: InputPatch::default(), status: StatusHandle::new() }
    }
}

/// What a replay did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReplaySummary {
    /// DMX packets fed to the receivers.
    pub packets: u64,
    /// Counters, as for live input.
    pub stats: Stats,
    /// Whether the shutdown future stopped it early.
    pub interrupted: bool,
}

/// The receivers and merge of a replay, driven by the recorded clock.
struct Player {
    artnet: ArtNetReceiver,
    sacn: SacnReceiver,
    stage: MergeStage,
    stats: StatsHandle,
    status: StatusHandle,
    base: Instant,
    /// Capture time of the first patched DMX data packet: replay time 0.
    first: Duration,
    last_tick: Instant,
    events: Vec<SourceEvent>,
}

impl Player {
    fn new(patch: &InputPatch, base: Instant, first: Duration, status: StatusHandle) -> Self {
        let artnet_filter = patch.map.filter(Protocol::ArtNet, &patch.universes);
        let sacn_filter = patch.map.filter(Protocol::Sacn, &patch.universes);
        Player {
            artnet: ArtNetReceiver::new(ArtNetReceiverConfig { filter: artnet_filter, ..Default::default() }),
            sacn: SacnReceiver::new(SacnReceiverConfig { filter: sacn_filter, ..Default::default() }),
            stage: MergeStage::new(patch, status.clone()),
            stats: status.stats(),
            status,
            base,
            first,
            last_tick: base,
            events: Vec::new(),
        }
    }

    /// The recorded time of a frame on the replay clock (packets before time
    /// 0, such as OLA's ArtPoll and ArtPollReply, count as time 0).
    fn now_of(&self, timestamp: Duration) -> Instant {
        self.base + timestamp.saturating_sub(self.first)
    }

    /// Runs timers if due: receivers every [`TICK`] (as live nodes do), merge timeouts.
    fn advance(&mut self, now: Instant, sink: &mut impl FnMut(&UniverseFrame)) {
        if now >= self.last_tick + TICK {
            self.tick(now, sink);
        } else if self.stage.merge.next_deadline().is_some_and(|d| d <= now) {
            self.stage.expire(now, &mut *sink);
        }
    }

    /// Runs all timers at `now`.
    fn tick(&mut self, now: Instant, sink: &mut impl FnMut(&UniverseFrame)) {
        self.last_tick = now;
        let events = &mut self.events;
        self.artnet.tick(now, &mut |e| events.push(e));
        self.sacn.tick(now, &mut |e| events.push(e));
        self.flush_events(sink);
        self.stage.expire(now, &mut *sink);
    }

    fn flush_events(&mut self, sink: &mut impl FnMut(&UniverseFrame)) {
        for event in self.events.drain(..) {
            if let Some(frame) = self.stage.apply(&event) {
                sink(frame);
            }
        }
    }

    /// Feeds one DMX datagram recorded at `now`.
    fn feed(
        &mut self,
        datagram: &Datagram<'_>,
        comment: Option<&str>,
        now: Instant,
        sink: &mut impl FnMut(&UniverseFrame),
    ) {
        self.advance(now, sink);
        let from = SocketAddr::V4(datagram.from);
        let peer = Some(from.ip());
        let events = &mut self.events;
        let mut unpatched = None;
        match (classify(datagram.payload), usb_widget(comment)) {
            (Some(Protocol::ArtNet), Some((widget, changes_only))) => {
                let source = SourceId::UsbPro { widget };
                let d = match artnet::packet::parse(datagram.payload) {
                    Ok(artnet::ArtPacket::Dmx(dmx)) => {
                        let timeout = (!changes_only).then_some(usb::SOURCE_TIMEOUT);
                        let levels = Levels::new(dmx.data);
                        let name = SourceName::default();
                        let kind = EventKind::Levels { priority: usb::PRIORITY, timeout, levels, name };
                        events.push(SourceEvent { at: now, input: InputUniverse::UsbPro(widget), source, kind });
                        Disposition::Applied
                    }
                    Ok(other) => Disposition::Ignored(IgnoreReason::Unsupported(other.opcode())),
                    Err(e) => Disposition::Malformed(e),
                };
                self.stats.lock().packet(Protocol::UsbPro, Some(source), None, &d);
            }
            (Some(Protocol::ArtNet), None) => {
                let h = self.artnet.handle(datagram.payload, from, now, &mut |e| events.push(e));
                self.stats.lock().packet(Protocol::ArtNet, h.source, peer, &h.disposition);
                if h.disposition == Disposition::Ignored(IgnoreReason::NotPatched) {
                    unpatched = h.input;
                }
            }
            (Some(Protocol::Sacn), _) => {
                let h = self.sacn.handle(datagram.payload, from, now, &mut |e| events.push(e));
                self.stats.lock().packet(Protocol::Sacn, h.source, peer, &h.disposition);
                if h.disposition == Disposition::Ignored(IgnoreReason::NotPatched) {
                    unpatched = h.input;
                }
            }
            _ => return,
        }
        if let Some(input) = unpatched {
            self.status.not_patched(input, now);
        }
        self.flush_events(sink);
    }
}

/// Replays `recording` into `sink` (called with every merged frame that
/// changes), pacing packets at `options.speed` from `options.start`, until
/// the end of the file or `shutdown`.
pub async fn replay(
    recording: &Recording,
    options: &ReplayOptions,
    mut sink: impl FnMut(&UniverseFrame),
    shutdown: impl Future<Output = ()>,
) -> Result<ReplaySummary, Error> {
    if options.speed.is_nan() || options.speed <= 0.0 {
        return Err(Error::Config(format!("replay speed must be above 0, got {}", options.speed)));
    }
    let first = recording.start_for(&options.patch)?;
    let mut reader = recording.reader()?;
    let started = Instant::now();
    let mut player = Player::new(&options.patch, started, first, options.status.clone());
    let mut summary = ReplaySummary::default();
    let mut skipping = !options.start.is_zero();
    tokio::pin!(shutdown);
    while let Some(frame) = reader.next_frame().map_err(|e| recording.capture_error(e))? {
        let Some(datagram) = udp_datagram(&frame).filter(|d| classify(d.payload).is_some()) else { continue };
        let now = player.now_of(frame.timestamp);
        let offset = now - started;
        if skipping && offset >= options.start {
            // Jumped: hand over the state at the start time, then play on.
            skipping = false;
            player.tick(started + options.start, &mut |_| {});
            player.stage.merge.frames().for_each(&mut sink);
        }
        if !skipping && options.speed.is_finite() {
            // A tiny speed must not overflow Duration or Instant: wait at most a century.
            let wait = Duration::try_from_secs_f64(offset.saturating_sub(options.start).as_secs_f64() / options.speed)
                .unwrap_or(MAX_STATE_AT)
                .min(MAX_STATE_AT);
            tokio::select! {
                biased;
                () = &mut shutdown => {
                    summary.interrupted = true;
                    break;
                }
                () = tokio::time::sleep_until(started + wait) => {}
            }
        }
        summary.packets += 1;
        if skipping {
            player.feed(&datagram, frame.comment, now, &mut |_| {});
        } else {
            player.feed(&datagram, frame.comment, now, &mut sink);
        }
    }
    if skipping {
        player.tick(started + options.start, &mut |_| {});
        player.stage.merge.frames().for_each(&mut sink);
    }
    summary.stats = player.stats.snapshot();
    Ok(summary)
}

/// The merged universes `t` after the first DMX data packet of a patched
/// universe in `recording` ([`Recording::start_for`]), as live input would
/// have had them then (for `footlight render --dmx FILE --at T`). A recording
/// with no DMX for the patch is an error naming the universes it holds.
pub fn state_at(recording: &Recording, t: Duration, patch: &InputPatch) -> Result<Vec<UniverseFrame>, Error> {
    let first = recording.start_for(patch)?;
    let mut reader = recording.reader()?;
    let base = Instant::now();
    let t = t.min(MAX_STATE_AT);
    let mut player = Player::new(patch, base, first, StatusHandle::new());
    while let Some(frame) = reader.next_frame().map_err(|e| recording.capture_error(e))? {
        let Some(datagram) = udp_datagram(&frame).filter(|d| classify(d.payload).is_some()) else { continue };
        let now = player.now_of(frame.timestamp);
        if now > base + t {
            break;
        }
        player.feed(&datagram, frame.comment, now, &mut |_| {});
    }
    player.tick(base + t, &mut |_| {});
    Ok(player.stage.merge.frames().cloned().collect())
}
