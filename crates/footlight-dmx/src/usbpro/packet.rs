//! Enttec DMX USB Pro framing: `0x7E, label, len LSB, len MSB, data[len], 0xE7`
//! with `len` ≤ 600 and no escaping. The decoder is a byte state machine: it
//! skips bytes until a 0x7E, rejects lengths over 600 and frames whose end
//! byte is not 0xE7, and starts over at the next 0x7E (as OLA's
//! `BaseUsbProWidget::ReceiveMessage` does). It holds at most one frame.

/// Start of message.
pub const SOM: u8 = 0x7E;
/// End of message.
pub const EOM: u8 = 0xE7;
/// Largest data length a widget sends or accepts.
pub const MAX_DATA: usize = 600;

/// Message labels we name.
pub mod label {
    /// Get widget parameters (firmware, break/MAB times, rate).
    pub const GET_PARAMS: u8 = 3;
    /// Received DMX packet (widget → host): status, START code, slots.
    pub const RECEIVED_DMX: u8 = 5;
    /// Output-only send DMX: switches the widget to output. Never sent.
    pub const OUTPUT_ONLY_SEND_DMX: u8 = 6;
    /// Receive DMX on change: 0 = every frame as label 5, 1 = changes as label 9.
    pub const RECEIVE_DMX_ON_CHANGE: u8 = 8;
    /// Received DMX change of state (widget → host).
    pub const CHANGE_OF_STATE: u8 = 9;
    /// Get widget serial number.
    pub const SERIAL_NUMBER: u8 = 10;
}

/// Why bytes on the serial line are not a valid message.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum UsbProError {
    /// Bytes skipped before a start byte.
    #[error("{bytes} bytes of garbage before a start byte")]
    Garbage {
        /// How many.
        bytes: usize,
    },
    /// A length over 600.
    #[error("message length {len} is over 600")]
    TooLong {
        /// The length field.
        len: usize,
    },
    /// The byte after the data is not 0xE7.
    #[error("end byte {byte:#04x} is not 0xe7")]
    BadEnd {
        /// The byte found.
        byte: u8,
    },
    /// A label 5 message shorter than status + START code.
    #[error("received-DMX message of {len} bytes lacks status and START code")]
    ShortDmx {
        /// Data length.
        len: usize,
    },
    /// A label 9 message whose size, mask or slot numbers do not agree.
    #[error("change-of-state message is inconsistent")]
    BadChange,
}

/// One decoded message, borrowing the decoder's buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Message<'a> {
    /// The label.
    pub label: u8,
    /// The data bytes.
    pub data: &'a [u8],
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    Label,
    LengthLow,
    LengthHigh,
    Data,
    End,
}

/// Reassembles messages from serial bytes.
pub struct Decoder {
    state: State,
    label: u8,
    len: usize,
    have: usize,
    skipped: usize,
    buf: [u8; MAX_DATA],
}

impl Default for Decoder {
    fn default() -> Self {
        Decoder { state: State::Idle, label: 0, len: 0, have: 0, skipped: 0, buf: [0; MAX_DATA] }
    }
}

impl Decoder {
    /// A decoder waiting for a start byte.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets any partial message (after reopening the port).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Feeds one byte; returns a message or an error when one completes.
    pub fn push(&mut self, byte: u8) -> Option<Result<Message<'_>, UsbProError>> {
        match self.state {
            State::Idle => {
                if byte != SOM {
                    self.skipped += 1;
                    return None;
                }
                self.state = State::Label;
                if self.skipped > 0 {
                    return Some(Err(UsbProError::Garbage { bytes: std::mem::take(&mut self.skipped) }));
                }
            }
            State::Label => (self.label, self.state) = (byte, State::LengthLow),
            State::LengthLow => (self.len, self.state) = (usize::from(byte), State::LengthHigh),
            State::LengthHigh => {
                self.len |= usize::from(byte) << 8;
                if self.len > MAX_DATA {
                    self.state = State::Idle;
                    return Some(Err(UsbProError::TooLong { len: self.len }));
                }
                self.have = 0;
                self.state = if self.len == 0 { State::End } else { State::Data };
            }
            State::Data => {
                self.buf[self.have] = byte;
                self.have += 1;
                if self.have == self.len {
                    self.state = State::End;
                }
            }
            State::End => {
                if byte == EOM {
                    self.state = State::Idle;
                    return Some(Ok(Message { label: self.label, data: &self.buf[..self.len] }));
                }
                // A start byte here may begin the next message.
                self.state = if byte == SOM { State::Label } else { State::Idle };
                return Some(Err(UsbProError::BadEnd { byte }));
            }
        }
        None
    }
}

/// Frames a message (host → widget requests; also test widgets).
pub fn encode(label: u8, data: &[u8]) -> Vec<u8> {
    let data = &data[..data.len().min(MAX_DATA)];
    let mut m = Vec::with_capacity(data.len() + 5);
    m.extend_from_slice(&[SOM, label]);
    m.extend_from_slice(&(data.len() as u16).to_le_bytes());
    m.extend_from_slice(data);
    m.push(EOM);
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_all(bytes: &[u8]) -> Vec<Result<(u8, Vec<u8>), UsbProError>> {
        let mut d = Decoder::new();
        bytes.iter().filter_map(|&b| d.push(b).map(|r| r.map(|m| (m.label, m.data.to_vec())))).collect()
    }

    #[test]
    fn garbage_bad_end_and_overlong_resync() {
        let mut bytes = vec![0x00, 0xE7, 0x13];
        bytes.extend(encode(5, &[0, 0, 9]));
        let mut bad = encode(5, &[0, 0, 1]);
        *bad.last_mut().unwrap() = 0x00;
        bytes.extend(bad);
        bytes.extend([SOM, 5, 0x59, 0x02]); // 601
        bytes.extend(encode(5, &[0, 0, 7]));
        assert_eq!(
            decode_all(&bytes),
            vec![
                Err(UsbProError::Garbage { bytes: 3 }),
                Ok((5, vec![0, 0, 9])),
                Err(UsbProError::BadEnd { byte: 0 }),
                Err(UsbProError::TooLong { len: 601 }),
                Ok((5, vec![0, 0, 7])),
            ]
        );
        // A start byte in place of the end byte starts the next message.
        let mut chained = encode(5, &[0, 0, 1]);
        chained.pop();
        chained.extend(&encode(5, &[0, 0, 2])[..]);
        assert_eq!(decode_all(&chained), vec![Err(UsbProError::BadEnd { byte: SOM }), Ok((5, vec![0, 0, 2]))]);
    }

    #[test]
    fn empty_and_largest_messages() {
        assert_eq!(decode_all(&encode(8, &[])), vec![Ok((8, vec![]))]);
        let big = vec![3; 600];
        assert_eq!(decode_all(&encode(5, &big)), vec![Ok((5, big))]);
    }
}
