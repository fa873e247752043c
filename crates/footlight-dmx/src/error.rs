//! The crate's error type: what stops a caller. Bad packets are not errors
//! (they are [`crate::Disposition`] values, counted and logged), so this enum
//! only holds setup and file failures, each with the context a user needs.

use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;

use crate::record::CaptureError;
use crate::source::Protocol;

/// Why DMX input, recording or replay could not start or go on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A UDP socket could not be created or bound (port taken without
    /// SO_REUSEPORT, address not on this machine, …).
    #[error("cannot bind the {protocol} socket to {addr}: {source}")]
    Bind {
        /// Which protocol's socket.
        protocol: Protocol,
        /// The address asked for.
        addr: SocketAddr,
        /// What the OS said.
        source: io::Error,
    },
    /// A capture file could not be created, read or written.
    #[error("{}: {source}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: io::Error,
    },
    /// A capture file is not a pcap/pcapng file this crate can read.
    #[error("{}: {source}", path.display())]
    Capture {
        /// The file.
        path: PathBuf,
        /// What is wrong with it, with the byte offset.
        source: CaptureError,
    },
    /// A recording holds no DMX data for the patch (wrong routes, or no
    /// ArtDmx / E1.31 data at all).
    #[error("{}: {holds}", path.display())]
    NoPatchedDmx {
        /// The recording.
        path: PathBuf,
        /// Which input universes it does hold, or that it holds no DMX.
        holds: String,
    },
    /// A configuration value is out of range (e.g. a replay speed of 0).
    #[error("invalid DMX input configuration: {0}")]
    Config(String),
}
