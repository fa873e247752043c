//! Art-Net over a real loopback socket.

use std::net::Ipv4Addr;
use std::time::Duration;

use artnet_protocol::{ArtCommand, Output, Poll};
use footlight_dmx::artnet::packet::{PortRange, build_dmx, build_poll, build_sync, opcode};
use footlight_dmx::{Protocol, SourceId};
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

#[tokio::test]
async fn artpoll_gets_a_unicast_artpollreply_at_port_6454() {
    // Two patch universes: one reply per port (Art-Net 4), BindIndex 1 and 2.
    let mut input = Running::start(loopback_config(vec![1, 17])).await;
    // The poller lives on its own loopback address, at the Art-Net port the reply must go to.
    let poller = UdpSocket::bind("127.0.0.2:6454").await.expect("bind 127.0.0.2:6454 for the poller");
    let recv =
        async |buf: &mut [u8], limit| tokio::time::timeout(Duration::from_millis(limit), poller.recv_from(buf)).await;
    // Data first, so GoodOutput shows "data" for Port-Address 0.
    sender().send_to(&build_dmx(0, 0, 0, &[1, 2]), input.artnet()).unwrap();
    input.wait_slots(1, &[1, 2]).await;

    let poll = ArtCommand::Poll(Poll::default()).write_to_buffer().unwrap();
    poller.send_to(&poll, input.artnet()).await.unwrap();
    let mut replies = Vec::new();
    for _ in 0..2 {
        let mut buf = [0u8; 1024];
        let (n, from) = recv(&mut buf, 3000).await.expect("an ArtPollReply within 3 s").unwrap();
        assert_eq!(from, input.artnet(), "sent from the node's Art-Net socket");
        assert_eq!(n, 239);
        replies.push(buf[..n].to_vec());
    }
    replies.sort_by_key(|r| r[211]);
    for (i, (r, pa)) in replies.iter().zip([0u16, 16]).enumerate() {
        // Offsets from the Art-Net 4 ArtPollReply table.
        assert_eq!(&r[0..8], b"Art-Net\0");
        assert_eq!(u16::from_le_bytes([r[8], r[9]]), 0x2100, "OpCode LE");
        assert_eq!(&r[10..14], &[127, 0, 0, 1], "IP of the node");
        assert_eq!(u16::from_le_bytes([r[14], r[15]]), 6454, "Port LE");
        assert_eq!(r[18], (pa >> 8) as u8, "NetSwitch");
        assert_eq!(r[19], ((pa >> 4) & 0xF) as u8, "SubSwitch");
        assert_eq!(&r[26..36], b"Footlight\0", "ShortName");
        assert!(r[108..172].starts_with(b"#0001 ["), "NodeReport");
        assert_eq!(u16::from_be_bytes([r[172], r[173]]), 1, "NumPorts");
        assert_eq!(r[174], 0x80, "PortTypes[0]: Art-Net → DMX output");
        assert_eq!(r[190], (pa & 0xF) as u8, "SwOut[0]");
        assert_eq!(r[200], 0x06, "Style = StVisual");
        assert_eq!(r[211], i as u8 + 1, "BindIndex");
        assert_eq!(r[212] & 0x08, 0x08, "Status2: 15-bit Port-Address");
    }
    assert_eq!(replies[0][182], 0x80, "GoodOutputA: data on Port-Address 0");
    assert_eq!(replies[1][182], 0x00, "no data on Port-Address 16");

    // The independent decoder agrees.
    let ArtCommand::PollReply(reply) = ArtCommand::from_buffer(&replies[1]).unwrap() else { panic!("not a PollReply") };
    assert_eq!(reply.address, Ipv4Addr::LOCALHOST);
    assert_eq!(reply.port, 6454);
    assert_eq!(reply.port_address, [0, 1]);
    assert_eq!(reply.swout[0], 0);
    assert_eq!(reply.style, 6);
    assert_eq!(&reply.short_name[..10], b"Footlight\0");

    // A targeted poll for Port-Addresses 10-20 gets only the reply for 16.
    poller.send_to(&build_poll(0, Some(PortRange { bottom: 10, top: 20 })), input.artnet()).await.unwrap();
    let mut buf = [0u8; 1024];
    let (n, _) = recv(&mut buf, 3000).await.expect("targeted reply").unwrap();
    assert_eq!((n, buf[19], buf[190]), (239, 1, 0));
    assert!(recv(&mut buf, 300).await.is_err(), "no reply for Port-Address 0");
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
