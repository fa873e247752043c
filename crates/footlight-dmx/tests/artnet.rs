//! Art-Net over a real loopback socket.

use std::net::Ipv4Addr;
use std::time::Duration;

use artnet_protocol::{ArtCommand, Output, Poll};
use footlight_dmx::artnet::packet::{PortRange, build_dmx, build_poll, build_sync, opcode};
use footlight_dmx::{InputUniverse, Protocol, SourceId};
use tokio::net::UdpSocket;

use crate::common::{Running, loopback_config, sender};

/// ArtDmx for Port-Address 1 (patch universe 2), written out from the spec
/// table rather than with our builder.
const ARTDMX_PA1: [u8; 22] = [
    b'A', b'r', b't', b'-', b'N', b'e', b't', 0, // ID
    0x00, 0x50, // OpCode 0x5000, little endian
    0x00, 0x0E, // ProtVer 14, big endian
    0x01, // Sequence
    0x00, // Physical
    0x01, 0x00, // SubUni, Net: Port-Address 1
    0x00, 0x04, // Length 4, big endian
    255, 128, 7, 1, // slots 1-4
];

#[tokio::test]
async fn artdmx_from_spec_bytes_reaches_patch_universe_n_plus_1() {
    let mut input = Running::start(loopback_config(vec![])).await;
    let tx = sender();
    tx.send_to(&ARTDMX_PA1, input.artnet()).unwrap();
    let f = input.wait_slots(2, &[255, 128, 7, 1]).await;
    assert!(!f.stale);
    assert_eq!(f.slots[4..], [0; 508]);

    // The independent artnet_protocol crate encodes an odd-length frame (it pads to even).
    let output = Output { data: vec![9, 8, 7].into(), port_address: 0.into(), ..Output::default() };
    tx.send_to(&ArtCommand::Output(output).write_to_buffer().unwrap(), input.artnet()).unwrap();
    input.wait_slots(1, &[9, 8, 7, 0]).await;
    let stats = input.stats.snapshot();
    let source = SourceId::ArtNet { ip: "127.0.0.1".parse().unwrap(), physical: 0 };
    assert_eq!((stats.artnet.received, stats.artnet.applied), (2, 2));
    assert_eq!(stats.sources[&source].applied, 2);
    input.stop().await;
}

/// A poller on its own loopback address `ip`, at a port the node replies to.
async fn poller_at(ip: &str, port: u16) -> UdpSocket {
    UdpSocket::bind((ip, port)).await.unwrap_or_else(|e| panic!("bind {ip}:{port} for a poller: {e}"))
}

/// Receives ArtPollReplies until none comes for `quiet_ms` (bounded: at most 100).
async fn replies(poller: &UdpSocket, quiet_ms: u64) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut buf = [0u8; 1024];
    while out.len() < 100 {
        match tokio::time::timeout(Duration::from_millis(quiet_ms), poller.recv_from(&mut buf)).await {
            Ok(Ok((n, _))) => out.push(buf[..n].to_vec()),
            _ => break,
        }
    }
    out
}

/// The Port-Addresses an ArtPollReply announces, decoded by artnet_protocol.
fn announced(reply: &[u8]) -> Vec<u16> {
    let ArtCommand::PollReply(r) = ArtCommand::from_buffer(reply).expect("decodes") else { panic!("not a PollReply") };
    let n = usize::from(u16::from_be_bytes(r.num_ports));
    let base = (u16::from(r.port_address[0] & 0x7F) << 8) | (u16::from(r.port_address[1] & 0x0F) << 4);
    (0..n).map(|i| base | u16::from(r.swout[i] & 0x0F)).collect()
}

