//! sACN (ANSI E1.31-2018) input: [`packet`] is the codec, [`receiver`] the
//! receive rules (per-CID sequence, termination, preview, priority,
//! synchronisation) with an injected clock, [`node`] the socket and its
//! multicast memberships.
//!
//! Parsed by hand rather than with the `sacn` crate: that crate (0.11) lacks
//! Force_Sync, a START-code filter and merging of unsynchronised data, and
//! surfaces out-of-order packets as errors (shared/notes/protocols.md §2).

pub mod node;
pub mod packet;
pub mod receiver;

pub use node::{SacnConfig, SacnNode, multicast_group};
pub use packet::{DataPacket, PORT, SacnError, SacnPacket, SyncPacket};
pub use receiver::{SacnHandled, SacnReceiver, SacnReceiverConfig};
