//! UDP sockets the way show networks need them, and the loop every UDP node
//! shares (receive, count, log, tap, tick, forward events, stop on shutdown).
//!
//! Sockets bind AF_INET with SO_REUSEADDR + SO_REUSEPORT so a desk program on
//! the same machine can bind 6454/5568 too (DESIGN.md "Sockets"). The price:
//! each *unicast* datagram reaches only one of the sockets sharing the port
//! (the kernel picks one); broadcast and multicast reach all of them.

use std::future::Future;
use std::io;
use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

use socket2::{Domain, Socket, Type};
use tokio::net::UdpSocket;
use tokio::time::Instant;

use crate::error::Error;
use crate::record::Tap;
use crate::source::{Disposition, InputUniverse, Protocol, SourceEvent, SourceId};
use crate::stats::StatsHandle;
use crate::status::StatusHandle;

/// How often node timers run (ArtSync fallback, sync loss, poll replies).
pub(crate) const TICK: Duration = Duration::from_millis(50);
/// Receive buffer asked for: 64 universes × 638 bytes, several frames deep.
const RECV_BUFFER: usize = 1 << 20;

/// Creates a non-blocking UDP socket bound to `addr` with address and port reuse.
pub(crate) fn bind_udp(protocol: Protocol, addr: SocketAddr) -> Result<std::net::UdpSocket, Error> {
    let bind_err = |source| Error::Bind { protocol, addr, source };
    let socket = Socket::new(Domain::for_address(addr), Type::DGRAM, Some(socket2::Protocol::UDP)).map_err(bind_err)?;
    // Sharing is for well-known ports. With port 0 the kernel may hand a
    // reuse-flagged socket a port another reuse-flagged socket already has,
    // and the two would then split each other's unicast traffic.
    if addr.port() != 0 {
        socket.set_reuse_address(true).map_err(bind_err)?;
        #[cfg(unix)]
        socket.set_reuse_port(true).map_err(bind_err)?;
    }
    // A small default buffer only costs dropped frames under load; not fatal.
    if let Err(e) = socket.set_recv_buffer_size(RECV_BUFFER) {
        tracing::debug!(%e, "could not enlarge the {protocol} receive buffer");
    }
    socket.set_nonblocking(true).map_err(bind_err)?;
    socket.bind(&addr.into()).map_err(bind_err)?;
    Ok(socket.into())
}

/// Wraps a bound std socket for tokio (needs a runtime).
pub(crate) fn into_tokio(
    protocol: Protocol,
    addr: SocketAddr,
    socket: std::net::UdpSocket,
) -> Result<UdpSocket, Error> {
    UdpSocket::from_std(socket).map_err(|source| Error::Bind { protocol, addr, source })
}

/// What every node reports to.
#[derive(Clone, Debug)]
pub struct NodeContext {
    /// Where events go (the merge stage). A full channel makes the node wait;
    /// a closed one stops it.
    pub events: tokio::sync::mpsc::Sender<SourceEvent>,
    /// Packet counters.
    pub stats: StatsHandle,
    /// The typed status (unpatched universes are reported here).
    pub status: StatusHandle,
    /// Raw packets for a recording, if one runs.
    pub tap: Option<Tap>,
}

/// What a datagram protocol did with one packet.
pub(crate) struct Tally<E> {
    pub source: Option<SourceId>,
    pub disposition: Disposition<E>,
    /// The input universe of a data packet no patch universe takes.
    pub unpatched: Option<InputUniverse>,
}

/// A protocol the shared UDP loop can drive.
pub(crate) trait DatagramProtocol: Send {
    /// Which protocol (for counters and logs).
    const PROTOCOL: Protocol;
    /// What makes a packet malformed.
    type Error: std::fmt::Display + Send;
    /// Handles one datagram; pushes events; may send on `socket` (replies).
    fn datagram(
        &mut self,
        data: &[u8],
        from: SocketAddr,
        now: Instant,
        events: &mut Vec<SourceEvent>,
        socket: &UdpSocket,
    ) -> Tally<Self::Error>;
    /// Runs timers every [`TICK`].
    fn tick(&mut self, now: Instant, events: &mut Vec<SourceEvent>, socket: &UdpSocket);
}

/// Logs malformed packets at most once per 10 s per node, with a count of the rest.
pub(crate) struct LogLimiter {
    last: Option<Instant>,
    suppressed: u64,
}

impl LogLimiter {
    pub(crate) const PERIOD: Duration = Duration::from_secs(10);

    pub(crate) fn new() -> Self {
        LogLimiter { last: None, suppressed: 0 }
    }

    /// Whether to log now; if so, how many were suppressed since the last log.
    pub(crate) fn allow(&mut self, now: Instant) -> Option<u64> {
        match self.last {
            Some(last) if now.saturating_duration_since(last) < Self::PERIOD => {
                self.suppressed += 1;
                None
            }
            _ => {
                self.last = Some(now);
                Some(std::mem::take(&mut self.suppressed))
            }
        }
    }
}