#[tokio::test]
async fn artpoll_gets_a_unicast_artpollreply_at_port_6454() {
    // Patch universes 1-3 and 17: Port-Addresses 0-2 share Net 0 / Sub-Net 0 and
    // go in one reply, 16 (Sub-Net 1) in a second one, BindIndex 1 and 2.
    let mut config = loopback_config(vec![1, 2, 3, 17]);
    config.artnet.as_mut().unwrap().reply_interval = Duration::ZERO;
    let mut input = Running::start(config).await;
    // The poller lives on its own loopback address, at the Art-Net port the reply must go to.
    let poller = poller_at("127.0.0.2", 6454).await;
    // Data first, so GoodOutput shows "data" for Port-Address 0.
    sender().send_to(&build_dmx(0, 0, 0, &[1, 2]), input.artnet()).unwrap();
    input.wait_slots(1, &[1, 2]).await;

    let poll = ArtCommand::Poll(Poll::default()).write_to_buffer().unwrap();
    poller.send_to(&poll, input.artnet()).await.unwrap();
    let mut buf = [0u8; 1024];
    let (_, from) = tokio::time::timeout(Duration::from_secs(3), poller.peek_from(&mut buf)).await.unwrap().unwrap();
    assert_eq!(from, input.artnet(), "sent from the node's Art-Net socket");
    let mut got = replies(&poller, 300).await;
    assert_eq!(got.len(), 2);
    got.sort_by_key(|r| r[211]);
    for (i, (r, ports)) in got.iter().zip([&[0u16, 1, 2][..], &[16]]).enumerate() {
        // Offsets from the Art-Net 4 ArtPollReply table.
        assert_eq!(r.len(), 239);
        assert_eq!(&r[0..8], b"Art-Net\0");
        assert_eq!(u16::from_le_bytes([r[8], r[9]]), 0x2100, "OpCode LE");
        assert_eq!(&r[10..14], &[127, 0, 0, 1], "IP of the node");
        assert_eq!(u16::from_le_bytes([r[14], r[15]]), 6454, "Port LE");
        assert_eq!(r[18], 0, "NetSwitch");
        assert_eq!(r[19], (ports[0] >> 4) as u8, "SubSwitch");
        assert_eq!(&r[26..36], b"Footlight\0", "ShortName");
        assert!(r[108..172].starts_with(b"#0001 ["), "NodeReport");
        assert_eq!(usize::from(u16::from_be_bytes([r[172], r[173]])), ports.len(), "NumPorts");
        for (k, pa) in ports.iter().enumerate() {
            assert_eq!(r[174 + k], 0x80, "PortTypes[{k}]: Art-Net → DMX output");
            assert_eq!(r[190 + k], (pa & 0xF) as u8, "SwOut[{k}]");
        }
        assert_eq!(r[200], 0x06, "Style = StVisual");
        assert_eq!(r[211], i as u8 + 1, "BindIndex");
        assert_eq!(r[212] & 0x08, 0x08, "Status2: 15-bit Port-Address");
        assert_eq!(announced(r), *ports, "the independent decoder agrees");
    }
    assert_eq!(&got[0][182..185], &[0x80, 0, 0], "GoodOutputA: data on Port-Address 0 only");
    assert_eq!(got[1][182], 0x00, "no data on Port-Address 16");
    let report = |r: &[u8]| String::from_utf8_lossy(&r[108..172]).trim_end_matches('\0').to_string();
    assert!(report(&got[0]).ends_with("] receiving 0; no data 1,2"), "{}", report(&got[0]));
    assert!(report(&got[1]).ends_with("] no data 16"), "{}", report(&got[1]));

    // The independent decoder reads the rest too.
    let ArtCommand::PollReply(reply) = ArtCommand::from_buffer(&got[1]).unwrap() else { panic!("not a PollReply") };
    assert_eq!(reply.address, Ipv4Addr::LOCALHOST);
    assert_eq!(reply.port, 6454);
    assert_eq!(reply.port_address, [0, 1]);
    assert_eq!(reply.style, 6);
    assert_eq!(&reply.short_name[..10], b"Footlight\0");

    // A targeted poll for Port-Addresses 10-20 gets only the reply for 16.
    poller.send_to(&build_poll(0, Some(PortRange { bottom: 10, top: 20 })), input.artnet()).await.unwrap();
    let targeted = replies(&poller, 1000).await;
    assert_eq!(targeted.len(), 1);
    assert_eq!(announced(&targeted[0]), vec![16]);
    input.stop().await;
}

