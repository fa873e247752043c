//! proptest fuzzing: random bytes and mutated valid packets never panic,
//! malformed input is counted, and receiver state stays bounded.

use std::net::SocketAddr;
use std::time::Duration;

use footlight_dmx::artnet::packet::{build_dmx, build_poll, build_sync};
use footlight_dmx::artnet::{self, ArtNetReceiver, ArtNetReceiverConfig};
use footlight_dmx::record::{CaptureReader, PcapngWriter, udp_datagram};
use footlight_dmx::sacn::packet::{DataSpec, build_data};
use footlight_dmx::sacn::{self, SacnReceiver, SacnReceiverConfig};
use footlight_dmx::usbpro::packet::encode;
use footlight_dmx::usbpro::{Decoder, ReceiveMode, UsbProReceiver};
use footlight_dmx::{Disposition, Stats};
use proptest::prelude::*;
use tokio::time::Instant;

const FROM: SocketAddr = SocketAddr::new(std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST), 1234);

/// Port-Addresses the fuzzed Art-Net receiver keeps.
const ART_PORTS: usize = 8;
/// Streams the fuzzed sACN receiver keeps.
const SACN_STREAMS: usize = 8;

/// `cases` cases from a fixed seed, so every CI run tries the same inputs
/// (the brief: seed every RNG). proptest's own `PROPTEST_RNG_SEED=<n>`
/// (read by its default config) tries another seed by hand:
/// `PROPTEST_RNG_SEED=7 cargo test -p footlight-dmx --test main fuzz`.
fn seeded(cases: u32) -> ProptestConfig {
    use proptest::test_runner::RngSeed;
    let default = ProptestConfig::default();
    let rng_seed = match default.rng_seed {
        RngSeed::Random => RngSeed::Fixed(0x466f_6f74_6c69_6768),
        chosen => chosen,
    };
    ProptestConfig { cases, rng_seed, ..default }
}

fn valid_artnet() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        (any::<u8>(), any::<u8>(), 0u16..0x8000, prop::collection::vec(any::<u8>(), 1..=512))
            .prop_map(|(seq, phys, pa, data)| build_dmx(seq, phys, pa, &data)),
        Just(build_sync()),
        Just(build_poll(0x02, None)),
    ]
}

fn valid_sacn() -> impl Strategy<Value = Vec<u8>> {
    (any::<[u8; 16]>(), 0u8..=200, any::<u8>(), any::<u8>(), 1u16..=63999, prop::collection::vec(any::<u8>(), 0..=512))
        .prop_map(|(cid, priority, sequence, options, universe, slots)| {
            build_data(&DataSpec {
                cid,
                source_name: "fuzz",
                priority,
                sync_address: 0,
                sequence,
                options,
                universe,
                start_code: 0,
                slots: &slots,
            })
        })
}

/// The case the fuzzer found (CI, stop 27): in synchronous mode one ArtSync
/// releases every held frame at once, one event per held Port-Address, so
/// a single datagram may emit more than one event.
#[test]
fn one_artsync_releases_every_held_port() {
    let t0 = Instant::now();
    let mut art = ArtNetReceiver::new(ArtNetReceiverConfig { max_ports: ART_PORTS, ..Default::default() });
    let mut levels = Vec::new();
    let run = |art: &mut ArtNetReceiver, p: &[u8], ms: u64, levels: &mut Vec<(u16, u8)>| {
        art.handle(p, FROM, t0 + Duration::from_millis(ms), &mut |e| {
            if let (
                footlight_dmx::InputUniverse::ArtNet(port),
                footlight_dmx::source::EventKind::Levels { levels: l, .. },
            ) = (e.input, e.kind)
            {
                levels.push((port, l.as_slice()[0]));
            }
        })
    };
    for port in 0..ART_PORTS as u16 {
        run(&mut art, &build_dmx(0, 0, port, &[1]), 0, &mut levels);
    }
    run(&mut art, &build_sync(), 1, &mut levels);
    assert!(art.synchronous());
    levels.clear();
    for port in 0..ART_PORTS as u16 {
        let h = run(&mut art, &build_dmx(0, 0, port, &[2 + port as u8]), 2, &mut levels);
        assert_eq!(h.disposition, Disposition::Held);
    }
    assert!(levels.is_empty(), "held, not applied: {levels:?}");
    run(&mut art, &build_sync(), 3, &mut levels);
    let want: Vec<(u16, u8)> = (0..ART_PORTS as u16).map(|p| (p, 2 + p as u8)).collect();
    assert_eq!(levels, want);
}

