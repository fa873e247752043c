//! Art-Net 4 wire format: parse ArtDmx, ArtPoll and ArtSync by hand; build
//! ArtPollReply. Pure functions over byte slices; nothing here panics on any
//! input (fuzzed in tests/suite/fuzz.rs).
//!
//! Header of every packet: bytes 0-7 `Art-Net\0`, 8-9 OpCode little endian,
//! 10-11 ProtVer big endian (≥ 14; not present in ArtPollReply).
//!
//! ArtDmx (OpCode 0x5000): 12 Sequence (0 = off), 13 Physical, 14 SubUni,
//! 15 Net, 16-17 Length big endian (2-512), 18.. data. Port-Address =
//! `(Net & 0x7F) << 8 | SubUni` (Net: bits 14-8, Sub-Net: 7-4, Universe: 3-0).
//!
//! ArtPoll (0x2000): 12 Flags, 13 DiagPriority, 14-15 TargetPortAddressTop,
//! 16-17 TargetPortAddressBottom (both big endian; Flags bit 5 = targeted);
//! short polls are zero-filled. ArtSync (0x5200): 12-13 Aux (zero).
//!
//! ArtPollReply (0x2100, 239 bytes): see [`build_poll_reply`] for the layout.

use std::net::Ipv4Addr;

/// The Art-Net UDP port.
pub const PORT: u16 = 6454;
/// The 8-byte packet ID.
pub const ID: &[u8; 8] = b"Art-Net\0";
/// The lowest protocol version we accept (Art-Net 4 sends 14).
pub const MIN_PROTOCOL_VERSION: u16 = 14;
/// Size of an ArtPollReply.
pub const POLL_REPLY_LEN: usize = 239;
/// ArtPoll Flags bit 5: only nodes with a Port-Address in the target range reply.
pub const POLL_FLAG_TARGETED: u8 = 0x20;

/// OpCodes we name (ArtDmx, ArtPoll, ArtSync are served; the rest are named
/// for the log only).
pub mod opcode {
    /// ArtPoll.
    pub const POLL: u16 = 0x2000;
    /// ArtPollReply.
    pub const POLL_REPLY: u16 = 0x2100;
    /// ArtDmx (OpOutput).
    pub const DMX: u16 = 0x5000;
    /// ArtNzs (non-zero START code) and ArtVlc.
    pub const NZS: u16 = 0x5100;
    /// ArtSync.
    pub const SYNC: u16 = 0x5200;
    /// ArtAddress.
    pub const ADDRESS: u16 = 0x6000;
    /// ArtInput.
    pub const INPUT: u16 = 0x7000;
    /// ArtTimeCode.
    pub const TIME_CODE: u16 = 0x9700;
    /// ArtIpProg.
    pub const IP_PROG: u16 = 0xF800;
}

/// Why bytes are not a valid Art-Net packet we serve.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ArtNetError {
    /// Shorter than the 10-byte ID + OpCode.
    #[error("{len} bytes is too short for an Art-Net header")]
    TooShort {
        /// Datagram length.
        len: usize,
    },
    /// The first 8 bytes are not `Art-Net\0` (e.g. `Art-Ext\0`).
    #[error("not an Art-Net packet (bad ID)")]
    BadId,
    /// ProtVer is below 14.
    #[error("protocol version {version} is below 14")]
    OldProtocol {
        /// The ProtVer field.
        version: u16,
    },
    /// An ArtDmx shorter than its 18-byte header.
    #[error("ArtDmx of {len} bytes is shorter than its header")]
    DmxTooShort {
        /// Datagram length.
        len: usize,
    },
    /// ArtDmx Length outside 1-512.
    #[error("ArtDmx Length {length} is outside 1-512")]
    BadLength {
        /// The Length field.
        length: u16,
    },
    /// ArtDmx carrying no data bytes after clamping Length to the datagram.
    #[error("ArtDmx carries no data")]
    NoData,
}

