//! E1.31-2018 wire format, parsed by hand with every layer validated. Pure
//! functions; nothing panics on any input (fuzzed in tests/suite/fuzz.rs).
//!
//! Root layer: 0-1 preamble 0x0010, 2-3 postamble 0, 4-15 `ASC-E1.17\0\0\0`,
//! 16-17 flags (0x7) and length (= PDU bytes from 16), 18-21 vector
//! (4 = data, 8 = extended), 22-37 CID.
//!
//! Data framing layer (vector 2): 38-39 flags/length, 40-43 vector,
//! 44-107 source name, 108 priority (0-200), 109-110 sync address,
//! 111 sequence, 112 options (0x80 Preview, 0x40 Stream_Terminated,
//! 0x20 Force_Sync), 113-114 universe (1-63999).
//!
//! DMP layer: 115-116 flags/length, 117 vector 0x02, 118 address and data type
//! 0xA1, 119-120 first property address 0, 121-122 increment 1,
//! 123-124 count (1-513, START code included), 125 START code, 126.. slots.
//!
//! Synchronisation packet (root vector 8, framing vector 1; 49 bytes):
//! 44 sequence, 45-46 sync address, 47-48 reserved. Universe discovery (root
//! 8, framing 2) is recognised and not parsed further.
//!
//! Lengths: each PDU's length must fit the datagram and the three must agree
//! with each other; bytes after the root PDU are ignored (as OLA does).

/// The sACN UDP port.
pub const PORT: u16 = 5568;
/// ACN packet identifier at bytes 4-15.
pub const ACN_ID: &[u8; 12] = b"ASC-E1.17\0\0\0";
/// Root vector of data packets.
pub const VECTOR_ROOT_DATA: u32 = 0x0000_0004;
/// Root vector of sync and discovery packets.
pub const VECTOR_ROOT_EXTENDED: u32 = 0x0000_0008;
/// Framing vector of data packets.
pub const VECTOR_FRAMING_DATA: u32 = 0x0000_0002;
/// Framing vector of sync packets (under root 8).
pub const VECTOR_FRAMING_SYNC: u32 = 0x0000_0001;
/// Framing vector of discovery packets (under root 8).
pub const VECTOR_FRAMING_DISCOVERY: u32 = 0x0000_0002;
/// Options bit: preview data, not for live output.
pub const OPTION_PREVIEW: u8 = 0x80;
/// Options bit: the source stops sending this universe.
pub const OPTION_TERMINATED: u8 = 0x40;
/// Options bit: after sync loss, update without waiting for sync.
pub const OPTION_FORCE_SYNC: u8 = 0x20;
/// Highest priority a source may send.
pub const MAX_PRIORITY: u8 = 200;

/// Why bytes are not a valid E1.31 packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SacnError {
    /// Too short for the layers its vectors announce.
    #[error("{len} bytes is too short")]
    TooShort {
        /// Datagram length.
        len: usize,
    },
    /// Preamble size is not 0x0010.
    #[error("preamble size {0:#06x} is not 0x0010")]
    Preamble(u16),
    /// Postamble size is not 0.
    #[error("postamble size {0:#06x} is not 0")]
    Postamble(u16),
    /// Bytes 4-15 are not `ASC-E1.17\0\0\0`.
    #[error("not an ACN packet (bad identifier)")]
    Identifier,
    /// A PDU's flags nibble is not 0x7.
    #[error("{layer} layer flags {flags:#x} are not 0x7")]
    Flags {
        /// Which layer.
        layer: &'static str,
        /// The top nibble found.
        flags: u8,
    },
    /// A PDU's length does not fit the datagram or the other layers.
    #[error("{layer} layer length {length} is inconsistent")]
    Length {
        /// Which layer.
        layer: &'static str,
        /// The length field.
        length: u16,
    },
    /// Unknown root vector.
    #[error("root vector {0:#010x} is neither data (4) nor extended (8)")]
    RootVector(u32),
    /// Unknown framing vector for the root vector.
    #[error("framing vector {0:#010x} is not valid here")]
    FramingVector(u32),
    /// Priority above 200.
    #[error("priority {0} is above 200")]
    Priority(u8),
    /// Universe 0 or 64000-65535.
    #[error("universe {0} is outside 1-63999")]
    Universe(u16),
    /// DMP vector is not 0x02.
    #[error("DMP vector {0:#04x} is not 0x02")]
    DmpVector(u8),
    /// DMP address/data type is not 0xA1.
    #[error("DMP address type {0:#04x} is not 0xa1")]
    AddressType(u8),
    /// DMP first property address is not 0.
    #[error("DMP first address {0} is not 0")]
    FirstAddress(u16),
    /// DMP address increment is not 1.
    #[error("DMP increment {0} is not 1")]
    Increment(u16),
    /// DMP property count outside 1-513 or not matching the length.
    #[error("DMP property count {0} is invalid")]
    Count(u16),
}

