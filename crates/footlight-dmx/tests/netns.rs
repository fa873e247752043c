//! Multicast inside a network namespace of our own (never on the host
//! network): the sACN node joins 239.255.x.y for its patched universes (more
//! than Linux's 20 memberships per socket) and receives multicast sent there.
//!
//! The parent test creates the namespace and runs this test binary inside it
//! (`ip netns exec`) with `FOOTLIGHT_DMX_NETNS=1`, which selects the child.

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::process::Command;
use std::time::Duration;

use footlight_dmx::sacn::packet::{DataSpec, build_data};
use footlight_dmx::sacn::{SacnConfig, multicast_group};
use footlight_dmx::{InputConfig, InputPatch, InputUniverse};

use crate::common::Running;

const CHILD_ENV: &str = "FOOTLIGHT_DMX_NETNS";

/// Deletes the namespace on drop.
struct Netns(String);

impl Drop for Netns {
    fn drop(&mut self) {
        let _ = Command::new("ip").args(["netns", "del", &self.0]).status();
    }
}

fn ip(args: &[&str]) -> bool {
    Command::new("ip").args(args).output().is_ok_and(|o| o.status.success())
}

#[test]
fn multicast_join_in_a_network_namespace() {
    let name = format!("footlight-dmx-{}", std::process::id());
    if !ip(&["netns", "add", &name]) {
        eprintln!("skipped: cannot create a network namespace (needs root and iproute2)");
        return;
    }
    let ns = Netns(name);
    assert!(ip(&["netns", "exec", &ns.0, "ip", "link", "set", "lo", "up"]));
    let exe = std::env::current_exe().unwrap();
    let out = Command::new("timeout")
        .args(["30", "ip", "netns", "exec", &ns.0])
        .arg(exe)
        .args(["--exact", "netns::multicast_child", "--include-ignored", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, "1")
        .output()
        .unwrap();
    let log = format!("{}\n{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success() && log.contains("1 passed"), "child test failed:\n{log}");
}

/// Runs only inside the namespace (see the module doc).
#[tokio::test]
#[ignore = "runs inside a network namespace made by multicast_join_in_a_network_namespace"]
async fn multicast_child() {
    if std::env::var_os(CHILD_ENV).is_none() {
        eprintln!("skipped: only meaningful inside the test's network namespace");
        return;
    }
    // 24 universes: past Linux's 20 memberships per socket.
    let universes: Vec<u16> = (1..=24).collect();
    let bind: SocketAddr = "0.0.0.0:5568".parse().unwrap();
    let config = InputConfig {
        artnet: None,
        sacn: Some(SacnConfig { bind, multicast: true, interface: Ipv4Addr::LOCALHOST }),
        usbpro: None,
        patch: InputPatch { universes: universes.clone(), ..InputPatch::default() },
    };
    let mut input = Running::start(config).await;
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    socket2::SockRef::from(&tx).set_multicast_if_v4(&Ipv4Addr::LOCALHOST).unwrap();
    for u in [1u16, 24, 30] {
        let p = build_data(&DataSpec {
            cid: [3; 16],
            source_name: "netns",
            priority: 100,
            sync_address: 0,
            sequence: 1,
            options: 0,
            universe: u,
            start_code: 0,
            slots: &[u as u8],
        });
        tx.send_to(&p, (multicast_group(u), 5568)).unwrap();
    }
    input.wait_slots(1, &[1]).await;
    input.wait_slots(24, &[24]).await;
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(input.frames.borrow().get(30).is_none(), "universe 30's group was not joined");
    assert_eq!(input.stats.snapshot().sacn.received, 2);
    input.stop().await;

    // Routes decide the groups: sACN 101 → patch 2 (patch 1 is routed from
    // Art-Net), so the node joins 239.255.0.101 on the chosen interface, not
    // the groups of patch universes 1 and 2.
    let mut patch = InputPatch { universes: vec![1, 2], ..InputPatch::default() };
    patch.map.route(InputUniverse::ArtNet(1), 1).route(InputUniverse::Sacn(101), 2);
    let config = InputConfig {
        artnet: None,
        sacn: Some(SacnConfig { bind, multicast: true, interface: Ipv4Addr::LOCALHOST }),
        usbpro: None,
        patch,
    };
    let input = footlight_dmx::DmxInput::bind(config).await.unwrap();
    assert_eq!(input.joined_groups(), vec![101]);
    let mut input = Running::start_input(input).await;
    for u in [2u16, 101] {
        let p = build_data(&DataSpec {
            cid: [4; 16],
            source_name: "netns routes",
            priority: 100,
            sync_address: 0,
            sequence: 1,
            options: 0,
            universe: u,
            start_code: 0,
            slots: &[u as u8],
        });
        tx.send_to(&p, (multicast_group(u), 5568)).unwrap();
    }
    input.wait_slots(2, &[101]).await;
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(input.stats.snapshot().sacn.received, 1, "universe 2's group was not joined");
    input.stop().await;
}
