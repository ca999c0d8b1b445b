//! A small W3C WebDriver client over blocking HTTP, for Debian's headless Chromium through
//! `chromedriver`: the handful of commands the page tests need, plus two that only
//! chromedriver has (the browser log, and DevTools commands for the viewport). A client
//! crate would bring an async stack and still not reach those two.

use base64::Engine;
use serde_json::{Value, json};
use std::net::TcpListener;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Debian's Chromium.
pub const CHROMIUM: &str = "/usr/bin/chromium";
/// Debian's chromedriver (package `chromium-driver`).
pub const CHROMEDRIVER: &str = "/usr/bin/chromedriver";
/// The W3C key for an element reference.
const ELEMENT_KEY: &str = "element-6066-11e4-a52e-4f735466cecf";
/// How long a condition may take to come true.
pub const PATIENCE: Duration = Duration::from_secs(30);

/// WebDriver's code for the Tab key.
pub const TAB: &str = "\u{E004}";
/// WebDriver's code for the Enter key.
pub const ENTER: &str = "\u{E007}";
/// The space bar.
pub const SPACE: &str = " ";

/// A chromedriver process and one headless Chromium session; both end when dropped.
pub struct Browser {
    driver: Child,
    base: String,
    client: reqwest::blocking::Client,
}

/// An element reference.
#[derive(Debug, Clone)]
pub struct Element(String);

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// Whether both programs are there.
fn browser_installed() -> bool {
    [CHROMIUM, CHROMEDRIVER]
        .iter()
        .all(|p| Path::new(p).exists())
}

/// Installs Debian's `chromium` and `chromium-driver` when they are missing and `apt-get`
/// can (root, Debian), once per test run, so that `cargo test` on a fresh machine with only
/// the Rust toolchain runs the browser tests too (as `.ci/run` does before it). Where it
/// cannot, [`Browser::start`] fails with the command to run.
fn install_browser_once() {
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    INSTALLED.call_once(|| {
        if browser_installed() || !Path::new("/usr/bin/apt-get").exists() {
            return;
        }
        eprintln!("browser tests: installing Debian's chromium and chromium-driver (apt-get)");
        for args in [
            &["update", "-qq"][..],
            &["install", "-y", "-qq", "chromium", "chromium-driver"][..],
        ] {
            let _ = Command::new("apt-get")
                .args(args)
                .env("DEBIAN_FRONTEND", "noninteractive")
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .status();
        }
    });
}

impl Browser {
    /// Starts chromedriver and a headless Chromium with a `width` × `height` viewport,
    /// installing them first when they are missing and can be ([`install_browser_once`]).
    ///
    /// # Panics
    /// When Chromium or chromedriver is not installed: the test must fail, not pass.
    pub fn start(width: u32, height: u32) -> Self {
        Self::start_with(width, height, &[])
    }

