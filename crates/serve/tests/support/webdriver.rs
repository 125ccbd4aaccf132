//! A small W3C WebDriver client over plain HTTP/1.1 (std only) for the browser test: sessions,
//! navigation, script execution, element clicks and keys, pointer actions, screenshots. Also
//! the HTTP client the test uses for the server's own API.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use serde_json::{json, Value};

/// One HTTP request to `127.0.0.1:port`: (status, body).
pub fn http(port: u16, method: &str, path: &str, body: Option<&Value>) -> (u16, String) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
    let payload = body.map(|b| b.to_string()).unwrap_or_default();
    let req = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{payload}",
        payload.len()
    );
    s.write_all(req.as_bytes()).expect("send");
    // Read the head, then exactly the body (a peer may keep the connection open).
    let mut raw = Vec::new();
    let mut buf = [0u8; 65536];
    let split = loop {
        if let Some(p) = raw.windows(4).position(|w| w == b"\r\n\r\n") {
            break p;
        }
        let n = s.read(&mut buf).expect("read");
        assert!(n > 0, "connection closed before the HTTP head ended");
        raw.extend_from_slice(&buf[..n]);
    };
    let head = String::from_utf8_lossy(&raw[..split]).to_string();
    let lower = head.to_ascii_lowercase();
    let length = lower
        .lines()
        .find_map(|l| l.strip_prefix("content-length:"))
        .and_then(|v| v.trim().parse::<usize>().ok());
    loop {
        let have = raw.len() - split - 4;
        let complete = match length {
            Some(len) => have >= len,
            None if lower.contains("transfer-encoding: chunked") => raw.ends_with(b"0\r\n\r\n"),
            None => false,
        };
        if complete {
            break;
        }
        let n = s.read(&mut buf).expect("read");
        if n == 0 {
            break;
        }
        raw.extend_from_slice(&buf[..n]);
    }
    let mut body = raw[split + 4..].to_vec();
    let status: u16 = head
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .expect("status");
    if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        body = dechunk(&body);
    }
    (status, String::from_utf8_lossy(&body).to_string())
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let Some(eol) = b.windows(2).position(|w| w == b"\r\n") else {
            return out;
        };
        let size =
            usize::from_str_radix(String::from_utf8_lossy(&b[..eol]).trim(), 16).unwrap_or(0);
        if size == 0 {
            return out;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + size]);
        b = &b[eol + 2 + size + 2..];
    }
}

/// A WebDriver session.
pub struct Session {
    port: u16,
    id: String,
}

