//! A bounded load of preview clients on loopback, for tests and
//! `footlight bench`: N keep-alive connections each polling
//! `/api/frame.png` back to back (what the preview page does) until a
//! deadline. Hand-written over tokio's TCP stream (about 60 lines) rather
//! than a client crate: it needs only `Content-Length` responses, and
//! hyper's client side is not compiled into the daemon.

use super::png::FRAME_HEADER;
use std::net::SocketAddr;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;
use tokio::time::Instant;

/// What a load run saw.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// Clients started.
    pub clients: usize,
    /// Clients that got at least one PNG.
    pub clients_served: usize,
    /// `200 OK` PNG responses received.
    pub frames: u64,
    /// Response bytes (bodies) received.
    pub bytes: u64,
    /// Requests that failed (connection error, a status other than 200, a malformed response).
    pub errors: u64,
    /// Distinct frame numbers seen (from the frame header).
    pub distinct_frames: usize,
    /// One received PNG with its frame number, for checking its content.
    pub sample: Option<(u64, Vec<u8>)>,
}

/// Runs `clients` clients against `addr` for `duration`, then returns. Every
/// client stops by itself at the deadline; a request in flight at the
/// deadline is abandoned.
pub async fn poll_frames(addr: SocketAddr, clients: usize, duration: Duration) -> LoadReport {
    let deadline = Instant::now() + duration;
    let mut tasks = tokio::task::JoinSet::new();
    for i in 0..clients {
        tasks.spawn(client(addr, deadline, i == 0));
    }
    let mut report = LoadReport { clients, ..LoadReport::default() };
    let mut seen = std::collections::BTreeSet::new();
    while let Some(done) = tasks.join_next().await {
        let Ok(c) = done else {
            report.errors += 1;
            continue;
        };
        report.clients_served += usize::from(c.frames > 0);
        report.frames += c.frames;
        report.bytes += c.bytes;
        report.errors += c.errors;
        seen.extend(c.numbers);
        if report.sample.is_none() {
            report.sample = c.sample;
        }
    }
    report.distinct_frames = seen.len();
    report
}

/// One client's tally.
#[derive(Default)]
struct ClientTally {
    frames: u64,
    bytes: u64,
    errors: u64,
    numbers: std::collections::BTreeSet<u64>,
    sample: Option<(u64, Vec<u8>)>,
}

/// Polls back to back on one keep-alive connection (reconnecting after an
/// error) until `deadline`.
async fn client(addr: SocketAddr, deadline: Instant, keep_sample: bool) -> ClientTally {
    let mut t = ClientTally::default();
    let mut stream: Option<BufReader<TcpStream>> = None;
    while Instant::now() < deadline {
        let s = match stream.as_mut() {
            Some(s) => s,
            None => match tokio::time::timeout_at(deadline, TcpStream::connect(addr)).await {
                Ok(Ok(s)) => stream.insert(BufReader::new(s)),
                Ok(Err(_)) => {
                    t.errors += 1;
                    tokio::time::sleep(Duration::from_millis(10)).await;
                    continue;
                }
                Err(_) => break,
            },
        };
        match tokio::time::timeout_at(deadline, get_frame(s, addr)).await {
            Ok(Ok((number, body))) => {
                t.frames += 1;
                t.bytes += body.len() as u64;
                t.numbers.insert(number);
                if keep_sample && t.sample.is_none() {
                    t.sample = Some((number, body));
                }
            }
            Ok(Err(_)) => {
                t.errors += 1;
                stream = None;
            }
            Err(_) => break,
        }
    }
    t
}

/// One keep-alive GET of the frame: its number and the PNG.
async fn get_frame(s: &mut BufReader<TcpStream>, addr: SocketAddr) -> std::io::Result<(u64, Vec<u8>)> {
    let bad = |what: &str| std::io::Error::new(std::io::ErrorKind::InvalidData, what.to_string());
    s.get_mut().write_all(format!("GET /api/frame.png HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes()).await?;
    let mut head = String::with_capacity(256);
    loop {
        let before = head.len();
        if s.read_line(&mut head).await? == 0 || head.len() > 16 * 1024 {
            return Err(bad("response head"));
        }
        if head[before..].trim().is_empty() {
            break;
        }
    }
    let head = head.to_ascii_lowercase();
    if !head.starts_with("http/1.1 200") {
        return Err(bad("status"));
    }
    let field = |name: &str| {
        head.lines().find_map(|l| l.strip_prefix(name).and_then(|v| v.strip_prefix(':')).map(|v| v.trim().to_string()))
    };
    let len: usize = field("content-length").and_then(|v| v.parse().ok()).ok_or_else(|| bad("content-length"))?;
    let number: u64 = field(FRAME_HEADER).and_then(|v| v.parse().ok()).ok_or_else(|| bad("frame header"))?;
    let mut body = vec![0u8; len];
    s.read_exact(&mut body).await?;
    Ok((number, body))
}
