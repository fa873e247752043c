//! The sACN node: a bound UDP socket, its multicast memberships, the
//! [`SacnReceiver`].
//!
//! Universe U is multicast to 239.255.{U >> 8}.{U & 0xFF}. The node joins the
//! groups of the patched universes at start and the group of each sync
//! address when data first names it (sync packets are sent to the sync
//! universe's group). Unicast to the bound port is accepted too, and the
//! universe field, not the group, decides where data goes.
//!
//! Linux allows 20 memberships per socket (`net.ipv4.igmp_max_memberships`).
//! Past that the node joins on extra, otherwise unused sockets: with Linux's
//! default IP_MULTICAST_ALL the receiving socket still gets every group the
//! host has joined on its port.

use std::collections::{BTreeMap, BTreeSet};
use std::future::Future;
use std::io;
use std::net::{Ipv4Addr, SocketAddr};

use socket2::{Domain, SockRef, Socket, Type};
use tokio::net::UdpSocket;
use tokio::time::Instant;

use super::packet::{self, SacnError};
use super::receiver::{SacnReceiver, SacnReceiverConfig};
use crate::net::{self, DatagramProtocol, NodeContext, Tally};
use crate::source::{Disposition, IgnoreReason, Protocol, SourceEvent};

/// sACN node settings.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SacnConfig {
    /// Where to bind (default `0.0.0.0:5568`).
    pub bind: SocketAddr,
    /// Join the multicast groups of the patched universes (off: unicast only).
    pub multicast: bool,
    /// The address of the network card to join the multicast groups on
    /// (`--sacn-iface`; `0.0.0.0`: the kernel's choice, the card of the
    /// default route). On a machine with several cards set it to the card on
    /// the show network, and keep `bind` at `0.0.0.0:5568`.
    pub interface: Ipv4Addr,
}

impl Default for SacnConfig {
    fn default() -> Self {
        SacnConfig {
            bind: SocketAddr::from(([0, 0, 0, 0], packet::PORT)),
            multicast: true,
            interface: Ipv4Addr::UNSPECIFIED,
        }
    }
}

/// The multicast group of an sACN universe.
pub fn multicast_group(universe: u16) -> Ipv4Addr {
    let [hi, lo] = universe.to_be_bytes();
    Ipv4Addr::new(239, 255, hi, lo)
}

/// Most sync universes joined at run time.
const MAX_RUNTIME_JOINS: usize = 64;

/// Group memberships of one receiving socket.
struct Memberships {
    interface: Ipv4Addr,
    /// Joined groups by universe: `None` on the receiving socket, `Some(i)` on helper `i`.
    joined: BTreeMap<u16, Option<usize>>,
    /// The patched universes' groups (kept for the node's life).
    fixed: BTreeSet<u16>,
    /// Most groups joined: the patched universes plus [`MAX_RUNTIME_JOINS`].
    limit: usize,
    /// Extra sockets holding memberships past the per-socket limit.
    helpers: Vec<Socket>,
}

impl Memberships {
    fn join(&mut self, socket: &UdpSocket, universe: u16) {
        if self.joined.contains_key(&universe) || self.joined.len() >= self.limit {
            return;
        }
        let group = multicast_group(universe);
        let result = match SockRef::from(socket).join_multicast_v4(&group, &self.interface) {
            Ok(()) => Ok(None),
            Err(first) => {
                tracing::debug!(%group, %first, "joining on a helper socket");
                self.join_on_helper(&group).map(Some)
            }
        };
        match result {
            Ok(at) => {
                self.joined.insert(universe, at);
                tracing::debug!(universe, %group, interface = %self.interface, "joined sACN multicast group");
            }
            Err(e) => tracing::warn!(
                "cannot join the sACN multicast group {group} (universe {universe}) on interface {}: {e}; \
                 unicast still works",
                self.interface
            ),
        }
    }

    fn join_on_helper(&mut self, group: &Ipv4Addr) -> io::Result<usize> {
        if let Some(h) = self.helpers.last()
            && h.join_multicast_v4(group, &self.interface).is_ok()
        {
            return Ok(self.helpers.len() - 1);
        }
        let h = Socket::new(Domain::IPV4, Type::DGRAM, Some(socket2::Protocol::UDP))?;
        h.bind(&SocketAddr::from(([0, 0, 0, 0], 0)).into())?;
        h.join_multicast_v4(group, &self.interface)?;
        self.helpers.push(h);
        Ok(self.helpers.len() - 1)
    }