    /// As [`Self::start`], with more Chromium switches (`--use-fake-device-for-media-stream`
    /// and the like).
    ///
    /// # Panics
    /// As [`Self::start`].
    pub fn start_with(width: u32, height: u32, switches: &[String]) -> Self {
        install_browser_once();
        for program in [CHROMIUM, CHROMEDRIVER] {
            assert!(
                Path::new(program).exists(),
                "{program} is missing: the browser tests need Debian's chromium and \
                 chromium-driver (`apt-get install -y chromium chromium-driver`; .ci/run \
                 installs them)"
            );
        }
        let port = free_port();
        let driver = Command::new(CHROMEDRIVER)
            .arg(format!("--port={port}"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts");
        super::support::tls_provider();
        let client = reqwest::blocking::Client::builder()
            .no_proxy()
            .timeout(Duration::from_secs(60))
            .build()
            .expect("a client");
        let driver_url = format!("http://127.0.0.1:{port}");
        let started = Instant::now();
        while client.get(format!("{driver_url}/status")).send().is_err() {
            assert!(started.elapsed() < PATIENCE, "chromedriver did not start");
            std::thread::sleep(Duration::from_millis(50));
        }
        let profile = super::support::scratch_dir(&format!("chromium-profile-{port}"));
        let mut args: Vec<String> = [
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--no-proxy-server",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-default-apps",
            "--disable-sync",
            "--no-first-run",
            "--disable-extensions",
            "--hide-scrollbars",
        ]
        .map(str::to_owned)
        .to_vec();
        args.push(format!("--window-size={width},{height}"));
        args.push(format!("--user-data-dir={}", profile.display()));
        args.extend_from_slice(switches);
        let capabilities = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:loggingPrefs": {"browser": "ALL"},
            "goog:chromeOptions": {"binary": CHROMIUM, "args": args},
        }}});
        let mut browser = Self {
            driver,
            base: driver_url,
            client,
        };
        let session = browser.call("POST", "/session", &capabilities);
        let id = session["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no session: {session}"))
            .to_owned();
        browser.base = format!("{}/session/{id}", browser.base);
        // The window's size includes what headless Chromium keeps for its toolbars.
        browser.set_viewport(width, height, false);
        browser
    }

    /// One WebDriver command; its `value`. Panics on a WebDriver error.
    fn call(&self, method: &str, path: &str, body: &Value) -> Value {
        let url = format!("{}{path}", self.base);
        let request = match method {
            "GET" => self.client.get(&url),
            "DELETE" => self.client.delete(&url),
            _ => self.client.post(&url).json(body),
        };
        let response: Value = request
            .send()
            .unwrap_or_else(|e| panic!("{method} {path}: {e}"))
            .json()
            .unwrap_or_else(|e| panic!("{method} {path}: {e}"));
        let value = response["value"].clone();
        if let Some(error) = value.get("error") {
            panic!("{method} {path}: {error}: {}", value["message"]);
        }
        value
    }

    /// Navigates to `url` and waits for the load event.
    pub fn goto(&self, url: &str) {
        self.call("POST", "/url", &json!({ "url": url }));
    }

    /// Runs `script` (a function body; `arguments` holds `args`) and returns its value.
    pub fn run(&self, script: &str, args: &[Value]) -> Value {
        self.call(
            "POST",
            "/execute/sync",
            &json!({"script": script, "args": args}),
        )
    }

    /// Polls `condition` (a script returning a truthy value when done) until it holds.
    pub fn wait_for(&self, what: &str, condition: &str) -> Value {
        let started = Instant::now();
        loop {
            let value = self.run(condition, &[]);
            if !(value.is_null() || value == json!(false)) {
                return value;
            }
            assert!(started.elapsed() < PATIENCE, "never came true: {what}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The element `css` selects.
    pub fn find(&self, css: &str) -> Element {
        let value = self.call(
            "POST",
            "/element",
            &json!({"using": "css selector", "value": css}),
        );
        Element(
            value[ELEMENT_KEY]
                .as_str()
                .unwrap_or_else(|| panic!("no element {css}: {value}"))
                .to_owned(),
        )
    }

    /// Clicks `element`.
    pub fn click(&self, element: &Element) {
        self.call("POST", &format!("/element/{}/click", element.0), &json!({}));
    }

    /// Types `text` into `element`; for a file input, `text` is the path of the file to
    /// choose (WebDriver's way: the operating system's file dialog is out of its reach).
    pub fn type_into(&self, element: &Element, text: &str) {
        self.call(
            "POST",
            &format!("/element/{}/value", element.0),
            &json!({ "text": text }),
        );
    }

    /// Presses and releases `key` on the keyboard, wherever the focus is.
    pub fn press(&self, key: &str) {
        let actions = json!({"actions": [{"type": "key", "id": "keyboard", "actions": [
            {"type": "keyDown", "value": key}, {"type": "keyUp", "value": key}]}]});
        self.call("POST", "/actions", &actions);
        self.call("DELETE", "/actions", &json!({}));
    }

    /// The id of the focused element ("" when none has one).
    pub fn focused_id(&self) -> String {
        self.run(
            "return document.activeElement ? document.activeElement.id : '';",
            &[],
        )
        .as_str()
        .unwrap_or_default()
        .to_owned()
    }

    /// Presses Tab until the element with `id` has the focus; how many presses it took.
    pub fn tab_to(&self, id: &str, at_most: usize) -> usize {
        for presses in 1..=at_most {
            self.press(TAB);
            if self.focused_id() == id {
                return presses;
            }
        }
        panic!("#{id} never got the focus in {at_most} presses of Tab")
    }

    /// Sets the viewport to `width` × `height` CSS px (phone widths below Chromium's
    /// smallest window), through the DevTools protocol.
    pub fn set_viewport(&self, width: u32, height: u32, mobile: bool) {
        let params =
            json!({"width": width, "height": height, "deviceScaleFactor": 1, "mobile": mobile});
        self.call(
            "POST",
            "/goog/cdp/execute",
            &json!({"cmd": "Emulation.setDeviceMetricsOverride", "params": params}),
        );
    }

    /// Scrolls the element `css` selects to the top of the viewport.
    pub fn scroll_to(&self, css: &str) {
        self.run(
            "document.querySelector(arguments[0]).scrollIntoView({block: 'start'});",
            &[json!(css)],
        );
    }

    /// A PNG of the viewport.
    pub fn screenshot(&self) -> Vec<u8> {
        let value = self.call("GET", "/screenshot", &Value::Null);
        base64::engine::general_purpose::STANDARD
            .decode(value.as_str().expect("base64"))
            .expect("a PNG")
    }

    /// The browser's log entries since the last call: `(level, message)`.
    pub fn log(&self) -> Vec<(String, String)> {
        let value = self.call("POST", "/se/log", &json!({"type": "browser"}));
        value
            .as_array()
            .map(|entries| {
                entries
                    .iter()
                    .map(|e| {
                        (
                            e["level"].as_str().unwrap_or_default().to_owned(),
                            e["message"].as_str().unwrap_or_default().to_owned(),
                        )
                    })
                    .collect()
            })
            .unwrap_or_default()
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.client.delete(&self.base).send();
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}
