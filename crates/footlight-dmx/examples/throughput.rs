//! How much CPU DMX input costs: packets parsed per second on one core, and
//! the share of one core that 64 universes at 44 Hz take (goal: under 2 %).
//!
//! ```sh
//! cargo run --release -p footlight-dmx --example throughput [-- SECONDS]
//! ```
//!
//! Part 1 (pure): sACN and Art-Net packets for 64 universes through the codec,
//! the receiver (sequence, sync rules) and the merge, in a loop on one thread.
//! Part 2 (live): a `DmxInput` on 127.0.0.1 in its own single-threaded tokio
//! runtime, fed 64 sACN universes at 44 Hz by a sender thread for SECONDS
//! (default 10); the input thread's CPU time comes from
//! `/proc/thread-self/schedstat`. Nothing is asserted: this is a measurement.

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use footlight_dmx::artnet::packet::build_dmx;
use footlight_dmx::artnet::{ArtNetReceiver, ArtNetReceiverConfig};
use footlight_dmx::sacn::packet::{DataSpec, build_data};
use footlight_dmx::sacn::{SacnConfig, SacnReceiver, SacnReceiverConfig};
use footlight_dmx::source::EventKind;
use footlight_dmx::{DmxInput, InputConfig, InputPatch, Merge, MergeConfig, SourceEvent, UniverseMap};

const UNIVERSES: u16 = 64;
const RATE_HZ: u32 = 44;

fn sacn_packets() -> Vec<Vec<u8>> {
    (1..=UNIVERSES)
        .map(|u| {
            let slots: Vec<u8> = (0..512).map(|i| (i as u16 ^ u) as u8).collect();
            build_data(&DataSpec {
                cid: [7; 16],
                source_name: "bench",
                priority: 100,
                sync_address: 0,
                sequence: 0,
                options: 0,
                universe: u,
                start_code: 0,
                slots: &slots,
            })
        })
        .collect()
}

/// Feeds `rounds` × 64 packets through `handle` + merge; returns packets per second.
fn pure(
    name: &str,
    mut packets: Vec<Vec<u8>>,
    seq_at: usize,
    mut handle: impl FnMut(&[u8], &mut dyn FnMut(SourceEvent)),
) {
    let map = UniverseMap::default();
    let mut merge = Merge::new(MergeConfig::default());
    let base = tokio::time::Instant::now();
    let rounds = 20_000u32;
    let mut frames = 0u64;
    let start = Instant::now();
    for round in 0..rounds {
        for p in &mut packets {
            p[seq_at] = (round % 255 + 1) as u8;
            handle(p, &mut |e| {
                if let (EventKind::Levels { priority, timeout, levels, .. }, Some(u)) =
                    (&e.kind, map.patch_universe(e.input))
                {
                    let _ = merge.apply(u, e.source, *priority, *timeout, levels, base);
                    frames += 1;
                }
            });
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let n = f64::from(rounds) * f64::from(UNIVERSES);
    assert_eq!(frames as f64, n, "every packet reached the merge");
    let rate = n / elapsed;
    let needed = f64::from(UNIVERSES) * f64::from(RATE_HZ);
    println!(
        "{name:8} parse + receive + merge: {:>9.0} packets/s on one core ({:.2} µs each); 64 × 44 Hz = {:.3} % of a core",
        rate,
        1e6 / rate,
        100.0 * needed / rate
    );
}

/// This thread's CPU time (Linux `schedstat`, nanoseconds on CPU).
fn thread_cpu() -> Option<Duration> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok().map(Duration::from_nanos)
}

fn live(seconds: u64) {
    let (addr_tx, addr_rx) = std::sync::mpsc::channel::<SocketAddr>();
    let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
    let input_thread = std::thread::Builder::new()
        .name("dmx-input".into())
        .spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
            rt.block_on(async move {
                let config = InputConfig {
                    artnet: None,
                    sacn: Some(SacnConfig {
                        bind: "127.0.0.1:0".parse().unwrap(),
                        multicast: false,
                        ..Default::default()
                    }),
                    usbpro: None,
                    patch: InputPatch { universes: (1..=UNIVERSES).collect(), ..InputPatch::default() },
                };
                let input = DmxInput::bind(config).await.unwrap();
                let stats = input.stats();
                addr_tx.send(input.local_addrs().sacn.unwrap()).unwrap();
                let (cpu0, wall0) = (thread_cpu(), Instant::now());
                let stop = async move {
                    tokio::task::spawn_blocking(move || done_rx.recv()).await.ok();
                };
                input.run(stop).await.unwrap();
                let (cpu, wall) = (thread_cpu().zip(cpu0).map(|(b, a)| b - a), wall0.elapsed());
                (cpu, wall, stats.snapshot())
            })
        })
        .unwrap();
    let to = addr_rx.recv().unwrap();
    let mut packets = sacn_packets();
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    let period = Duration::from_secs_f64(1.0 / f64::from(RATE_HZ));
    let start = Instant::now();
    let mut sent = 0u64;
    for frame in 0..(seconds * u64::from(RATE_HZ)) {
        for p in &mut packets {
            p[111] = frame as u8;
            tx.send_to(p, to).unwrap();
            sent += 1;
        }
        let next = start + period * (frame as u32 + 1);
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    std::thread::sleep(Duration::from_millis(200));
    done_tx.send(()).unwrap();
    let (cpu, wall, stats) = input_thread.join().unwrap();
    let share = cpu.map(|c| 100.0 * c.as_secs_f64() / wall.as_secs_f64());
    println!(
        "live sACN, 64 universes × 44 Hz for {seconds} s: sent {sent}, applied {}, dropped {}; input thread CPU {:?} over {:.1} s = {}",
        stats.sacn.applied,
        stats.sacn.dropped,
        cpu.unwrap_or_default(),
        wall.as_secs_f64(),
        share.map_or("n/a (no /proc/thread-self/schedstat)".into(), |s| format!("{s:.2} % of one core")),
    );
}

fn main() {
    let seconds = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    let from: SocketAddr = "127.0.0.1:5568".parse().unwrap();
    let t0 = tokio::time::Instant::now();

    let mut rx = SacnReceiver::new(SacnReceiverConfig::default());
    pure("sACN", sacn_packets(), 111, |p, out| {
        rx.handle(p, from, t0, &mut |e| out(e));
    });
    let artnet: Vec<Vec<u8>> = (0..UNIVERSES).map(|pa| build_dmx(1, 0, pa, &[pa as u8; 512])).collect();
    let mut rx = ArtNetReceiver::new(ArtNetReceiverConfig::default());
    pure("Art-Net", artnet, 12, |p, out| {
        rx.handle(p, from, t0, &mut |e| out(e));
    });
    live(seconds);
}
