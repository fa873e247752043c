//! Shared test helpers: a running DmxInput on loopback, bounded waits, peers.

use std::net::{SocketAddr, UdpSocket};
use std::process::Command;
use std::time::Duration;

use footlight_dmx::artnet::ArtNetConfig;
use footlight_dmx::sacn::SacnConfig;
use footlight_dmx::{
    DmxInput, Error, InputConfig, InputPatch, LocalAddrs, StatsHandle, StatusHandle, UniverseFrame, Universes,
};
use tokio::sync::{oneshot, watch};
use tokio::task::JoinHandle;

/// Art-Net and sACN on 127.0.0.1 with kernel-chosen ports, no multicast, no
/// ArtPollReply delay; `universes` as the patch universes (empty: all).
pub fn loopback_config(universes: Vec<u16>) -> InputConfig {
    InputConfig {
        artnet: Some(ArtNetConfig {
            bind: "127.0.0.1:0".parse().unwrap(),
            reply_delay_max: Duration::ZERO,
            ..ArtNetConfig::default()
        }),
        sacn: Some(SacnConfig { bind: "127.0.0.1:0".parse().unwrap(), multicast: false, ..SacnConfig::default() }),
        usbpro: None,
        patch: InputPatch { universes, ..InputPatch::default() },
    }
}

/// A DmxInput running in a task, with a way to stop it.
pub struct Running {
    pub frames: watch::Receiver<Universes>,
    pub stats: StatsHandle,
    pub status: StatusHandle,
    pub addrs: LocalAddrs,
    stop: Option<oneshot::Sender<()>>,
    task: JoinHandle<Result<(), Error>>,
}

impl Running {
    pub async fn start(config: InputConfig) -> Running {
        Self::start_input(DmxInput::bind(config).await.expect("bind loopback input")).await
    }

    pub async fn start_input(input: DmxInput) -> Running {
        let (frames, stats, status, addrs) = (input.frames(), input.stats(), input.status(), input.local_addrs());
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(input.run(async {
            let _ = stopped.await;
        }));
        Running { frames, stats, status, addrs, stop: Some(stop), task }
    }

    pub fn artnet(&self) -> SocketAddr {
        self.addrs.artnet.expect("Art-Net on")
    }

    pub fn sacn(&self) -> SocketAddr {
        self.addrs.sacn.expect("sACN on")
    }

    /// Waits (at most 5 s of tokio time) until `pred` holds for the frames.
    pub async fn wait_until(&mut self, what: &str, pred: impl Fn(&Universes) -> bool) -> Universes {
        let frames = &mut self.frames;
        let waited = tokio::time::timeout(Duration::from_secs(5), async {
            loop {
                {
                    let now = frames.borrow_and_update();
                    if pred(&now) {
                        return now.clone();
                    }
                }
                frames.changed().await.expect("input stopped");
            }
        })
        .await;
        match waited {
            Ok(u) => u,
            Err(_) => panic!("timed out waiting for {what}; frames: {:?}", summary(&self.frames.borrow())),
        }
    }

    /// Waits until universe `u` starts with `prefix`.
    pub async fn wait_slots(&mut self, u: u16, prefix: &[u8]) -> UniverseFrame {
        let what = format!("universe {u} = {prefix:?}");
        let all = self.wait_until(&what, |f| f.get(u).is_some_and(|f| f.slots.starts_with(prefix))).await;
        all.get(u).unwrap().clone()
    }

    pub async fn stop(mut self) {
        let _ = self.stop.take().unwrap().send(());
        let result = tokio::time::timeout(Duration::from_secs(5), self.task).await;
        result.expect("input stops within 5 s").expect("no panic").expect("run returns Ok");
    }
}

/// The first slots of each universe, for failure messages.
pub fn summary(u: &Universes) -> Vec<(u16, Vec<u8>, bool)> {
    u.iter().map(|f| (f.universe, f.slots[..8].to_vec(), f.stale)).collect()
}

/// A sending socket on 127.0.0.1.
pub fn sender() -> UdpSocket {
    UdpSocket::bind("127.0.0.1:0").unwrap()
}

/// Whether `program` runs (`program --version` or `-h` exits, whatever the code).
pub fn have(program: &str) -> bool {
    Command::new(program).arg("--version").output().is_ok()
}

/// Whether python3 can import `module`; prints why a test skips otherwise.
pub fn python_module(module: &str) -> bool {
    match Command::new("python3").args(["-c", &format!("import {module}")]).output() {
        Ok(o) if o.status.success() => true,
        Ok(_) => {
            require_peers(&format!("python3 cannot import `{module}`"));
            eprintln!("skipped: python3 module `{module}` is missing (.ci/run installs it with pip)");
            false
        }
        Err(_) => {
            require_peers("python3 is not installed");
            eprintln!("skipped: python3 is not installed");
            false
        }
    }
}

/// Prints the skip message for a missing program and returns false.
pub fn require(program: &str, package: &str) -> bool {
    if have(program) {
        return true;
    }
    require_peers(&format!("`{program}` is not installed (Debian package `{package}`)"));
    eprintln!("skipped: `{program}` is not installed (Debian package `{package}`)");
    false
}

/// With `FOOTLIGHT_REQUIRE_PEERS` set (`.ci/run` sets it), a missing peer
/// fails the test instead of skipping it: CI never passes a peer test that
/// did not run.
pub fn require_peers(missing: &str) {
    assert!(std::env::var_os("FOOTLIGHT_REQUIRE_PEERS").is_none(), "FOOTLIGHT_REQUIRE_PEERS is set but {missing}");
}
