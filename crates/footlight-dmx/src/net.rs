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
use crate::stats::{SocketCounters, StatsHandle};
use crate::status::StatusHandle;

/// How often node timers run (ArtSync fallback, sync loss, poll replies).
pub(crate) const TICK: Duration = Duration::from_millis(50);
/// Datagrams the receive buffer holds: 64 universes at DMX's full refresh
/// rate (44 Hz) for one second, so a receive task that does not run for a
/// second (a loaded 2-core machine, a desk's burst after a cue) drops none.
pub const BURST_DATAGRAMS: usize = 64 * 44;
/// Kernel memory one queued datagram costs (the socket buffer's "truesize",
/// which the receive buffer limits, not the payload): 1,280 bytes measured on
/// loopback for 530- and 638-byte datagrams (`/proc/net/udp` rx_queue over
/// 100 queued datagrams); network drivers that receive into 2 KiB pages cost
/// more, so 2,304 bytes is taken (estimated: a 2 KiB fragment plus the
/// 256-byte `sk_buff`).
pub const DATAGRAM_TRUESIZE: usize = 2304;
/// Receive buffer wanted, in bytes of kernel memory (6.5 MB).
pub const RECV_BUFFER: usize = BURST_DATAGRAMS * DATAGRAM_TRUESIZE;
/// How often the kernel's drop count is read.
const DROPS_PERIOD: Duration = Duration::from_secs(1);
/// Datagrams read per wake-up before the loop looks at its timers again.
const BATCH: usize = 64;

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
    size_recv_buffer(&socket, protocol);
    socket.set_nonblocking(true).map_err(bind_err)?;
    socket.bind(&addr.into()).map_err(bind_err)?;
    Ok(socket.into())
}

/// Asks for [`RECV_BUFFER`]. Linux doubles the value it is given (half of
/// the buffer is its bookkeeping) and caps `SO_RCVBUF` at
/// `net.core.rmem_max` (208 KiB on a stock Debian); a daemon allowed to
/// (root, `CAP_NET_ADMIN`) sets it past that cap with `SO_RCVBUFFORCE`.
/// What was granted is read back by the node and shown in the status; a
/// smaller buffer only costs drops under load, so it is not an error.
fn size_recv_buffer(socket: &Socket, protocol: Protocol) {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        let ask = RECV_BUFFER / 2;
        if nix::sys::socket::setsockopt(socket.as_raw_fd(), nix::sys::socket::sockopt::RcvBufForce, &ask).is_ok() {
            return;
        }
        if let Err(e) = socket.set_recv_buffer_size(ask) {
            tracing::debug!(%e, "could not enlarge the {protocol} receive buffer");
        }
    }
    #[cfg(not(target_os = "linux"))]
    if let Err(e) = socket.set_recv_buffer_size(RECV_BUFFER) {
        tracing::debug!(%e, "could not enlarge the {protocol} receive buffer");
    }
}

/// The kernel's view of a socket: its receive buffer now, and a way to read
/// the datagrams it dropped.
struct KernelSocket {
    /// The socket's inode (Linux: its line in `/proc/net/udp`).
    inode: Option<u64>,
    /// `/proc/net/udp` or `/proc/net/udp6`.
    table: &'static str,
}

impl KernelSocket {
    /// Reads the granted buffer into the status (warning once when it is
    /// short of [`RECV_BUFFER`]) and finds the socket's drop counter.
    fn open(socket: &UdpSocket, protocol: Protocol, stats: &StatsHandle) -> KernelSocket {
        let granted = socket2::SockRef::from(socket).recv_buffer_size().unwrap_or(0);
        if granted < RECV_BUFFER {
            tracing::warn!(
                "{protocol} receive buffer is {} KiB, short of the {} KiB that holds 64 universes at 44 Hz \
                 for a second: under load the kernel may drop datagrams (counted in /api/status). \
                 Raise the cap with `sysctl -w net.core.rmem_max={}` or run with CAP_NET_ADMIN",
                granted / 1024,
                RECV_BUFFER / 1024,
                RECV_BUFFER / 2
            );
        }
        let v6 = socket.local_addr().is_ok_and(|a| a.is_ipv6());
        let k =
            KernelSocket { inode: socket_inode(socket), table: if v6 { "/proc/net/udp6" } else { "/proc/net/udp" } };
        let counters = SocketCounters {
            recv_buffer_bytes: granted as u64,
            recv_buffer_wanted: RECV_BUFFER as u64,
            kernel_drops: k.drops(),
        };
        if let Some(slot) = stats.lock().socket_mut(protocol) {
            *slot = Some(counters);
        }
        k
    }

    /// Datagrams the kernel dropped on this socket (Linux `/proc/net/udp`'s
    /// last column; `None` elsewhere or when the line is gone).
    fn drops(&self) -> Option<u64> {
        let inode = self.inode?;
        let table = std::fs::read_to_string(self.table).ok()?;
        udp_table_drops(&table, inode)
    }
}

/// The inode of a socket, from `/proc/self/fd/N` → `socket:[INODE]` (Linux).
fn socket_inode(socket: &UdpSocket) -> Option<u64> {
    #[cfg(unix)]
    {
        use std::os::fd::AsRawFd;
        let link = std::fs::read_link(format!("/proc/self/fd/{}", socket.as_raw_fd())).ok()?;
        let link = link.to_str()?;
        link.strip_prefix("socket:[")?.strip_suffix(']')?.parse().ok()
    }
    #[cfg(not(unix))]
    {
        let _ = socket;
        None
    }
}