/// An ArtDmx packet, borrowing its data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArtDmx<'a> {
    /// 1-255, or 0 when the sender does not sequence.
    pub sequence: u8,
    /// The sender's physical input port (informational; part of the source id).
    pub physical: u8,
    /// 15-bit Port-Address.
    pub port_address: u16,
    /// Slot values, Length clamped to the bytes received.
    pub data: &'a [u8],
}

/// An ArtPoll packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArtPoll {
    /// Flags (bit 1: reply on change; bit 5: targeted).
    pub flags: u8,
    /// Lowest diagnostics priority wanted.
    pub diag_priority: u8,
    /// Targeted mode: reply only for Port-Addresses in bottom..=top.
    pub target: Option<PortRange>,
}

/// An inclusive Port-Address range (targeted ArtPoll).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PortRange {
    /// Lowest Port-Address.
    pub bottom: u16,
    /// Highest Port-Address.
    pub top: u16,
}

impl PortRange {
    /// Whether `port_address` is in the range.
    pub fn contains(&self, port_address: u16) -> bool {
        (self.bottom..=self.top).contains(&port_address)
    }
}

/// A parsed Art-Net packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArtPacket<'a> {
    /// ArtDmx: levels.
    Dmx(ArtDmx<'a>),
    /// ArtPoll: answer with ArtPollReply.
    Poll(ArtPoll),
    /// ArtSync: release held ArtDmx.
    Sync,
    /// A valid header with an OpCode we do not serve.
    Unsupported {
        /// The OpCode.
        opcode: u16,
    },
}

impl ArtPacket<'_> {
    /// The packet's OpCode.
    pub fn opcode(&self) -> u16 {
        match self {
            ArtPacket::Dmx(_) => opcode::DMX,
            ArtPacket::Poll(_) => opcode::POLL,
            ArtPacket::Sync => opcode::SYNC,
            ArtPacket::Unsupported { opcode } => *opcode,
        }
    }
}

fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

/// Parses one UDP payload.
pub fn parse(buf: &[u8]) -> Result<ArtPacket<'_>, ArtNetError> {
    if buf.len() < 10 {
        return Err(ArtNetError::TooShort { len: buf.len() });
    }
    if &buf[..8] != ID {
        return Err(ArtNetError::BadId);
    }
    let opcode = u16::from_le_bytes([buf[8], buf[9]]);
    if !matches!(opcode, opcode::DMX | opcode::POLL | opcode::SYNC) {
        return Ok(ArtPacket::Unsupported { opcode });
    }
    if buf.len() < 12 {
        return Err(ArtNetError::TooShort { len: buf.len() });
    }
    let version = be16(buf, 10);
    if version < MIN_PROTOCOL_VERSION {
        return Err(ArtNetError::OldProtocol { version });
    }
    match opcode {
        opcode::DMX => parse_dmx(buf).map(ArtPacket::Dmx),
        opcode::POLL => Ok(ArtPacket::Poll(parse_poll(buf))),
        _ => Ok(ArtPacket::Sync),
    }
}

fn parse_dmx(buf: &[u8]) -> Result<ArtDmx<'_>, ArtNetError> {
    if buf.len() < 18 {
        return Err(ArtNetError::DmxTooShort { len: buf.len() });
    }
    let length = be16(buf, 16);
    if length == 0 || usize::from(length) > crate::SLOTS {
        return Err(ArtNetError::BadLength { length });
    }
    // Clamp to what arrived (OLA does the same; odd and short frames are tolerated).
    let end = buf.len().min(18 + usize::from(length));
    let data = &buf[18..end];
    if data.is_empty() {
        return Err(ArtNetError::NoData);
    }
    let port_address = (u16::from(buf[15] & 0x7F) << 8) | u16::from(buf[14]);
    Ok(ArtDmx { sequence: buf[12], physical: buf[13], port_address, data })
}

