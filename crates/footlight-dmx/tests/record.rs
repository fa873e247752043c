//! Record, replay, state_at; captures written or converted by tshark/tcpdump.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use footlight_dmx::artnet::packet::build_dmx;
use footlight_dmx::record::PcapngWriter;
use footlight_dmx::sacn::packet::{DataSpec, OPTION_TERMINATED, build_data};
use footlight_dmx::usbpro::packet::encode;
use footlight_dmx::usbpro::{Opener, UsbProConfig, UsbProNode};
use footlight_dmx::{
    DmxInput, InputPatch, InputUniverse, Recording, ReplayOptions, StatusHandle, UniverseFrame, Universes,
    record_input, replay, state_at,
};
use serialport::{SerialPort, TTYPort};
use tokio::sync::oneshot;

use crate::common::{Running, loopback_config, require, sender};

fn sacn(cid: u8, priority: u8, seq: u8, universe: u16, options: u8, slots: &[u8]) -> Vec<u8> {
    build_data(&DataSpec {
        cid: [cid; 16],
        source_name: "t",
        priority,
        sync_address: 0,
        sequence: seq,
        options,
        universe,
        start_code: 0,
        slots,
    })
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("footlight-dmx-record-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// (universe, slots, stale): a frame without its timestamp.
type Look = (u16, Vec<u8>, bool);

fn look(f: &UniverseFrame) -> Look {
    (f.universe, f.slots.to_vec(), f.stale)
}

fn looks(u: &Universes) -> Vec<Look> {
    u.iter().map(look).collect()
}

/// Replays as fast as possible and returns every frame the sink saw.
async fn replay_all(path: &Path, patch: InputPatch) -> (Vec<Look>, footlight_dmx::ReplaySummary) {
    let recording = Recording::open(path).unwrap();
    let options = ReplayOptions { speed: f64::INFINITY, patch, ..ReplayOptions::default() };
    let mut seen = Vec::new();
    let summary = replay(&recording, &options, |f| seen.push(look(f)), std::future::pending()).await.unwrap();
    (seen, summary)
}

#[tokio::test]
async fn record_then_replay_gives_the_same_merged_frames() {
    let path = temp("live.pcapng");
    let input = DmxInput::bind(loopback_config(vec![])).await.unwrap();
    let (mut frames, addrs) = (input.frames(), input.local_addrs());
    let (stop, stopped) = oneshot::channel::<()>();
    let out = path.clone();
    let recorder = tokio::spawn(async move { record_input(&out, input, async { stopped.await.unwrap() }).await });
    let (art, sac) = (addrs.artnet.unwrap(), addrs.sacn.unwrap());
    let tx = sender();
    let mut snapshots = Vec::new();
    let mut phase = async |packets: &[(&[u8], std::net::SocketAddr)], until: &dyn Fn(&Universes) -> bool| {
        for (p, to) in packets {
            tx.send_to(p, to).unwrap();
        }
        let got = tokio::time::timeout(Duration::from_secs(5), frames.wait_for(|u| until(u))).await;
        snapshots.push(looks(&got.expect("phase reached").unwrap()));
    };
    let (a, b) = (sacn(1, 100, 1, 1, 0, &[10, 20]), build_dmx(0, 0, 0, &[30]));
    phase(&[(&a, sac), (&b, art)], &|u| u.get(1).is_some_and(|f| f.slots[..2] == [30, 20])).await;
    let c = sacn(2, 150, 1, 1, 0, &[1]);
    phase(&[(&c, sac)], &|u| u.get(1).is_some_and(|f| f.slots[..2] == [1, 0])).await;
    let d = sacn(2, 150, 2, 1, OPTION_TERMINATED, &[1]);
    phase(&[(&d, sac)], &|u| u.get(1).is_some_and(|f| f.slots[..2] == [30, 20])).await;
    let (e, junk) = (build_dmx(0, 0, 1, &[5, 6]), b"Art-Net\0\x00\x50\x00".to_vec());
    phase(&[(&junk, art), (&e, art)], &|u| u.get(2).is_some_and(|f| f.slots[..2] == [5, 6])).await;
    stop.send(()).unwrap();
    let summary = recorder.await.unwrap().unwrap();
    assert_eq!((summary.packets, summary.lost), (6, 0));

    let (seen, replayed) = replay_all(&path, InputPatch::default()).await;
    assert_eq!(replayed.packets, 6);
    assert_eq!(replayed.stats.artnet.malformed, 1, "the junk datagram was recorded and is malformed again");
    // Every state live input settled in appears, in order, among the replayed frames.
    let mut at = 0;
    for snapshot in &snapshots {
        for frame in snapshot {
            let found = seen[at..].iter().position(|f| f == frame).map(|i| i + at);
            at = found.unwrap_or_else(|| panic!("live frame {:?} not replayed after #{at}: {seen:?}", &frame.1[..4]));
        }
    }
    let recording = Recording::open(&path).unwrap();
    let end = state_at(&recording, recording.duration(), &InputPatch::default()).unwrap();
    assert_eq!(end.iter().map(look).collect::<Vec<_>>(), *snapshots.last().unwrap());
    let _ = std::fs::remove_file(&path);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn usb_frames_are_recorded_as_artdmx_and_replayed_as_the_widget() {
    let path = temp("usb.pcapng");
    let (mut master, slave) = TTYPort::pair().unwrap();
    let mut slave = Some(slave);
    let opener: Opener = Box::new(move || {
        slave.take().map(|p| Box::new(p) as Box<dyn SerialPort>).ok_or_else(|| std::io::Error::other("gone"))
    });
    let config = footlight_dmx::InputConfig { artnet: None, sacn: None, usbpro: None, patch: InputPatch::default() };
    let input =
        DmxInput::bind(config).await.unwrap().with_usbpro(UsbProNode::with_opener(UsbProConfig::new("pty"), opener));
    let mut frames = input.frames();
    let (stop, stopped) = oneshot::channel::<()>();
    let out = path.clone();
    let recorder = tokio::spawn(async move { record_input(&out, input, async { stopped.await.unwrap() }).await });
    use std::io::Write;
    master.write_all(&encode(5, &[0, 0, 1, 2, 3])).unwrap();
    master.write_all(&encode(5, &[0, 0, 4, 5, 6])).unwrap();
    let got =
        tokio::time::timeout(Duration::from_secs(5), frames.wait_for(|u| u.get(1).is_some_and(|f| f.slots[0] == 4)));
    got.await.unwrap().unwrap();
    stop.send(()).unwrap();
    let summary = recorder.await.unwrap().unwrap();
    assert_eq!(summary.packets, 2);
    let (seen, replayed) = replay_all(&path, InputPatch::default()).await;
    assert_eq!(replayed.stats.usbpro.applied, 2, "{:?}", replayed.stats);
    assert_eq!(seen.last().unwrap().1[..3], [4, 5, 6]);
    if require("tshark", "tshark") {
        let fields = tshark(&path, &["-T", "fields", "-e", "artnet.output.universe", "-e", "frame.comment"]);
        assert!(fields.lines().all(|l| l.starts_with("0\tfootlight-dmx usbpro widget=0")), "{fields}");
    }
    let _ = std::fs::remove_file(&path);
}

fn tshark(path: &Path, args: &[&str]) -> String {
    let out = Command::new("tshark").arg("-r").arg(path).args(args).output().expect("tshark runs");
    assert!(out.status.success(), "tshark: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// A pcapng written by hand: Art-Net PA 0 at 0, 1, 2 s with slot 1 = 10, 20, 30,
/// and sACN universe 2 at 0.5 s.
fn small_capture(path: &Path) {
    let file = std::fs::File::create(path).unwrap();
    let mut w = PcapngWriter::new(std::io::BufWriter::new(file)).unwrap();
    let (desk, node) = ("192.0.2.1:6454".parse().unwrap(), "192.0.2.2:6454".parse().unwrap());
    let t0 = Duration::from_secs(1_700_000_000);
    for (i, v) in [10u8, 20, 30].into_iter().enumerate() {
        w.write_udp(t0 + Duration::from_secs(i as u64), desk, node, &build_dmx(i as u8 + 1, 0, 0, &[v, 1]), None)
            .unwrap();
        if i == 0 {
            let (from, to) = ("192.0.2.1:49152".parse().unwrap(), "239.255.0.2:5568".parse().unwrap());
            w.write_udp(t0 + Duration::from_millis(500), from, to, &sacn(1, 100, 1, 2, 0, &[99]), None).unwrap();
        }
    }
    w.flush().unwrap();
}

#[tokio::test]
async fn tshark_decodes_our_pcapng_and_its_classic_pcap_replays_the_same() {
    let path = temp("small.pcapng");
    small_capture(&path);
    if !require("tshark", "tshark") {
        return;
    }
    let fields = tshark(&path, &["-T", "fields", "-e", "ip.src", "-e", "udp.dstport", "-e", "artnet.output.universe"]);
    assert_eq!(
        fields.lines().collect::<Vec<_>>(),
        ["192.0.2.1\t6454\t0", "192.0.2.1\t5568\t", "192.0.2.1\t6454\t0", "192.0.2.1\t6454\t0"]
    );
    // Wireshark's ACN dissector is a heuristic that is off by default.
    let details = tshark(&path, &["--enable-heuristic", "acn", "-o", "acn.dmx_enable:TRUE", "-V"]);
    assert!(details.contains("Streaming DMX, Universe: 2, Priority: 100"), "tshark decodes the sACN packet: {details}");

    let recording = Recording::open(&path).unwrap();
    let ours = state_at(&recording, Duration::from_millis(1500), &InputPatch::default()).unwrap();
    assert_eq!(ours.iter().map(|f| (f.universe, f.slots[0])).collect::<Vec<_>>(), [(1, 20), (2, 99)]);
    for format in ["pcap", "nsecpcap"] {
        let converted = temp(&format!("small.{format}"));
        let status =
            Command::new("tshark").arg("-r").arg(&path).args(["-F", format, "-w"]).arg(&converted).status().unwrap();
        assert!(status.success());
        let theirs = Recording::open(&converted).unwrap();
        assert_eq!(theirs.dmx_packets(), 4);
        let state = state_at(&theirs, Duration::from_millis(1500), &InputPatch::default()).unwrap();
        assert_eq!(state.iter().map(look).collect::<Vec<_>>(), ours.iter().map(look).collect::<Vec<_>>(), "{format}");
        let _ = std::fs::remove_file(&converted);
    }
    let _ = std::fs::remove_file(&path);
}

#[tokio::test(start_paused = true)]
async fn replay_paces_packets_at_speed_and_can_jump() {
    let path = temp("pacing.pcapng");
    small_capture(&path);
    let recording = Recording::open(&path).unwrap();
    assert_eq!((recording.dmx_packets(), recording.duration()), (4, Duration::from_secs(2)));
    let t0 = tokio::time::Instant::now();
    let mut when = Vec::new();
    let options = ReplayOptions { speed: 2.0, ..ReplayOptions::default() };
    replay(&recording, &options, |f| when.push((f.universe, f.slots[0], t0.elapsed())), std::future::pending())
        .await
        .unwrap();
    let ms = Duration::from_millis;
    assert_eq!(when, [(1, 10, ms(0)), (2, 99, ms(250)), (1, 20, ms(500)), (1, 30, ms(1000))]);

    // Start 1.5 s in: the state there first, then the rest in real time.
    let t0 = tokio::time::Instant::now();
    let mut when = Vec::new();
    let options = ReplayOptions { speed: 1.0, start: ms(1500), ..ReplayOptions::default() };
    replay(&recording, &options, |f| when.push((f.universe, f.slots[0], t0.elapsed())), std::future::pending())
        .await
        .unwrap();
    assert_eq!(when, [(1, 20, ms(0)), (2, 99, ms(0)), (1, 30, ms(500))]);

    // A shutdown stops it early; a speed of 0 is refused.
    let options = ReplayOptions::default();
    let summary = replay(&recording, &options, |_| {}, tokio::time::sleep(ms(1200))).await.unwrap();
    assert!(summary.interrupted && summary.packets == 3, "{summary:?}");
    let zero = ReplayOptions { speed: 0.0, ..ReplayOptions::default() };
    assert!(replay(&recording, &zero, |_| {}, std::future::pending()).await.is_err());
    let _ = std::fs::remove_file(&path);
}

/// Runs tcpdump on `iface` with link type `link` (None: default) until it has
/// captured `count` UDP packets to `port`; returns the file.
fn start_tcpdump(iface: &str, link: Option<&str>, port: u16, count: usize, file: &Path) -> Option<std::process::Child> {
    let mut cmd = Command::new("timeout");
    cmd.args(["15", "tcpdump", "-i", iface, "-U", "-c", &count.to_string(), "-w"]).arg(file);
    if let Some(link) = link {
        cmd.args(["-y", link]);
    }
    cmd.args(["udp", "and", "dst", "port", &port.to_string(), "and", "dst", "host", "127.0.0.1"]);
    let mut child = cmd.stdout(Stdio::null()).stderr(Stdio::piped()).spawn().ok()?;
    // tcpdump says "listening on …" once the capture is open.
    let mut stderr = BufReader::new(child.stderr.take()?);
    let mut line = String::new();
    while stderr.read_line(&mut line).ok()? > 0 {
        if line.contains("listening on") {
            std::thread::spawn(move || std::io::copy(&mut stderr, &mut std::io::sink()));
            return Some(child);
        }
        line.clear();
    }
    eprintln!("skipped: tcpdump could not capture on {iface} ({link:?}): {line}");
    let _ = child.wait();
    None
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tcpdump_captures_replay_ethernet_and_linux_cooked() {
    if !require("tcpdump", "tcpdump") {
        return;
    }
    let mut input = Running::start(loopback_config(vec![])).await;
    let (art, sac) = (input.artnet(), input.sacn());
    for (i, (iface, link)) in
        [("lo", None), ("any", Some("LINUX_SLL")), ("any", Some("LINUX_SLL2"))].into_iter().enumerate()
    {
        let file = temp(&format!("tcpdump-{i}.pcap"));
        let Some(mut dump) = start_tcpdump(iface, link, art.port(), 2, &file) else { continue };
        let Some(mut dump2) = start_tcpdump(iface, link, sac.port(), 1, &temp(&format!("tcpdump-{i}-sacn.pcap")))
        else {
            let _ = dump.kill();
            continue;
        };
        let v = 40 + i as u8;
        let tx = sender();
        tx.send_to(&build_dmx(0, 0, 0, &[v, v]), art).unwrap();
        tx.send_to(&build_dmx(0, 0, 3, &[v]), art).unwrap();
        tx.send_to(&sacn(7, 100, v, 9, 0, &[v]), sac).unwrap();
        input.wait_slots(4, &[v]).await;
        input.wait_slots(9, &[v]).await;
        let ok = tokio::task::block_in_place(|| dump.wait().unwrap().success() && dump2.wait().unwrap().success());
        assert!(ok, "tcpdump finished");
        for (f, expect) in [(file, vec![(1, v), (4, v)]), (temp(&format!("tcpdump-{i}-sacn.pcap")), vec![(9, v)])] {
            let recording = Recording::open(&f).unwrap();
            let state = state_at(&recording, recording.duration(), &InputPatch::default()).unwrap();
            assert_eq!(state.iter().map(|f| (f.universe, f.slots[0])).collect::<Vec<_>>(), expect, "{iface} {link:?}");
            let _ = std::fs::remove_file(&f);
        }
    }
    input.stop().await;
}

/// An OLA-like capture: ArtPoll, ArtPollReply and ArtTodRequest during the
/// first second (encoded by artnet_protocol or from the spec table), then
/// ArtDmx Port-Address 1 at 1.0 s (10) and 2.0 s (20), sACN universe 101 at
/// 1.2 s (50), ArtDmx Port-Address 0 at 1.5 s (99).
fn ola_like_capture(path: &Path, with_dmx: bool) {
    use artnet_protocol::{ArtCommand, Poll};
    let file = std::fs::File::create(path).unwrap();
    let mut w = PcapngWriter::new(std::io::BufWriter::new(file)).unwrap();
    let (ola, bcast) = ("192.0.2.1:6454".parse().unwrap(), "192.0.2.255:6454".parse().unwrap());
    let t0 = Duration::from_secs(1_700_000_000);
    let ms = |n: u64| t0 + Duration::from_millis(n);
    let poll = ArtCommand::Poll(Poll::default()).write_to_buffer().unwrap();
    let reply = ArtCommand::PollReply(Box::default()).write_to_buffer().unwrap();
    // ArtTodRequest (OpCode 0x8000): ID, OpCode LE, ProtVer 14, filler, Net, Command, AddCount, Address.
    let mut tod = b"Art-Net\0\x00\x80\x00\x0e".to_vec();
    tod.extend([0; 9]);
    tod.extend([0, 0, 1, 0]);
    w.write_udp(ms(0), ola, bcast, &poll, None).unwrap();
    w.write_udp(ms(10), ola, bcast, &reply, None).unwrap();
    w.write_udp(ms(500), ola, bcast, &tod, None).unwrap();
    if with_dmx {
        w.write_udp(ms(1000), ola, bcast, &build_dmx(0, 0, 1, &[10, 11]), None).unwrap();
        let (from, to) = ("192.0.2.1:49152".parse().unwrap(), "239.255.0.101:5568".parse().unwrap());
        w.write_udp(ms(1200), from, to, &sacn(1, 100, 1, 101, 0, &[50]), None).unwrap();
        w.write_udp(ms(1500), ola, bcast, &build_dmx(0, 0, 0, &[99]), None).unwrap();
        w.write_udp(ms(2000), ola, bcast, &build_dmx(0, 0, 1, &[20, 21]), None).unwrap();
    }
    w.flush().unwrap();
}

/// Art-Net Port-Address 1 → patch 1, sACN 101 → patch 2; patch universes 1 and 2.
fn routed_patch() -> InputPatch {
    let mut patch = InputPatch { universes: vec![1, 2], ..InputPatch::default() };
    patch.map.route(InputUniverse::ArtNet(1), 1).route(InputUniverse::Sacn(101), 2);
    patch
}

fn slots_of(frames: &[UniverseFrame], u: u16) -> Option<Vec<u8>> {
    frames.iter().find(|f| f.universe == u).map(|f| f.slots[..2].to_vec())
}

#[test]
fn state_at_0_is_the_first_patched_dmx_not_the_first_artpoll() {
    let path = temp("ola-like.pcapng");
    ola_like_capture(&path, true);
    let rec = Recording::open(&path).unwrap();
    assert_eq!(rec.dmx_packets(), 4, "ArtPoll, ArtPollReply and ArtTodRequest are not DMX data");
    assert_eq!(rec.duration(), Duration::from_secs(1));
    let routed = routed_patch();
    assert_eq!(rec.start_for(&routed).unwrap(), Duration::from_secs(1_700_000_001));
    let at = |t: u64, patch: &InputPatch| state_at(&rec, Duration::from_millis(t), patch).unwrap();
    let s = at(0, &routed);
    assert_eq!((slots_of(&s, 1), slots_of(&s, 2)), (Some(vec![10, 11]), None), "the first DMX levels at 0");
    let s = at(200, &routed);
    assert_eq!(slots_of(&s, 2), Some(vec![50, 0]), "sACN 101 drives patch universe 2");
    let s = at(1000, &routed);
    assert_eq!((slots_of(&s, 1), s.len()), (Some(vec![20, 21]), 2), "Port-Address 0 reaches nothing");
    // Without routes Port-Address 1 is patch universe 2, and 0 is 1.
    let s = at(600, &InputPatch::default());
    assert_eq!((slots_of(&s, 1), slots_of(&s, 2)), (Some(vec![99, 0]), Some(vec![10, 11])));
    // Patch universe 1 alone with the default map: time 0 is Port-Address 0's first packet (1.5 s).
    let only1 = InputPatch { universes: vec![1], ..InputPatch::default() };
    assert_eq!(slots_of(&at(0, &only1), 1), Some(vec![99, 0]));
    let _ = std::fs::remove_file(&path);
}

#[test]
fn a_recording_without_patched_dmx_is_an_error_that_names_what_it_holds() {
    let path = temp("unpatched.pcapng");
    ola_like_capture(&path, true);
    let rec = Recording::open(&path).unwrap();
    let far = InputPatch { universes: vec![7], ..InputPatch::default() };
    let err = state_at(&rec, Duration::ZERO, &far).unwrap_err().to_string();
    assert!(err.starts_with(&format!("{}: none of its DMX reaches patch universes 7", path.display())), "{err}");
    assert!(err.contains("Art-Net Port-Address 0 (1 packet, patch universe 1 by default)"), "{err}");
    assert!(err.contains("Art-Net Port-Address 1 (2 packets, patch universe 2 by default)"), "{err}");
    assert!(err.contains("sACN universe 101 (1 packet, patch universe 101 by default)"), "{err}");
    let empty = temp("no-dmx.pcapng");
    ola_like_capture(&empty, false);
    let rec = Recording::open(&empty).unwrap();
    let err = state_at(&rec, Duration::ZERO, &InputPatch::default()).unwrap_err().to_string();
    assert!(err.ends_with("it holds no DMX data at all (no ArtDmx, no E1.31 data with START code 0)"), "{err}");
    let _ = (std::fs::remove_file(&path), std::fs::remove_file(&empty));
}

#[tokio::test]
async fn replay_applies_routes_and_reports_status_like_live_input() {
    let path = temp("ola-like-replay.pcapng");
    ola_like_capture(&path, true);
    let recording = Recording::open(&path).unwrap();
    let status = StatusHandle::new();
    let options = ReplayOptions {
        speed: f64::INFINITY,
        patch: routed_patch(),
        status: status.clone(),
        ..ReplayOptions::default()
    };
    let mut seen = Vec::new();
    let summary = replay(&recording, &options, |f| seen.push(look(f)), std::future::pending()).await.unwrap();
    assert_eq!(summary.packets, 7, "every Art-Net and sACN datagram is fed");
    let last = |u: u16| seen.iter().rev().find(|l| l.0 == u).map(|l| l.1[..2].to_vec());
    assert_eq!((last(1), last(2)), (Some(vec![20, 21]), Some(vec![50, 0])));
    let s = status.snapshot();
    let fed: Vec<(u16, u64)> = s.universes.iter().map(|u| (u.universe, u.packets)).collect();
    assert_eq!(fed, vec![(1, 2), (2, 1)]);
    assert_eq!(s.universes[1].sources[0].input.universe, 101);
    assert_eq!(s.unpatched.len(), 1);
    assert_eq!((s.unpatched[0].input.universe, s.unpatched[0].packets), (0, 1));
    assert_eq!((s.counters.artnet.received, s.counters.sacn.received), (6, 1));
    assert_eq!(
        s.counters,
        footlight_dmx::status::ProtocolCounters {
            artnet: summary.stats.artnet,
            sacn: summary.stats.sacn,
            usbpro: summary.stats.usbpro,
        }
    );
    let _ = std::fs::remove_file(&path);
}

#[tokio::test]
async fn recording_follows_routes_live_and_the_file_replays_with_them() {
    let path = temp("routed.pcapng");
    let mut config = loopback_config(vec![1, 2]);
    config.patch = routed_patch();
    let input = DmxInput::bind(config).await.unwrap();
    let (mut frames, addrs) = (input.frames(), input.local_addrs());
    let (stop, stopped) = oneshot::channel::<()>();
    let out = path.clone();
    let recorder = tokio::spawn(async move { record_input(&out, input, async { stopped.await.unwrap() }).await });
    let tx = sender();
    tx.send_to(&build_dmx(0, 0, 1, &[1, 2]), addrs.artnet.unwrap()).unwrap();
    tx.send_to(&sacn(1, 100, 1, 101, 0, &[3, 4]), addrs.sacn.unwrap()).unwrap();
    tx.send_to(&build_dmx(0, 0, 0, &[9, 9]), addrs.artnet.unwrap()).unwrap();
    let both = |u: &Universes| {
        u.get(1).is_some_and(|f| f.slots[..2] == [1, 2]) && u.get(2).is_some_and(|f| f.slots[..2] == [3, 4])
    };
    tokio::time::timeout(Duration::from_secs(5), frames.wait_for(both)).await.unwrap().unwrap();
    // Let the last datagram be counted before stopping (bounded).
    tokio::time::sleep(Duration::from_millis(100)).await;
    stop.send(()).unwrap();
    assert_eq!(recorder.await.unwrap().unwrap().packets, 3, "every datagram is recorded, routed or not");
    let (seen, _) = replay_all(&path, routed_patch()).await;
    let universes: std::collections::BTreeSet<u16> = seen.iter().map(|l| l.0).collect();
    assert_eq!(universes.into_iter().collect::<Vec<_>>(), vec![1, 2]);
    let (seen, _) = replay_all(&path, InputPatch::default()).await;
    let universes: std::collections::BTreeSet<u16> = seen.iter().map(|l| l.0).collect();
    assert_eq!(universes.into_iter().collect::<Vec<_>>(), vec![1, 2, 101], "without routes: the defaults");
    let _ = std::fs::remove_file(&path);
}