/// The `drops` column of the `/proc/net/udp` line whose inode column is
/// `inode` (columns: sl, local, remote, st, tx:rx queue, tr:when, retrnsmt,
/// uid, timeout, inode, ref, pointer, drops).
fn udp_table_drops(table: &str, inode: u64) -> Option<u64> {
    table.lines().skip(1).find_map(|line| {
        let cols: Vec<&str> = line.split_whitespace().collect();
        (cols.len() >= 13 && cols[9].parse() == Ok(inode)).then(|| cols[12].parse().ok()).flatten()
    })
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
    let kernel = KernelSocket::open(&socket, name, &ctx.stats);
    let mut drops_read = Instant::now();
    // Largest valid packets: sACN 638 bytes, Art-Net 530; more is truncated and fails to parse.
    let mut buf = vec![0u8; 2048];
    let mut events: Vec<SourceEvent> = Vec::with_capacity(64);
    let mut ticker = tokio::time::interval(TICK);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut logs = Logs { malformed: LogLimiter::new(), errors: LogLimiter::new() };
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            biased;
            () = &mut shutdown => break,
            // Timers before packets: a flood must not starve the ArtSync
            // fallback, sync loss or poll replies.
            _ = ticker.tick() => {
                let now = Instant::now();
                protocol.tick(now, &mut events, &socket);
                if now.saturating_duration_since(drops_read) >= DROPS_PERIOD {
                    drops_read = now;
                    let drops = kernel.drops();
                    if let Some(Some(c)) = ctx.stats.lock().socket_mut(name) {
                        c.kernel_drops = drops;
                    }
                }
            }
            received = socket.recv_from(&mut buf) => {
                let mut received = received;
                // Drain what is queued (up to a batch) before the timers and
                // the merge get their turn: one wake-up per burst, not per datagram.
                for read in 1..=BATCH {
                    match received {
                        Ok((n, from)) => {
                            let now = Instant::now();
                            let tally = protocol.datagram(&buf[..n], from, now, &mut events, &socket);
                            count_datagram(&ctx, &mut logs, (now, local, from), &buf[..n], name, tally);
                        }
                        Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                        Err(e) if transient(&e) => tracing::debug!(%e, "{name} socket"),
                        Err(e) => {
                            if let Some(suppressed) = logs.errors.allow(Instant::now()) {
                                tracing::warn!(%e, suppressed, "{name} socket receive error");
                            }
                            // A persistent error must not spin the core.
                            tokio::time::sleep(Duration::from_millis(10)).await;
                            break;
                        }
                    }
                    if read == BATCH {
                        break;
                    }
                    received = socket.try_recv_from(&mut buf);
                }
            }
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

/// The receive loop's rate-limited logs.
struct Logs {
    malformed: LogLimiter,
    errors: LogLimiter,
}

/// Records, logs and counts one datagram the protocol has handled.
fn count_datagram<E: std::fmt::Display>(
    ctx: &NodeContext,
    logs: &mut Logs,
    (now, local, from): (Instant, SocketAddr, SocketAddr),
    data: &[u8],
    name: Protocol,
    tally: Tally<E>,
) {
    if let Some(tap) = &ctx.tap {
        tap.datagram(now, from, local, data);
    }
    if let Disposition::Malformed(e) = &tally.disposition
        && let Some(suppressed) = logs.malformed.allow(now)
    {
        tracing::warn!(%from, suppressed, "malformed {name} packet: {e}");
    }
    ctx.stats.lock().packet(name, tally.source, Some(from.ip()), &tally.disposition);
    if let Some(input) = tally.unpatched {
        ctx.status.not_patched(input, now);
    }
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

    #[test]
    fn udp_table_drops_reads_the_last_column_of_the_socket_line() {
        let table = "   sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout inode ref pointer drops\n\
            \x20 12: 0100007F:1936 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 4242 2 0000000000000000 17\n\
            \x20 13: 00000000:15C0 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 99 2 0000000000000000 0\n";
        assert_eq!(udp_table_drops(table, 4242), Some(17));
        assert_eq!(udp_table_drops(table, 99), Some(0));
        assert_eq!(udp_table_drops(table, 7), None);
    }

    /// The kernel's own count: a socket with a tiny buffer that nobody reads
    /// overflows, and the drops read through its inode are the datagrams
    /// sent minus those still queued.
    #[cfg(target_os = "linux")]
    #[tokio::test]
    async fn kernel_drops_of_an_unread_socket_are_counted() {
        let small = Socket::new(Domain::IPV4, Type::DGRAM, None).unwrap();
        small.set_recv_buffer_size(2048).unwrap();
        small.bind(&SocketAddr::from(([127, 0, 0, 1], 0)).into()).unwrap();
        small.set_nonblocking(true).unwrap();
        let std: std::net::UdpSocket = small.into();
        let to = std.local_addr().unwrap();
        let reader = std.try_clone().unwrap();
        let socket = UdpSocket::from_std(std).unwrap();
        let stats = StatsHandle::new();
        let kernel = KernelSocket::open(&socket, Protocol::ArtNet, &stats);
        assert_eq!(kernel.drops(), Some(0));
        let sender = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        for _ in 0..200 {
            sender.send_to(&[0u8; 530], to).unwrap();
        }
        let mut queued = 0;
        let mut buf = [0u8; 2048];
        while reader.recv_from(&mut buf).is_ok() {
            queued += 1;
        }
        assert!(queued < 200, "a 4 KiB buffer cannot hold 200 datagrams");
        assert_eq!(kernel.drops(), Some(200 - queued));
        let c = stats.snapshot().artnet_socket.unwrap();
        assert_eq!(c.recv_buffer_wanted, RECV_BUFFER as u64);
        assert!(c.recv_buffer_bytes > 0 && c.recv_buffer_bytes < RECV_BUFFER as u64);
    }
}
