//! Art-Net 4 input: [`packet`] is the codec, [`receiver`] the receive rules
//! (sequence, two-source limit, ArtSync) with an injected clock, [`node`] the
//! socket, timers and ArtPollReply.
//!
//! Served: ArtDmx (0x5000), ArtPoll (0x2000, answered by unicast to the
//! poller's IP at port 6454), ArtSync (0x5200). Everything else with a valid
//! header (ArtIpProg, ArtAddress, ArtNzs, TimeCode, RDM, firmware, other
//! nodes' ArtPollReply, …) is ignored with a debug log and counted.

pub mod node;
pub mod packet;
pub mod receiver;

pub use node::{ArtNetConfig, ArtNetNode};
pub use packet::{ArtDmx, ArtNetError, ArtPacket, ArtPoll, PORT};
pub use receiver::{ArtNetHandled, ArtNetReceiver, ArtNetReceiverConfig};
