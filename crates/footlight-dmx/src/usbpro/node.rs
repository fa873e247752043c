//! The USB Pro node: opens the serial port, asks for receive mode, reads
//! messages, and reopens the port with backoff when the widget is unplugged.
//!
//! `serialport` is blocking, so the node runs on a `spawn_blocking` thread
//! that reads with a 100 ms timeout and checks a stop flag between reads. On
//! open it sends label 8 (receive DMX on change) and nothing else: label 6
//! would switch the widget to output. When the port fails (unplugged), the
//! source leaves the merge (the frame holds, stale) and the node retries
//! every 0.25 s, doubling to 5 s, logging the first failure as a warning.

use std::future::Future;
use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use serialport::SerialPort;
use tokio::time::Instant;

use super::packet::{encode, label};
use super::receiver::{ReceiveMode, UsbProReceiver};
use crate::net::{LogLimiter, NodeContext};
use crate::source::{Disposition, EventKind, InputUniverse, Protocol, SourceEvent};

/// USB Pro node settings.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UsbProConfig {
    /// Serial device, e.g. `/dev/ttyUSB0`.
    pub port: String,
    /// Widget index (source id; default map: widget N-1 → patch universe N).
    pub widget: u8,
    /// Every frame (label 5) or changes only (label 9).
    pub mode: ReceiveMode,
    /// First retry delay after the port fails or will not open.
    pub retry_min: Duration,
    /// Longest retry delay.
    pub retry_max: Duration,
}

impl UsbProConfig {
    /// Widget 0 on `port`, every-frame mode, default retries.
    pub fn new(port: impl Into<String>) -> Self {
        UsbProConfig {
            port: port.into(),
            widget: 0,
            mode: ReceiveMode::EveryFrame,
            retry_min: Duration::from_millis(250),
            retry_max: Duration::from_secs(5),
        }
    }
}

/// Opens the serial port (injectable, so tests can hand in a pty).
pub type Opener = Box<dyn FnMut() -> io::Result<Box<dyn SerialPort>> + Send>;

/// Read timeout: how quickly the thread notices a stop request.
const READ_TIMEOUT: Duration = Duration::from_millis(100);

/// A USB Pro input.
pub struct UsbProNode {
    config: UsbProConfig,
    opener: Opener,
}

impl UsbProNode {
    /// A node that opens `config.port` at 115200 8N1 (the USB Pro ignores the rate).
    pub fn new(config: UsbProConfig) -> Self {
        let path = config.port.clone();
        let opener: Opener =
            Box::new(move || serialport::new(&path, 115_200).timeout(READ_TIMEOUT).open().map_err(io::Error::from));
        UsbProNode { config, opener }
    }

    /// A node that gets its port from `opener` (called again after each failure).
    pub fn with_opener(config: UsbProConfig, opener: Opener) -> Self {
        UsbProNode { config, opener }
    }

    /// Reads until `shutdown` resolves or `ctx.events` closes.
    pub async fn run(self, ctx: NodeContext, shutdown: impl Future<Output = ()>) {
        let stop = Arc::new(AtomicBool::new(false));
        let stop_thread = Arc::clone(&stop);
        let mut thread = tokio::task::spawn_blocking(move || self.blocking_loop(&ctx, &stop_thread));
        tokio::select! {
            () = shutdown => {
                stop.store(true, Ordering::Relaxed);
                let _ = thread.await;
            }
            _ = &mut thread => {}
        }
    }

    fn blocking_loop(mut self, ctx: &NodeContext, stop: &AtomicBool) {
        let port_name = self.config.port.clone();
        let mut receiver = UsbProReceiver::new(self.config.widget, self.config.mode);
        let mut delay = self.config.retry_min;
        let mut failures = 0u32;
        while !stop.load(Ordering::Relaxed) {
            let mut port = match (self.opener)() {
                Ok(port) => port,
                Err(e) => {
                    if failures == 0 {
                        tracing::warn!(port = %port_name, %e, "cannot open USB Pro widget; retrying");
                    } else {
                        tracing::debug!(port = %port_name, %e, failures, "USB Pro widget still missing");
                    }
                    failures += 1;
                    sleep_unless_stopped(delay, stop);
                    delay = (delay * 2).min(self.config.retry_max);
                    continue;
                }
            };
            tracing::info!(port = %port_name, "USB Pro widget open, receive mode {:?}", self.config.mode);
            (failures, delay) = (0, self.config.retry_min);
            receiver.reset();
            match self.read_port(&mut *port, &mut receiver, ctx, stop) {
                Ok(()) => return,
                Err(e) => tracing::warn!(port = %port_name, %e, "USB Pro widget lost; reopening"),
            }
            drop(port);
            // The widget is gone: its source leaves the merge (the frame holds, stale).
            let gone = SourceEvent {
                at: Instant::now(),
                input: InputUniverse::UsbPro(self.config.widget),
                source: receiver.source(),
                kind: EventKind::Gone,
            };
            if ctx.events.blocking_send(gone).is_err() {
                return;
            }
            sleep_unless_stopped(delay, stop);
        }
    }

    /// Requests receive mode, then reads until a stop (`Ok`) or until the
    /// port fails (`Err`).
    fn read_port(
        &self,
        port: &mut dyn SerialPort,
        receiver: &mut UsbProReceiver,
        ctx: &NodeContext,
        stop: &AtomicBool,
    ) -> io::Result<()> {
        port.set_timeout(READ_TIMEOUT)?;
        port.write_all(&encode(label::RECEIVE_DMX_ON_CHANGE, &[self.config.mode.request_byte()]))?;
        port.flush()?;
        let mut buf = [0u8; 1024];
        let mut events = Vec::new();
        let mut malformed_log = LogLimiter::new();
        let widget = self.config.widget;
        loop {
            if stop.load(Ordering::Relaxed) {
                return Ok(());
            }
            let n = match port.read(&mut buf) {
                Ok(0) => return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "serial port closed")),
                Ok(n) => n,
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => continue,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            let now = Instant::now();
            let source = Some(receiver.source());
            receiver.handle(&buf[..n], now, &mut |e| events.push(e), &mut |d| {
                if let Disposition::Malformed(e) = &d
                    && let Some(suppressed) = malformed_log.allow(now)
                {
                    tracing::warn!(widget, suppressed, "malformed USB Pro message: {e}");
                }
                ctx.stats.lock().packet(Protocol::UsbPro, source, None, &d);
            });
            for event in events.drain(..) {
                if let (Some(tap), EventKind::Levels { levels, .. }) = (&ctx.tap, &event.kind) {
                    tap.usb_frame(event.at, widget, self.config.mode, levels);
                }
                if ctx.events.blocking_send(event).is_err() {
                    return Ok(());
                }
            }
        }
    }
}

fn sleep_unless_stopped(total: Duration, stop: &AtomicBool) {
    let step = Duration::from_millis(50);
    let mut left = total;
    while !left.is_zero() && !stop.load(Ordering::Relaxed) {
        let d = left.min(step);
        std::thread::sleep(d);
        left -= d;
    }
}
