//! DMX input for Footlight: Art-Net 4, sACN (ANSI E1.31-2018) and the Enttec
//! DMX USB Pro, merged per patch universe into [`UniverseFrame`]s, plus
//! recording to pcapng and replay of pcap/pcapng captures.
//!
//! The crate knows nothing about the renderer (STYLE.md §15). It is layered
//! like OLA (STYLE.md §6-9): each protocol is a pure codec (bytes → typed
//! packet, or a malformed value; never a panic), a sans-IO receiver that
//! applies the protocol's rules (sequence, sync, priority, termination) with an
//! injected `now`, and a node that owns the socket or serial port and its
//! timers. Nodes emit [`SourceEvent`]s; [`Merge`] turns them into frames with
//! HTP/LTP and priority, knowing nothing about sockets.
//!
//! ```text
//!  UDP 6454 ──ArtNetNode──┐
//!  UDP 5568 ──SacnNode────┼─ SourceEvent ─> UniverseMap ─> Merge ─> watch<Universes> ─> patch
//!  serial ────UsbProNode──┘   (mpsc)         (input →       (HTP/LTP,     (latest frame per
//!        └──────── tap ──> record (pcapng)     patch univ.)   priority)     patch universe)
//!  pcap/pcapng ──replay: same receivers, same merge, recorded clock
//! ```
//!
//! # Layout (in data-flow order)
//! - [`source`]: what every node emits (source ids, input universes, levels, events, dispositions).
//! - [`artnet`]: Art-Net 4 codec, receiver (sequence, 2-source rule, ArtSync) and node (ArtPollReply).
//! - [`sacn`]: E1.31 codec, receiver (per-CID sequence, termination, preview, sync) and node (multicast).
//! - [`usbpro`]: Enttec DMX USB Pro framing codec, receiver (labels 5 and 9) and serial node (reconnects).
//! - [`map`]: which input universe feeds which patch universe (Art-Net N-1 and sACN N → patch N).
//! - [`merge`]: per patch universe and slot: priority, HTP/LTP, timeouts, stale hold.
//! - [`stats`]: received/applied/malformed/dropped/ignored counters per protocol and source.
//! - [`status`]: the typed status ([`InputStatus`]): per patch universe its routes, sources,
//!   packets, age and staleness; data on unpatched universes (logged, rate-limited).
//! - [`input`]: [`DmxInput`] runs the nodes as tokio tasks and publishes merged frames.
//! - [`record`](mod@record): pcapng writer, pcap/pcapng reader, [`record()`], [`replay`], [`state_at`].
//! - `net` (private): sockets bound with SO_REUSEADDR/SO_REUSEPORT, and the loop both UDP nodes share.
//!
//! Errors: [`Error`] covers what stops a caller (a socket that cannot be
//! bound, a capture that cannot be read). A bad packet is never an `Error`: it
//! is a value ([`Disposition::Malformed`]) that nodes count and log.
#![deny(missing_docs)]

pub mod artnet;
mod error;
pub mod input;
pub mod map;
pub mod merge;
mod net;
pub mod record;
pub mod sacn;
pub mod source;
pub mod stats;
pub mod status;
pub mod usbpro;

pub use error::Error;
pub use input::{DmxInput, InputConfig, InputPatch, LocalAddrs, Universes};
pub use map::{UniverseFilter, UniverseMap};
pub use merge::{Merge, MergeConfig, SlotMask, UniverseFrame};
pub use net::NodeContext;
pub use record::{Recording, ReplayOptions, ReplaySummary, record, record_input, replay, state_at};
pub use source::{Disposition, InputUniverse, Levels, Protocol, SLOTS, SourceEvent, SourceId, SourceName};
pub use stats::{Counters, Stats, StatsHandle};
pub use status::{FeedState, InputRef, InputStatus, SourceStatus, StatusHandle, UniverseStatus, UnpatchedStatus};