/// A valid packet with a few bytes overwritten, or cut short.
fn mutated(valid: impl Strategy<Value = Vec<u8>>) -> impl Strategy<Value = Vec<u8>> {
    (valid, prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6), any::<prop::sample::Index>())
        .prop_map(|(mut p, edits, cut)| {
            for (at, v) in edits {
                let i = at.index(p.len());
                p[i] = v;
            }
            let keep = cut.index(p.len() + 1).max(p.len() / 2);
            p.truncate(keep);
            p
        })
}

fn bytes() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(any::<u8>(), 0..700)
}

proptest! {
    #![proptest_config(seeded(512))]

    #[test]
    fn artnet_parser_never_panics(p in prop_oneof![bytes(), mutated(valid_artnet())]) {
        if let Ok(artnet::ArtPacket::Dmx(d)) = artnet::packet::parse(&p) {
            prop_assert!(!d.data.is_empty() && d.data.len() <= 512 && d.port_address <= 0x7FFF);
        }
    }

    #[test]
    fn sacn_parser_never_panics(p in prop_oneof![bytes(), mutated(valid_sacn())]) {
        if let Ok(sacn::SacnPacket::Data(d)) = sacn::packet::parse(&p) {
            prop_assert!(d.slots.len() <= 512 && d.priority <= 200 && (1..=63999).contains(&d.universe));
        }
    }

    #[test]
    fn receivers_count_every_packet_and_stay_bounded(
        packets in prop::collection::vec(prop_oneof![bytes(), mutated(valid_artnet()), mutated(valid_sacn()), valid_sacn()], 1..40)
    ) {
        let t0 = Instant::now();
        let mut art = ArtNetReceiver::new(ArtNetReceiverConfig { max_ports: ART_PORTS, ..Default::default() });
        let mut sacn = SacnReceiver::new(SacnReceiverConfig { max_streams: SACN_STREAMS, ..Default::default() });
        // One datagram's events: its own (one per receiver), plus an ArtSync
        // (or an ArtDmx after the 4 s sync timeout) releasing every held
        // frame, at most one per (Port-Address, source) with two sources per
        // port, plus an sACN sync packet releasing every held stream.
        let bound = 2 + 2 * ART_PORTS + SACN_STREAMS;
        let mut stats = Stats::default();
        let mut malformed = 0;
        for (i, p) in packets.iter().enumerate() {
            let now = t0 + Duration::from_millis(i as u64 * 7);
            let mut events = 0usize;
            let a = art.handle(p, FROM, now, &mut |_| events += 1);
            let s = sacn.handle(p, FROM, now, &mut |_| events += 1);
            malformed += usize::from(matches!(a.disposition, Disposition::Malformed(_)));
            malformed += usize::from(matches!(s.disposition, Disposition::Malformed(_)));
            stats.packet(footlight_dmx::Protocol::ArtNet, a.source, Some(FROM.ip()), &a.disposition);
            stats.packet(footlight_dmx::Protocol::Sacn, s.source, Some(FROM.ip()), &s.disposition);
            prop_assert!(events <= bound, "{events} events from packet {i}");
            prop_assert!(sacn.streams() <= SACN_STREAMS);
            art.tick(now, &mut |_| {});
            sacn.tick(now, &mut |_| {});
        }
        prop_assert_eq!(stats.artnet.received + stats.sacn.received, 2 * packets.len() as u64);
        prop_assert_eq!((stats.artnet.malformed + stats.sacn.malformed) as usize, malformed);
        prop_assert!(stats.sources.len() <= 256);
    }

    #[test]
    fn usbpro_decoder_resyncs_after_any_garbage(
        garbage in prop::collection::vec(any::<u8>(), 0..300),
        slots in prop::collection::vec(any::<u8>(), 0..=512),
    ) {
        // Garbage may hold a start byte and a length that swallows up to 604
        // bytes of what follows. With no 0x7E inside the frames except their
        // start bytes, the decoder is back in step by the first start byte
        // after that, so the last of enough repeated frames decodes.
        let mut slots: Vec<u8> = slots.into_iter().map(|v| if v == 0x7E { 0 } else { v }).collect();
        if (slots.len() + 2) & 0xFF == 0x7E {
            slots.pop();
        }
        let frame = encode(5, &[&[0u8, 0][..], &slots].concat());
        let mut stream = garbage.clone();
        for _ in 0..(700 / frame.len() + 2) {
            stream.extend(&frame);
        }
        let mut rx = UsbProReceiver::new(0, ReceiveMode::EveryFrame);
        let mut last = None;
        rx.handle(&stream, Instant::now(), &mut |e| {
            if let footlight_dmx::source::EventKind::Levels { levels, .. } = e.kind { last = Some(levels) }
        }, &mut |_| {});
        let last = last.expect("a frame decodes");
        prop_assert_eq!(last.as_slice(), &slots[..]);
        let mut d = Decoder::new();
        for b in garbage { let _ = d.push(b); }
    }

    #[test]
    fn capture_reader_never_panics(
        p in prop_oneof![
            bytes(),
            mutated(Just(sample_capture())),
            Just(sample_capture()).prop_flat_map(|c| { let n = c.len(); (Just(c), 0..n) }).prop_map(|(c, n)| c[..n].to_vec()),
        ]
    ) {
        if let Ok(mut r) = CaptureReader::new(&p[..]) {
            for _ in 0..64 {
                match r.next_frame() {
                    Ok(Some(f)) => { let _ = udp_datagram(&f); }
                    Ok(None) | Err(_) => break,
                }
            }
        }
    }
}

