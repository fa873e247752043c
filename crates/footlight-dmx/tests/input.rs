//! DmxInput orchestration: mapping, LTP policy, malformed floods, a consumer
//! that never reads, shutdown.

use std::time::Duration;

use footlight_dmx::artnet::packet::build_dmx;
use footlight_dmx::sacn::packet::{DataSpec, build_data};
use footlight_dmx::{FeedState, InputUniverse, SlotMask, UniverseMap};

use crate::common::{Running, loopback_config, sender};

fn sacn(cid: u8, seq: u8, universe: u16, slots: &[u8]) -> Vec<u8> {
    build_data(&DataSpec {
        cid: [cid; 16],
        source_name: "t",
        priority: 100,
        sync_address: 0,
        sequence: seq,
        options: 0,
        universe,
        start_code: 0,
        slots,
    })
}

#[tokio::test]
async fn mapping_overrides_filters_and_ltp_slots() {
    let mut config = loopback_config(vec![1, 2]);
    let mut map = UniverseMap::default();
    map.route(InputUniverse::Sacn(101), 2).block(InputUniverse::ArtNet(1));
    config.patch.map = map;
    config.patch.ltp.insert(1, SlotMask::from_addresses([2]));
    let mut input = Running::start(config).await;
    let tx = sender();
    // sACN 101 feeds patch universe 2; sACN 3 is not patched; Art-Net 1 is blocked.
    tx.send_to(&sacn(1, 1, 101, &[7]), input.sacn()).unwrap();
    tx.send_to(&sacn(1, 1, 3, &[7]), input.sacn()).unwrap();
    tx.send_to(&build_dmx(0, 0, 1, &[9, 9]), input.artnet()).unwrap();
    input.wait_slots(2, &[7]).await;
    // Universe 1 merges slot 1 HTP and slot 2 LTP between Art-Net and sACN (both priority 100).
    tx.send_to(&build_dmx(0, 0, 0, &[100, 200]), input.artnet()).unwrap();
    input.wait_slots(1, &[100, 200]).await;
    tx.send_to(&sacn(2, 1, 1, &[50, 20]), input.sacn()).unwrap();
    input.wait_slots(1, &[100, 20]).await;
    let s = input.stats.snapshot();
    assert_eq!(s.sacn.ignored, 1, "sACN universe 3 is not patched");
    assert_eq!(s.artnet.ignored, 1, "Art-Net 1 is blocked");
    assert_eq!(input.frames.borrow().len(), 2);
    input.stop().await;
}

#[tokio::test]
async fn a_malformed_flood_never_stalls_the_nodes() {
    let mut input = Running::start(loopback_config(vec![])).await;
    let tx = sender();
    let garbage: Vec<Vec<u8>> =
        (0..40u8).map(|i| (0..(i as usize * 13) % 700).map(|j| (j as u8) ^ i).collect()).collect();
    let mut sent = 0u64;
    for round in 0..25u8 {
        for g in &garbage {
            tx.send_to(g, input.artnet()).unwrap();
            tx.send_to(g, input.sacn()).unwrap();
            sent += 1;
        }
        tx.send_to(&build_dmx(0, 0, 0, &[round]), input.artnet()).unwrap();
        tx.send_to(&sacn(1, round, 2, &[round]), input.sacn()).unwrap();
        // Let the kernel buffer drain now and then (it holds about 200 small datagrams).
        if round % 5 == 4 {
            input.wait_slots(2, &[round]).await;
        }
    }
    input.wait_slots(1, &[24]).await;
    input.wait_slots(2, &[24]).await;
    let s = input.stats.snapshot();
    assert_eq!(s.artnet.malformed + s.artnet.applied, sent + 25, "{s:?}");
    assert_eq!(s.sacn.malformed + s.sacn.applied, sent + 25, "{s:?}");
    assert_eq!((s.artnet.applied, s.sacn.applied), (25, 25));
    input.stop().await;
}

