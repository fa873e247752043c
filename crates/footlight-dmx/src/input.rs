//! [`DmxInput`]: runs the configured nodes as tokio tasks, merges what they
//! report and publishes the latest frame of every patch universe.
//!
//! ```no_run
//! # async fn demo() -> Result<(), footlight_dmx::Error> {
//! use footlight_dmx::{DmxInput, InputConfig};
//! let input = DmxInput::bind(InputConfig::default()).await?; // 0.0.0.0:6454 and :5568
//! let mut frames = input.frames();
//! tokio::spawn(input.run(async { tokio::signal::ctrl_c().await.ok(); }));
//! while frames.changed().await.is_ok() {
//!     let latest = frames.borrow_and_update().clone(); // copy out, release the lock
//!     if let Some(u1) = latest.get(1) { println!("dimmer at 1: {}", u1.slots[0]); }
//! }
//! # Ok(()) }
//! ```
//!
//! Tasks: one per node (Art-Net, sACN, USB Pro on a blocking thread) and the
//! merge stage in [`DmxInput::run`] itself. Nodes send [`SourceEvent`]s over a
//! bounded mpsc channel (1024 events; a full queue makes a node wait, so the
//! kernel's socket buffer absorbs bursts rather than memory). The merge stage
//! is the only owner of [`Merge`], so it needs no lock.
//!
//! Why `tokio::sync::watch` for the output: the renderer wants the newest
//! state, not every intermediate frame, and must never slow the input down.
//! A watch keeps one value, overwritten in place ([`watch::Sender::send_modify`],
//! no allocation per packet) and readers see only the latest. A broadcast
//! channel was rejected: a slow reader would lag and lose frames in a queue
//! it then has to drain. Readers should copy what they need and drop the
//! borrow at once (the input takes the write lock for each update).
//!
//! Shutdown is an argument (mini-redis): when it resolves, the nodes get a
//! stop signal, `run` waits for all of them, and returns.

use std::collections::BTreeMap;
use std::future::Future;
use std::net::SocketAddr;

use tokio::sync::{mpsc, watch};
use tokio::task::JoinSet;
use tokio::time::Instant;

use crate::artnet::{ArtNetConfig, ArtNetNode, ArtNetReceiverConfig};
use crate::error::Error;
use crate::map::{UniverseFilter, UniverseMap};
use crate::merge::{Merge, MergeConfig, SlotMask, UniverseFrame};
use crate::net::{self, LogLimiter, NodeContext};
use crate::record::{Captures, Tap};
use crate::sacn::{SacnConfig, SacnNode, SacnReceiverConfig};
use crate::source::{EventKind, Protocol, SourceEvent};
use crate::stats::StatsHandle;
use crate::status::{self, StatusHandle};
use crate::usbpro::{UsbProConfig, UsbProNode};

/// Events queued between the nodes and the merge stage.
const EVENT_QUEUE: usize = 1024;

/// What the patch tells the DMX input (live or replayed).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct InputPatch {
    /// Input universe → patch universe.
    pub map: UniverseMap,
    /// Patch universes in use. The input universes routed to them decide the
    /// sACN groups joined and the Art-Net Port-Addresses announced; data for
    /// any other patch universe is dropped as not patched (counted, shown in
    /// the status, logged). Empty: accept every mapped universe, join no
    /// group, announce Port-Address 0.
    pub universes: Vec<u16>,
    /// Slots that merge LTP, per patch universe (the rest merge HTP).
    pub ltp: BTreeMap<u16, SlotMask>,
    /// Merge limits.
    pub merge: MergeConfig,
}

/// Which inputs run, and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputConfig {
    /// Art-Net (`None`: off).
    pub artnet: Option<ArtNetConfig>,
    /// sACN (`None`: off).
    pub sacn: Option<SacnConfig>,
    /// An Enttec USB Pro (`None`: none).
    pub usbpro: Option<UsbProConfig>,
    /// Mapping, universes and merge policy.
    pub patch: InputPatch,
}

impl Default for InputConfig {
    /// Art-Net on 0.0.0.0:6454 and sACN on 0.0.0.0:5568 for patch universe 1.
    fn default() -> Self {
        InputConfig {
            artnet: Some(ArtNetConfig::default()),
            sacn: Some(SacnConfig::default()),
            usbpro: None,
            patch: InputPatch { universes: vec![1], ..InputPatch::default() },
        }
    }
}

/// The latest merged frame of every patch universe that has had a source.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Universes {
    /// Sorted by universe number.
    frames: Vec<UniverseFrame>,
}

impl Universes {
    /// The frame of `universe` (1-based).
    pub fn get(&self, universe: u16) -> Option<&UniverseFrame> {
        let i = self.frames.binary_search_by_key(&universe, |f| f.universe).ok()?;
        Some(&self.frames[i])
    }

    /// All frames by universe number.
    pub fn iter(&self) -> impl Iterator<Item = &UniverseFrame> {
        self.frames.iter()
    }

