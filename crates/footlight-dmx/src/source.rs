//! What every protocol node emits: source-level events (OLA's `DmxSource`).
//!
//! A node turns datagrams or serial frames into [`SourceEvent`]s: "source S
//! sent these levels for input universe U at priority P", "S is still there
//! (data held for sync)", "S has gone". The merge (via [`crate::UniverseMap`])
//! turns them into patch-universe frames. Every packet a receiver handles also
//! gets a [`Disposition`], which the node counts in [`crate::Stats`].

use std::fmt;
use std::net::IpAddr;
use std::time::Duration;

use tokio::time::Instant;

/// Slots in a DMX512 universe (the START code is not counted).
pub const SLOTS: usize = 512;

/// The input protocols. Serialised as `"artnet"`, `"sacn"`, `"usbpro"` (the
/// patch file's `[[input]] protocol` values).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    /// Art-Net 4 over UDP 6454.
    ArtNet,
    /// sACN, ANSI E1.31-2018, over UDP 5568.
    Sacn,
    /// Enttec DMX USB Pro over a serial port.
    UsbPro,
}

impl fmt::Display for Protocol {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Protocol::ArtNet => "Art-Net",
            Protocol::Sacn => "sACN",
            Protocol::UsbPro => "USB Pro",
        })
    }
}

/// Who sent a stream of levels: the unit the merge counts and times out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SourceId {
    /// An Art-Net sender: its IP and the ArtDmx Physical field (one IP with two
    /// Physical values is two sources, as in the Art-Net merge rules).
    ArtNet {
        /// Sender IP address.
        ip: IpAddr,
        /// ArtDmx Physical (the sender's physical input port).
        physical: u8,
    },
    /// An sACN source, by its Component Identifier.
    Sacn {
        /// The 16-byte CID from the root layer.
        cid: [u8; 16],
    },
    /// An Enttec USB Pro widget, by its index in the input configuration.
    UsbPro {
        /// Widget index (0 for the first `--usbpro` port).
        widget: u8,
    },
}

impl SourceId {
    /// The protocol this source speaks.
    pub fn protocol(&self) -> Protocol {
        match self {
            SourceId::ArtNet { .. } => Protocol::ArtNet,
            SourceId::Sacn { .. } => Protocol::Sacn,
            SourceId::UsbPro { .. } => Protocol::UsbPro,
        }
    }
}

impl fmt::Display for SourceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SourceId::ArtNet { ip, physical } => write!(f, "Art-Net {ip} physical {physical}"),
            SourceId::Sacn { cid } => {
                f.write_str("sACN CID ")?;
                cid.iter().try_for_each(|b| write!(f, "{b:02x}"))
            }
            SourceId::UsbPro { widget } => write!(f, "USB Pro widget {widget}"),
        }
    }
}

/// A universe as the protocol numbers it, before [`crate::UniverseMap`] maps
/// it to a patch universe.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum InputUniverse {
    /// Art-Net 15-bit Port-Address (0-32767).
    ArtNet(u16),
    /// sACN universe (1-63999).
    Sacn(u16),
    /// A USB Pro widget's single DMX line, by widget index.
    UsbPro(u8),
}

impl fmt::Display for InputUniverse {
    /// As a user reads it: `Art-Net Port-Address 1`, `sACN universe 101`, `USB Pro widget 0`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            InputUniverse::ArtNet(n) => write!(f, "Art-Net Port-Address {n}"),
            InputUniverse::Sacn(n) => write!(f, "sACN universe {n}"),
            InputUniverse::UsbPro(w) => write!(f, "USB Pro widget {w}"),
        }
    }
}

impl InputUniverse {
    /// The universe number as the protocol counts it (Port-Address, sACN
    /// universe, widget index).
    pub fn number(&self) -> u16 {
        match self {
            InputUniverse::ArtNet(n) | InputUniverse::Sacn(n) => *n,
            InputUniverse::UsbPro(w) => u16::from(*w),
        }
    }