fn parse_poll(buf: &[u8]) -> ArtPoll {
    // Zero-fill: polls from Art-Net 3 and earlier stop after byte 13.
    let mut b = [0u8; 18];
    let n = buf.len().min(18);
    b[..n].copy_from_slice(&buf[..n]);
    let flags = b[12];
    let target = (flags & POLL_FLAG_TARGETED != 0)
        .then(|| PortRange { top: be16(&b, 14) & 0x7FFF, bottom: be16(&b, 16) & 0x7FFF });
    ArtPoll { flags, diag_priority: b[13], target }
}

/// Builds an ArtDmx packet (for tests, the synthetic frames of USB Pro
/// recordings, and example senders).
pub fn build_dmx(sequence: u8, physical: u8, port_address: u16, data: &[u8]) -> Vec<u8> {
    let data = &data[..data.len().min(crate::SLOTS)];
    let mut p = Vec::with_capacity(18 + data.len());
    p.extend_from_slice(ID);
    p.extend_from_slice(&opcode::DMX.to_le_bytes());
    p.extend_from_slice(&MIN_PROTOCOL_VERSION.to_be_bytes());
    p.extend_from_slice(&[sequence, physical, (port_address & 0xFF) as u8, ((port_address >> 8) & 0x7F) as u8]);
    p.extend_from_slice(&(data.len() as u16).to_be_bytes());
    p.extend_from_slice(data);
    p
}

/// Builds an ArtSync packet.
pub fn build_sync() -> Vec<u8> {
    let mut p = Vec::with_capacity(14);
    p.extend_from_slice(ID);
    p.extend_from_slice(&opcode::SYNC.to_le_bytes());
    p.extend_from_slice(&MIN_PROTOCOL_VERSION.to_be_bytes());
    p.extend_from_slice(&[0, 0]);
    p
}

/// Builds an ArtPoll packet (Art-Net 4 layout, 22 bytes).
pub fn build_poll(flags: u8, target: Option<PortRange>) -> Vec<u8> {
    let mut p = Vec::with_capacity(22);
    p.extend_from_slice(ID);
    p.extend_from_slice(&opcode::POLL.to_le_bytes());
    p.extend_from_slice(&MIN_PROTOCOL_VERSION.to_be_bytes());
    let flags = if target.is_some() { flags | POLL_FLAG_TARGETED } else { flags };
    p.extend_from_slice(&[flags, 0]);
    let range = target.unwrap_or(PortRange { bottom: 0, top: 0 });
    p.extend_from_slice(&range.top.to_be_bytes());
    p.extend_from_slice(&range.bottom.to_be_bytes());
    p.extend_from_slice(&[0; 4]); // EstaMan, Oem
    p
}

/// Most ports one ArtPollReply describes (the four-entry port arrays).
pub const PORTS_PER_REPLY: usize = 4;

/// One output port in an ArtPollReply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplyPort {
    /// Its 15-bit Port-Address.
    pub port_address: u16,
    /// GoodOutputA bits (0x80 data is arriving, 0x08 merging, 0x02 LTP).
    pub good_output: u8,
}

/// What one ArtPollReply says about the node and up to four of its ports.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PollReplyInfo<'a> {
    /// The IP the poller reaches us at.
    pub ip: Ipv4Addr,
    /// The node's MAC (zeros when unknown).
    pub mac: [u8; 6],
    /// Short name (17 characters kept).
    pub short_name: &'a str,
    /// Long name (63 characters kept).
    pub long_name: &'a str,
    /// Node report text after `#0001 [count] ` (RcPowerOk); 50 characters kept.
    pub report: &'a str,
    /// Counts replies sent, shown in the node report.
    pub report_count: u32,
    /// The ports (at most [`PORTS_PER_REPLY`] are used). They must share Net
    /// and Sub-Net (bits 14-4): the reply carries those once (NetSwitch,
    /// SubSwitch) and only the low nibble per port (SwOut). [`reply_groups`]
    /// groups a node's ports that way.
    pub ports: &'a [ReplyPort],
    /// 1..n: which of the node's replies this is (Art-Net 4 BindIndex).
    pub bind_index: u8,
}