/// Errors a UDP socket reports that are about an earlier send (ICMP port
/// unreachable after a reply) or the moment, not the socket: keep going.
fn transient(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionRefused
            | io::ErrorKind::ConnectionReset
            | io::ErrorKind::Interrupted
            | io::ErrorKind::WouldBlock
            | io::ErrorKind::HostUnreachable
            | io::ErrorKind::NetworkUnreachable
    )
}

/// Receives until `shutdown` resolves or the event channel closes.
pub(crate) async fn run_datagram_node<P: DatagramProtocol>(
    socket: UdpSocket,
    mut protocol: P,
    ctx: NodeContext,
    shutdown: impl Future<Output = ()>,
) {
    let name = P::PROTOCOL;
    let local = socket.local_addr().unwrap_or_else(|_| SocketAddr::from(([0, 0, 0, 0], 0)));
    tracing::info!(%local, "{name} input listening");
    // Largest valid packets: sACN 638 bytes, Art-Net 530; more is truncated and fails to parse.
    let mut buf = vec![0u8; 2048];
    let mut events: Vec<SourceEvent> = Vec::with_capacity(64);
    let mut ticker = tokio::time::interval(TICK);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut malformed_log = LogLimiter::new();
    let mut error_log = LogLimiter::new();
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            biased;
            () = &mut shutdown => break,
            // Timers before packets: a flood must not starve the ArtSync
            // fallback, sync loss or poll replies.
            _ = ticker.tick() => protocol.tick(Instant::now(), &mut events, &socket),
            received = socket.recv_from(&mut buf) => match received {
                Ok((n, from)) => {
                    let now = Instant::now();
                    let data = &buf[..n];
                    if let Some(tap) = &ctx.tap {
                        tap.datagram(now, from, local, data);
                    }
                    let tally = protocol.datagram(data, from, now, &mut events, &socket);
                    if let Disposition::Malformed(e) = &tally.disposition
                        && let Some(suppressed) = malformed_log.allow(now)
                    {
                        tracing::warn!(%from, suppressed, "malformed {name} packet: {e}");
                    }
                    ctx.stats.lock().packet(name, tally.source, Some(from.ip()), &tally.disposition);
                    if let Some(input) = tally.unpatched {
                        ctx.status.not_patched(input, now);
                    }
                }
                Err(e) if transient(&e) => tracing::debug!(%e, "{name} socket"),
                Err(e) => {
                    if let Some(suppressed) = error_log.allow(Instant::now()) {
                        tracing::warn!(%e, suppressed, "{name} socket receive error");
                    }
                    // A persistent error must not spin the core.
                    tokio::time::sleep(Duration::from_millis(10)).await;
                }
            },
        }
        for event in events.drain(..) {
            if ctx.events.send(event).await.is_err() {
                tracing::debug!("{name} node: merge stage gone, stopping");
                return;
            }
        }
    }
    tracing::info!("{name} input stopped");
}

/// The local IPv4 address that routes to `peer` (for ArtPollReply's IP field
/// when bound to 0.0.0.0). Connecting a UDP socket sends nothing.
pub(crate) fn local_ip_towards(peer: IpAddr) -> Option<IpAddr> {
    let probe = std::net::UdpSocket::bind(("0.0.0.0", 0)).ok()?;
    probe.connect((peer, 9)).ok()?;
    probe.local_addr().ok().map(|a| a.ip())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_limiter_counts_suppressed() {
        let t = Instant::now();
        let mut l = LogLimiter::new();
        assert_eq!(l.allow(t), Some(0));
        assert_eq!(l.allow(t + Duration::from_secs(1)), None);
        assert_eq!(l.allow(t + Duration::from_secs(2)), None);
        assert_eq!(l.allow(t + Duration::from_secs(10)), Some(2));
    }

    #[test]
    fn two_sockets_share_a_fixed_port_but_not_port_0() {
        let probe = std::net::UdpSocket::bind("127.0.0.3:0").unwrap();
        let port = probe.local_addr().unwrap().port();
        drop(probe);
        let at = SocketAddr::from(([127, 0, 0, 3], port));
        let _a = bind_udp(Protocol::ArtNet, at).unwrap();
        assert!(bind_udp(Protocol::ArtNet, at).is_ok(), "SO_REUSEPORT lets a second socket bind the same port");
        let c = bind_udp(Protocol::Sacn, "127.0.0.1:0".parse().unwrap()).unwrap();
        let c = socket2::SockRef::from(&c);
        assert!(!c.reuse_port().unwrap() && !c.reuse_address().unwrap(), "a port-0 socket is not shared");
        assert_eq!(local_ip_towards("127.0.0.1".parse().unwrap()), Some("127.0.0.1".parse().unwrap()));
    }
}
