//! Reads classic pcap (µs or ns, either byte order) and pcapng (any byte
//! order, several sections and interfaces, `if_tsresol`, `opt_comment`), and
//! digs out IPv4 UDP datagrams from Ethernet (with one VLAN tag), Linux
//! cooked (SLL and SLL2), BSD loopback and raw-IP link types. Streaming: one
//! packet in memory at a time; blocks over 16 MiB are refused.

use std::io::{self, Read};
use std::net::{Ipv4Addr, SocketAddrV4};
use std::time::Duration;

use super::pcapng::{BLOCK_EPB, BLOCK_IDB, BLOCK_PB, BLOCK_SHB, BLOCK_SPB, BYTE_ORDER_MAGIC};

/// Largest block or record accepted.
const MAX_BLOCK: usize = 16 << 20;

/// Why a capture cannot be read. Every variant knows the byte offset where
/// reading stopped ([`CaptureError::offset`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CaptureError {
    /// Reading failed.
    #[error("read error at byte {offset}: {source}")]
    Io {
        /// Where the block or record being read starts.
        offset: u64,
        /// What the OS said.
        source: io::Error,
    },
    /// The first bytes are neither a pcap nor a pcapng magic number.
    #[error("not a pcap or pcapng file (no magic number at byte 0)")]
    NotACapture,
    /// The file ends inside a block or record.
    #[error("truncated at byte {offset}")]
    Truncated {
        /// Where the block or record started.
        offset: u64,
    },
    /// A block or record is malformed.
    #[error("bad block at byte {offset}: {reason}")]
    BadBlock {
        /// Where it starts.
        offset: u64,
        /// What is wrong.
        reason: &'static str,
    },
}

impl CaptureError {
    /// The byte offset of the block or record where reading stopped (0 for
    /// a file that is not a capture).
    pub fn offset(&self) -> u64 {
        match self {
            CaptureError::Io { offset, .. }
            | CaptureError::Truncated { offset }
            | CaptureError::BadBlock { offset, .. } => *offset,
            CaptureError::NotACapture => 0,
        }
    }
}

/// One captured frame, borrowing the reader's buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Capture time since the Unix epoch.
    pub timestamp: Duration,
    /// Link type of the interface.
    pub link_type: u16,
    /// Captured bytes.
    pub data: &'a [u8],
    /// The packet comment, if any (pcapng only).
    pub comment: Option<&'a str>,
}

/// An IPv4 UDP datagram found in a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Datagram<'a> {
    /// Sender.
    pub from: SocketAddrV4,
    /// Destination.
    pub to: SocketAddrV4,
    /// UDP payload.
    pub payload: &'a [u8],
}

#[derive(Clone, Copy, Debug)]
struct Interface {
    link_type: u16,
    /// Timestamp units: (10 or 2, exponent).
    resolution: (u8, u8),
}

enum Format {
    Pcap { big_endian: bool, nanos: bool, link_type: u16 },
    Pcapng { big_endian: bool, interfaces: Vec<Interface>, last_timestamp: Duration },
}

/// A streaming pcap/pcapng reader.
pub struct CaptureReader<R: Read> {
    r: R,
    format: Format,
    offset: u64,
    /// The first SHB's block type, read while sniffing the format.
    pending: Option<[u8; 4]>,
    buf: Vec<u8>,
}

fn u16_at(b: &[u8], at: usize, big: bool) -> u16 {
    let v = [b[at], b[at + 1]];
    if big { u16::from_be_bytes(v) } else { u16::from_le_bytes(v) }
}

fn u32_at(b: &[u8], at: usize, big: bool) -> u32 {
    let v = [b[at], b[at + 1], b[at + 2], b[at + 3]];
    if big { u32::from_be_bytes(v) } else { u32::from_le_bytes(v) }
}

/// Converts a pcapng timestamp in units of `base^-exp` seconds.
fn ticks_to_duration(ticks: u64, (base, exp): (u8, u8)) -> Duration {
    if base == 2 {
        let exp = u32::from(exp.min(63));
        let secs = ticks >> exp;
        let frac = u128::from(ticks & ((1u64 << exp) - 1));
        return Duration::new(secs, ((frac * 1_000_000_000) >> exp) as u32);
    }
    let per_sec = 10u128.pow(u32::from(exp.min(38)));
    let ticks = u128::from(ticks);
    Duration::new((ticks / per_sec) as u64, ((ticks % per_sec) * 1_000_000_000 / per_sec) as u32)
}