/// A small pcapng with three datagrams.
fn sample_capture() -> Vec<u8> {
    let mut w = PcapngWriter::new(Vec::new()).unwrap();
    let a = "10.0.0.1:6454".parse().unwrap();
    let b = "10.0.0.2:6454".parse().unwrap();
    w.write_udp(Duration::from_secs(1), a, b, &build_dmx(1, 0, 0, &[1, 2]), None).unwrap();
    w.write_udp(Duration::from_secs(2), a, b, &build_sync(), Some("note")).unwrap();
    w.write_udp(Duration::from_secs(3), a, b, &encode(5, &[0, 0, 1]), None).unwrap();
    w.into_inner()
}

// ---- pcap / pcapng reader: a seed corpus in tests/corpus/capture/ ----

/// The seed captures: every format, byte order and link type the reader
/// knows, one or a few DMX datagrams each, built by hand from the pcap and
/// pcapng layouts (draft-ietf-opsawg-pcap, -pcapng) and kept in the repo.
fn seeds() -> Vec<(&'static str, Vec<u8>)> {
    let art = build_dmx(1, 0, 3, &[1, 2, 3, 4]);
    let sacn = build_data(&DataSpec {
        cid: [7; 16],
        source_name: "seed",
        priority: 100,
        sync_address: 0,
        sequence: 1,
        options: 0,
        universe: 9,
        start_code: 0,
        slots: &[5, 6],
    });
    let ip = |payload: &[u8], dport: u16| -> Vec<u8> {
        let total = (20 + 8 + payload.len()) as u16;
        let mut p = vec![0x45, 0];
        p.extend(total.to_be_bytes());
        p.extend([0, 1, 0x40, 0, 64, 17, 0, 0, 192, 0, 2, 1, 192, 0, 2, 2]); // id, DF, TTL, UDP, src, dst
        p.extend(6454u16.to_be_bytes());
        p.extend(dport.to_be_bytes());
        p.extend((8 + payload.len() as u16).to_be_bytes());
        p.extend([0, 0]);
        p.extend(payload);
        p
    };
    let ether_vlan = |ip: Vec<u8>| [&[0xFF; 6][..], &[2, 0, 0, 0, 0, 1], &[0x81, 0], &[0, 5], &[8, 0], &ip].concat();
    let sll = |ip: Vec<u8>| [&[0, 0, 0, 1, 0, 6][..], &[2, 0, 0, 0, 0, 1, 0, 0], &[8, 0], &ip].concat();
    let sll2 = |ip: Vec<u8>| [&[8, 0, 0, 0][..], &[0, 0, 0, 2], &[0, 1, 0, 6], &[2, 0, 0, 0, 0, 1, 0, 0], &ip].concat();
    let null_le = |ip: Vec<u8>| [&[2, 0, 0, 0][..], &ip].concat();

    // Classic pcap: magic, version 2.4, zone, sigfigs, snaplen, link type; then records.
    let pcap = |big: bool, nanos: bool, link: u32, frames: &[Vec<u8>]| -> Vec<u8> {
        let u32b = |v: u32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        let u16b = |v: u16| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        let mut f = u32b(if nanos { 0xA1B2_3C4D } else { 0xA1B2_C3D4 }).to_vec();
        f.extend(u16b(2));
        f.extend(u16b(4));
        f.extend([0; 8]);
        f.extend(u32b(65535));
        f.extend(u32b(link));
        for (i, data) in frames.iter().enumerate() {
            f.extend(u32b(1_700_000_000 + i as u32));
            f.extend(u32b(if nanos { 500_000_000 } else { 500_000 }));
            f.extend(u32b(data.len() as u32));
            f.extend(u32b(data.len() as u32));
            f.extend(data);
        }
        f
    };
    // pcapng blocks in either byte order.
    let block = |big: bool, kind: u32, body: &[u8]| -> Vec<u8> {
        let u32b = |v: u32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        let mut body = body.to_vec();
        body.resize(body.len().div_ceil(4) * 4, 0);
        let total = (12 + body.len()) as u32;
        [&u32b(kind)[..], &u32b(total), &body, &u32b(total)].concat()
    };
    let pcapng = |big: bool, link: u16, frames: &[Vec<u8>]| -> Vec<u8> {
        let u32b = |v: u32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        let u16b = |v: u16| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        let shb = [&u32b(0x1A2B_3C4D)[..], &u16b(1), &u16b(0), &[0xFF; 8]].concat();
        let mut f = block(big, 0x0A0D_0D0A, &shb);
        // IDB with if_tsresol = 2^-20 (option 9), then opt_endofopt.
        let idb = [&u16b(link)[..], &[0, 0], &u32b(0), &u16b(9), &u16b(1), &[0x94, 0, 0, 0], &[0; 4]].concat();
        f.extend(block(big, 1, &idb));
        f.extend(block(big, 0x0000_0BAD, b"custom block, skipped")); // an unknown block type
        for (i, data) in frames.iter().enumerate() {
            let ticks = (1_700_000_000u64 + i as u64) << 20;
            let stamp = [&u32b((ticks >> 32) as u32)[..], &u32b(ticks as u32)].concat();
            let len = u32b(data.len() as u32);
            let mut padded = data.clone();
            padded.resize(data.len().div_ceil(4) * 4, 0);
            match i % 3 {
                0 => {
                    let comment = [&u16b(1)[..], &u16b(4), b"seed", &[0; 4]].concat();
                    let epb = [&u32b(0)[..], &stamp, &len, &len, &padded, &comment].concat();
                    f.extend(block(big, 6, &epb));
                }
                1 => f.extend(block(big, 3, &[&len[..], data].concat())), // simple packet block
                _ => {
                    let pb = [&u16b(0)[..], &u16b(0), &stamp, &len, &len, &padded].concat();
                    f.extend(block(big, 2, &pb)); // obsolete packet block
                }
            }
        }
        f
    };
    vec![
        ("ours.pcapng", sample_capture()),
        ("ethernet-vlan-us-le.pcap", pcap(false, false, 1, &[ether_vlan(ip(&art, 6454)), ether_vlan(ip(&sacn, 5568))])),
        ("linux-sll-ns-be.pcap", pcap(true, true, 113, &[sll(ip(&sacn, 5568))])),
        ("raw-ip-us-be.pcap", pcap(true, false, 101, &[ip(&art, 6454)])),
        ("sll2-be.pcapng", pcapng(true, 276, &[sll2(ip(&art, 6454)), sll2(ip(&sacn, 5568)), sll2(ip(&art, 6454))])),
        (
            "null-le.pcapng",
            [pcapng(false, 0, &[null_le(ip(&sacn, 5568))]), pcapng(false, 101, &[ip(&art, 1)])].concat(),
        ),
    ]
}