#[tokio::test]
async fn artpollreply_announces_the_routed_port_addresses() {
    // Art-Net Port-Address 1 → patch 1, sACN 101 → patch 2; patch universes 1 and 2.
    let mut config = loopback_config(vec![1, 2]);
    config.patch.map.route(InputUniverse::ArtNet(1), 1).route(InputUniverse::Sacn(101), 2);
    let input = footlight_dmx::DmxInput::bind(config).await.unwrap();
    assert_eq!(input.announced_ports(), vec![vec![1]]);
    let mut input = Running::start_input(input).await;
    let poller = poller_at("127.0.0.5", 6454).await;
    let tx = sender();
    tx.send_to(&build_dmx(0, 0, 1, &[11, 12]), input.artnet()).unwrap();
    tx.send_to(&build_dmx(0, 0, 0, &[99]), input.artnet()).unwrap(); // the default of patch 1: not any more
    input.wait_slots(1, &[11, 12]).await;
    poller.send_to(&build_poll(0, None), input.artnet()).await.unwrap();
    let got = replies(&poller, 1500).await;
    assert_eq!(got.len(), 1);
    assert_eq!(announced(&got[0]), vec![1]);
    assert_eq!(got[0][182], 0x80, "GoodOutputA: data on Port-Address 1");
    let s = input.stats.snapshot();
    assert_eq!((s.artnet.applied, s.artnet.ignored), (1, 1), "ArtDmx on PA 0 is not patched any more");
    let status = input.status.snapshot();
    assert_eq!(status.unpatched.len(), 1);
    let pa0 = &status.unpatched[0];
    assert_eq!((pa0.input.protocol, pa0.input.universe, pa0.packets), (Protocol::ArtNet, 0, 1));
    assert_eq!((pa0.default_patch_universe, pa0.routed_to, pa0.blocked), (Some(1), None, false));
    input.stop().await;
}

