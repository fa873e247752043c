//! USB Pro receive rules, sans IO: serial bytes in, [`SourceEvent`]s and one
//! [`Disposition`] per message (or framing error) out.
//!
//! - Label 5 (received DMX): `[status, START code, slots…]`. Status bit 0
//!   (receive queue overflow) or bit 1 (overrun) → the frame is dropped.
//!   START code ≠ 0 → ignored.
//! - Label 9 (change of state): `[block n, 5-byte mask (LSB first), values…]`;
//!   mask bit i covers DMX index `n*8 + i` (index 0 = START code, index k =
//!   slot k), with one value byte per set bit. Changes apply to a copy of the
//!   universe that label 8 zeroed, and the whole universe is emitted.
//! - Other labels (replies to requests we did not make) are ignored.

use std::time::Duration;

use tokio::time::Instant;

use super::packet::{Decoder, Message, UsbProError, label};
use crate::source::{
    Disposition, DropReason, EventKind, IgnoreReason, InputUniverse, Levels, SourceEvent, SourceId, SourceName,
};

/// USB Pro sources merge as if they had sACN priority 100.
pub const PRIORITY: u8 = 100;
/// In every-frame mode a widget that sends nothing for this long leaves the merge.
pub const SOURCE_TIMEOUT: Duration = Duration::from_millis(2500);

/// How the widget reports received DMX (the label 8 request byte).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ReceiveMode {
    /// Every DMX frame as label 5 (default): silence means the line is dead.
    #[default]
    EveryFrame,
    /// Only changes, as label 9: less USB traffic, but silence says nothing,
    /// so the source stays until the port closes.
    ChangesOnly,
}

impl ReceiveMode {
    /// The label 8 data byte.
    pub fn request_byte(self) -> u8 {
        match self {
            ReceiveMode::EveryFrame => 0,
            ReceiveMode::ChangesOnly => 1,
        }
    }
}

/// Receive state for one widget.
pub struct UsbProReceiver {
    widget: u8,
    mode: ReceiveMode,
    decoder: Decoder,
    /// The universe as the widget last reported it (label 9 patches this).
    levels: Levels,
}

impl UsbProReceiver {
    /// A receiver for widget number `widget`.
    pub fn new(widget: u8, mode: ReceiveMode) -> Self {
        UsbProReceiver { widget, mode, decoder: Decoder::new(), levels: Levels::zero() }
    }

    /// The source id events carry.
    pub fn source(&self) -> SourceId {
        SourceId::UsbPro { widget: self.widget }
    }

    /// Forgets partial input and the change baseline (after (re)opening the
    /// port, when label 8 zeroes the widget's baseline too).
    pub fn reset(&mut self) {
        self.decoder.reset();
        self.levels = Levels::zero();
    }

    /// Feeds serial bytes; `out` gets events, `tally` one disposition per
    /// message or framing error.
    pub fn handle(
        &mut self,
        bytes: &[u8],
        now: Instant,
        out: &mut impl FnMut(SourceEvent),
        tally: &mut impl FnMut(Disposition<UsbProError>),
    ) {
        let (source, input) = (self.source(), InputUniverse::UsbPro(self.widget));
        let timeout = match self.mode {
            ReceiveMode::EveryFrame => Some(SOURCE_TIMEOUT),
            ReceiveMode::ChangesOnly => None,
        };
        for &b in bytes {
            let disposition = match self.decoder.push(b) {
                None => continue,
                Some(Err(e)) => Disposition::Malformed(e),
                Some(Ok(message)) => apply(message, &mut self.levels),
            };
            if disposition == Disposition::Applied {
                let kind = EventKind::Levels {
                    priority: PRIORITY,
                    timeout,
                    levels: self.levels.clone(),
                    name: SourceName::default(),
                };
                out(SourceEvent { at: now, input, source, kind });
            }
            tally(disposition);
        }
    }
}

/// Applies one message to the universe copy.
fn apply(m: Message<'_>, levels: &mut Levels) -> Disposition<UsbProError> {
    match m.label {
        label::RECEIVED_DMX => {
            let [status, start_code, slots @ ..] = m.data else {
                return Disposition::Malformed(UsbProError::ShortDmx { len: m.data.len() });
            };
            if status & 0x03 != 0 {
                return Disposition::Dropped(DropReason::WidgetOverrun);
            }
            if *start_code != 0 {
                return Disposition::Ignored(IgnoreReason::StartCode(*start_code));
            }
            levels.set(slots);
            Disposition::Applied
        }
        label::CHANGE_OF_STATE => match change_of_state(m.data, levels) {
            Ok(()) => Disposition::Applied,
            Err(e) => Disposition::Malformed(e),
        },
        other => Disposition::Ignored(IgnoreReason::Label(other)),
    }
}