    /// The protocol of this universe.
    pub fn protocol(&self) -> Protocol {
        match self {
            InputUniverse::ArtNet(_) => Protocol::ArtNet,
            InputUniverse::Sacn(_) => Protocol::Sacn,
            InputUniverse::UsbPro(_) => Protocol::UsbPro,
        }
    }
}

/// One universe's slot values as a source sent them: slot 1 is `slots[0]`;
/// slots past `len` (a short frame) are 0. Fixed size so events and held
/// frames never allocate.
#[derive(Clone, PartialEq, Eq)]
pub struct Levels {
    len: u16,
    slots: [u8; SLOTS],
}

impl Levels {
    /// Levels from the slots a packet carried (without START code); more than
    /// 512 are cut off.
    pub fn new(data: &[u8]) -> Self {
        let mut levels = Levels::zero();
        levels.set(data);
        levels
    }

    /// No slots, all zero.
    pub fn zero() -> Self {
        Levels { len: 0, slots: [0; SLOTS] }
    }

    /// Replaces the levels in place (the no-allocation path for held frames).
    pub fn set(&mut self, data: &[u8]) {
        let n = data.len().min(SLOTS);
        self.slots[..n].copy_from_slice(&data[..n]);
        self.slots[n..].fill(0);
        self.len = n as u16;
    }

    /// Sets one slot (0-based index), growing `len` to cover it.
    pub fn set_slot(&mut self, index: usize, value: u8) {
        if index < SLOTS {
            self.slots[index] = value;
            self.len = self.len.max(index as u16 + 1);
        }
    }

    /// How many slots the source sent.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// True when the source sent no slots.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The slots the source sent.
    pub fn as_slice(&self) -> &[u8] {
        &self.slots[..self.len()]
    }

    /// All 512 slots, zero past `len`.
    pub fn slots(&self) -> &[u8; SLOTS] {
        &self.slots
    }
}

impl fmt::Debug for Levels {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let shown = self.len().min(16);
        write!(f, "Levels[{}]{:?}", self.len, &self.slots[..shown])?;
        if self.len() > shown {
            f.write_str("…")?;
        }
        Ok(())
    }
}

/// A source's name as it sent it (the 64-byte E1.31 Source Name; empty for
/// Art-Net and USB Pro). Fixed size so events never allocate.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct SourceName {
    len: u8,
    bytes: [u8; 64],
}

impl Default for SourceName {
    fn default() -> Self {
        SourceName { len: 0, bytes: [0; 64] }
    }
}

impl SourceName {
    /// The name in a NUL-terminated field (cut at the first NUL, at most 64 bytes).
    pub fn new(field: &[u8]) -> Self {
        let field = &field[..field.len().min(64)];
        let len = field.iter().position(|&b| b == 0).unwrap_or(field.len());
        let mut name = SourceName { len: len as u8, bytes: [0; 64] };
        name.bytes[..len].copy_from_slice(&field[..len]);
        name
    }

    /// The raw bytes.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }

    /// True when the source sent no name.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The name as text (invalid UTF-8 replaced).
    pub fn to_text(&self) -> String {
        String::from_utf8_lossy(self.as_bytes()).into_owned()
    }
}

impl fmt::Debug for SourceName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&self.to_text(), f)
    }
}

/// One thing a node tells the merge.
#[derive(Clone, Debug)]
pub struct SourceEvent {
    /// When it happened (the packet's arrival, or the sync that released it).
    pub at: Instant,
    /// The universe as the protocol numbers it.
    pub input: InputUniverse,
    /// Who sent it.
    pub source: SourceId,
    /// What happened.
    pub kind: EventKind,
}

/// What a [`SourceEvent`] says.
// The Levels variant is ~520 bytes inline on purpose: events travel through a
// bounded channel by value, and boxing would allocate once per packet.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum EventKind {
    /// New levels to merge.
    Levels {
        /// sACN priority 0-200; Art-Net and USB Pro count as 100.
        priority: u8,
        /// How long the merge keeps this source without news (`None`: until
        /// it says it has gone).
        timeout: Option<Duration>,
        /// The slot values.
        levels: Levels,
        /// The source's name (sACN), for the status.
        name: SourceName,
    },
    /// The source is alive but its data is held (waiting for a sync).
    Alive,
    /// The source has left this universe (sACN Stream_Terminated, a USB
    /// widget unplugged).
    Gone,
}