/// Splits a node's Port-Addresses into ArtPollReplies: sorted, without
/// duplicates, grouped by Net + Sub-Net (bits 14-4, which one reply carries
/// once), at most [`PORTS_PER_REPLY`] per reply. Reply `i` gets BindIndex `i + 1`.
///
/// ```
/// use footlight_dmx::artnet::packet::reply_groups;
/// // Port-Addresses 0-4 share Net 0 / Sub-Net 0 but one reply holds 4; 16 is Sub-Net 1.
/// assert_eq!(reply_groups(&[16, 4, 3, 2, 1, 0, 1]), vec![vec![0, 1, 2, 3], vec![4], vec![16]]);
/// ```
pub fn reply_groups(port_addresses: &[u16]) -> Vec<Vec<u16>> {
    let mut ports: Vec<u16> = port_addresses.iter().map(|p| p & 0x7FFF).collect();
    ports.sort_unstable();
    ports.dedup();
    let mut groups: Vec<Vec<u16>> = Vec::new();
    for p in ports {
        match groups.last_mut() {
            Some(g) if g.len() < PORTS_PER_REPLY && g[0] >> 4 == p >> 4 => g.push(p),
            _ => groups.push(vec![p]),
        }
    }
    groups
}

/// Builds a 239-byte ArtPollReply for up to four output ports (Art-Net → DMX).
///
/// Offsets (Art-Net 4; KSY `artpollreply`), sizes in parentheses:
///
/// ```text
/// 0 ID (8), 8 OpCode 0x2100 LE, 10 IP (4), 14 Port 0x1936 LE, 16 VersInfo,
/// 18 NetSwitch, 19 SubSwitch, 20 Oem, 22 Ubea, 23 Status1, 24 EstaMan LE,
/// 26 ShortName (18), 44 LongName (64), 108 NodeReport (64), 172 NumPorts BE,
/// 174 PortTypes (4), 178 GoodInput (4), 182 GoodOutputA (4), 186 SwIn (4),
/// 190 SwOut (4), 194 AcnPriority, 195 SwMacro, 196 SwRemote, 197 spare (3),
/// 200 Style, 201 MAC (6), 207 BindIp (4), 211 BindIndex, 212 Status2,
/// 213 GoodOutputB (4), 217 Status3, 218 DefaultRespUID (6), 224 User,
/// 226 RefreshRate, 228 filler (11).
/// ```
pub fn build_poll_reply(info: &PollReplyInfo<'_>) -> [u8; POLL_REPLY_LEN] {
    let mut p = [0u8; POLL_REPLY_LEN];
    let ports = &info.ports[..info.ports.len().min(PORTS_PER_REPLY)];
    let top = ports.first().map_or(0, |p| p.port_address);
    p[..8].copy_from_slice(ID);
    p[8..10].copy_from_slice(&opcode::POLL_REPLY.to_le_bytes());
    p[10..14].copy_from_slice(&info.ip.octets());
    p[14..16].copy_from_slice(&PORT.to_le_bytes());
    p[16..18].copy_from_slice(&1u16.to_be_bytes()); // VersInfo: our firmware revision 1
    p[18] = ((top >> 8) & 0x7F) as u8; // NetSwitch
    p[19] = ((top >> 4) & 0x0F) as u8; // SubSwitch
    p[20..22].copy_from_slice(&0x00FFu16.to_be_bytes()); // Oem: 0x00FF = unknown/unregistered
    p[23] = 0xD0; // Status1: indicators normal, Port-Address set locally (config), no RDM
    copy_str(&mut p[26..44], info.short_name);
    copy_str(&mut p[44..108], info.long_name);
    // "#xxxx [yyyy] text": a short stack buffer, so building a reply does not allocate.
    let mut report = [0u8; 64];
    let head = format_report_head(info.report_count, &mut report);
    let text = info.report.as_bytes();
    let n = text.len().min(report.len() - 1 - head);
    report[head..head + n].copy_from_slice(&text[..n]);
    p[108..172].copy_from_slice(&report);
    p[171] = 0;
    p[172..174].copy_from_slice(&(ports.len() as u16).to_be_bytes()); // NumPorts
    for (i, port) in ports.iter().enumerate() {
        p[174 + i] = 0x80; // PortTypes: outputs Art-Net data, DMX512
        p[182 + i] = port.good_output; // GoodOutputA
        p[190 + i] = (port.port_address & 0x0F) as u8; // SwOut
        p[213 + i] = 0x80; // GoodOutputB: RDM disabled (not supported)
    }
    p[194] = 100; // AcnPriority
    p[200] = 0x06; // Style: StVisual
    p[201..207].copy_from_slice(&info.mac);
    p[207..211].copy_from_slice(&info.ip.octets()); // BindIp: we are our own root device
    p[211] = info.bind_index;
    p[212] = 0x08; // Status2: 15-bit Port-Addresses
    p[217] = 0x00; // Status3: failsafe = hold last state
    p[226..228].copy_from_slice(&44u16.to_be_bytes()); // RefreshRate: DMX512 rate
    p
}

