//! Enttec USB Pro over pseudo-terminals: a `TTYPort::pair()` injected into the
//! node, and a socat pair opened by path (unplug = kill socat).

use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use footlight_dmx::usbpro::packet::encode;
use footlight_dmx::usbpro::{Opener, ReceiveMode, UsbProConfig, UsbProNode};
use footlight_dmx::{DmxInput, InputConfig, InputPatch, SourceId};
use serialport::{SerialPort, TTYPort};

use crate::common::{Running, require};

/// The label 8 request the node must send on open (every-frame mode).
const RECEIVE_MODE_REQUEST: [u8; 6] = [0x7E, 8, 1, 0, 0, 0xE7];

fn config(port: &str) -> UsbProConfig {
    UsbProConfig {
        retry_min: Duration::from_millis(20),
        retry_max: Duration::from_millis(200),
        ..UsbProConfig::new(port)
    }
}

async fn input_with(node: UsbProNode) -> Running {
    let only_usb = InputConfig { artnet: None, sacn: None, usbpro: None, patch: InputPatch::default() };
    Running::start_input(DmxInput::bind(only_usb).await.unwrap().with_usbpro(node)).await
}

/// Reads exactly `n` bytes (bounded by the port's timeout per read, 50 tries).
fn read_n(port: &mut dyn Read, n: usize) -> Vec<u8> {
    let mut got = Vec::new();
    let mut buf = [0u8; 64];
    for _ in 0..50 {
        if got.len() >= n {
            break;
        }
        match port.read(&mut buf) {
            Ok(k) => got.extend_from_slice(&buf[..k]),
            Err(e) if e.kind() == io::ErrorKind::TimedOut => {}
            Err(e) => panic!("reading the widget side: {e}"),
        }
    }
    got
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pty_pair_garbage_bad_end_unplug_and_replug() {
    let (mut master, slave) = TTYPort::pair().expect("pty pair");
    let (ports, next_port) = std::sync::mpsc::channel::<TTYPort>();
    ports.send(slave).unwrap();
    let opener: Opener = Box::new(move || match next_port.try_recv() {
        Ok(port) => Ok(Box::new(port) as Box<dyn SerialPort>),
        Err(_) => Err(io::Error::new(io::ErrorKind::NotFound, "widget unplugged")),
    });
    let mut input = input_with(UsbProNode::with_opener(config("pty"), opener)).await;

    let request = tokio::task::block_in_place(|| read_n(&mut master, 6));
    assert_eq!(request, RECEIVE_MODE_REQUEST, "receive mode requested, nothing else (never label 6)");

    let mut bytes = vec![0x00, 0x13, 0xE7, 0x55]; // garbage before the first frame
    bytes.extend(encode(5, &[0, 0, 10, 20, 30]));
    let mut bad = encode(5, &[0, 0, 99, 99, 99]);
    *bad.last_mut().unwrap() = 0x00; // bad end byte
    bytes.extend(bad);
    bytes.extend(encode(5, &[0, 0, 11, 21]));
    master.write_all(&bytes).unwrap();
    let f = input.wait_slots(1, &[11, 21, 0]).await;
    assert!(!f.stale);
    let s = input.stats.snapshot();
    assert_eq!((s.usbpro.received, s.usbpro.malformed, s.usbpro.applied), (4, 2, 2));
    assert_eq!(s.sources[&SourceId::UsbPro { widget: 0 }].applied, 2);

    // Unplug: the frame holds, stale.
    drop(master);
    let u = input.wait_until("stale after unplug", |u| u.get(1).is_some_and(|f| f.stale)).await;
    assert_eq!(u.get(1).unwrap().slots[..2], [11, 21]);

    // Replug: the node reopens, asks for receive mode again, and data flows.
    let (mut master, slave) = TTYPort::pair().unwrap();
    ports.send(slave).unwrap();
    let request = tokio::task::block_in_place(|| read_n(&mut master, 6));
    assert_eq!(request, RECEIVE_MODE_REQUEST);
    master.write_all(&encode(5, &[0, 0, 42])).unwrap();
    let f = input.wait_slots(1, &[42]).await;
    assert!(!f.stale);
    input.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn change_of_state_mode_patches_slots() {
    let (mut master, slave) = TTYPort::pair().unwrap();
    let mut slave = Some(slave);
    let opener: Opener = Box::new(move || {
        slave.take().map(|p| Box::new(p) as Box<dyn SerialPort>).ok_or_else(|| io::Error::other("gone"))
    });
    let node = UsbProNode::with_opener(UsbProConfig { mode: ReceiveMode::ChangesOnly, ..config("pty") }, opener);
    let mut input = input_with(node).await;
    let request = tokio::task::block_in_place(|| read_n(&mut master, 6));
    assert_eq!(request, [0x7E, 8, 1, 0, 1, 0xE7]);
    // Block 0, mask bits 1 and 2: slots 1 and 2. Block 1, bit 0: slot 8.
    master.write_all(&encode(9, &[0, 0b110, 0, 0, 0, 0, 5, 6])).unwrap();
    master.write_all(&encode(9, &[1, 1, 0, 0, 0, 0, 8])).unwrap();
    input.wait_slots(1, &[5, 6, 0, 0, 0, 0, 0, 8]).await;
    input.stop().await;
}

/// A socat pty pair with stable link names, killed on drop.
struct Socat {
    child: Child,
}

impl Socat {
    fn start(widget: &Path, desk: &Path) -> Socat {
        let child = Command::new("socat")
            .arg("-d")
            .arg(format!("pty,raw,echo=0,link={}", widget.display()))
            .arg(format!("pty,raw,echo=0,link={}", desk.display()))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("socat starts");
        let socat = Socat { child }; // killed and waited for on drop, also if we panic below
        for _ in 0..100 {
            if widget.exists() && desk.exists() {
                return socat;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        panic!("socat made no ptys in 2 s");
    }
}

impl Drop for Socat {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn open_desk(path: &Path) -> Box<dyn SerialPort> {
    serialport::new(path.to_string_lossy(), 115_200).timeout(Duration::from_millis(100)).open().expect("open desk side")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn socat_pair_opened_by_path_recovers_from_unplugging() {
    if !require("socat", "socat") {
        return;
    }
    let dir: PathBuf = std::env::temp_dir().join(format!("footlight-dmx-socat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (widget, desk) = (dir.join("widget"), dir.join("desk"));
    let socat = Socat::start(&widget, &desk);
    let mut port = open_desk(&desk);
    let mut input = input_with(UsbProNode::new(config(&widget.to_string_lossy()))).await;
    let request = tokio::task::block_in_place(|| read_n(&mut port, 6));
    assert_eq!(request, RECEIVE_MODE_REQUEST);
    port.write_all(&encode(5, &[0, 0, 1, 2, 3])).unwrap();
    input.wait_slots(1, &[1, 2, 3]).await;

    // Unplug: socat goes away with both ptys.
    drop(port);
    drop(socat);
    input.wait_until("stale after unplug", |u| u.get(1).is_some_and(|f| f.stale)).await;
    // Plug back in under the same name: the node finds it again.
    let _socat = Socat::start(&widget, &desk);
    let mut port = open_desk(&desk);
    let request = tokio::task::block_in_place(|| read_n(&mut port, 6));
    assert_eq!(request, RECEIVE_MODE_REQUEST);
    port.write_all(&encode(5, &[0, 0, 4, 5])).unwrap();
    let f = input.wait_slots(1, &[4, 5]).await;
    assert!(!f.stale);
    input.stop().await;
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_routed_widget_feeds_its_patch_universe_and_an_unrouted_one_is_unpatched() {
    // Widget 0 → patch universe 3; patch universes 3 only.
    let mut patch = InputPatch { universes: vec![3], ..InputPatch::default() };
    patch.map.route(footlight_dmx::InputUniverse::UsbPro(0), 3);
    let start = async |widget: u8, patch: InputPatch| {
        let (master, slave) = TTYPort::pair().unwrap();
        let mut slave = Some(slave);
        let opener: Opener = Box::new(move || {
            slave.take().map(|p| Box::new(p) as Box<dyn SerialPort>).ok_or_else(|| io::Error::other("gone"))
        });
        let node = UsbProNode::with_opener(UsbProConfig { widget, ..config("pty") }, opener);
        let only_usb = InputConfig { artnet: None, sacn: None, usbpro: None, patch };
        (master, Running::start_input(DmxInput::bind(only_usb).await.unwrap().with_usbpro(node)).await)
    };
    let (mut master, mut input) = start(0, patch.clone()).await;
    tokio::task::block_in_place(|| read_n(&mut master, 6));
    master.write_all(&encode(5, &[0, 0, 7, 8])).unwrap();
    input.wait_slots(3, &[7, 8]).await;
    assert!(input.frames.borrow().get(1).is_none());
    let status = input.status.snapshot();
    assert_eq!(status.universes[0].sources[0].widget, Some(0));
    input.stop().await;

    // Widget 1 has no route and its default (patch 2) is not patched: counted, shown, dropped.
    let (mut master, input) = start(1, patch).await;
    tokio::task::block_in_place(|| read_n(&mut master, 6));
    master.write_all(&encode(5, &[0, 0, 9])).unwrap();
    for _ in 0..500 {
        if input.stats.snapshot().usbpro.ignored == 1 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let status = input.status.snapshot();
    assert_eq!(status.counters.usbpro.ignored, 1);
    let u = &status.unpatched[0];
    assert_eq!((u.input.universe, u.packets, u.default_patch_universe), (1, 1, Some(2)));
    assert!(input.frames.borrow().is_empty());
    input.stop().await;
}