/// What a receiver did with one packet, for the counters and the log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Disposition<E> {
    /// Levels were emitted to the merge now.
    Applied,
    /// Levels are held for a synchronisation packet.
    Held,
    /// A control packet was acted on (ArtPoll, ArtSync, E1.31 sync or
    /// termination, USB Pro parameters).
    Control,
    /// A valid packet we do not use.
    Ignored(IgnoreReason),
    /// A valid packet we discarded by a protocol rule.
    Dropped(DropReason),
    /// Bytes that are not a valid packet.
    Malformed(E),
}

impl<E> Disposition<E> {
    /// Maps the malformed value (e.g. to a common type for the counters).
    pub fn map_err<F>(self, f: impl FnOnce(E) -> F) -> Disposition<F> {
        match self {
            Disposition::Applied => Disposition::Applied,
            Disposition::Held => Disposition::Held,
            Disposition::Control => Disposition::Control,
            Disposition::Ignored(r) => Disposition::Ignored(r),
            Disposition::Dropped(r) => Disposition::Dropped(r),
            Disposition::Malformed(e) => Disposition::Malformed(f(e)),
        }
    }
}

/// Why a valid packet was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IgnoreReason {
    /// An Art-Net OpCode we do not serve (ArtIpProg, ArtAddress, ArtNzs,
    /// TimeCode, RDM, firmware, other nodes' ArtPollReply, …).
    Unsupported(u16),
    /// A universe no patch universe wants.
    NotPatched,
    /// sACN Preview_Data (for visualisers' preview, not live output).
    Preview,
    /// A START code other than 0 (e.g. 0xDD per-slot priority, 0xCC RDM).
    StartCode(u8),
    /// sACN universe discovery.
    Discovery,
    /// An ArtSync from another IP than the last ArtDmx, or while merging.
    SyncNotApplicable,
    /// An E1.31 sync packet for address 0 or for an address no held data uses.
    SyncUnused,
    /// A USB Pro message label we do not use (replies to requests we did not send).
    Label(u8),
}

/// Why a valid packet was discarded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DropReason {
    /// Its sequence number is in the (-20, 0] window behind the last one.
    OutOfOrder,
    /// More sources than the receiver tracks (Art-Net: a third sender on a
    /// Port-Address; sACN: the stream table is full).
    SourcesExceeded,
    /// USB Pro reported a receive-queue overflow or overrun for this frame.
    WidgetOverrun,
}

/// E1.31 6.7.2 / OLA: a sequence number is stale when `(i8)(new - last)` is in
/// (-20, 0]. The signed 8-bit difference makes 255 → 0 a step forward.
pub fn sequence_is_stale(last: u8, new: u8) -> bool {
    let d = new.wrapping_sub(last) as i8;
    d <= 0 && d > -20
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_window_uses_signed_difference() {
        assert!(!sequence_is_stale(10, 11));
        assert!(sequence_is_stale(10, 10));
        assert!(sequence_is_stale(10, 9));
        assert!(sequence_is_stale(10, 250)); // -16
        assert!(!sequence_is_stale(10, 246)); // -20: far enough back to be a restart
        assert!(!sequence_is_stale(255, 0)); // wrap is +1
        assert!(!sequence_is_stale(250, 3)); // wrap is +9
        assert!(sequence_is_stale(3, 250)); // -9 across the wrap
    }

    #[test]
    fn levels_zero_past_len_and_cut_at_512() {
        let l = Levels::new(&[1, 2, 3]);
        assert_eq!(l.len(), 3);
        assert_eq!(l.slots()[..4], [1, 2, 3, 0]);
        let long = Levels::new(&[7; 600]);
        assert_eq!(long.len(), 512);
        let mut m = Levels::zero();
        m.set_slot(9, 5);
        assert_eq!((m.len(), m.as_slice()[9]), (10, 5));
        m.set_slot(512, 1);
        assert_eq!(m.len(), 10);
    }
}
