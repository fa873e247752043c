//! Headless Chromium driven over the DevTools protocol (loopback only), for
//! the tests that check the preview page in a real browser: the stream's
//! WebGL2 composite, the light table's layout, camera drags.

use std::net::SocketAddr;
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::{self, Message};

/// The Chromium binary, or `None` (the test skips) when it is not
/// installed; with `FOOTLIGHT_REQUIRE_BROWSER` set (CI) a missing browser
/// fails the test instead.
pub fn chromium() -> Option<&'static str> {
    let found = ["chromium", "chromium-browser"]
        .into_iter()
        .find(|c| std::process::Command::new(c).arg("--version").output().map(|o| o.status.success()).unwrap_or(false));
    if found.is_none() {
        assert!(std::env::var_os("FOOTLIGHT_REQUIRE_BROWSER").is_none(), "chromium required but not installed");
        eprintln!("skipping: chromium not installed");
    }
    found
}

/// One headless Chromium with one page open.
pub struct Browser {
    child: std::process::Child,
    ws: tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<std::net::TcpStream>>,
    id: u64,
    dir: std::path::PathBuf,
}

impl Browser {
    /// Starts Chromium with a `width`×`height` window on `url` and connects
    /// to that page's DevTools socket (waits up to 60 s for both).
    pub fn open(chromium: &str, url: &str, (width, height): (u32, u32)) -> Self {
        static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("footlight-chromium-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let child = std::process::Command::new(chromium)
            .args(["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run"])
            .args(["--disable-background-networking", "--disable-component-update", "--disable-sync"])
            .args(["--remote-debugging-address=127.0.0.1", "--remote-debugging-port=0"])
            .arg(format!("--window-size={width},{height}"))
            .arg(format!("--user-data-dir={}", dir.display()))
            .arg(url)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let t = Instant::now();
        let port: u16 = loop {
            if let Some(p) = std::fs::read_to_string(dir.join("DevToolsActivePort"))
                .ok()
                .and_then(|s| s.lines().next().and_then(|l| l.trim().parse().ok()))
            {
                break p;
            }
            assert!(t.elapsed() < Duration::from_secs(60), "Chromium did not open its DevTools port");
            std::thread::sleep(Duration::from_millis(50));
        };
        let devtools = SocketAddr::from(([127, 0, 0, 1], port));
        let page = loop {
            let list = devtools_list(devtools);
            if let Some(p) = list.as_array().unwrap().iter().find(|p| p["type"] == "page" && p["url"] == url) {
                break p["webSocketDebuggerUrl"].as_str().unwrap().to_string();
            }
            assert!(t.elapsed() < Duration::from_secs(60), "no page in {list}");
            std::thread::sleep(Duration::from_millis(50));
        };
        let (ws, _) = tungstenite::connect(page).unwrap();
        Self { child, ws, id: 0, dir }
    }

    /// One DevTools command: its `result`, or the error message.
    pub fn try_call(
        &mut self,
        method: &str,
        params: serde_json::Value,
    ) -> Result<serde_json::Value, serde_json::Value> {
        self.id += 1;
        let msg = serde_json::json!({"id": self.id, "method": method, "params": params});
        self.ws.send(Message::text(msg.to_string())).unwrap();
        loop {
            let Message::Text(t) = self.ws.read().unwrap() else { continue };
            let v: serde_json::Value = serde_json::from_str(&t).unwrap();
            if v["id"] == self.id {
                return if v["error"].is_null() { Ok(v["result"].clone()) } else { Err(v) };
            }
        }
    }

    /// One DevTools command that must succeed.
    pub fn call(&mut self, method: &str, params: serde_json::Value) -> serde_json::Value {
        self.try_call(method, params).unwrap_or_else(|e| panic!("{method}: {e}"))
    }

    /// Evaluates `expr` in the page (a promise is awaited) and returns its
    /// JSON value; tries again while the page is still loading (its context
    /// replaced). An exception in the script fails the test.
    pub fn eval(&mut self, expr: &str) -> serde_json::Value {
        let params = serde_json::json!({"expression": expr, "awaitPromise": true, "returnByValue": true});
        for _ in 0..100 {
            match self.try_call("Runtime.evaluate", params.clone()) {
                Ok(r) => {
                    assert!(r["exceptionDetails"].is_null(), "{expr}: {r}");
                    return r["result"]["value"].clone();
                }
                Err(e) => eprintln!("DevTools: {e}; trying again"),
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        panic!("{expr}: the page never answered");
    }

    /// A PNG of the viewport. Headless Chromium answers "Unable to capture
    /// screenshot" while a frame is not yet painted (seen in CI on a loaded
    /// 2-core machine), so that error is tried again for up to 20 s.
    pub fn screenshot(&mut self) -> Vec<u8> {
        let params = serde_json::json!({"format": "png"});
        for _ in 0..100 {
            match self.try_call("Page.captureScreenshot", params.clone()) {
                Ok(r) => return base64::decode(r["data"].as_str().unwrap()).unwrap(),
                Err(e) => eprintln!("DevTools: {e}; trying again"),
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        panic!("Page.captureScreenshot never succeeded");
    }

    /// A real mouse drag with the left button: pressed at (`x`, `y`), moved
    /// `dx` pixels in 10 px steps, released.
    pub fn drag(&mut self, x: f64, y: f64, dx: f64) {
        let mouse = |kind: &str, x: f64, buttons: u32| serde_json::json!({"type": kind, "x": x, "y": y, "button": "left", "buttons": buttons, "clickCount": 1});
        self.call("Input.dispatchMouseEvent", mouse("mouseMoved", x, 0));
        self.call("Input.dispatchMouseEvent", mouse("mousePressed", x, 1));
        let steps = (dx.abs() / 10.0).round() as i32;
        for i in 1..=steps {
            let at = x + dx * f64::from(i) / f64::from(steps);
            self.call("Input.dispatchMouseEvent", mouse("mouseMoved", at, 1));
            std::thread::sleep(Duration::from_millis(15));
        }
        self.call("Input.dispatchMouseEvent", mouse("mouseReleased", x + dx, 0));
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// `GET /json/list` of the DevTools HTTP endpoint (it keeps the connection
/// open, so the body is read by its Content-Length).
fn devtools_list(addr: SocketAddr) -> serde_json::Value {
    use std::io::{BufRead, BufReader, Read, Write};
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(s, "GET /json/list HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut r = BufReader::new(s);
    let mut len = 0;
    loop {
        let mut line = String::new();
        r.read_line(&mut line).unwrap();
        if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
            len = v.trim().parse().unwrap();
        }
        if line.trim().is_empty() {
            break;
        }
    }
    let mut body = vec![0; len];
    r.read_exact(&mut body).unwrap();
    serde_json::from_slice(&body).unwrap()
}
