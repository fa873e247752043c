//! The Art-Net node: a bound UDP socket, the [`ArtNetReceiver`], ArtPollReply.
//!
//! Controllers poll every 2.5-3 s and send ArtDmx by unicast only to nodes
//! whose reply lists the universe, so the reply matters. The node announces
//! the Port-Addresses routed to patched universes (`InputPatch`), up to four
//! per ArtPollReply (ports of one reply share Net and Sub-Net;
//! [`packet::reply_groups`]), BindIndex 1..n, Style = visualiser, sent by
//! unicast to the poller's IP at port 6454 after a random 0-1 s delay (spec:
//! spreads replies of large rigs). Each port's GoodOutputA and the NodeReport
//! say what is true now: receiving, stale (every source timed out, the frame
//! holds) or no data yet. Nothing is sent unsolicited (DESIGN.md "Sockets").
//!
//! Amplification guard (an 18-byte ArtPoll would otherwise draw up to 16
//! replies of 239 bytes, to any spoofed address): one reply burst per
//! requesting IP per [`ArtNetConfig::reply_interval`] (default 1 s; further
//! polls in that time are counted and dropped), and all replies together
//! capped at [`ArtNetConfig::reply_bytes_per_sec`] (a token bucket). A poll
//! storm from one address thus costs one burst a second and leaves the budget
//! to genuine controllers, which poll every 2.5-3 s.

use std::future::Future;
use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::time::Duration;

use tokio::net::UdpSocket;
use tokio::time::Instant;

use std::collections::HashMap;

use super::packet::{self, ArtNetError, ArtPoll, POLL_REPLY_LEN, PollReplyInfo, ReplyPort};
use super::receiver::{ArtNetReceiver, ArtNetReceiverConfig, PortStatus};
use crate::net::{self, DatagramProtocol, LogLimiter, NodeContext, Tally};
use crate::source::{Disposition, IgnoreReason, Protocol, SourceEvent};

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
    /// At most one reply burst per requesting IP in this time.
    pub reply_interval: Duration,
    /// All ArtPollReply bytes together, per second (token bucket; a burst is
    /// sent whole or not at all).
    pub reply_bytes_per_sec: u32,
}

impl Default for ArtNetConfig {
    fn default() -> Self {
        ArtNetConfig {
            bind: SocketAddr::from(([0, 0, 0, 0], packet::PORT)),
            short_name: "Footlight".into(),
            long_name: "Footlight stage lighting visualiser".into(),
            reply_delay_max: Duration::from_secs(1),
            reply_port: packet::PORT,
            reply_interval: Duration::from_secs(1),
            reply_bytes_per_sec: 64 * 1024,
        }
    }
}

/// Most Port-Addresses announced (at most 64 replies even if no two share a Sub-Net).
const MAX_REPLY_PORTS: usize = 64;
/// Most polls waiting for their delayed reply (one per requester).
const MAX_PENDING: usize = 16;
/// Most requesters remembered for the per-requester limit.
const MAX_REQUESTERS: usize = 256;

/// The NodeReport text for the ports of one reply, e.g.
/// `receiving 1,2; stale 3; no data 4` (Port-Addresses). Fits the 50
/// characters left after `#0001 [nnnn] ` for four 5-digit Port-Addresses.
pub fn report_text(ports: &[(u16, PortStatus)]) -> String {
    let mut out = String::new();
    /// Which state a port is in, by the word the report uses.
    type Pick = fn(&PortStatus) -> bool;
    let states: [(&str, Pick); 3] =
        [("receiving", |s| s.data), ("stale", |s| !s.data && s.stale), ("no data", |s| !s.data && !s.stale)];
    for (word, pick) in states {
        let mut first = true;
        for (pa, _) in ports.iter().filter(|(_, s)| pick(s)) {
            if first {
                if !out.is_empty() {
                    out.push_str("; ");
                }
                out.push_str(word);
                out.push(' ');
                first = false;
            } else {
                out.push(',');
            }
            out.push_str(&pa.to_string());
        }
    }
    out
}

