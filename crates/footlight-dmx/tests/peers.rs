//! Independent senders: PyPI `stupidArtnet` 1.6.0 and `sacn` 1.11.0
//! (installed by `.ci/run`), sending to loopback addresses only.

use std::net::SocketAddr;
use std::process::Command;

use footlight_dmx::sacn::SacnConfig;
use footlight_dmx::sacn::packet::{DataSpec, build_data};
use footlight_dmx::{InputConfig, InputPatch, InputUniverse, Protocol, SourceId};

use crate::common::{Running, loopback_config, python_module, sender};

/// Runs a Python script with a 20 s watchdog; panics with its output on failure.
fn python(script: &str) {
    let out = Command::new("timeout").args(["20", "python3", "-c", script]).output().expect("run python3");
    assert!(
        out.status.success(),
        "python failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stupidartnet_frames_with_and_without_artsync() {
    if !python_module("stupidArtnet") {
        return;
    }
    let mut input = Running::start(loopback_config(vec![])).await;
    let port = input.artnet().port();
    // Universe 5 in stupidArtnet's "simplified" addressing is Port-Address 5 → patch universe 6.
    let script = format!(
        r#"
from stupidArtnet import StupidArtnet
a = StupidArtnet(target_ip='127.0.0.1', universe=5, packet_size=512, fps=30, port={port})
a.set(bytearray([10, 20, 30] + [0] * 509))
a.show()
a.close()
b = StupidArtnet(target_ip='127.0.0.1', universe=0, packet_size=6, fps=30, artsync=True, port={port})
b.set(bytearray([1, 2, 3, 4, 5, 6]))
b.show()
b.set(bytearray([7, 8, 9, 10, 11, 12]))
b.show()
b.close()
"#
    );
    tokio::task::block_in_place(|| python(&script));
    input.wait_slots(6, &[10, 20, 30, 0]).await;
    // Second frame was held by the first ArtSync and released by the second.
    input.wait_slots(1, &[7, 8, 9, 10, 11, 12, 0]).await;
    let s = input.stats.snapshot();
    assert_eq!(s.artnet.malformed, 0);
    assert_eq!(s.artnet.received, 5, "3 ArtDmx + 2 ArtSync");
    assert_eq!(s.artnet.applied, 3);
    input.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_sacn_sender_priority_and_termination() {
    if !python_module("sacn") {
        return;
    }
    // The sacn sender always sends to port 5568, so our receiver takes 5568 on a
    // loopback address of its own; its sender binds port 0 (protocols.md: a
    // sender bound to 5568 would swallow unicast meant for us).
    let bind: SocketAddr = "127.0.0.77:5568".parse().unwrap();
    let config = InputConfig {
        artnet: None,
        sacn: Some(SacnConfig { bind, multicast: false, ..SacnConfig::default() }),
        usbpro: None,
        patch: InputPatch::default(),
    };
    let mut input = Running::start(config).await;
    // Our own priority-100 source on universe 1.
    let ours = build_data(&DataSpec {
        cid: [0xAB; 16],
        source_name: "rust",
        priority: 100,
        sync_address: 0,
        sequence: 1,
        options: 0,
        universe: 1,
        start_code: 0,
        slots: &[200, 200, 200],
    });
    sender().send_to(&ours, bind).unwrap();
    input.wait_slots(1, &[200, 200, 200]).await;

    let script = r#"
import sacn, time
s = sacn.sACNsender(bind_address='127.0.0.1', bind_port=0, universeDiscovery=False, source_name='python')
s.start()
s.activate_output(1)
s[1].destination = '127.0.0.77'
s[1].priority = 150
s[1].dmx_data = (10, 20, 30)
time.sleep(0.5)
print('SENT', flush=True)
s.deactivate_output(1)
time.sleep(0.2)
s.stop()
"#;
    let peer = tokio::task::spawn_blocking(move || python(script));
    // Priority 150 beats ours while it sends (sacn pads to 512 slots).
    input.wait_slots(1, &[10, 20, 30, 0]).await;
    peer.await.unwrap();
    // Its three Stream_Terminated packets make it leave: ours is back at once.
    input.wait_slots(1, &[200, 200, 200]).await;
    let s = input.stats.snapshot();
    assert_eq!(s.sacn.malformed, 0, "{s:?}");
    let python_source = s.sources.keys().find(|k| matches!(k, SourceId::Sacn { cid } if *cid != [0xAB; 16]));
    assert!(python_source.is_some(), "the Python CID is counted as a source");
    input.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_senders_follow_the_patch_routes() {
    if !python_module("stupidArtnet") || !python_module("sacn") {
        return;
    }
    // Art-Net Port-Address 1 → patch universe 1, sACN 101 → patch universe 2
    // (OLA's and many desks' numbering), patch universes 1 and 2.
    let sacn_at: SocketAddr = "127.0.0.78:5568".parse().unwrap();
    let mut config = loopback_config(vec![1, 2]);
    config.sacn = Some(SacnConfig { bind: sacn_at, multicast: false, ..SacnConfig::default() });
    config.patch.map.route(InputUniverse::ArtNet(1), 1).route(InputUniverse::Sacn(101), 2);
    let mut input = Running::start(config).await;
    let port = input.artnet().port();
    let script = format!(
        r#"
import sacn, time
from stupidArtnet import StupidArtnet
a = StupidArtnet(target_ip='127.0.0.1', universe=1, packet_size=4, fps=30, port={port})
a.set(bytearray([1, 2, 3, 4]))
a.show()
z = StupidArtnet(target_ip='127.0.0.1', universe=0, packet_size=4, fps=30, port={port})
z.set(bytearray([99, 99, 99, 99]))
z.show()
a.close(); z.close()
s = sacn.sACNsender(bind_address='127.0.0.1', bind_port=0, universeDiscovery=False, source_name='python routes')
s.start()
s.activate_output(101)
s[101].destination = '127.0.0.78'
s[101].dmx_data = (5, 6, 7)
time.sleep(0.5)
s.stop()
"#
    );
    tokio::task::block_in_place(|| python(&script));
    input.wait_slots(1, &[1, 2, 3, 4]).await;
    input.wait_slots(2, &[5, 6, 7, 0]).await;
    let status = input.status.snapshot();
    let u2 = &status.universes[1];
    assert_eq!(u2.sources[0].name.as_deref(), Some("python routes"));
    assert_eq!((u2.sources[0].input.protocol, u2.sources[0].input.universe), (Protocol::Sacn, 101));
    let pa0 = status.unpatched.iter().find(|u| u.input.protocol == Protocol::ArtNet).expect("Art-Net 0 unpatched");
    assert_eq!((pa0.input.universe, pa0.packets, pa0.default_patch_universe), (0, 1, Some(1)));
    assert_eq!(input.frames.borrow().get(1).unwrap().slots[0], 1, "Port-Address 0 does not reach patch universe 1");
    input.stop().await;
}