    /// How many universes.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True before any DMX arrived.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Stores `frame` in place (allocates only for a new universe).
    pub fn update(&mut self, frame: &UniverseFrame) {
        match self.frames.binary_search_by_key(&frame.universe, |f| f.universe) {
            Ok(i) => self.frames[i].clone_from(frame),
            Err(i) => self.frames.insert(i, frame.clone()),
        }
    }
}

/// Events → patch universes → merge, with counting and the status board.
/// Shared by the live input and replay so both merge (and report) the same way.
pub(crate) struct MergeStage {
    map: UniverseMap,
    /// The patch universes taken (all when the patch lists none).
    patched: UniverseFilter,
    pub(crate) merge: Merge,
    stats: StatsHandle,
    status: StatusHandle,
    refused_log: LogLimiter,
    /// Universes whose sources timed out in one `expire` (reused, no allocation).
    expired: Vec<u16>,
}

impl MergeStage {
    /// A stage for `patch` reporting into `status` (reset for this patch).
    pub(crate) fn new(patch: &InputPatch, status: StatusHandle) -> Self {
        status.configure(patch);
        let mut merge = Merge::new(patch.merge);
        for (&u, mask) in &patch.ltp {
            merge.set_ltp(u, mask.clone());
        }
        MergeStage {
            map: patch.map.clone(),
            patched: status::patched_filter(patch),
            merge,
            stats: status.stats(),
            status,
            refused_log: LogLimiter::new(),
            expired: Vec::new(),
        }
    }

    /// Applies one event; returns the frame it changed.
    pub(crate) fn apply(&mut self, event: &SourceEvent) -> Option<&UniverseFrame> {
        let (source, at) = (event.source, event.at);
        let patched = self.map.patch_universe(event.input).filter(|&u| self.patched.accepts(u));
        let Some(universe) = patched else {
            if matches!(event.kind, EventKind::Levels { .. }) {
                self.stats.lock().not_patched(source);
                self.status.not_patched(event.input, at);
            }
            return None;
        };
        match &event.kind {
            EventKind::Levels { priority, timeout, levels, name } => {
                match self.merge.apply(universe, source, *priority, *timeout, levels, at) {
                    Ok(frame) => {
                        self.stats.lock().applied(source);
                        self.status.lock().levels(universe, (source, event.input), *priority, name, at);
                        Some(frame)
                    }
                    Err(e) => {
                        self.stats.lock().merge_dropped(source);
                        if let Some(suppressed) = self.refused_log.allow(at) {
                            tracing::warn!(%source, suppressed, "merge refused levels: {e}");
                        }
                        None
                    }
                }
            }
            EventKind::Alive => {
                self.merge.keep_alive(universe, source, at);
                self.status.lock().alive(universe, source, at);
                None
            }
            EventKind::Gone => {
                let frame = self.merge.remove(universe, source, at)?;
                self.status.lock().left(universe, frame.stale, self.merge.source_ids(universe));
                self.merge.frame(universe)
            }
        }
    }

    /// Drops sources whose timeout has passed; calls `changed` with each frame that changed.
    pub(crate) fn expire(&mut self, now: Instant, mut changed: impl FnMut(&UniverseFrame)) {
        let mut expired = std::mem::take(&mut self.expired);
        expired.clear();
        self.merge.expire(now, |f| expired.push(f.universe));
        for &u in &expired {
            if let Some(frame) = self.merge.frame(u) {
                changed(frame);
                self.status.lock().left(u, frame.stale, self.merge.source_ids(u));
            }
        }
        self.expired = expired;
    }
}

/// Where the sockets ended up (useful after binding port 0).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LocalAddrs {
    /// The Art-Net socket, if on.
    pub artnet: Option<SocketAddr>,
    /// The sACN socket, if on.
    pub sacn: Option<SocketAddr>,
}

/// The DMX input: bound sockets and nodes, ready to [`run`](Self::run).
pub struct DmxInput {
    artnet: Option<ArtNetNode>,
    sacn: Option<SacnNode>,
    usbpro: Option<UsbProNode>,
    stage: MergeStage,
    frames: watch::Sender<Universes>,
    status: StatusHandle,
    tap: Option<Tap>,
    local: LocalAddrs,
}