impl Session {
    /// Starts headless Chromium through the chromedriver listening on `port`.
    pub fn start(port: u16, chromium: &str, profile: &std::path::Path) -> Session {
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": chromium,
                // WebGL (the solve view's three.js) on SwiftShader, the CPU renderer.
                "args": ["--headless", "--no-sandbox", "--use-angle=swiftshader",
                         "--enable-unsafe-swiftshader", "--disable-quic",
                         "--no-first-run", "--disable-background-networking",
                         "--disable-component-update", "--disable-sync",
                         "--disable-dev-shm-usage", "--window-size=1600,1100",
                         format!("--user-data-dir={}", profile.display())],
            }
        }}});
        let (st, body) = http(port, "POST", "/session", Some(&caps));
        assert_eq!(st, 200, "new session: {body}");
        let v: Value = serde_json::from_str(&body).unwrap();
        let id = v["value"]["sessionId"]
            .as_str()
            .expect("session id")
            .to_string();
        Session { port, id }
    }

    fn call(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let (st, text) = http(
            self.port,
            method,
            &format!("/session/{}{path}", self.id),
            body.as_ref(),
        );
        let v: Value = serde_json::from_str(&text).unwrap_or(Value::Null);
        assert_eq!(st, 200, "{method} {path}: {text}");
        v["value"].clone()
    }

    /// Opens `url`.
    pub fn goto(&self, url: &str) {
        self.call("POST", "/url", Some(json!({ "url": url })));
    }

    /// Runs `script` (a function body; `arguments` are `args`) and returns its value.
    pub fn js(&self, script: &str, args: Value) -> Value {
        self.call(
            "POST",
            "/execute/sync",
            Some(json!({ "script": script, "args": args })),
        )
    }

    /// Runs an async `script` (it calls `arguments[arguments.length - 1]` with its result).
    pub fn js_async(&self, script: &str, args: Value) -> Value {
        self.call(
            "POST",
            "/execute/async",
            Some(json!({ "script": script, "args": args })),
        )
    }

    /// The element of CSS `selector`.
    pub fn find(&self, selector: &str) -> String {
        let v = self.call(
            "POST",
            "/element",
            Some(json!({ "using": "css selector", "value": selector })),
        );
        v.as_object()
            .and_then(|o| o.values().next())
            .and_then(|x| x.as_str())
            .expect("element id")
            .to_string()
    }

    /// Clicks the element of `selector`.
    pub fn click(&self, selector: &str) {
        let e = self.find(selector);
        self.call("POST", &format!("/element/{e}/click"), Some(json!({})));
    }

    /// Types `text` into the element of `selector` (WebDriver key codes allowed).
    pub fn keys(&self, selector: &str, text: &str) {
        let e = self.find(selector);
        self.call(
            "POST",
            &format!("/element/{e}/value"),
            Some(json!({ "text": text })),
        );
    }

    /// Clears the input of `selector`.
    pub fn clear(&self, selector: &str) {
        let e = self.find(selector);
        self.call("POST", &format!("/element/{e}/clear"), Some(json!({})));
    }

    /// A pointer action sequence in viewport coordinates: each step is
    /// ("move", x, y), ("down", button, 0) or ("up", button, 0).
    pub fn pointer(&self, steps: &[(&str, i64, i64)]) {
        let actions: Vec<Value> = steps
            .iter()
            .map(|&(k, a, b)| match k {
                "move" => json!({"type": "pointerMove", "duration": 0, "origin": "viewport", "x": a, "y": b}),
                "down" => json!({"type": "pointerDown", "button": a}),
                "up" => json!({"type": "pointerUp", "button": a}),
                _ => panic!("unknown pointer step {k}"),
            })
            .collect();
        self.call(
            "POST",
            "/actions",
            Some(json!({"actions": [{"type": "pointer", "id": "mouse",
                "parameters": {"pointerType": "mouse"}, "actions": actions}]})),
        );
        self.call("DELETE", "/actions", None);
    }

    /// Opens a new tab (same browser, same profile) and returns its handle; the session stays
    /// on the current tab until [`Session::switch_to`].
    pub fn new_tab(&self) -> String {
        let v = self.call("POST", "/window/new", Some(json!({ "type": "tab" })));
        v["handle"].as_str().expect("window handle").to_string()
    }

    /// The handle of the current tab.
    pub fn handle(&self) -> String {
        self.call("GET", "/window", None)
            .as_str()
            .expect("window handle")
            .to_string()
    }

    /// Makes the tab of `handle` the current one.
    pub fn switch_to(&self, handle: &str) {
        self.call("POST", "/window", Some(json!({ "handle": handle })));
    }

    /// Sets the browser window's size (headless: the viewport's).
    pub fn set_window(&self, width: u32, height: u32) {
        self.call(
            "POST",
            "/window/rect",
            Some(json!({ "width": width, "height": height })),
        );
    }

    /// A PNG screenshot of the page.
    pub fn screenshot(&self) -> Vec<u8> {
        let b64 = self.call("GET", "/screenshot", None);
        base64_decode(b64.as_str().expect("screenshot"))
    }

    /// Ends the session (the browser quits).
    pub fn quit(self) {
        let _ = http(self.port, "DELETE", &format!("/session/{}", self.id), None);
    }
}

fn base64_decode(s: &str) -> Vec<u8> {
    let val = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0);
    for c in s.bytes() {
        let Some(v) = val(c) else { continue };
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    out
}
