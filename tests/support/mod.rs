//! Shared by the test binaries (`service`, `browser`, and `api` for its TLS provider):
//! `qrpose serve` on a free port, its first stdout line, photos made by `qrpose-sim render`
//! (in this process) with their ground truth, and reqwest clients.

#![allow(dead_code)]

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

/// How long the server gets to start.
const START_PATIENCE: Duration = Duration::from_secs(30);

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_qrpose");

/// `qrpose serve` on 127.0.0.1 and a free port; killed when dropped.
pub struct Server {
    child: Child,
    /// `http://127.0.0.1:PORT`.
    pub base_url: String,
}

impl Server {
    /// Starts the server and waits for its `listening on` line.
    pub fn start() -> Self {
        Self::start_with(&[])
    }

    /// As [`Self::start`], with more `serve` flags.
    pub fn start_with(flags: &[&str]) -> Self {
        let mut child = Command::new(BIN)
            .args(["serve", "--addr", "127.0.0.1:0"])
            .args(flags)
            .env("RUST_LOG", "warn")
            .env_remove("QRPOSE_ADDR")
            .env_remove("QRPOSE_SITE")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("qrpose serve starts");
        let line = first_stdout_line(&mut child, START_PATIENCE);
        let base_url = line
            .trim()
            .strip_prefix("listening on ")
            .unwrap_or_else(|| panic!("qrpose serve printed no address: {line:?}"))
            .to_owned();
        Self { child, base_url }
    }

    /// The server's process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// `base_url` + `path`.
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base_url)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The first line `child` writes to its piped stdout (`qrpose serve` prints `listening on
/// http://…` there), or an empty string when none comes within `patience`.
pub fn first_stdout_line(child: &mut Child, patience: Duration) -> String {
    let Some(stdout) = child.stdout.take() else {
        return String::new();
    };
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut first = String::new();
        let _ = BufReader::new(stdout).read_line(&mut first);
        let _ = tx.send(first);
    });
    rx.recv_timeout(patience).unwrap_or_default()
}

/// A directory of this test binary's own under Cargo's test scratch space.
pub fn scratch_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}

/// The camera and marker of every rendered photo as query parameters (`qrpose render`'s
/// defaults: 1280 × 720, f = 1000 px, principal point at the centre; a 50 mm code).
pub const PHOTO_QUERY: &str = "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50";
/// The marker side of every rendered photo, mm.
pub const MARKER_SIZE_MM: f64 = 50.0;
/// The payload of every rendered photo.
pub const PAYLOAD: &str = "SKU-1";

/// `qrpose-sim render` with `args`, in this process: the ground truth it prints.
pub fn render(args: &[&std::ffi::OsStr]) -> Value {
    qrpose_sim::cli::render(args).unwrap_or_else(|e| panic!("qrpose-sim render {args:?}: {e}"))
}

/// Renders `out` (under `dir`) with `qrpose-sim render` and these pose flags; returns its
/// path and the ground truth it printed.
pub fn render_photo(dir: &Path, out: &str, pose_args: &[&str]) -> (PathBuf, Value) {
    let path = dir.join(out);
    let mut args = vec!["--out".as_ref(), path.as_os_str()];
    let fixed = [
        "--payload",
        PAYLOAD,
        "--marker-size-mm",
        "50",
        "--blur-px",
        "0.6",
    ];
    let effects = ["--noise", "1.5", "--seed", "5"];
    args.extend(
        fixed
            .iter()
            .chain(&effects)
            .chain(pose_args)
            .map(std::ffi::OsStr::new),
    );
    let truth = render(&args);
    (path, truth)
}

/// Installs the service's TLS provider, ring, for reqwest's clients: the package builds
/// reqwest with TLS for `qrpose healthcheck` but without a provider of its own.
pub fn tls_provider() {
    let _ = rustls::crypto::ring::default_provider().install_default();
}

/// A blocking client that never uses a proxy.
pub fn client() -> reqwest::blocking::Client {
    tls_provider();
    reqwest::blocking::Client::builder()
        .no_proxy()
        .timeout(Duration::from_secs(60))
        .build()
        .expect("a client")
}
