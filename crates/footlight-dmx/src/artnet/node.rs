//! The Art-Net node: a bound UDP socket, the [`ArtNetReceiver`], ArtPollReply.
//!
//! Controllers poll every 2.5-3 s and send ArtDmx by unicast only to nodes
//! whose reply lists the universe, so the reply matters: one ArtPollReply per
//! port (Art-Net 4, BindIndex 1..n), each naming one output Port-Address,
//! Style = visualiser, sent by unicast to the poller's IP at port 6454 after a
//! random 0-1 s delay (spec: spreads replies of large rigs). Nothing is sent
//! unsolicited (DESIGN.md "Sockets").

use std::future::Future;
use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::time::Duration;

use tokio::net::UdpSocket;
use tokio::time::Instant;

use super::packet::{self, ArtNetError, ArtPoll, PollReplyInfo};
use super::receiver::{ArtNetReceiver, ArtNetReceiverConfig};
use crate::net::{self, DatagramProtocol, NodeContext, Tally};
use crate::source::{Protocol, SourceEvent};

/// Art-Net node settings.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ArtNetConfig {
    /// Where to bind (default `0.0.0.0:6454`; a NIC address misses broadcasts on Linux).
    pub bind: SocketAddr,
    /// ArtPollReply ShortName (17 characters kept).
    pub short_name: String,
    /// ArtPollReply LongName (63 characters kept).
    pub long_name: String,
    /// Upper bound of the random delay before an ArtPollReply (spec: up to 1 s).
    pub reply_delay_max: Duration,
    /// Destination port of ArtPollReply (the spec says 6454; only tests change it).
    pub reply_port: u16,
}

impl Default for ArtNetConfig {
    fn default() -> Self {
        ArtNetConfig {
            bind: SocketAddr::from(([0, 0, 0, 0], packet::PORT)),
            short_name: "Footlight".into(),
            long_name: "Footlight stage lighting visualiser".into(),
            reply_delay_max: Duration::from_secs(1),
            reply_port: packet::PORT,
        }
    }
}

/// Most Port-Addresses announced (one ArtPollReply each).
const MAX_REPLY_PORTS: usize = 64;
/// Most polls waiting for their delayed reply.
const MAX_PENDING: usize = 16;

struct PendingReply {
    due: Instant,
    poller: IpAddr,
    poll: ArtPoll,
}

/// The protocol half the shared UDP loop drives.
struct ArtNetProtocol {
    receiver: ArtNetReceiver,
    config: ArtNetConfig,
    /// Port-Addresses announced in ArtPollReply.
    ports: Vec<u16>,
    /// The bound IP, if not the wildcard.
    bound_ip: Option<Ipv4Addr>,
    pending: Vec<PendingReply>,
    replies_sent: u32,
    /// xorshift64 state for the reply delay (no cryptographic need).
    rng: u64,
}

impl ArtNetProtocol {
    fn random_delay(&mut self) -> Duration {
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        let max = self.config.reply_delay_max.as_micros() as u64;
        Duration::from_micros(if max == 0 { 0 } else { self.rng % (max + 1) })
    }

    fn send_replies(&mut self, reply: &PendingReply, now: Instant, socket: &UdpSocket) {
        let ip = match self.bound_ip.or_else(|| match net::local_ip_towards(reply.poller) {
            Some(IpAddr::V4(ip)) => Some(ip),
            _ => None,
        }) {
            Some(ip) => ip,
            None => return tracing::debug!(poller = %reply.poller, "no IPv4 route to the poller; no ArtPollReply"),
        };
        let ports = self.ports.iter().filter(|&&p| reply.poll.target.is_none_or(|t| t.contains(p)));
        let mut sent = 0;
        for (i, &port_address) in ports.enumerate() {
            let status = self.receiver.port_status(port_address, now);
            let good_output = if status.data { 0x80 } else { 0 } | if status.merging { 0x08 } else { 0 };
            self.replies_sent = self.replies_sent.wrapping_add(1);
            let info = PollReplyInfo {
                ip,
                mac: [0; 6],
                short_name: &self.config.short_name,
                long_name: &self.config.long_name,
                report: "Footlight receiving",
                report_count: self.replies_sent,
                port_address,
                bind_index: (i + 1) as u8,
                good_output,
            };
            let bytes = packet::build_poll_reply(&info);
            let to = SocketAddr::new(reply.poller, self.config.reply_port);
            match socket.try_send_to(&bytes, to) {
                Ok(_) => sent += 1,
                Err(e) => tracing::debug!(%to, %e, "ArtPollReply not sent"),
            }
        }
        tracing::debug!(poller = %reply.poller, sent, "ArtPollReply");
    }
}

impl DatagramProtocol for ArtNetProtocol {
    const PROTOCOL: Protocol = Protocol::ArtNet;
    type Error = ArtNetError;

    fn datagram(
        &mut self,
        data: &[u8],
        from: SocketAddr,
        now: Instant,
        events: &mut Vec<SourceEvent>,
        _socket: &UdpSocket,
    ) -> Tally<ArtNetError> {
        let handled = self.receiver.handle(data, from, now, &mut |e| events.push(e));
        if let Some(poll) = handled.poll {
            if self.pending.len() < MAX_PENDING {
                let due = now + self.random_delay();
                self.pending.push(PendingReply { due, poller: from.ip(), poll });
            } else {
                tracing::debug!(%from, "ArtPoll flood: reply skipped");
            }
        }
        Tally { source: handled.source, disposition: handled.disposition }
    }

    fn tick(&mut self, now: Instant, events: &mut Vec<SourceEvent>, socket: &UdpSocket) {
        self.receiver.tick(now, &mut |e| events.push(e));
        let mut i = 0;
        while i < self.pending.len() {
            if self.pending[i].due <= now {
                let reply = self.pending.swap_remove(i);
                self.send_replies(&reply, now, socket);
            } else {
                i += 1;
            }
        }
    }
}

/// A running Art-Net input on one socket.
pub struct ArtNetNode {
    socket: UdpSocket,
    protocol: ArtNetProtocol,
}

impl ArtNetNode {
    /// A node on an already bound socket. `ports` are the Port-Addresses the
    /// ArtPollReply announces (the first 64; Port-Address 0 if empty).
    pub fn new(socket: UdpSocket, config: ArtNetConfig, receiver: ArtNetReceiverConfig, ports: Vec<u16>) -> Self {
        let mut ports: Vec<u16> = ports.into_iter().filter(|p| *p <= 0x7FFF).take(MAX_REPLY_PORTS).collect();
        if ports.is_empty() {
            ports.push(0);
        }
        let bound_ip = match socket.local_addr() {
            Ok(SocketAddr::V4(a)) if !a.ip().is_unspecified() => Some(*a.ip()),
            _ => None,
        };
        let seed =
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(1, |d| d.as_nanos() as u64);
        let protocol = ArtNetProtocol {
            receiver: ArtNetReceiver::new(receiver),
            config,
            ports,
            bound_ip,
            pending: Vec::new(),
            replies_sent: 0,
            rng: seed | 1,
        };
        ArtNetNode { socket, protocol }
    }

    /// The address the socket is bound to.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Receives until `shutdown` resolves or `ctx.events` closes.
    pub async fn run(self, ctx: NodeContext, shutdown: impl Future<Output = ()>) {
        net::run_datagram_node(self.socket, self.protocol, ctx, shutdown).await;
    }
}
