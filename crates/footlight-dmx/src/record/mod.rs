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
//! recorded clock: `now` = replay start + (packet time - first DMX packet
//! time). USB Pro frames (by their comment) re-enter as the widget's source.
//! [`replay`] paces packets in real time (or `speed` times faster);
//! [`state_at`] computes the merged universes at a time without waiting.

mod pcapng;
mod reader;

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
use crate::merge::UniverseFrame;
use crate::net::TICK;
use crate::sacn::{self, SacnReceiver, SacnReceiverConfig};
use crate::source::{Disposition, EventKind, IgnoreReason, InputUniverse, Levels, Protocol, SourceEvent, SourceId};
use crate::stats::{Stats, StatsHandle};
use crate::usbpro::receiver::{self as usb, ReceiveMode};

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
    first: Option<Duration>,
    last: Option<Duration>,
}

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

impl Recording {
    /// Opens a pcap or pcapng file and scans it once (streaming) for its DMX
    /// packets and time span.
    pub fn open(path: impl AsRef<Path>) -> Result<Recording, Error> {
        let path = path.as_ref().to_path_buf();
        let mut recording = Recording { path, dmx_packets: 0, first: None, last: None };
        let mut reader = recording.reader()?;
        while let Some(frame) = reader.next_frame().map_err(|e| recording.capture_error(e))? {
            if udp_datagram(&frame).and_then(|d| classify(d.payload)).is_some() {
                recording.dmx_packets += 1;
                recording.first.get_or_insert(frame.timestamp);
                recording.last = Some(frame.timestamp);
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

    /// Art-Net and sACN packets in the file.
    pub fn dmx_packets(&self) -> usize {
        self.dmx_packets
    }

    /// From the first to the last DMX packet.
    pub fn duration(&self) -> Duration {
        match (self.first, self.last) {
            (Some(a), Some(b)) => b.saturating_sub(a),
            _ => Duration::ZERO,
        }
    }

    /// Wall-clock time of the first DMX packet.
    pub fn started_at(&self) -> Option<SystemTime> {
        self.first.map(|d| UNIX_EPOCH + d)
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
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions { speed: 1.0, start: Duration::ZERO, patch: InputPatch::default() }
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
    base: Instant,
    first: Option<Duration>,
    last_tick: Instant,
    events: Vec<SourceEvent>,
}

impl Player {
    fn new(patch: &InputPatch, base: Instant) -> Self {
        let stats = StatsHandle::new();
        let artnet_filter = patch.map.filter(Protocol::ArtNet, &patch.universes);
        let sacn_filter = patch.map.filter(Protocol::Sacn, &patch.universes);
        Player {
            artnet: ArtNetReceiver::new(ArtNetReceiverConfig { filter: artnet_filter, ..Default::default() }),
            sacn: SacnReceiver::new(SacnReceiverConfig { filter: sacn_filter, ..Default::default() }),
            stage: MergeStage::new(patch, stats.clone()),
            stats,
            base,
            first: None,
            last_tick: base,
            events: Vec::new(),
        }
    }

    /// The recorded time of a frame on the replay clock.
    fn now_of(&mut self, timestamp: Duration) -> Instant {
        let first = *self.first.get_or_insert(timestamp);
        self.base + timestamp.saturating_sub(first)
    }

    /// Runs timers if due: receivers every [`TICK`] (as live nodes do), merge timeouts.
    fn advance(&mut self, now: Instant, sink: &mut impl FnMut(&UniverseFrame)) {
        if now >= self.last_tick + TICK {
            self.tick(now, sink);
        } else if self.stage.merge.next_deadline().is_some_and(|d| d <= now) {
            self.stage.merge.expire(now, &mut *sink);
        }
    }

    /// Runs all timers at `now`.
    fn tick(&mut self, now: Instant, sink: &mut impl FnMut(&UniverseFrame)) {
        self.last_tick = now;
        let events = &mut self.events;
        self.artnet.tick(now, &mut |e| events.push(e));
        self.sacn.tick(now, &mut |e| events.push(e));
        self.flush_events(sink);
        self.stage.merge.expire(now, &mut *sink);
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
        let usb = comment.and_then(|c| c.strip_prefix(USB_COMMENT)).and_then(|rest| {
            let (widget, changes_only) = match rest.strip_suffix(USB_CHANGES_ONLY) {
                Some(w) => (w, true),
                None => (rest, false),
            };
            widget.parse::<u8>().ok().map(|w| (w, changes_only))
        });
        match (classify(datagram.payload), usb) {
            (Some(Protocol::ArtNet), Some((widget, changes_only))) => {
                let source = SourceId::UsbPro { widget };
                let d = match artnet::packet::parse(datagram.payload) {
                    Ok(artnet::ArtPacket::Dmx(dmx)) => {
                        let timeout = (!changes_only).then_some(usb::SOURCE_TIMEOUT);
                        let kind =
                            EventKind::Levels { priority: usb::PRIORITY, timeout, levels: Levels::new(dmx.data) };
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
            }
            (Some(Protocol::Sacn), _) => {
                let h = self.sacn.handle(datagram.payload, from, now, &mut |e| events.push(e));
                self.stats.lock().packet(Protocol::Sacn, h.source, peer, &h.disposition);
            }
            _ => return,
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
    let mut reader = recording.reader()?;
    let started = Instant::now();
    let mut player = Player::new(&options.patch, started);
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
            let wait = offset.saturating_sub(options.start).div_f64(options.speed);
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

/// The merged universes `t` after the first DMX packet of `recording`, as
/// live input would have had them then (for `footlight render --dmx FILE --at T`).
pub fn state_at(recording: &Recording, t: Duration, patch: &InputPatch) -> Result<Vec<UniverseFrame>, Error> {
    let mut reader = recording.reader()?;
    let base = Instant::now();
    let mut player = Player::new(patch, base);
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
