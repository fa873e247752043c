//! Enttec DMX USB Pro input: [`packet`] is the framing codec, [`receiver`]
//! turns labels 5 and 9 into levels, [`node`] owns the serial port (receive
//! mode request, reconnect with backoff).

pub mod node;
pub mod packet;
pub mod receiver;

pub use node::{Opener, UsbProConfig, UsbProNode};
pub use packet::{Decoder, Message, UsbProError};
pub use receiver::{ReceiveMode, UsbProReceiver};