/// The reply limits: one burst per requester per interval, bytes per second overall.
struct ReplyLimiter {
    interval: Duration,
    rate: f64,
    last_burst: HashMap<IpAddr, Instant>,
    /// Token bucket in bytes, and when it was last filled.
    tokens: f64,
    filled: Option<Instant>,
    /// Polls or bursts refused since the last log line.
    refused: u64,
}

impl ReplyLimiter {
    fn new(interval: Duration, bytes_per_sec: u32) -> Self {
        let rate = f64::from(bytes_per_sec);
        ReplyLimiter { interval, rate, last_burst: HashMap::new(), tokens: rate, filled: None, refused: 0 }
    }

    /// Whether `requester` may get a burst now (and notes that it does).
    fn allow_requester(&mut self, requester: IpAddr, now: Instant) -> bool {
        let interval = self.interval;
        if let Some(last) = self.last_burst.get(&requester)
            && now.saturating_duration_since(*last) < interval
        {
            self.refused += 1;
            return false;
        }
        if self.last_burst.len() >= MAX_REQUESTERS && !self.last_burst.contains_key(&requester) {
            self.last_burst.retain(|_, t| now.saturating_duration_since(*t) < interval);
            if self.last_burst.len() >= MAX_REQUESTERS {
                self.refused += 1;
                return false;
            }
        }
        self.last_burst.insert(requester, now);
        true
    }

    /// Takes `bytes` from the budget if there are enough. The bucket holds
    /// one second's worth, or one burst if that is more.
    fn take_bytes(&mut self, bytes: usize, now: Instant) -> bool {
        let bytes = bytes as f64;
        let cap = self.rate.max(bytes);
        if let Some(filled) = self.filled {
            self.tokens = (self.tokens + now.saturating_duration_since(filled).as_secs_f64() * self.rate).min(cap);
        } else {
            self.tokens = cap;
        }
        self.filled = Some(now);
        if self.tokens >= bytes {
            self.tokens -= bytes;
            true
        } else {
            self.refused += 1;
            false
        }
    }
}

struct PendingReply {
    due: Instant,
    poller: IpAddr,
    poll: ArtPoll,
}