fn corpus_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/capture")
}

/// The committed seed files (FOOTLIGHT_BLESS=1 rewrites them from [`seeds`]).
fn corpus() -> Vec<(String, Vec<u8>)> {
    let bless = std::env::var_os("FOOTLIGHT_BLESS").is_some();
    seeds()
        .into_iter()
        .map(|(name, bytes)| {
            let path = corpus_dir().join(name);
            if bless {
                std::fs::create_dir_all(corpus_dir()).unwrap();
                std::fs::write(&path, &bytes).unwrap();
            }
            let committed = std::fs::read(&path)
                .unwrap_or_else(|e| panic!("{}: {e} (FOOTLIGHT_BLESS=1 writes it)", path.display()));
            assert!(committed == bytes, "{name} differs from its generator (FOOTLIGHT_BLESS=1 rewrites it)");
            (name.to_string(), committed)
        })
        .collect()
}

/// Reads a capture to its end (at most 256 frames): the DMX payloads found,
/// or the error. Panics if an error's offset lies past the input.
fn read_all(bytes: &[u8]) -> Result<Vec<Vec<u8>>, footlight_dmx::record::CaptureError> {
    let check = |e: footlight_dmx::record::CaptureError| {
        assert!(e.offset() <= bytes.len() as u64, "offset {} past {} bytes: {e}", e.offset(), bytes.len());
        assert!(e.to_string().contains("byte"), "the message names the byte: {e}");
        e
    };
    let mut r = CaptureReader::new(bytes).map_err(check)?;
    let mut out = Vec::new();
    for _ in 0..256 {
        match r.next_frame().map_err(check)? {
            Some(f) => out.extend(udp_datagram(&f).map(|d| d.payload.to_vec())),
            None => break,
        }
    }
    Ok(out)
}

