//! The recordings in `tests/replays/` (documented in its README.md). They are
//! made here, deterministically: the test regenerates each file and compares
//! it byte for byte; `FOOTLIGHT_BLESS=1` rewrites them after an intended change.
//!
//! Layout on patch universe 1 (see the README): fixture at address 1 with
//! dimmer (1), scroller frame (2), zoom (3), focus (4), iris (5); a moving head
//! at address 11 with pan coarse/fine (11, 12), tilt coarse/fine (13, 14),
//! dimmer (15). 16 slots are sent.

use std::net::SocketAddrV4;
use std::path::{Path, PathBuf};
use std::time::Duration;

use footlight_dmx::artnet::packet::build_dmx;
use footlight_dmx::record::PcapngWriter;
use footlight_dmx::sacn::packet::{DataSpec, OPTION_TERMINATED, build_data};
use footlight_dmx::{InputPatch, Recording, state_at};

/// 2025-01-01 20:00:00 UTC: curtain up.
const CURTAIN: Duration = Duration::from_secs(1_735_761_600);
const DESK: &str = "192.0.2.10";

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/replays")
}

/// Linear fade from `a` to `b` over [t0, t1], as a DMX value.
fn fade(t: f64, t0: f64, t1: f64, a: f64, b: f64) -> u8 {
    let x = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    (a + (b - a) * x).round() as u8
}

struct Writer {
    w: PcapngWriter<Vec<u8>>,
}

impl Writer {
    fn new() -> Self {
        Writer { w: PcapngWriter::new(Vec::new()).unwrap() }
    }
    fn sacn(&mut self, t: f64, seq: u8, options: u8, slots: &[u8]) {
        let from: SocketAddrV4 = format!("{DESK}:49152").parse().unwrap();
        let to: SocketAddrV4 = "239.255.0.1:5568".parse().unwrap();
        let packet = build_data(&DataSpec {
            cid: *b"footlight-replay",
            source_name: "Footlight test desk",
            priority: 100,
            sync_address: 0,
            sequence: seq,
            options,
            universe: 1,
            start_code: 0,
            slots,
        });
        self.w.write_udp(CURTAIN + Duration::from_secs_f64(t), from, to, &packet, None).unwrap();
    }
    fn artnet(&mut self, t: f64, seq: u8, slots: &[u8]) {
        let from: SocketAddrV4 = format!("{DESK}:6454").parse().unwrap();
        let to: SocketAddrV4 = "192.0.2.255:6454".parse().unwrap();
        self.w.write_udp(CURTAIN + Duration::from_secs_f64(t), from, to, &build_dmx(seq, 0, 0, slots), None).unwrap();
    }
}

/// Cue list over sACN universe 1 at 30 Hz for 10 s, then Stream_Terminated ×3.
fn cue_fades() -> Vec<u8> {
    let mut w = Writer::new();
    for i in 0..300u32 {
        let t = f64::from(i) / 30.0;
        let mut s = [0u8; 16];
        // Cue 1 at 0.5 s: dimmer up in 3 s; zoom, focus, iris set.
        s[0] = fade(t, 0.5, 3.5, 0.0, 255.0);
        if t >= 0.5 {
            (s[2], s[3], s[4]) = (128, 64, 255);
        }
        // Cue 2 at 4 s: dimmer to 50 % and the moving head's dimmer up, both in 2 s.
        if t >= 4.0 {
            s[0] = fade(t, 4.0, 6.0, 255.0, 128.0);
            s[14] = fade(t, 4.0, 6.0, 0.0, 255.0);
        }
        // Cue 3 at 7 s: everything out in 2 s.
        if t >= 7.0 {
            s[0] = fade(t, 7.0, 9.0, 128.0, 0.0);
            s[14] = fade(t, 7.0, 9.0, 255.0, 0.0);
        }
        w.sacn(t, i as u8, 0, &s);
    }
    for k in 0..3u32 {
        w.sacn(10.0 + f64::from(k) * 0.01, (300 + k) as u8, OPTION_TERMINATED, &[0; 16]);
    }
    w.w.into_inner()
}

