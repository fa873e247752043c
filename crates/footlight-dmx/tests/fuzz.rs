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
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

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
        let mut art = ArtNetReceiver::new(ArtNetReceiverConfig { max_ports: 8, ..Default::default() });
        let mut sacn = SacnReceiver::new(SacnReceiverConfig { max_streams: 8, ..Default::default() });
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
            prop_assert!(events <= 2);
            prop_assert!(sacn.streams() <= 8);
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
