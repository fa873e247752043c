//! sACN over a real loopback socket.

use std::time::Duration;

use footlight_dmx::SourceId;
use footlight_dmx::sacn::packet::{DataSpec, OPTION_PREVIEW, OPTION_TERMINATED, build_data, build_sync};

use crate::common::{Running, loopback_config, sender};

fn data(cid: u8, priority: u8, sequence: u8, universe: u16, slots: &[u8]) -> Vec<u8> {
    build_data(&DataSpec {
        cid: [cid; 16],
        source_name: "test desk",
        priority,
        sync_address: 0,
        sequence,
        options: 0,
        universe,
        start_code: 0,
        slots,
    })
}

fn with_options(mut packet: Vec<u8>, options: u8) -> Vec<u8> {
    packet[112] = options;
    packet
}

/// A minimal data packet for universe 1, slots [1, 2, 3], written out from the
/// E1.31 tables (CID 0x01…, priority 100, sequence 7), not with our builder.
fn spec_bytes() -> Vec<u8> {
    let mut p = vec![0x00, 0x10, 0x00, 0x00]; // preamble, postamble
    p.extend(b"ASC-E1.17\0\0\0");
    p.extend([0x70, 0x71]); // flags | length 129 - 16 = 113
    p.extend([0, 0, 0, 4]); // VECTOR_ROOT_E131_DATA
    p.extend([1; 16]); // CID
    p.extend([0x70, 0x5B]); // flags | length 129 - 38 = 91
    p.extend([0, 0, 0, 2]); // VECTOR_E131_DATA_PACKET
    let mut name = [0u8; 64];
    name[..4].copy_from_slice(b"spec");
    p.extend(name);
    p.extend([100, 0, 0, 7, 0, 0, 1]); // priority, sync address, sequence, options, universe
    p.extend([0x70, 0x0E]); // flags | length 129 - 115 = 14
    p.extend([0x02, 0xA1, 0, 0, 0, 1, 0, 4]); // vector, type, first, increment, count 4
    p.extend([0, 1, 2, 3]); // START code, slots
    assert_eq!(p.len(), 129);
    p
}

#[tokio::test]
async fn spec_bytes_and_priority_and_htp() {
    let mut input = Running::start(loopback_config(vec![])).await;
    let tx = sender();
    let to = input.sacn();
    tx.send_to(&spec_bytes(), to).unwrap();
    input.wait_slots(1, &[1, 2, 3]).await;
    // Equal priority: HTP per slot.
    tx.send_to(&data(2, 100, 1, 1, &[0, 9, 1, 5]), to).unwrap();
    input.wait_slots(1, &[1, 9, 3, 5]).await;
    // Higher priority takes the whole universe.
    tx.send_to(&data(3, 150, 1, 1, &[4]), to).unwrap();
    input.wait_slots(1, &[4, 0, 0, 0]).await;
    // Lower priority changes nothing.
    tx.send_to(&data(2, 100, 2, 1, &[200, 200]), to).unwrap();
    tx.send_to(&data(3, 150, 2, 1, &[5]), to).unwrap();
    input.wait_slots(1, &[5, 0]).await;
    input.stop().await;
}

#[tokio::test]
async fn sequence_per_source_per_universe_with_wrap_and_window() {
    let mut input = Running::start(loopback_config(vec![])).await;
    let tx = sender();
    let to = input.sacn();
    // Same CID on two universes: independent counters (WLED#742).
    tx.send_to(&data(1, 100, 250, 1, &[1]), to).unwrap();
    tx.send_to(&data(1, 100, 3, 2, &[1]), to).unwrap();
    // Wrap 250 → 255 → 0 → 4: all forward.
    for (seq, v) in [(255, 2), (0, 3), (4, 4)] {
        tx.send_to(&data(1, 100, seq, 1, &[v]), to).unwrap();
    }
    input.wait_slots(1, &[4]).await;
    // -1, -19: dropped. -20: outside the window, taken (a restarted sender).
    tx.send_to(&data(1, 100, 3, 1, &[50]), to).unwrap();
    tx.send_to(&data(1, 100, 241, 1, &[51]), to).unwrap();
    tx.send_to(&data(1, 100, 4, 1, &[52]), to).unwrap(); // duplicate: d = 0
    tx.send_to(&data(1, 100, 240, 1, &[60]), to).unwrap();
    input.wait_slots(1, &[60]).await;
    tx.send_to(&data(1, 100, 4, 2, &[70]), to).unwrap();
    input.wait_slots(2, &[70]).await;
    let s = input.stats.snapshot();
    assert_eq!(s.sacn.dropped, 3);
    assert_eq!(s.sources[&SourceId::Sacn { cid: [1; 16] }].dropped, 3);
    input.stop().await;
}