/// A data packet, borrowing its slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DataPacket<'a> {
    /// Component identifier of the source.
    pub cid: [u8; 16],
    /// Source name up to its NUL (not validated as UTF-8).
    pub source_name: &'a [u8],
    /// 0-200.
    pub priority: u8,
    /// Universe whose sync packets release this data; 0 = act now.
    pub sync_address: u16,
    /// Sequence number.
    pub sequence: u8,
    /// Options bits.
    pub options: u8,
    /// 1-63999.
    pub universe: u16,
    /// DMX512 START code (0 = levels).
    pub start_code: u8,
    /// Slot values after the START code (0-512).
    pub slots: &'a [u8],
}

impl DataPacket<'_> {
    /// Preview_Data: for preview displays, not live output.
    pub fn preview(&self) -> bool {
        self.options & OPTION_PREVIEW != 0
    }
    /// Stream_Terminated: the source has stopped sending this universe.
    pub fn terminated(&self) -> bool {
        self.options & OPTION_TERMINATED != 0
    }
    /// Force_Synchronization: after sync loss, process data without sync.
    pub fn force_sync(&self) -> bool {
        self.options & OPTION_FORCE_SYNC != 0
    }
}

/// A universe synchronisation packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncPacket {
    /// Component identifier of the source.
    pub cid: [u8; 16],
    /// Sequence number (counted separately from data).
    pub sequence: u8,
    /// The synchronisation address (universe) it releases.
    pub sync_address: u16,
}

/// A parsed E1.31 packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SacnPacket<'a> {
    /// Levels (or another START code).
    Data(DataPacket<'a>),
    /// Universe synchronisation.
    Sync(SyncPacket),
    /// Universe discovery (not needed to receive data).
    Discovery {
        /// Component identifier of the source.
        cid: [u8; 16],
    },
}

fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn be32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Checks a flags/length word at `at` and returns the PDU length.
fn pdu_length(b: &[u8], at: usize, layer: &'static str) -> Result<usize, SacnError> {
    let word = be16(b, at);
    let flags = (word >> 12) as u8;
    if flags != 0x7 {
        return Err(SacnError::Flags { layer, flags });
    }
    Ok(usize::from(word & 0x0FFF))
}

/// Parses one UDP payload.
pub fn parse(buf: &[u8]) -> Result<SacnPacket<'_>, SacnError> {
    // Root layer.
    if buf.len() < 38 {
        return Err(SacnError::TooShort { len: buf.len() });
    }
    match (be16(buf, 0), be16(buf, 2)) {
        (0x0010, 0) => {}
        (0x0010, post) => return Err(SacnError::Postamble(post)),
        (pre, _) => return Err(SacnError::Preamble(pre)),
    }
    if &buf[4..16] != ACN_ID {
        return Err(SacnError::Identifier);
    }
    let root_len = pdu_length(buf, 16, "root")?;
    let end = 16 + root_len;
    if end > buf.len() || end < 38 + 2 + 4 {
        return Err(SacnError::Length { layer: "root", length: root_len as u16 });
    }
    let buf = &buf[..end];
    let root_vector = be32(buf, 18);
    let mut cid = [0u8; 16];
    cid.copy_from_slice(&buf[22..38]);
    // Framing layer: its length covers everything from 38 to the end.
    let framing_len = pdu_length(buf, 38, "framing")?;
    if 38 + framing_len != end {
        return Err(SacnError::Length { layer: "framing", length: framing_len as u16 });
    }
    let framing_vector = be32(buf, 40);
    match (root_vector, framing_vector) {
        (VECTOR_ROOT_DATA, VECTOR_FRAMING_DATA) => parse_data(buf, cid).map(SacnPacket::Data),
        (VECTOR_ROOT_EXTENDED, VECTOR_FRAMING_SYNC) => {
            if end < 49 {
                return Err(SacnError::TooShort { len: end });
            }
            Ok(SacnPacket::Sync(SyncPacket { cid, sequence: buf[44], sync_address: be16(buf, 45) }))
        }
        (VECTOR_ROOT_EXTENDED, VECTOR_FRAMING_DISCOVERY) => Ok(SacnPacket::Discovery { cid }),
        (VECTOR_ROOT_DATA | VECTOR_ROOT_EXTENDED, v) => Err(SacnError::FramingVector(v)),
        (v, _) => Err(SacnError::RootVector(v)),
    }
}