fn change_of_state(data: &[u8], levels: &mut Levels) -> Result<(), UsbProError> {
    let Some((block, rest)) = data.split_first() else { return Err(UsbProError::BadChange) };
    if rest.len() < 5 {
        return Err(UsbProError::BadChange);
    }
    let (mask, values) = rest.split_at(5);
    let bits = u64::from_le_bytes([mask[0], mask[1], mask[2], mask[3], mask[4], 0, 0, 0]);
    if bits.count_ones() as usize != values.len() {
        return Err(UsbProError::BadChange);
    }
    // Validate every index before changing anything.
    let first = usize::from(*block) * 8;
    let indices = (0..40).filter(|i| bits & (1 << i) != 0).map(|i| first + i);
    if indices.clone().any(|index| index > crate::SLOTS) {
        return Err(UsbProError::BadChange);
    }
    for (index, &value) in indices.zip(values) {
        if index > 0 {
            levels.set_slot(index - 1, value); // index 0 is the START code
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::usbpro::packet::encode;

    fn feed(rx: &mut UsbProReceiver, bytes: &[u8]) -> (Vec<Disposition<UsbProError>>, Vec<Levels>) {
        let (mut d, mut l) = (Vec::new(), Vec::new());
        rx.handle(
            bytes,
            Instant::now(),
            &mut |e| {
                if let EventKind::Levels { levels, .. } = e.kind {
                    l.push(levels)
                }
            },
            &mut |x| d.push(x),
        );
        (d, l)
    }

    #[test]
    fn label5_status_and_start_code() {
        let mut rx = UsbProReceiver::new(0, ReceiveMode::EveryFrame);
        let (d, l) = feed(&mut rx, &encode(5, &[0, 0, 10, 20]));
        assert_eq!((d, l[0].as_slice()), (vec![Disposition::Applied], &[10u8, 20][..]));
        assert_eq!(feed(&mut rx, &encode(5, &[2, 0, 1])).0, vec![Disposition::Dropped(DropReason::WidgetOverrun)]);
        assert_eq!(
            feed(&mut rx, &encode(5, &[0, 0xCC, 1])).0,
            vec![Disposition::Ignored(IgnoreReason::StartCode(0xCC))]
        );
        assert_eq!(feed(&mut rx, &encode(5, &[0])).0, vec![Disposition::Malformed(UsbProError::ShortDmx { len: 1 })]);
        assert_eq!(feed(&mut rx, &encode(3, &[1, 2])).0, vec![Disposition::Ignored(IgnoreReason::Label(3))]);
    }

    #[test]
    fn label9_patches_the_universe() {
        let mut rx = UsbProReceiver::new(0, ReceiveMode::ChangesOnly);
        // Block 0: bit 0 = START code, bits 1 and 3 = slots 1 and 3.
        let (d, l) = feed(&mut rx, &encode(9, &[0, 0b1011, 0, 0, 0, 0, 0, 7, 9]));
        assert_eq!((d, l[0].as_slice()), (vec![Disposition::Applied], &[7u8, 0, 9][..]));
        // Block 2 (index 16..55): bit 0 = slot 16, bit 39 = slot 55.
        let (_, l) = feed(&mut rx, &encode(9, &[2, 1, 0, 0, 0, 0x80, 5, 6]));
        assert_eq!((l[0].as_slice()[15], l[0].as_slice()[54], l[0].as_slice()[0]), (5, 6, 7));
        // Count mismatch, and an index past 512 (block 64 covers 512..551).
        assert_eq!(
            feed(&mut rx, &encode(9, &[0, 1, 0, 0, 0, 0])).0,
            vec![Disposition::Malformed(UsbProError::BadChange)]
        );
        assert_eq!(
            feed(&mut rx, &encode(9, &[64, 2, 0, 0, 0, 0, 1])).0,
            vec![Disposition::Malformed(UsbProError::BadChange)]
        );
        let (d, l) = feed(&mut rx, &encode(9, &[64, 1, 0, 0, 0, 0, 3]));
        assert_eq!((d, l[0].as_slice()[511]), (vec![Disposition::Applied], 3));
    }
}
