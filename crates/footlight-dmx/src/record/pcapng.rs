//! A minimal pcapng writer: one Section Header Block, one Interface
//! Description Block (LINKTYPE_RAW = 101: each packet is an IPv4 header, so
//! Wireshark shows "IPv4 / UDP / Art-Net" or "/ sACN"), then one Enhanced
//! Packet Block per datagram with nanosecond timestamps (`if_tsresol` = 9).
//! All little endian, every block padded to 4 bytes, as the pcapng spec
//! (draft-ietf-opsawg-pcapng) lays out.

use std::io::{self, Write};
use std::net::SocketAddrV4;
use std::time::Duration;

/// Block types.
pub(crate) const BLOCK_SHB: u32 = 0x0A0D_0D0A;
pub(crate) const BLOCK_IDB: u32 = 0x0000_0001;
pub(crate) const BLOCK_SPB: u32 = 0x0000_0003;
pub(crate) const BLOCK_PB: u32 = 0x0000_0002;
pub(crate) const BLOCK_EPB: u32 = 0x0000_0006;
/// Byte-order magic in the SHB.
pub(crate) const BYTE_ORDER_MAGIC: u32 = 0x1A2B_3C4D;
/// LINKTYPE_RAW: raw IPv4/IPv6.
pub(crate) const LINKTYPE_RAW: u16 = 101;

/// Writes DMX datagrams as IPv4/UDP packets into a pcapng stream.
pub struct PcapngWriter<W: Write> {
    out: W,
    /// IPv4 identification field, counting packets.
    ip_id: u16,
    block: Vec<u8>,
}

fn option(block: &mut Vec<u8>, code: u16, value: &[u8]) {
    block.extend_from_slice(&code.to_le_bytes());
    block.extend_from_slice(&(value.len() as u16).to_le_bytes());
    block.extend_from_slice(value);
    pad(block);
}

fn pad(block: &mut Vec<u8>) {
    while !block.len().is_multiple_of(4) {
        block.push(0);
    }
}

/// RFC 791 header checksum.
fn ipv4_checksum(header: &[u8]) -> u16 {
    let mut sum: u32 = header.chunks(2).map(|c| u32::from(u16::from_be_bytes([c[0], c[1]]))).sum();
    while sum > 0xFFFF {
        sum = (sum & 0xFFFF) + (sum >> 16);
    }
    !(sum as u16)
}

impl<W: Write> PcapngWriter<W> {
    /// Writes the section and interface headers.
    pub fn new(mut out: W) -> io::Result<Self> {
        let mut shb = Vec::with_capacity(64);
        shb.extend_from_slice(&BYTE_ORDER_MAGIC.to_le_bytes());
        shb.extend_from_slice(&1u16.to_le_bytes()); // major
        shb.extend_from_slice(&0u16.to_le_bytes()); // minor
        shb.extend_from_slice(&(-1i64).to_le_bytes()); // section length: unknown
        option(&mut shb, 4, concat!("footlight-dmx ", env!("CARGO_PKG_VERSION")).as_bytes()); // shb_userappl
        option(&mut shb, 0, &[]);
        write_block(&mut out, BLOCK_SHB, &shb)?;
        let mut idb = Vec::with_capacity(32);
        idb.extend_from_slice(&LINKTYPE_RAW.to_le_bytes());
        idb.extend_from_slice(&0u16.to_le_bytes()); // reserved
        idb.extend_from_slice(&0u32.to_le_bytes()); // snaplen: no limit
        option(&mut idb, 2, b"footlight DMX input"); // if_name
        option(&mut idb, 9, &[9]); // if_tsresol: 10^-9 s
        option(&mut idb, 0, &[]);
        write_block(&mut out, BLOCK_IDB, &idb)?;
        Ok(PcapngWriter { out, ip_id: 0, block: Vec::with_capacity(1024) })
    }

    /// Writes one UDP datagram at `timestamp` (since the Unix epoch), with an
    /// optional packet comment.
    pub fn write_udp(
        &mut self,
        timestamp: Duration,
        from: SocketAddrV4,
        to: SocketAddrV4,
        payload: &[u8],
        comment: Option<&str>,
    ) -> io::Result<()> {
        let payload = &payload[..payload.len().min(65_507)];
        let udp_len = 8 + payload.len();
        let ip_len = 20 + udp_len;
        self.ip_id = self.ip_id.wrapping_add(1);
        let mut ip = [0u8; 20];
        ip[0] = 0x45; // IPv4, 5-word header
        ip[2..4].copy_from_slice(&(ip_len as u16).to_be_bytes());
        ip[4..6].copy_from_slice(&self.ip_id.to_be_bytes());
        ip[6] = 0x40; // don't fragment
        ip[8] = 64; // TTL
        ip[9] = 17; // UDP
        ip[12..16].copy_from_slice(&from.ip().octets());
        ip[16..20].copy_from_slice(&to.ip().octets());
        let sum = ipv4_checksum(&ip);
        ip[10..12].copy_from_slice(&sum.to_be_bytes());

        let ns = timestamp.as_nanos() as u64;
        let b = &mut self.block;
        b.clear();
        b.extend_from_slice(&0u32.to_le_bytes()); // interface 0
        b.extend_from_slice(&((ns >> 32) as u32).to_le_bytes());
        b.extend_from_slice(&(ns as u32).to_le_bytes());
        b.extend_from_slice(&(ip_len as u32).to_le_bytes()); // captured
        b.extend_from_slice(&(ip_len as u32).to_le_bytes()); // original
        b.extend_from_slice(&ip);
        b.extend_from_slice(&from.port().to_be_bytes());
        b.extend_from_slice(&to.port().to_be_bytes());
        b.extend_from_slice(&(udp_len as u16).to_be_bytes());
        b.extend_from_slice(&0u16.to_be_bytes()); // UDP checksum 0 = none (allowed over IPv4)
        b.extend_from_slice(payload);
        pad(b);
        if let Some(c) = comment {
            option(b, 1, c.as_bytes()); // opt_comment
            option(b, 0, &[]);
        }
        write_block(&mut self.out, BLOCK_EPB, &self.block)
    }

    /// Flushes the underlying writer.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    /// The underlying writer.
    pub fn into_inner(self) -> W {
        self.out
    }
}

fn write_block(out: &mut impl Write, kind: u32, body: &[u8]) -> io::Result<()> {
    let total = (12 + body.len()) as u32;
    out.write_all(&kind.to_le_bytes())?;
    out.write_all(&total.to_le_bytes())?;
    out.write_all(body)?;
    out.write_all(&total.to_le_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checksum_of_a_known_header() {
        // Example header from RFC 1071 discussions (checksum field zeroed): 0xB861.
        let h = [
            0x45, 0x00, 0x00, 0x73, 0x00, 0x00, 0x40, 0x00, 0x40, 0x11, 0, 0, 0xC0, 0xA8, 0x00, 0x01, 0xC0, 0xA8, 0x00,
            0xC7,
        ];
        assert_eq!(ipv4_checksum(&h), 0xB861);
    }

    #[test]
    fn blocks_are_padded_and_framed() {
        let mut w = PcapngWriter::new(Vec::new()).unwrap();
        let a = "127.0.0.1:1".parse().unwrap();
        w.write_udp(Duration::from_secs(1), a, a, &[1, 2, 3], Some("x")).unwrap();
        let bytes = w.into_inner();
        assert_eq!(bytes.len() % 4, 0);
        assert_eq!(&bytes[..4], &BLOCK_SHB.to_le_bytes());
    }
}