impl<R: Read> CaptureReader<R> {
    /// Reads the file header and decides the format.
    pub fn new(mut r: R) -> Result<Self, CaptureError> {
        let mut head = [0u8; 24];
        read_exact_or(&mut r, &mut head[..4], 0)?;
        let magic = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
        if magic == BLOCK_SHB {
            // The SHB is parsed by next_packet like any later section.
            let format = Format::Pcapng { big_endian: false, interfaces: Vec::new(), last_timestamp: Duration::ZERO };
            let pending = Some([head[0], head[1], head[2], head[3]]);
            return Ok(CaptureReader { r, format, offset: 0, pending, buf: Vec::new() });
        }
        let (big_endian, nanos) = match magic {
            0xA1B2_C3D4 => (false, false),
            0xD4C3_B2A1 => (true, false),
            0xA1B2_3C4D => (false, true),
            0x4D3C_B2A1 => (true, true),
            _ => return Err(CaptureError::NotACapture),
        };
        read_exact_or(&mut r, &mut head[4..], 0)?;
        let link_type = (u32_at(&head, 20, big_endian) & 0xFFFF) as u16;
        let format = Format::Pcap { big_endian, nanos, link_type };
        Ok(CaptureReader { r, format, offset: 24, pending: None, buf: Vec::new() })
    }