/// Colour scroller chase over Art-Net Port-Address 0 at 30 Hz for 8 s: dimmer
/// full, frame k (DMX 32k + 16) for second k.
fn colour_chase() -> Vec<u8> {
    let mut w = Writer::new();
    for i in 0..240u32 {
        let t = f64::from(i) / 30.0;
        let mut s = [0u8; 16];
        s[0] = 255;
        s[1] = (32 * (i / 30) + 16) as u8;
        w.artnet(t, (i % 255 + 1) as u8, &s); // sequence 1..255, never 0
    }
    w.w.into_inner()
}

/// Pan/tilt sweep over sACN universe 1 at 44 Hz for 6 s: pan 0 → 65535 in
/// 16 bits, tilt 16384 + 16384·(1 - cos(πt/3)) / 2 … back (one sine period),
/// dimmer 15 full.
fn pan_tilt_sweep() -> Vec<u8> {
    let mut w = Writer::new();
    for i in 0..264u32 {
        let t = f64::from(i) / 44.0;
        let pan = (t / 6.0 * 65535.0).round().min(65535.0) as u16;
        let tilt = (32768.0 - 16384.0 * (std::f64::consts::PI * t / 3.0).cos()).round() as u16;
        let mut s = [0u8; 16];
        s[10..12].copy_from_slice(&pan.to_be_bytes());
        s[12..14].copy_from_slice(&tilt.to_be_bytes());
        s[14] = 255;
        w.sacn(t, i as u8, 0, &s);
    }
    w.w.into_inner()
}

/// Heads in the 44-head chase (`chase-44.pcapng`, `chase-44.toml`).
const CHASE_HEADS: usize = 44;
/// Heads per universe (16 slots apart: 22 × 16 = 352 slots).
const CHASE_PER_UNIVERSE: usize = 22;

/// One head's 16-bit pan and tilt at `t` seconds: a smooth chase, each head
/// a phase behind the previous one (pan ±49°, tilt 15° ± 12° off straight down).
pub fn chase_pan_tilt(head: usize, t: f64) -> (u16, u16) {
    use std::f64::consts::TAU;
    let phase = head as f64 * 0.3;
    let pan = 32768.0 + 6000.0 * (TAU * 0.25 * t + phase).sin();
    let tilt = 32768.0 + 3640.0 + 3000.0 * (TAU * 0.2 * t + phase).sin();
    (pan.round() as u16, tilt.round() as u16)
}

/// 44 generic moving spots (13-channel standard mode, 18° zoom, dimmer 25 %),
/// 22 on each of Art-Net Port-Addresses 0 and 1 (patch universes 1 and 2),
/// a smooth pan/tilt chase at 40 Hz for 5 s (issue 18).
fn chase_44() -> Vec<u8> {
    let mut w = Writer::new();
    for i in 0..200u32 {
        let t = f64::from(i) / 40.0;
        for u in 0..2u16 {
            let mut s = [0u8; 512];
            for k in 0..CHASE_PER_UNIVERSE {
                let head = usize::from(u) * CHASE_PER_UNIVERSE + k;
                let (pan, tilt) = chase_pan_tilt(head, t);
                let at = k * 16; // address 16k + 1
                s[at..at + 2].copy_from_slice(&pan.to_be_bytes());
                s[at + 2..at + 4].copy_from_slice(&tilt.to_be_bytes());
                s[at + 7] = 64; // zoom: 12° + 24° × 64/255 = 18°
                s[at + 10] = 255; // shutter open
                s[at + 11] = 64; // dimmer at 25 %: the beams stay apart on the floor
                s[at + 12] = 0; // dimmer fine
            }
            let from: SocketAddrV4 = format!("{DESK}:6454").parse().unwrap();
            let to: SocketAddrV4 = "192.0.2.255:6454".parse().unwrap();
            let packet = build_dmx((i % 255 + 1) as u8, 0, u, &s[..CHASE_PER_UNIVERSE * 16]);
            w.w.write_udp(CURTAIN + Duration::from_secs_f64(t), from, to, &packet, None).unwrap();
        }
    }
    w.w.into_inner()
}