#[tokio::test]
async fn a_consumer_that_never_reads_does_not_block_input() {
    let mut input = Running::start(loopback_config(vec![])).await;
    let idle_consumer = input.frames.clone();
    let tx = sender();
    for i in 0..=255u8 {
        tx.send_to(&sacn(1, i, 1, &[i]), input.sacn()).unwrap();
        if i % 64 == 63 {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }
    input.wait_slots(1, &[255]).await;
    assert_eq!(input.stats.snapshot().sacn.applied, 256);
    assert!(idle_consumer.has_changed().unwrap(), "the idle consumer only sees that something changed");
    input.stop().await;
}

#[tokio::test]
async fn shutdown_stops_every_node_promptly() {
    let input = Running::start(loopback_config(vec![1])).await;
    let started = std::time::Instant::now();
    input.stop().await;
    assert!(started.elapsed() < Duration::from_secs(1));
}

#[tokio::test]
async fn patch_universe_zero_is_a_config_error() {
    let err = footlight_dmx::DmxInput::bind(loopback_config(vec![0, 1])).await.err().expect("refused");
    assert!(err.to_string().contains("count from 1"), "{err}");
}

/// The brief's patch: Art-Net Port-Address 1 → patch 1, sACN 101 → patch 2,
/// sACN 3 blocked; patch universes 1, 2, 3.
fn routed_config() -> footlight_dmx::InputConfig {
    let mut config = loopback_config(vec![1, 2, 3]);
    config
        .patch
        .map
        .route(InputUniverse::ArtNet(1), 1)
        .route(InputUniverse::Sacn(101), 2)
        .block(InputUniverse::Sacn(3));
    config
}

#[tokio::test]
async fn routes_drive_patch_universes_and_block_drops() {
    let mut input = Running::start(routed_config()).await;
    let tx = sender();
    tx.send_to(&build_dmx(0, 0, 1, &[11, 12]), input.artnet()).unwrap();
    tx.send_to(&sacn(7, 1, 101, &[21, 22]), input.sacn()).unwrap();
    // Defaults of the routed universes (Art-Net 0, sACN 1 and 2) no longer feed them,
    // the blocked sACN 3 is dropped, and Art-Net 2 still feeds patch 3 by default.
    tx.send_to(&build_dmx(0, 0, 0, &[99]), input.artnet()).unwrap();
    tx.send_to(&sacn(7, 1, 1, &[99]), input.sacn()).unwrap();
    tx.send_to(&sacn(7, 1, 2, &[99]), input.sacn()).unwrap();
    tx.send_to(&sacn(7, 1, 3, &[99]), input.sacn()).unwrap();
    tx.send_to(&build_dmx(0, 0, 2, &[31]), input.artnet()).unwrap();
    input.wait_slots(1, &[11, 12]).await;
    input.wait_slots(2, &[21, 22]).await;
    input.wait_slots(3, &[31]).await;
    // Every datagram counted (bounded wait: 500 × 10 ms).
    for _ in 0..500 {
        let s = input.stats.snapshot();
        if s.artnet.received + s.sacn.received == 7 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let u = input.frames.borrow().clone();
    assert_eq!(u.len(), 3);
    assert!(u.iter().all(|f| f.slots[0] != 99), "{:?}", crate::common::summary(&u));
    let status = input.status.snapshot();
    let fed: Vec<(u16, u64, usize)> =
        status.universes.iter().map(|u| (u.universe, u.packets, u.sources.len())).collect();
    assert_eq!(fed, vec![(1, 1, 1), (2, 1, 1), (3, 1, 1)]);
    let s2 = &status.universes[1].sources[0];
    assert_eq!((s2.name.as_deref(), s2.input.universe, s2.priority), (Some("t"), 101, 100));
    assert_eq!(status.universes[0].sources[0].ip, Some("127.0.0.1".parse().unwrap()));
    let unpatched: Vec<(u16, Option<u16>, bool)> =
        status.unpatched.iter().map(|u| (u.input.universe, u.default_patch_universe, u.blocked)).collect();
    // Art-Net 0, then sACN 1, 2 and the blocked 3 (BTreeMap order: protocol, number).
    assert_eq!(unpatched, vec![(0, Some(1), false), (1, Some(1), false), (2, Some(2), false), (3, Some(3), true)]);
    assert_eq!((status.counters.artnet.ignored, status.counters.sacn.ignored), (1, 3));
    input.stop().await;
}

#[tokio::test(start_paused = true)]
async fn an_art_net_source_that_stops_marks_its_universe_stale_after_10_s() {
    let poller = tokio::net::UdpSocket::bind("127.0.0.6:0").await.unwrap();
    let mut config = loopback_config(vec![1]);
    config.artnet.as_mut().unwrap().reply_port = poller.local_addr().unwrap().port();
    let mut input = Running::start(config).await;
    let tx = sender();
    tx.send_to(&build_dmx(0, 0, 0, &[40, 41]), input.artnet()).unwrap();
    let f = input.wait_slots(1, &[40, 41]).await;
    let t0 = f.at;
    let status = input.status.snapshot();
    assert_eq!((status.universes[0].state, status.universes[0].stale), (FeedState::Receiving, false));
    let art = input.artnet();
    let poll_report = async |expect_good: u8| {
        poller.send_to(&footlight_dmx::artnet::packet::build_poll(0, None), art).await.unwrap();
        let mut buf = [0u8; 512];
        let (n, _) = tokio::time::timeout(Duration::from_secs(3), poller.recv_from(&mut buf)).await.unwrap().unwrap();
        assert_eq!((n, buf[182]), (239, expect_good), "GoodOutputA");
        String::from_utf8_lossy(&buf[121..172]).trim_end_matches('\0').to_string()
    };
    assert_eq!(poll_report(0x80).await, "receiving 0");
    tokio::time::sleep_until(t0 + Duration::from_millis(9900)).await;
    assert!(!input.frames.borrow().get(1).unwrap().stale, "Art-Net holds a silent source for 10 s");
    let f = input.wait_until("stale", |u| u.get(1).is_some_and(|f| f.stale)).await.get(1).unwrap().clone();
    assert_eq!(f.at - t0, Duration::from_secs(10), "stale exactly at the Art-Net timeout");
    assert_eq!(f.slots[..2], [40, 41], "the frame holds");
    let status = input.status.snapshot();
    let u = &status.universes[0];
    assert_eq!((u.state, u.stale, u.packets, u.sources.len()), (FeedState::Stale, true, 1, 0));
    assert!(u.last_packet_ms.unwrap() >= 10_000);
    tokio::time::sleep(Duration::from_millis(1100)).await; // past the poll interval
    assert_eq!(poll_report(0x00).await, "stale 0");
    input.stop().await;
}