    /// The next frame, or `None` at the end of the file.
    pub fn next_frame(&mut self) -> Result<Option<Frame<'_>>, CaptureError> {
        match self.format {
            Format::Pcap { big_endian, nanos, link_type } => self.next_pcap(big_endian, nanos, link_type),
            Format::Pcapng { .. } => self.next_pcapng(),
        }
    }

    fn next_pcap(&mut self, big: bool, nanos: bool, link_type: u16) -> Result<Option<Frame<'_>>, CaptureError> {
        let start = self.offset;
        let mut h = [0u8; 16];
        if !read_or_eof(&mut self.r, &mut h, start)? {
            return Ok(None);
        }
        let (secs, frac, incl) = (u32_at(&h, 0, big), u32_at(&h, 4, big), u32_at(&h, 8, big) as usize);
        if incl > MAX_BLOCK {
            return Err(CaptureError::BadBlock { offset: start, reason: "record larger than 16 MiB" });
        }
        let nanos = if nanos { frac } else { frac.saturating_mul(1000) };
        if nanos >= 1_000_000_000 {
            return Err(CaptureError::BadBlock { offset: start, reason: "fraction of a second out of range" });
        }
        self.buf.resize(incl, 0);
        read_exact_or(&mut self.r, &mut self.buf, start)?;
        self.offset += 16 + incl as u64;
        let timestamp = Duration::new(u64::from(secs), nanos);
        Ok(Some(Frame { timestamp, link_type, data: &self.buf, comment: None }))
    }

    fn next_pcapng(&mut self) -> Result<Option<Frame<'_>>, CaptureError> {
        // Blocks are read until a packet block; the frame borrows the buffer only at the end.
        let packet = loop {
            match self.next_block()? {
                Block::End => return Ok(None),
                Block::Other => {}
                Block::Packet(p) => break p,
            }
        };
        let data = &self.buf[packet.data];
        let comment = packet.comment.and_then(|r| std::str::from_utf8(&self.buf[r]).ok());
        Ok(Some(Frame { timestamp: packet.timestamp, link_type: packet.link_type, data, comment }))
    }

    /// Reads one pcapng block into `buf`.
    fn next_block(&mut self) -> Result<Block, CaptureError> {
        {
            let start = self.offset;
            // Block header: type and total length (the first SHB's type is already buffered).
            let mut head = [0u8; 8];
            self.buf.clear();
            match self.pending.take() {
                Some(kind) => head[..4].copy_from_slice(&kind),
                None if !read_or_eof(&mut self.r, &mut head[..4], start)? => return Ok(Block::End),
                None => {}
            }
            read_exact_or(&mut self.r, &mut head[4..], start)?;
            let Format::Pcapng { big_endian, .. } = self.format else { unreachable!("pcapng reader") };
            let mut big = big_endian;
            let kind = u32_at(&head, 0, big);
            if kind == BLOCK_SHB {
                // The byte order comes from this block's magic.
                let mut magic = [0u8; 4];
                read_exact_or(&mut self.r, &mut magic, start)?;
                big = match u32::from_le_bytes(magic) {
                    BYTE_ORDER_MAGIC => false,
                    m if m.swap_bytes() == BYTE_ORDER_MAGIC => true,
                    _ => return Err(CaptureError::BadBlock { offset: start, reason: "bad byte-order magic" }),
                };
                self.buf.extend_from_slice(&magic);
            }
            let total = u32_at(&head, 4, big) as usize;
            if total < 12 || !total.is_multiple_of(4) || total > MAX_BLOCK {
                return Err(CaptureError::BadBlock { offset: start, reason: "bad block length" });
            }
            let body_start = self.buf.len();
            self.buf.resize(total - 8, 0);
            read_exact_or(&mut self.r, &mut self.buf[body_start..], start)?;
            self.offset += total as u64;
            let body_len = total - 12;
            if u32_at(&self.buf, body_len, big) as usize != total {
                return Err(CaptureError::BadBlock { offset: start, reason: "trailing length differs" });
            }
            let Format::Pcapng { big_endian, interfaces, last_timestamp } = &mut self.format else {
                unreachable!("pcapng reader")
            };
            let body = &self.buf[..body_len];
            match kind {
                BLOCK_SHB => {
                    *big_endian = big;
                    interfaces.clear();
                }
                BLOCK_IDB => {
                    if body.len() < 8 {
                        return Err(CaptureError::BadBlock { offset: start, reason: "short interface block" });
                    }
                    let link_type = u16_at(body, 0, big);
                    let mut resolution = (10, 6);
                    for (code, value) in options(&body[8..], big) {
                        if code == 9 && value.len() == 1 {
                            let r = value[0];
                            resolution = if r & 0x80 != 0 { (2, r & 0x7F) } else { (10, r) };
                        }
                    }
                    interfaces.push(Interface { link_type, resolution });
                }
                BLOCK_EPB | BLOCK_PB => {
                    let (iface, fixed) = if kind == BLOCK_EPB {
                        if body.len() < 20 {
                            return Err(CaptureError::BadBlock { offset: start, reason: "short packet block" });
                        }
                        (u32_at(body, 0, big) as usize, 20)
                    } else {
                        if body.len() < 20 {
                            return Err(CaptureError::BadBlock { offset: start, reason: "short packet block" });
                        }
                        (usize::from(u16_at(body, 0, big)), 20)
                    };
                    let Some(interface) = interfaces.get(iface).copied() else {
                        return Err(CaptureError::BadBlock { offset: start, reason: "unknown interface" });
                    };
                    let ticks = (u64::from(u32_at(body, 4, big)) << 32) | u64::from(u32_at(body, 8, big));
                    let caplen = u32_at(body, 12, big) as usize;
                    let data_end = fixed + caplen;
                    if data_end > body.len() {
                        return Err(CaptureError::BadBlock { offset: start, reason: "captured length past block" });
                    }
                    let options_at = (data_end + 3) & !3;
                    let comment = (kind == BLOCK_EPB && options_at <= body.len())
                        .then(|| options(&body[options_at..], big).find(|(c, _)| *c == 1))
                        .flatten()
                        .map(|(_, v)| {
                            let at = v.as_ptr() as usize - body.as_ptr() as usize;
                            at..at + v.len()
                        });
                    let timestamp = ticks_to_duration(ticks, interface.resolution);
                    *last_timestamp = timestamp;
                    let link_type = interface.link_type;
                    return Ok(Block::Packet(PacketAt { timestamp, link_type, data: fixed..data_end, comment }));
                }
                BLOCK_SPB => {
                    let Some(interface) = interfaces.first().copied() else {
                        return Err(CaptureError::BadBlock { offset: start, reason: "unknown interface" });
                    };
                    if body.len() < 4 {
                        return Err(CaptureError::BadBlock { offset: start, reason: "short simple packet block" });
                    }
                    let len = (u32_at(body, 0, big) as usize).min(body.len() - 4);
                    // A simple packet has no timestamp: it takes the previous one.
                    let (timestamp, link_type) = (*last_timestamp, interface.link_type);
                    return Ok(Block::Packet(PacketAt { timestamp, link_type, data: 4..4 + len, comment: None }));
                }
                _ => {} // name resolution, statistics, custom, …: skip
            }
            Ok(Block::Other)
        }
    }
}

/// What [`CaptureReader::next_block`] found.
enum Block {
    End,
    Other,
    Packet(PacketAt),
}

/// A packet block, as ranges into the reader's buffer.
struct PacketAt {
    timestamp: Duration,
    link_type: u16,
    data: std::ops::Range<usize>,
    comment: Option<std::ops::Range<usize>>,
}

/// Iterates pcapng options (code, value) until opt_endofopt or the end.
fn options(mut b: &[u8], big: bool) -> impl Iterator<Item = (u16, &[u8])> {
    std::iter::from_fn(move || {
        if b.len() < 4 {
            return None;
        }
        let (code, len) = (u16_at(b, 0, big), usize::from(u16_at(b, 2, big)));
        if code == 0 || 4 + len > b.len() {
            return None;
        }
        let value = &b[4..4 + len];
        b = &b[((4 + len + 3) & !3).min(b.len())..];
        Some((code, value))
    })
}