fn parse_data(buf: &[u8], cid: [u8; 16]) -> Result<DataPacket<'_>, SacnError> {
    // Smallest data packet: a DMP layer with only the START code.
    if buf.len() < 126 {
        return Err(SacnError::TooShort { len: buf.len() });
    }
    let name = &buf[44..108];
    let source_name = &name[..name.iter().position(|&b| b == 0).unwrap_or(name.len())];
    let priority = buf[108];
    if priority > MAX_PRIORITY {
        return Err(SacnError::Priority(priority));
    }
    let universe = be16(buf, 113);
    if !(1..=crate::map::SACN_MAX_UNIVERSE).contains(&universe) {
        return Err(SacnError::Universe(universe));
    }
    // DMP layer.
    let dmp_len = pdu_length(buf, 115, "DMP")?;
    if 115 + dmp_len != buf.len() {
        return Err(SacnError::Length { layer: "DMP", length: dmp_len as u16 });
    }
    if buf[117] != 0x02 {
        return Err(SacnError::DmpVector(buf[117]));
    }
    if buf[118] != 0xA1 {
        return Err(SacnError::AddressType(buf[118]));
    }
    match (be16(buf, 119), be16(buf, 121)) {
        (0, 1) => {}
        (0, inc) => return Err(SacnError::Increment(inc)),
        (first, _) => return Err(SacnError::FirstAddress(first)),
    }
    let count = be16(buf, 123);
    if !(1..=513).contains(&count) || 125 + usize::from(count) != buf.len() {
        return Err(SacnError::Count(count));
    }
    Ok(DataPacket {
        cid,
        source_name,
        priority,
        sync_address: be16(buf, 109),
        sequence: buf[111],
        options: buf[112],
        universe,
        start_code: buf[125],
        slots: &buf[126..],
    })
}

/// What goes into a data packet we build (tests, example senders, recordings).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DataSpec<'a> {
    /// Source CID.
    pub cid: [u8; 16],
    /// Source name (63 bytes kept).
    pub source_name: &'a str,
    /// Priority 0-200.
    pub priority: u8,
    /// Sync address (0 = none).
    pub sync_address: u16,
    /// Sequence number.
    pub sequence: u8,
    /// Options bits.
    pub options: u8,
    /// Universe 1-63999.
    pub universe: u16,
    /// START code.
    pub start_code: u8,
    /// Slots (512 kept).
    pub slots: &'a [u8],
}

fn root_layer(p: &mut Vec<u8>, total: usize, vector: u32, cid: &[u8; 16]) {
    p.extend_from_slice(&0x0010u16.to_be_bytes());
    p.extend_from_slice(&0u16.to_be_bytes());
    p.extend_from_slice(ACN_ID);
    p.extend_from_slice(&(0x7000 | (total - 16) as u16).to_be_bytes());
    p.extend_from_slice(&vector.to_be_bytes());
    p.extend_from_slice(cid);
}

/// Builds an E1.31 data packet.
pub fn build_data(spec: &DataSpec<'_>) -> Vec<u8> {
    let slots = &spec.slots[..spec.slots.len().min(crate::SLOTS)];
    let total = 126 + slots.len();
    let mut p = Vec::with_capacity(total);
    root_layer(&mut p, total, VECTOR_ROOT_DATA, &spec.cid);
    p.extend_from_slice(&(0x7000 | (total - 38) as u16).to_be_bytes());
    p.extend_from_slice(&VECTOR_FRAMING_DATA.to_be_bytes());
    let mut name = [0u8; 64];
    let n = spec.source_name.len().min(63);
    name[..n].copy_from_slice(&spec.source_name.as_bytes()[..n]);
    p.extend_from_slice(&name);
    p.push(spec.priority);
    p.extend_from_slice(&spec.sync_address.to_be_bytes());
    p.push(spec.sequence);
    p.push(spec.options);
    p.extend_from_slice(&spec.universe.to_be_bytes());
    p.extend_from_slice(&(0x7000 | (total - 115) as u16).to_be_bytes());
    p.extend_from_slice(&[0x02, 0xA1, 0, 0, 0, 1]);
    p.extend_from_slice(&(slots.len() as u16 + 1).to_be_bytes());
    p.push(spec.start_code);
    p.extend_from_slice(slots);
    p
}