/// The protocol half the shared UDP loop drives.
struct ArtNetProtocol {
    receiver: ArtNetReceiver,
    config: ArtNetConfig,
    /// Port-Addresses announced, one group per ArtPollReply.
    groups: Vec<Vec<u16>>,
    limiter: ReplyLimiter,
    /// The bound IP, if not the wildcard.
    bound_ip: Option<Ipv4Addr>,
    pending: Vec<PendingReply>,
    replies_sent: u32,
    poll_log: LogLimiter,
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
        // Targeted polls get the replies with a port in their range.
        let wanted = |g: &&Vec<u16>| reply.poll.target.is_none_or(|t| g.iter().any(|&p| t.contains(p)));
        let count = self.groups.iter().filter(wanted).count();
        if count == 0 {
            return;
        }
        if !self.limiter.take_bytes(count * POLL_REPLY_LEN, now) {
            return tracing::debug!(poller = %reply.poller, "ArtPollReply byte budget spent: burst skipped");
        }
        let mut sent = 0;
        for (i, group) in self.groups.iter().enumerate().filter(|(_, g)| wanted(g)) {
            let mut ports = [ReplyPort { port_address: 0, good_output: 0 }; packet::PORTS_PER_REPLY];
            let mut states = Vec::with_capacity(group.len());
            for (slot, &port_address) in ports.iter_mut().zip(group) {
                let status = self.receiver.port_status(port_address, now);
                let good_output = if status.data { 0x80 } else { 0 } | if status.merging { 0x08 } else { 0 };
                *slot = ReplyPort { port_address, good_output };
                states.push((port_address, status));
            }
            self.replies_sent = self.replies_sent.wrapping_add(1);
            let report = report_text(&states);
            let info = PollReplyInfo {
                ip,
                mac: [0; 6],
                short_name: &self.config.short_name,
                long_name: &self.config.long_name,
                report: &report,
                report_count: self.replies_sent,
                ports: &ports[..group.len()],
                bind_index: (i + 1) as u8,
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
            let poller = from.ip();
            if self.pending.len() >= MAX_PENDING || self.pending.iter().any(|p| p.poller == poller) {
                self.limiter.refused += 1;
            } else if self.limiter.allow_requester(poller, now) {
                let due = now + self.random_delay();
                self.pending.push(PendingReply { due, poller, poll });
            }
            if self.limiter.refused > 0
                && let Some(suppressed) = self.poll_log.allow(now)
            {
                let refused = std::mem::take(&mut self.limiter.refused);
                tracing::debug!(%from, refused, suppressed, "ArtPoll rate limit: polls without a reply");
            }
        }
        let unpatched = match (&handled.disposition, handled.input) {
            (Disposition::Ignored(IgnoreReason::NotPatched), Some(input)) => Some(input),
            _ => None,
        };
        Tally { source: handled.source, disposition: handled.disposition, unpatched }
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
    /// ArtPollReply announces (the lowest 64; Port-Address 0 if empty),
    /// grouped into replies by [`packet::reply_groups`].
    pub fn new(socket: UdpSocket, config: ArtNetConfig, receiver: ArtNetReceiverConfig, ports: Vec<u16>) -> Self {
        let mut ports: Vec<u16> = ports.into_iter().filter(|p| *p <= 0x7FFF).collect();
        ports.sort_unstable();
        ports.dedup();
        ports.truncate(MAX_REPLY_PORTS);
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
            limiter: ReplyLimiter::new(config.reply_interval, config.reply_bytes_per_sec),
            poll_log: LogLimiter::new(),
            config,
            groups: packet::reply_groups(&ports),
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

    /// The Port-Addresses each ArtPollReply announces (reply `i` has BindIndex `i + 1`).
    pub fn announced(&self) -> &[Vec<u16>] {
        &self.protocol.groups
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
    fn report_text_says_what_each_port_does() {
        let rx = PortStatus { data: true, merging: false, stale: false };
        let stale = PortStatus { data: false, merging: false, stale: true };
        let none = PortStatus::default();
        assert_eq!(report_text(&[(1, rx), (2, rx)]), "receiving 1,2");
        assert_eq!(report_text(&[(0, none)]), "no data 0");
        let worst = [(32764, rx), (32765, stale), (32766, none), (32767, none)];
        let text = report_text(&worst);
        assert_eq!(text, "receiving 32764; stale 32765; no data 32766,32767");
        assert!(text.len() <= 50, "fits after the 13-byte report head: {}", text.len());
    }

    #[test]
    fn one_burst_per_requester_per_interval_and_a_byte_budget() {
        let t = Instant::now();
        let ms = |n| t + Duration::from_millis(n);
        let (a, b): (IpAddr, IpAddr) = ("10.0.0.1".parse().unwrap(), "10.0.0.2".parse().unwrap());
        let mut l = ReplyLimiter::new(Duration::from_secs(1), 1000);
        assert!(l.allow_requester(a, t));
        assert!(!l.allow_requester(a, ms(999)), "storming requester waits");
        assert!(l.allow_requester(b, ms(10)), "another requester is not held up by the storm");
        assert!(l.allow_requester(a, ms(1000)));
        // 1000 bytes per second: four 239-byte replies fit, a fifth does not until refilled.
        assert!(l.take_bytes(4 * 239, t));
        assert!(!l.take_bytes(239, ms(1)));
        assert!(!l.take_bytes(239, ms(100)), "100 ms refill 100 bytes: 144 in all");
        assert!(l.take_bytes(239, ms(200)));
        // A burst bigger than a second's budget still goes out when the bucket is full.
        let mut small = ReplyLimiter::new(Duration::from_secs(1), 100);
        assert!(small.take_bytes(239, t));
        assert!(!small.take_bytes(239, ms(500)));
        assert!(small.take_bytes(239, ms(3000)));
        assert_eq!(small.refused, 1);
        // The requester table is bounded.
        let mut many = ReplyLimiter::new(Duration::from_secs(1), 1000);
        for i in 0..MAX_REQUESTERS as u32 {
            assert!(many.allow_requester(IpAddr::from(std::net::Ipv4Addr::from(i + 1)), t));
        }
        assert!(!many.allow_requester(b, ms(10)), "table full of fresh entries");
        assert!(many.allow_requester(b, ms(1000)), "old entries are pruned");
    }
}