/// Reads exactly `buf`, mapping an early end to `Truncated`.
fn read_exact_or(r: &mut impl Read, buf: &mut [u8], offset: u64) -> Result<(), CaptureError> {
    r.read_exact(buf).map_err(|e| match e.kind() {
        io::ErrorKind::UnexpectedEof => CaptureError::Truncated { offset },
        _ => CaptureError::Io { offset, source: e },
    })
}

/// Like [`read_exact_or`], but a clean end before the first byte is `Ok(false)`.
fn read_or_eof(r: &mut impl Read, buf: &mut [u8], offset: u64) -> Result<bool, CaptureError> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) if got == 0 => return Ok(false),
            Ok(0) => return Err(CaptureError::Truncated { offset }),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(CaptureError::Io { offset, source: e }),
        }
    }
    Ok(true)
}

/// Link types understood.
pub mod link {
    /// BSD loopback: 4-byte address family in the capturing host's byte order.
    pub const NULL: u16 = 0;
    /// Ethernet II (tcpdump on `lo` and NICs).
    pub const ETHERNET: u16 = 1;
    /// Raw IP (version from the first nibble).
    pub const RAW: u16 = 101;
    /// Linux cooked capture v1 (`tcpdump -i any`, older libpcap).
    pub const LINUX_SLL: u16 = 113;
    /// Raw IPv4.
    pub const IPV4: u16 = 228;
    /// Linux cooked capture v2 (`tcpdump -i any`, libpcap ≥ 1.10).
    pub const LINUX_SLL2: u16 = 276;
}

/// Finds the IPv4 UDP datagram in a frame (`None` for anything else, or for
/// IP fragments).
pub fn udp_datagram<'a>(frame: &Frame<'a>) -> Option<Datagram<'a>> {
    let d = frame.data;
    let ip = match frame.link_type {
        link::ETHERNET => {
            let (mut ethertype, mut at) = (u16::from_be_bytes([*d.get(12)?, *d.get(13)?]), 14);
            if ethertype == 0x8100 {
                (ethertype, at) = (u16::from_be_bytes([*d.get(16)?, *d.get(17)?]), 18);
            }
            (ethertype == 0x0800).then_some(d.get(at..)?)?
        }
        link::NULL => {
            let family = d.get(..4)?;
            (family == [2, 0, 0, 0] || family == [0, 0, 0, 2]).then_some(d.get(4..)?)?
        }
        link::LINUX_SLL => (d.get(14..16)? == [0x08, 0x00]).then_some(d.get(16..)?)?,
        link::LINUX_SLL2 => (d.get(..2)? == [0x08, 0x00]).then_some(d.get(20..)?)?,
        link::RAW | link::IPV4 => d,
        _ => return None,
    };
    let (&version_ihl, _) = ip.split_first()?;
    let ihl = usize::from(version_ihl & 0x0F) * 4;
    if version_ihl >> 4 != 4 || ihl < 20 || ip.len() < ihl + 8 || ip[9] != 17 {
        return None;
    }
    let fragment = u16::from_be_bytes([ip[6], ip[7]]);
    if fragment & 0x3FFF != 0 {
        return None; // more fragments, or not the first: DMX packets are never fragmented
    }
    let total = usize::from(u16::from_be_bytes([ip[2], ip[3]])).clamp(ihl, ip.len());
    let ip = &ip[..total];
    let src = Ipv4Addr::new(ip[12], ip[13], ip[14], ip[15]);
    let dst = Ipv4Addr::new(ip[16], ip[17], ip[18], ip[19]);
    let udp = ip.get(ihl..)?;
    if udp.len() < 8 {
        return None;
    }
    let udp_len = usize::from(u16::from_be_bytes([udp[4], udp[5]])).clamp(8, udp.len());
    Some(Datagram {
        from: SocketAddrV4::new(src, u16::from_be_bytes([udp[0], udp[1]])),
        to: SocketAddrV4::new(dst, u16::from_be_bytes([udp[2], udp[3]])),
        payload: &udp[8..udp_len],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamp_resolutions() {
        assert_eq!(ticks_to_duration(1_500_000, (10, 6)), Duration::from_millis(1500));
        assert_eq!(ticks_to_duration(1_500_000_001, (10, 9)), Duration::new(1, 500_000_001));
        assert_eq!(ticks_to_duration(3 << 19, (2, 20)), Duration::from_millis(1500));
        assert_eq!(ticks_to_duration(u64::MAX, (10, 30)), Duration::ZERO);
    }

    #[test]
    fn rejects_what_is_not_a_capture() {
        assert!(matches!(CaptureReader::new(&b"hello world, this is text"[..]), Err(CaptureError::NotACapture)));
        assert!(matches!(CaptureReader::new(&b"\xd4\xc3"[..]), Err(CaptureError::Truncated { .. })));
    }
}