/// Builds an E1.31 synchronisation packet.
pub fn build_sync(cid: &[u8; 16], sequence: u8, sync_address: u16) -> Vec<u8> {
    let mut p = Vec::with_capacity(49);
    root_layer(&mut p, 49, VECTOR_ROOT_EXTENDED, cid);
    p.extend_from_slice(&(0x7000 | (49 - 38) as u16).to_be_bytes());
    p.extend_from_slice(&VECTOR_FRAMING_SYNC.to_be_bytes());
    p.push(sequence);
    p.extend_from_slice(&sync_address.to_be_bytes());
    p.extend_from_slice(&[0, 0]);
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(slots: &[u8]) -> DataSpec<'_> {
        DataSpec {
            cid: [7; 16],
            source_name: "desk",
            priority: 100,
            sync_address: 0,
            sequence: 1,
            options: 0,
            universe: 1,
            start_code: 0,
            slots,
        }
    }

    #[test]
    fn data_roundtrip() {
        let p = build_data(&spec(&[10, 20, 30]));
        assert_eq!(p.len(), 129);
        let SacnPacket::Data(d) = parse(&p).unwrap() else { panic!() };
        assert_eq!((d.source_name, d.universe, d.slots, d.start_code), (&b"desk"[..], 1, &[10u8, 20, 30][..], 0));
        let full = build_data(&spec(&[0; 512]));
        assert_eq!(full.len(), 638);
        assert!(parse(&full).is_ok());
        // Bytes after the root PDU are ignored.
        let mut padded = p.clone();
        padded.extend_from_slice(&[0; 5]);
        assert!(parse(&padded).is_ok());
    }

    #[test]
    fn every_layer_is_checked() {
        let p = build_data(&spec(&[1, 2]));
        let bad = |at: usize, v: u8| {
            let mut q = p.clone();
            q[at] = v;
            parse(&q).unwrap_err()
        };
        assert_eq!(bad(1, 0x11), SacnError::Preamble(0x0011));
        assert_eq!(bad(3, 1), SacnError::Postamble(1));
        assert_eq!(bad(4, b'X'), SacnError::Identifier);
        assert_eq!(bad(16, 0x60), SacnError::Flags { layer: "root", flags: 6 });
        assert!(matches!(bad(17, 0xFF), SacnError::Length { layer: "root", .. }));
        assert_eq!(bad(21, 5), SacnError::RootVector(5));
        assert!(matches!(bad(39, 0), SacnError::Length { layer: "framing", .. }));
        assert_eq!(bad(43, 3), SacnError::FramingVector(3));
        assert_eq!(bad(108, 201), SacnError::Priority(201));
        assert_eq!(bad(114, 0), SacnError::Universe(0));
        assert_eq!(bad(117, 3), SacnError::DmpVector(3));
        assert_eq!(bad(118, 0xA0), SacnError::AddressType(0xA0));
        assert_eq!(bad(120, 1), SacnError::FirstAddress(1));
        assert_eq!(bad(122, 2), SacnError::Increment(2));
        assert_eq!(bad(124, 2), SacnError::Count(2));
        assert!(matches!(bad(116, 0), SacnError::Length { layer: "DMP", .. }));
        let mut u = p.clone();
        u[113..115].copy_from_slice(&64000u16.to_be_bytes());
        assert_eq!(parse(&u).unwrap_err(), SacnError::Universe(64000));
    }

    #[test]
    fn sync_and_discovery() {
        let s = build_sync(&[3; 16], 9, 7000);
        assert_eq!(parse(&s), Ok(SacnPacket::Sync(SyncPacket { cid: [3; 16], sequence: 9, sync_address: 7000 })));
        let mut d = s.clone();
        d[43] = 2;
        assert_eq!(parse(&d), Ok(SacnPacket::Discovery { cid: [3; 16] }));
        assert_eq!(parse(&s[..40]).unwrap_err(), SacnError::Length { layer: "root", length: 33 });
    }
}