/// Writes `#0001 [nnnn] ` (RcPowerOk and the reply counter mod 10000) and
/// returns its length (13).
fn format_report_head(count: u32, out: &mut [u8; 64]) -> usize {
    let head = b"#0001 [";
    out[..7].copy_from_slice(head);
    let n = count % 10_000;
    for (i, d) in [n / 1000, n / 100 % 10, n / 10 % 10, n % 10].into_iter().enumerate() {
        out[7 + i] = b'0' + d as u8;
    }
    out[11] = b']';
    out[12] = b' ';
    13
}

/// Copies a string into a fixed, NUL-terminated field (truncating).
fn copy_str(field: &mut [u8], s: &str) {
    let n = s.len().min(field.len() - 1);
    field[..n].copy_from_slice(&s.as_bytes()[..n]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dmx_roundtrip_and_length_clamp() {
        let p = build_dmx(7, 2, 0x1234, &[1, 2, 3, 4]);
        let ArtPacket::Dmx(d) = parse(&p).unwrap() else { panic!() };
        assert_eq!((d.sequence, d.physical, d.port_address, d.data), (7, 2, 0x1234, &[1u8, 2, 3, 4][..]));
        // Length says 512 but 4 bytes came: clamp.
        let mut q = p.clone();
        q[16..18].copy_from_slice(&512u16.to_be_bytes());
        let ArtPacket::Dmx(d) = parse(&q).unwrap() else { panic!() };
        assert_eq!(d.data.len(), 4);
        // Length 2 with 4 bytes: only 2 used.
        q[16..18].copy_from_slice(&2u16.to_be_bytes());
        let ArtPacket::Dmx(d) = parse(&q).unwrap() else { panic!() };
        assert_eq!(d.data, &[1, 2]);
        q[16..18].copy_from_slice(&513u16.to_be_bytes());
        assert_eq!(parse(&q), Err(ArtNetError::BadLength { length: 513 }));
        assert_eq!(parse(&p[..18]), Err(ArtNetError::NoData));
        assert_eq!(parse(&p[..17]), Err(ArtNetError::DmxTooShort { len: 17 }));
    }

    #[test]
    fn header_checks() {
        let mut p = build_dmx(0, 0, 0, &[1, 2]);
        p[10..12].copy_from_slice(&13u16.to_be_bytes());
        assert_eq!(parse(&p), Err(ArtNetError::OldProtocol { version: 13 }));
        let mut q = build_dmx(0, 0, 0, &[1, 2]);
        q[..8].copy_from_slice(b"Art-Ext\0");
        assert_eq!(parse(&q), Err(ArtNetError::BadId));
        assert_eq!(parse(b"Art-Net"), Err(ArtNetError::TooShort { len: 7 }));
        let mut r = build_sync();
        r[8..10].copy_from_slice(&opcode::TIME_CODE.to_le_bytes());
        assert_eq!(parse(&r), Ok(ArtPacket::Unsupported { opcode: opcode::TIME_CODE }));
        assert_eq!(parse(&build_sync()), Ok(ArtPacket::Sync));
    }

    #[test]
    fn net_top_bit_is_masked() {
        let mut p = build_dmx(0, 0, 0, &[1, 2]);
        p[15] = 0xFF;
        p[14] = 0x01;
        let ArtPacket::Dmx(d) = parse(&p).unwrap() else { panic!() };
        assert_eq!(d.port_address, 0x7F01);
    }

    #[test]
    fn short_and_targeted_polls() {
        let short = &build_poll(0x02, None)[..12];
        assert_eq!(parse(short), Ok(ArtPacket::Poll(ArtPoll { flags: 0, diag_priority: 0, target: None })));
        let t = build_poll(0, Some(PortRange { bottom: 3, top: 9 }));
        let ArtPacket::Poll(p) = parse(&t).unwrap() else { panic!() };
        assert_eq!(p.target, Some(PortRange { bottom: 3, top: 9 }));
    }

    #[test]
    fn poll_reply_fields_at_spec_offsets() {
        let info = PollReplyInfo {
            ip: Ipv4Addr::new(192, 0, 2, 7),
            mac: [1, 2, 3, 4, 5, 6],
            short_name: "Footlight",
            long_name: "Footlight stage visualiser with a name longer than sixty-three characters in all",
            report: "ok",
            report_count: 10_003,
            ports: &[
                ReplyPort { port_address: 0x0123, good_output: 0x80 },
                ReplyPort { port_address: 0x0125, good_output: 0x88 },
            ],
            bind_index: 2,
        };
        let p = build_poll_reply(&info);
        assert_eq!(&p[8..10], &[0x00, 0x21]);
        assert_eq!(&p[10..14], &[192, 0, 2, 7]);
        assert_eq!(&p[14..16], &[0x36, 0x19]);
        assert_eq!((p[18], p[19], p[190], p[191], p[192]), (0x01, 0x02, 0x03, 0x05, 0));
        assert_eq!(&p[26..36], b"Footlight\0");
        assert_eq!(p[44 + 63], 0); // long name NUL-terminated
        assert!(p[108..172].starts_with(b"#0001 [0003] ok\0"));
        assert_eq!(u16::from_be_bytes([p[172], p[173]]), 2, "NumPorts");
        assert_eq!(&p[174..178], &[0x80, 0x80, 0, 0], "PortTypes");
        assert_eq!(&p[182..186], &[0x80, 0x88, 0, 0], "GoodOutputA");
        assert_eq!((p[200], p[211], p[212]), (6, 2, 0x08));
        assert_eq!(&p[201..207], &[1, 2, 3, 4, 5, 6]);
        // A long report is cut, and the field stays NUL-terminated.
        let long = "x".repeat(80);
        let p = build_poll_reply(&PollReplyInfo { report: &long, ..info });
        assert_eq!((p[170], p[171]), (b'x', 0));
    }

    #[test]
    fn reply_groups_share_net_and_subnet_and_hold_four() {
        assert_eq!(reply_groups(&[]), Vec::<Vec<u16>>::new());
        let ports: Vec<u16> = (0..10).chain([0x10, 0x7FFF, 0x0100]).collect();
        let g = reply_groups(&ports);
        assert_eq!(g, vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7], vec![8, 9], vec![0x10], vec![0x100], vec![0x7FFF]]);
        for group in &g {
            assert!(group.len() <= PORTS_PER_REPLY && group.iter().all(|p| p >> 4 == group[0] >> 4));
        }
    }
}