#[tokio::test(start_paused = true)]
async fn a_poll_storm_does_not_silence_a_genuine_poller() {
    // Replies go to port P on each poller's own loopback address.
    let genuine = UdpSocket::bind("127.0.0.3:0").await.unwrap();
    let port = genuine.local_addr().unwrap().port();
    let storm = poller_at("127.0.0.4", port).await;
    let mut config = loopback_config((1..=16).collect()); // 16 Port-Addresses: 4 replies per burst
    config.artnet.as_mut().unwrap().reply_port = port;
    let input = Running::start(config).await;
    let to = input.artnet();
    let poll = build_poll(0, None);
    // 3 s of storm: a poll every 10 ms from 127.0.0.4; the genuine controller
    // polls every 2.5 s (at 0.5 s and 3.0 s).
    let (mut from_storm, mut from_genuine) = (0, 0);
    let mut buf = [0u8; 1024];
    for tick in 0..300u32 {
        storm.send_to(&poll, to).await.unwrap();
        if tick == 50 || tick == 299 {
            genuine.send_to(&poll, to).await.unwrap();
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
        while let Ok((n, _)) = storm.try_recv_from(&mut buf) {
            assert_eq!(n, 239);
            from_storm += 1;
        }
        while let Ok((n, _)) = genuine.try_recv_from(&mut buf) {
            assert_eq!(n, 239);
            from_genuine += 1;
        }
    }
    for _ in 0..100 {
        tokio::time::sleep(Duration::from_millis(20)).await;
        while storm.try_recv_from(&mut buf).is_ok() {
            from_storm += 1;
        }
        while genuine.try_recv_from(&mut buf).is_ok() {
            from_genuine += 1;
        }
    }
    assert_eq!(from_genuine, 8, "both genuine polls answered in full (4 replies each)");
    // One burst per second for the storm: at 0, 1, 2 s (and 3 s at the edge), not 300.
    assert!((12..=16).contains(&from_storm), "storm got {from_storm} replies for 300 polls");
    input.stop().await;
}

#[tokio::test(start_paused = true)]
async fn artsync_holds_and_releases_and_falls_back_after_4_s() {
    let mut input = Running::start(loopback_config(vec![1])).await;
    let tx = sender();
    let to = input.artnet();
    let start = tokio::time::Instant::now();
    tx.send_to(&build_dmx(0, 0, 0, &[10]), to).unwrap();
    input.wait_slots(1, &[10]).await;

    // After the first ArtSync, ArtDmx waits for the next one.
    tx.send_to(&build_sync(), to).unwrap();
    tx.send_to(&build_dmx(0, 0, 0, &[20]), to).unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(input.frames.borrow().get(1).unwrap().slots[0], 10, "held until ArtSync");
    tx.send_to(&build_sync(), to).unwrap();
    input.wait_slots(1, &[20]).await;

    // Held again, and no ArtSync follows: out after 4 s.
    let held_at = tokio::time::Instant::now();
    tx.send_to(&build_dmx(0, 0, 0, &[30]), to).unwrap();
    tokio::time::sleep(Duration::from_millis(3500)).await;
    assert_eq!(input.frames.borrow().get(1).unwrap().slots[0], 20, "still held at 3.5 s");
    let f = input.wait_slots(1, &[30]).await;
    let released = f.at - held_at;
    assert!(released >= Duration::from_millis(3900), "released after {released:?}");
    assert!(released <= Duration::from_millis(4200), "released after {released:?}");

    // Unsynchronised again: the next ArtDmx goes straight out.
    tx.send_to(&build_dmx(0, 0, 0, &[40]), to).unwrap();
    input.wait_slots(1, &[40]).await;
    assert!(start.elapsed() < Duration::from_secs(6));
    input.stop().await;
}

#[tokio::test]
async fn unserved_opcodes_and_bad_headers_are_counted_and_harmless() {
    let mut input = Running::start(loopback_config(vec![])).await;
    let tx = sender();
    let to = input.artnet();
    let with_opcode = |op: u16| {
        let mut p = build_sync();
        p[8..10].copy_from_slice(&op.to_le_bytes());
        p.resize(40, 0);
        p
    };
    for op in
        [opcode::IP_PROG, opcode::ADDRESS, opcode::TIME_CODE, opcode::NZS, 0x8300 /* ArtRdm */, opcode::POLL_REPLY]
    {
        tx.send_to(&with_opcode(op), to).unwrap();
    }
    let mut ext = build_dmx(0, 0, 0, &[1, 2]);
    ext[..8].copy_from_slice(b"Art-Ext\0");
    tx.send_to(&ext, to).unwrap();
    let mut old = build_dmx(0, 0, 0, &[1, 2]);
    old[11] = 13;
    tx.send_to(&old, to).unwrap();
    tx.send_to(b"Art-N", to).unwrap();
    tx.send_to(&build_dmx(0, 0, 0, &[77]), to).unwrap();
    input.wait_slots(1, &[77]).await;
    let s = input.stats.snapshot();
    assert_eq!(s.protocol(Protocol::ArtNet).received, 10);
    assert_eq!(s.artnet.ignored, 6);
    assert_eq!(s.artnet.malformed, 3);
    assert_eq!(s.artnet.applied, 1);
    assert_eq!(s.malformed_peers[&"127.0.0.1".parse().unwrap()], 3);
    input.stop().await;
}

/// A burst larger than the node reads per wake-up is counted whole: every
/// datagram sent to the socket is received (none lost between batches), and
/// the kernel reports no drop for the 6.5 MB buffer.
#[tokio::test]
async fn a_burst_of_datagrams_is_received_whole() {
    let input = Running::start(loopback_config(vec![])).await;
    let tx = sender();
    const SENT: u64 = 3000;
    for i in 0..SENT {
        let frame = build_dmx((i % 255 + 1) as u8, 0, (i % 4) as u16, &[i as u8; 512]);
        tx.send_to(&frame, input.artnet()).unwrap();
        // Bursts of 200 (several read batches each) that fit even a stock
        // 208 KiB `rmem_max` buffer, so the test does not need root.
        if i % 200 == 199 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    }
    let mut received = 0;
    for _ in 0..200 {
        received = input.stats.snapshot().artnet.received;
        if received >= SENT {
            break;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    assert_eq!(received, SENT, "every datagram of the burst is counted");
    let status = input.status.snapshot();
    let socket = status.sockets.artnet.expect("the Art-Net socket's counters");
    assert_eq!(socket.recv_buffer_wanted, 64 * 44 * 2304);
    assert!(socket.recv_buffer_bytes > 0);
    input.stop().await;
}