    /// Leaves the run-time groups (sync addresses) that `keep` no longer wants.
    fn leave_unused(&mut self, socket: &UdpSocket, keep: impl Fn(u16) -> bool) {
        let fixed = &self.fixed;
        let leave: Vec<(u16, Option<usize>)> =
            self.joined.iter().filter(|(u, _)| !fixed.contains(u) && !keep(**u)).map(|(u, at)| (*u, *at)).collect();
        for (universe, at) in leave {
            let group = multicast_group(universe);
            let result = match at {
                None => SockRef::from(socket).leave_multicast_v4(&group, &self.interface),
                Some(i) => self.helpers[i].leave_multicast_v4(&group, &self.interface),
            };
            if let Err(e) = result {
                tracing::debug!(%group, %e, "leaving sACN multicast group");
            }
            self.joined.remove(&universe);
        }
    }
}

struct SacnProtocol {
    receiver: SacnReceiver,
    memberships: Option<Memberships>,
}

impl DatagramProtocol for SacnProtocol {
    const PROTOCOL: Protocol = Protocol::Sacn;
    type Error = SacnError;

    fn datagram(
        &mut self,
        data: &[u8],
        from: SocketAddr,
        now: Instant,
        events: &mut Vec<SourceEvent>,
        socket: &UdpSocket,
    ) -> Tally<SacnError> {
        let handled = self.receiver.handle(data, from, now, &mut |e| events.push(e));
        if let (Some(universe), Some(m)) = (handled.join, &mut self.memberships) {
            m.join(socket, universe);
        }
        let unpatched = match (&handled.disposition, handled.input) {
            (Disposition::Ignored(IgnoreReason::NotPatched), Some(input)) => Some(input),
            _ => None,
        };
        Tally { source: handled.source, disposition: handled.disposition, unpatched }
    }

    fn tick(&mut self, now: Instant, events: &mut Vec<SourceEvent>, socket: &UdpSocket) {
        self.receiver.tick(now, &mut |e| events.push(e));
        // Leave the groups of sync addresses the receiver has forgotten.
        if let Some(m) = &mut self.memberships {
            let receiver = &self.receiver;
            m.leave_unused(socket, |u| receiver.tracks_sync_address(u));
        }
    }
}

/// A running sACN input on one socket.
pub struct SacnNode {
    socket: UdpSocket,
    protocol: SacnProtocol,
}

impl SacnNode {
    /// A node on an already bound socket; joins the groups of `universes`
    /// (sACN universe numbers) when `config.multicast` is on. Join failures
    /// are logged, not fatal: unicast still arrives.
    pub fn new(socket: UdpSocket, config: &SacnConfig, receiver: SacnReceiverConfig, universes: &[u16]) -> Self {
        let bound = socket.local_addr().ok();
        if config.multicast
            && let Some(SocketAddr::V4(a)) = bound
            && !a.ip().is_unspecified()
            && !a.ip().is_multicast()
        {
            // Linux delivers a group's datagrams only to sockets bound to the
            // wildcard or to the group address itself, never to a unicast address.
            tracing::warn!(
                "the sACN socket is bound to {a}: multicast sACN (the usual way desks send it) will not \
                 arrive on an address like this; bind 0.0.0.0:{} and choose the network card with the \
                 multicast interface option (--sacn-iface {})",
                a.port(),
                a.ip()
            );
        }
        let memberships = config.multicast.then(|| {
            let limit = universes.len() + MAX_RUNTIME_JOINS;
            let mut m = Memberships {
                interface: config.interface,
                joined: BTreeMap::new(),
                fixed: universes.iter().copied().collect(),
                limit,
                helpers: Vec::new(),
            };
            for &u in universes {
                m.join(&socket, u);
            }
            m
        });
        SacnNode { socket, protocol: SacnProtocol { receiver: SacnReceiver::new(receiver), memberships } }
    }

    /// The sACN universes whose groups are joined.
    pub fn joined(&self) -> Vec<u16> {
        self.protocol.memberships.as_ref().map(|m| m.joined.keys().copied().collect()).unwrap_or_default()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_follow_the_universe_number() {
        assert_eq!(multicast_group(1), Ipv4Addr::new(239, 255, 0, 1));
        assert_eq!(multicast_group(63999), Ipv4Addr::new(239, 255, 249, 255));
        assert_eq!(multicast_group(64214), Ipv4Addr::new(239, 255, 250, 214));
    }
}