impl DmxInput {
    /// Binds the sockets and prepares the nodes (inside a tokio runtime).
    /// Fails if a socket cannot be bound; a missing USB Pro is not an error
    /// (the node keeps trying to open it).
    pub async fn bind(config: InputConfig) -> Result<DmxInput, Error> {
        let patch = &config.patch;
        if let Some(0) = patch.universes.iter().copied().min() {
            return Err(Error::Config("patch universes count from 1".into()));
        }
        let status = StatusHandle::new();
        let mut local = LocalAddrs::default();
        // The Port-Addresses to announce and the sACN groups to join: the
        // input universes routed to patched universes.
        let inputs = |protocol| patch.map.input_universes(protocol, &patch.universes);
        let artnet = match &config.artnet {
            None => None,
            Some(c) => {
                let socket = net::into_tokio(Protocol::ArtNet, c.bind, net::bind_udp(Protocol::ArtNet, c.bind)?)?;
                local.artnet = socket.local_addr().ok();
                let filter = patch.map.filter(Protocol::ArtNet, &patch.universes);
                let receiver = ArtNetReceiverConfig { filter, ..ArtNetReceiverConfig::default() };
                Some(ArtNetNode::new(socket, c.clone(), receiver, inputs(Protocol::ArtNet)))
            }
        };
        let sacn = match &config.sacn {
            None => None,
            Some(c) => {
                let socket = net::into_tokio(Protocol::Sacn, c.bind, net::bind_udp(Protocol::Sacn, c.bind)?)?;
                local.sacn = socket.local_addr().ok();
                let filter = patch.map.filter(Protocol::Sacn, &patch.universes);
                let receiver = SacnReceiverConfig { filter, ..SacnReceiverConfig::default() };
                Some(SacnNode::new(socket, c, receiver, &inputs(Protocol::Sacn)))
            }
        };
        let usbpro = config.usbpro.clone().map(UsbProNode::new);
        Ok(DmxInput {
            artnet,
            sacn,
            usbpro,
            stage: MergeStage::new(patch, status.clone()),
            frames: watch::Sender::new(Universes::default()),
            status,
            tap: None,
            local,
        })
    }

    /// Replaces the USB Pro node (e.g. one with an injected port for tests).
    pub fn with_usbpro(mut self, node: UsbProNode) -> Self {
        self.usbpro = Some(node);
        self
    }

    /// A receiver of the latest merged frames.
    pub fn frames(&self) -> watch::Receiver<Universes> {
        self.frames.subscribe()
    }

    /// The packet counters.
    pub fn stats(&self) -> StatsHandle {
        self.status.stats()
    }

    /// The typed status (per patch universe, unpatched data, counters); the
    /// handle keeps working after [`Self::run`] consumed the input.
    pub fn status(&self) -> StatusHandle {
        self.status.clone()
    }

    /// The Port-Addresses each ArtPollReply announces (reply `i` has
    /// BindIndex `i + 1`); empty when Art-Net is off.
    pub fn announced_ports(&self) -> Vec<Vec<u16>> {
        self.artnet.as_ref().map(|n| n.announced().to_vec()).unwrap_or_default()
    }

    /// The sACN universes whose multicast groups were joined; empty when sACN
    /// or multicast is off.
    pub fn joined_groups(&self) -> Vec<u16> {
        self.sacn.as_ref().map(SacnNode::joined).unwrap_or_default()
    }

    /// Where the sockets are bound.
    pub fn local_addrs(&self) -> LocalAddrs {
        self.local
    }

    /// Starts capturing every received datagram and USB Pro frame (for
    /// [`crate::record()`]); `capacity` packets queue before new ones are lost.
    pub fn capture(&mut self, capacity: usize) -> Captures {
        let (tap, rx) = Tap::new(capacity);
        self.tap = Some(tap);
        rx
    }

    /// Runs until `shutdown` resolves, then stops every node and returns.
    pub async fn run(self, shutdown: impl Future<Output = ()>) -> Result<(), Error> {
        let DmxInput { artnet, sacn, usbpro, mut stage, frames, status, tap, .. } = self;
        let (events, mut rx) = mpsc::channel(EVENT_QUEUE);
        let (stop, stopped) = watch::channel(false);
        let stop_signal = move || {
            let mut stopped = stopped.clone();
            async move {
                let _ = stopped.wait_for(|s| *s).await;
            }
        };
        let ctx = NodeContext { events, stats: status.stats(), status, tap };
        let mut nodes = JoinSet::new();
        if let Some(node) = artnet {
            nodes.spawn(node.run(ctx.clone(), stop_signal()));
        }
        if let Some(node) = sacn {
            nodes.spawn(node.run(ctx.clone(), stop_signal()));
        }
        if let Some(node) = usbpro {
            nodes.spawn(node.run(ctx.clone(), stop_signal()));
        }
        // Only the nodes hold senders now: `rx` closes when they have all stopped.
        drop(ctx);
        tokio::pin!(shutdown);
        loop {
            let deadline = stage.merge.next_deadline();
            tokio::select! {
                biased;
                () = &mut shutdown => break,
                // Timeouts before events, so a flood cannot starve them.
                () = sleep_until(deadline) => {
                    stage.expire(Instant::now(), |f| frames.send_modify(|u| u.update(f)));
                }
                event = rx.recv() => match event {
                    Some(event) => {
                        if let Some(frame) = stage.apply(&event) {
                            frames.send_modify(|u| u.update(frame));
                        }
                    }
                    None => break,
                },
            }
        }
        let _ = stop.send(true);
        while let Some(result) = nodes.join_next().await {
            if let Err(e) = result {
                tracing::error!(%e, "DMX input node panicked");
            }
        }
        Ok(())
    }
}

/// Sleeps until `deadline`, or forever without one.
pub(crate) async fn sleep_until(deadline: Option<Instant>) {
    match deadline {
        Some(d) => tokio::time::sleep_until(d).await,
        None => std::future::pending().await,
    }
}
