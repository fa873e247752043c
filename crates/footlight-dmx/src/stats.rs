//! Packet counters per protocol and per source, for the status page.
//!
//! Nodes count what they receive and what their receiver did with it; the
//! merge stage counts what reached the merge ("applied") and what the merge
//! refused. A malformed packet has no trustworthy source id, so it is counted
//! per protocol and per sender IP ([`Stats::malformed_peers`]).
//!
//! Why a `std::sync::Mutex` and not atomics or a channel: every update touches
//! a protocol counter and a map entry together, the lock is held for a few
//! nanoseconds and never across an `.await`, and a reader wants one consistent
//! snapshot. Both maps are capped ([`MAX_TRACKED`]) so a flood of fake sources
//! cannot grow memory; past the cap only the protocol counters move.

use std::collections::BTreeMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex, MutexGuard};

use crate::source::{Disposition, Protocol, SourceId};

/// Most sources (and most malformed-packet peers) tracked individually.
pub const MAX_TRACKED: usize = 256;

/// One set of packet counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counters {
    /// Datagrams or serial frames read.
    pub received: u64,
    /// Level frames that reached the merge.
    pub applied: u64,
    /// Bytes that were not a valid packet.
    pub malformed: u64,
    /// Valid packets discarded by a rule (stale sequence, too many sources,
    /// widget overrun, merge limits).
    pub dropped: u64,
    /// Valid packets we do not use (other OpCodes, preview, other START
    /// codes, unpatched or blocked universes).
    pub ignored: u64,
}

/// What the kernel did with one UDP socket: its receive buffer and the
/// datagrams it dropped because that buffer was full (the receive task fell
/// behind). Read from the socket and, on Linux, `/proc/net/udp`'s `drops`
/// column once a second ([`crate::net`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SocketCounters {
    /// The receive buffer the kernel granted, in bytes of kernel memory.
    pub recv_buffer_bytes: u64,
    /// The receive buffer asked for (64 universes at 44 Hz for one second).
    pub recv_buffer_wanted: u64,
    /// Datagrams the kernel dropped on this socket since it was opened
    /// (`None` where the platform does not tell).
    pub kernel_drops: Option<u64>,
}

/// All counters.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Art-Net totals.
    pub artnet: Counters,
    /// sACN totals.
    pub sacn: Counters,
    /// USB Pro totals.
    pub usbpro: Counters,
    /// Per source (at most [`MAX_TRACKED`]).
    pub sources: BTreeMap<SourceId, Counters>,
    /// Malformed packets per sending IP (at most [`MAX_TRACKED`]).
    pub malformed_peers: BTreeMap<IpAddr, u64>,
    /// The Art-Net socket's buffer and kernel drops (`None`: no socket).
    pub artnet_socket: Option<SocketCounters>,
    /// The sACN socket's buffer and kernel drops (`None`: no socket).
    pub sacn_socket: Option<SocketCounters>,
}

impl Stats {
    /// The totals of one protocol.
    pub fn protocol(&self, protocol: Protocol) -> &Counters {
        match protocol {
            Protocol::ArtNet => &self.artnet,
            Protocol::Sacn => &self.sacn,
            Protocol::UsbPro => &self.usbpro,
        }
    }

    fn protocol_mut(&mut self, protocol: Protocol) -> &mut Counters {
        match protocol {
            Protocol::ArtNet => &mut self.artnet,
            Protocol::Sacn => &mut self.sacn,
            Protocol::UsbPro => &mut self.usbpro,
        }
    }

    /// The socket counters of a UDP protocol (`None` for USB Pro).
    pub fn socket_mut(&mut self, protocol: Protocol) -> Option<&mut Option<SocketCounters>> {
        match protocol {
            Protocol::ArtNet => Some(&mut self.artnet_socket),
            Protocol::Sacn => Some(&mut self.sacn_socket),
            Protocol::UsbPro => None,
        }
    }

    /// Updates the protocol counter and, if known and room is left, the
    /// source's counter.
    fn bump(&mut self, protocol: Protocol, source: Option<SourceId>, f: impl Fn(&mut Counters)) {
        f(self.protocol_mut(protocol));
        if let Some(id) = source {
            let len = self.sources.len();
            if let Some(c) = self.sources.get_mut(&id) {
                f(c);
            } else if len < MAX_TRACKED {
                f(self.sources.entry(id).or_default());
            }
        }
    }

    /// Counts one received packet and its disposition. `Applied`/`Held`/
    /// `Control` add only to `received`: "applied" is counted when the merge
    /// takes the levels ([`Stats::applied`]).
    pub fn packet<E>(
        &mut self,
        protocol: Protocol,
        source: Option<SourceId>,
        peer: Option<IpAddr>,
        disposition: &Disposition<E>,
    ) {
        self.bump(protocol, source, |c| {
            c.received += 1;
            match disposition {
                Disposition::Malformed(_) => c.malformed += 1,
                Disposition::Dropped(_) => c.dropped += 1,
                Disposition::Ignored(_) => c.ignored += 1,
                Disposition::Applied | Disposition::Held | Disposition::Control => {}
            }
        });
        if let (Disposition::Malformed(_), Some(ip)) = (disposition, peer) {
            let len = self.malformed_peers.len();
            if let Some(n) = self.malformed_peers.get_mut(&ip) {
                *n += 1;
            } else if len < MAX_TRACKED {
                self.malformed_peers.insert(ip, 1);
            }
        }
    }

    /// Counts levels the merge took.
    pub fn applied(&mut self, source: SourceId) {
        self.bump(source.protocol(), Some(source), |c| c.applied += 1);
    }

    /// Counts levels the merge refused (limits).
    pub fn merge_dropped(&mut self, source: SourceId) {
        self.bump(source.protocol(), Some(source), |c| c.dropped += 1);
    }

    /// Counts levels that reached the merge stage but no patch universe takes
    /// (as ignored, like a receiver's unpatched universes).
    pub fn not_patched(&mut self, source: SourceId) {
        self.bump(source.protocol(), Some(source), |c| c.ignored += 1);
    }
}

/// A shared handle to the counters (cheap to clone).
#[derive(Clone, Debug, Default)]
pub struct StatsHandle(Arc<Mutex<Stats>>);

impl StatsHandle {
    /// New, all counters zero.
    pub fn new() -> Self {
        Self::default()
    }

    /// A consistent copy of all counters.
    pub fn snapshot(&self) -> Stats {
        self.lock().clone()
    }

    /// Locks for an update. A poisoned lock (a panic elsewhere while holding
    /// it) still holds valid counters, so it is used as is.
    pub fn lock(&self) -> MutexGuard<'_, Stats> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}