#[test]
fn capture_seeds_decode_to_their_datagrams() {
    for (name, bytes) in corpus() {
        let payloads = read_all(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        let expected = match name.as_str() {
            "ours.pcapng" | "sll2-be.pcapng" => 3,
            "ethernet-vlan-us-le.pcap" | "null-le.pcapng" => 2,
            _ => 1,
        };
        assert_eq!(payloads.len(), expected, "{name}");
        // tshark, an independent reader, finds the same UDP payloads.
        if crate::common::have("tshark") {
            let path = corpus_dir().join(&name);
            let out = std::process::Command::new("tshark")
                .arg("-r")
                .arg(&path)
                .args(["-T", "fields", "-e", "udp.length"])
                .output()
                .expect("tshark runs");
            let lengths: Vec<usize> = String::from_utf8_lossy(&out.stdout)
                .lines()
                .filter_map(|l| l.trim().parse::<usize>().ok())
                .map(|udp| udp - 8)
                .collect();
            assert_eq!(lengths, payloads.iter().map(Vec::len).collect::<Vec<_>>(), "{name}: tshark agrees");
        }
        for p in &payloads {
            let dmx = artnet::packet::parse(p).is_ok() || sacn::packet::parse(p).is_ok();
            assert!(dmx || name == "ours.pcapng", "{name}: a DMX payload");
        }
    }
}

/// A seed with edits: bytes overwritten, a range cut out, a range repeated, the end cut.
fn mutated_seed() -> impl Strategy<Value = Vec<u8>> {
    let seeds: Vec<Vec<u8>> = seeds().into_iter().map(|(_, b)| b).collect();
    (
        prop::sample::select(seeds),
        prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..8),
        any::<(prop::sample::Index, prop::sample::Index)>(),
        0u8..4,
        any::<prop::sample::Index>(),
    )
        .prop_map(|(mut p, edits, (a, b), op, cut)| {
            for (at, v) in edits {
                let i = at.index(p.len());
                p[i] = v;
            }
            let (a, b) = (a.index(p.len()), b.index(p.len()));
            let (lo, hi) = (a.min(b), a.max(b));
            match op {
                0 => drop(p.drain(lo..hi)),
                1 => {
                    let chunk = p[lo..hi].to_vec();
                    p.splice(hi..hi, chunk);
                }
                2 => p.truncate(cut.index(p.len() + 1)),
                _ => {}
            }
            p
        })
}

proptest! {
    #![proptest_config(seeded(1024))]

    #[test]
    fn capture_reader_mutated_seeds_never_panic_and_errors_carry_offsets(p in mutated_seed()) {
        let _ = read_all(&p);
    }
}