#[tokio::test(start_paused = true)]
async fn a_silent_source_leaves_after_2_5_s_and_the_frame_holds_stale() {
    let mut input = Running::start(loopback_config(vec![1])).await;
    let tx = sender();
    let to = input.sacn();
    tx.send_to(&data(1, 100, 1, 1, &[100, 50]), to).unwrap();
    tx.send_to(&data(2, 100, 1, 1, &[10, 200]), to).unwrap();
    input.wait_slots(1, &[100, 200]).await;
    // Source 2 keeps sending; source 1 falls silent.
    tokio::time::sleep(Duration::from_millis(1200)).await;
    tx.send_to(&data(2, 100, 2, 1, &[10, 200]), to).unwrap();
    tokio::time::sleep(Duration::from_millis(1200)).await;
    assert_eq!(input.frames.borrow().get(1).unwrap().slots[0], 100, "source 1 still counts at 2.4 s");
    tx.send_to(&data(2, 100, 3, 1, &[10, 200]), to).unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let f = input.frames.borrow().get(1).unwrap().clone();
    assert_eq!((f.slots[0], f.slots[1], f.stale), (10, 200, false), "source 1 gone at 2.6 s");
    // Then source 2 falls silent too: last frame holds, marked stale.
    let f = input.wait_until("stale", |u| u.get(1).is_some_and(|f| f.stale)).await;
    assert_eq!(f.get(1).unwrap().slots[..2], [10, 200]);
    input.stop().await;
}

#[tokio::test]
async fn termination_leaves_at_once_and_preview_is_ignored() {
    let mut input = Running::start(loopback_config(vec![])).await;
    let tx = sender();
    let to = input.sacn();
    tx.send_to(&data(1, 100, 1, 1, &[100]), to).unwrap();
    tx.send_to(&data(2, 100, 1, 1, &[10, 10]), to).unwrap();
    input.wait_slots(1, &[100, 10]).await;
    tx.send_to(&with_options(data(3, 200, 1, 1, &[255, 255]), OPTION_PREVIEW), to).unwrap();
    // Termination: its slots are ignored, the source leaves now.
    tx.send_to(&with_options(data(1, 100, 2, 1, &[255]), OPTION_TERMINATED), to).unwrap();
    input.wait_slots(1, &[10, 10]).await;
    tx.send_to(&with_options(data(2, 100, 2, 1, &[0]), OPTION_TERMINATED), to).unwrap();
    let u = input.wait_until("stale after the last termination", |u| u.get(1).is_some_and(|f| f.stale)).await;
    assert_eq!(u.get(1).unwrap().slots[..2], [10, 10]);
    let s = input.stats.snapshot();
    assert_eq!(s.sacn.ignored, 1, "preview");
    input.stop().await;
}

#[tokio::test]
async fn universe_sync_holds_data_until_the_sync_packet() {
    let mut input = Running::start(loopback_config(vec![1, 2])).await;
    let tx = sender();
    let to = input.sacn();
    let synced = |universe, seq, v: u8| {
        let mut p = data(1, 100, seq, universe, &[v]);
        p[109..111].copy_from_slice(&7000u16.to_be_bytes());
        p
    };
    // Before the first sync packet for 7000: acted on at once.
    tx.send_to(&synced(1, 1, 10), to).unwrap();
    input.wait_slots(1, &[10]).await;
    tx.send_to(&build_sync(&[9; 16], 1, 7000), to).unwrap();
    tx.send_to(&synced(1, 2, 20), to).unwrap();
    tx.send_to(&synced(2, 1, 21), to).unwrap();
    // A marker on an unsynchronised source proves the held packets were processed.
    tx.send_to(&data(5, 100, 1, 2, &[1]), to).unwrap();
    input.wait_slots(2, &[1]).await;
    assert_eq!(input.frames.borrow().get(1).unwrap().slots[0], 10, "held");
    tx.send_to(&build_sync(&[9; 16], 2, 7000), to).unwrap();
    let u = input.wait_until("both released", |u| {
        u.get(1).is_some_and(|f| f.slots[0] == 20) && u.get(2).is_some_and(|f| f.slots[0] == 21)
    });
    u.await;
    input.stop().await;
}
