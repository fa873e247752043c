//! DmxInput orchestration: mapping, LTP policy, malformed floods, a consumer
//! that never reads, shutdown.

use std::time::Duration;

use footlight_dmx::artnet::packet::build_dmx;
use footlight_dmx::sacn::packet::{DataSpec, build_data};
use footlight_dmx::{InputUniverse, SlotMask, UniverseMap};

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