fn check_or_bless(name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir().join(name);
    assert!(bytes.len() < 200_000, "{name} is {} bytes", bytes.len());
    if std::env::var_os("FOOTLIGHT_BLESS").is_some() {
        std::fs::write(&path, bytes).unwrap();
    }
    let committed = std::fs::read(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (run with FOOTLIGHT_BLESS=1 to write it)", path.display()));
    assert!(committed == bytes, "{name} differs from its generator (FOOTLIGHT_BLESS=1 rewrites it)");
    path
}

fn slots_at(path: &Path, t: f64) -> (Vec<u8>, bool) {
    let recording = Recording::open(path).unwrap();
    let state = state_at(&recording, Duration::from_secs_f64(t), &InputPatch::default()).unwrap();
    let u1 = state.iter().find(|f| f.universe == 1).expect("universe 1");
    (u1.slots[..16].to_vec(), u1.stale)
}

#[test]
fn cue_fades_recording() {
    let path = check_or_bless("cue-fades.pcapng", &cue_fades());
    let r = Recording::open(&path).unwrap();
    // 300 data packets; the 3 Stream_Terminated packets are not DMX data.
    assert_eq!(r.dmx_packets(), 300);
    let (s, _) = slots_at(&path, 2.0);
    assert!((s[0] as i32 - 128).abs() <= 3, "halfway up the first fade: {}", s[0]);
    assert_eq!(s[2..5], [128, 64, 255]);
    let (s, _) = slots_at(&path, 6.5);
    assert_eq!((s[0], s[14]), (128, 255));
    let (s, stale) = slots_at(&path, 9.5);
    assert_eq!((s[0], s[14], stale), (0, 0, false));
    let (_, stale) = slots_at(&path, 11.0);
    assert!(stale, "the desk terminated its stream");
}

#[test]
fn colour_chase_recording() {
    let path = check_or_bless("colour-chase.pcapng", &colour_chase());
    for k in 0..8 {
        let (s, _) = slots_at(&path, f64::from(k) + 0.5);
        assert_eq!((s[0], s[1]), (255, 32 * k as u8 + 16));
    }
}

#[test]
fn pan_tilt_sweep_recording() {
    let path = check_or_bless("pan-tilt-sweep.pcapng", &pan_tilt_sweep());
    let (s, _) = slots_at(&path, 3.0);
    let (pan, tilt) = (u16::from_be_bytes([s[10], s[11]]), u16::from_be_bytes([s[12], s[13]]));
    assert!((i32::from(pan) - 32768).abs() < 400, "pan at 3 s: {pan}");
    assert!((i32::from(tilt) - 49152).abs() < 20, "tilt at 3 s: {tilt}");
    assert_eq!(s[14], 255);
}

#[test]
fn chase_44_recording() {
    let path = check_or_bless("chase-44.pcapng", &chase_44());
    assert_eq!(CHASE_HEADS, 2 * CHASE_PER_UNIVERSE);
    let rec = Recording::open(&path).unwrap();
    let patch = InputPatch { universes: vec![1, 2], ..InputPatch::default() };
    for t in [0.0, 2.5, 4.9] {
        let frames = state_at(&rec, Duration::from_secs_f64(t), &patch).unwrap();
        assert_eq!(frames.len(), 2, "both universes at {t} s");
        for f in &frames {
            for k in 0..CHASE_PER_UNIVERSE {
                let head = usize::from(f.universe - 1) * CHASE_PER_UNIVERSE + k;
                let s = &f.slots[k * 16..];
                // The state at t is the last packet at or before t (40 Hz).
                let sent = chase_pan_tilt(head, (t * 40.0).floor() / 40.0);
                assert_eq!(
                    (u16::from_be_bytes([s[0], s[1]]), u16::from_be_bytes([s[2], s[3]])),
                    sent,
                    "head {head} at {t} s"
                );
                assert_eq!((s[7], s[10], s[11], s[12]), (64, 255, 64, 0));
            }
        }
    }
}
