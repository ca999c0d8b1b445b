//! The curl suite (`tests/curl/*.sh`, the README's examples) against the real binary, with
//! a photo the binary renders itself for `image.sh`, and the binary's shutdown on SIGTERM
//! and SIGINT.
//!
//! Needs `bash` and `curl` on the PATH (CI's image has both).

mod support;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// How long to wait for the server to start or stop before failing.
const PATIENCE: Duration = Duration::from_secs(30);

/// `qrpose serve` on a free port; killed when dropped, if still running.
struct Server {
    child: Child,
    base_url: String,
    log: PathBuf,
}

impl Server {
    fn start(name: &str) -> Self {
        Self::start_with(name, &[])
    }

    fn start_with(name: &str, extra_args: &[&str]) -> Self {
        let log = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("curl-suite-{name}.log"));
        let log_file = std::fs::File::create(&log).expect("a log file");
        let child = Command::new(env!("CARGO_BIN_EXE_qrpose"))
            .args([
                "serve",
                "--addr",
                "127.0.0.1:0",
                "--shutdown-grace-ms",
                "5000",
            ])
            .args(extra_args)
            .env("RUST_LOG", "info")
            .env_remove("QRPOSE_ADDR")
            .env_remove("QRPOSE_LOG_FORMAT")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(log_file)
            .spawn()
            .expect("qrpose starts");
        let mut server = Self {
            child,
            base_url: String::new(),
            log,
        };
        let line = support::first_stdout_line(&mut server.child, PATIENCE);
        match line.trim().strip_prefix("listening on ") {
            Some(url) => server.base_url = url.to_owned(),
            None => panic!("no address printed: {line:?}\n{}", server.logs()),
        }
        server
    }

    fn logs(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    fn signal(&self, signal: &str) {
        let status = Command::new("kill")
            .args([format!("-{signal}"), self.child.id().to_string()])
            .status()
            .expect("kill runs");
        assert!(status.success(), "kill -{signal} failed");
    }

    fn wait(&mut self) -> ExitStatus {
        let started = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().expect("the child's status") {
                return status;
            }
            assert!(
                started.elapsed() < PATIENCE,
                "the server did not stop\n{}",
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

fn scripts() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/curl");
    let mut scripts: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("tests/curl exists")
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "sh"))
        .collect();
    scripts.sort();
    scripts
}

/// Renders the photo that `tests/curl/image.sh` sends, with the binary's own `render`: a
/// 1280x720 JPEG of a 50 mm code 400 mm away (f = 1000 px), tilted, blurred and noisy.
fn render_photo() -> PathBuf {
    let photo = Path::new(env!("CARGO_TARGET_TMPDIR")).join("curl-suite-photo.jpg");
    let output = Command::new(env!("CARGO_BIN_EXE_qrpose"))
        .arg("render")
        .arg("--out")
        .arg(&photo)
        .args([
            "--payload",
            "SKU-1",
            "--marker-size-mm",
            "50",
            "--x-mm",
            "20",
            "--z-mm",
            "400",
            "--alpha-deg",
            "20",
            "--beta-deg",
            "-10",
            "--blur-px",
            "0.8",
            "--noise",
            "2",
            "--seed",
            "3",
        ])
        .output()
        .expect("qrpose render runs");
    assert!(output.status.success(), "qrpose render: {output:?}");
    photo
}

#[test]
fn every_curl_script_passes_against_the_real_binary() {
    let mut server = Server::start("scripts");
    let scripts = scripts();
    assert!(scripts.len() >= 4, "scripts: {scripts:?}");
    let photo = render_photo();

    for script in &scripts {
        let output = Command::new("bash")
            .arg(script)
            .env("BASE_URL", &server.base_url)
            .env("IMAGE_PATH", &photo)
            .output()
            .expect("bash runs");
        assert!(
            output.status.success(),
            "{} failed:\n{}{}\nserver log:\n{}",
            script.display(),
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr),
            server.logs()
        );
    }

    server.signal("TERM");
    let status = server.wait();
    assert_eq!(
        status.code(),
        Some(0),
        "exit after SIGTERM\n{}",
        server.logs()
    );
    let logs = server.logs();
    assert!(logs.contains("SIGTERM received"), "{logs}");
    assert!(
        logs.contains("request_id"),
        "request spans in the log: {logs}"
    );
}

#[test]
fn sigint_stops_the_server_with_exit_code_0_and_json_logs_carry_the_request_id() {
    let mut server = Server::start_with("sigint", &["--log-format", "json"]);
    let curl = Command::new("curl")
        .args([
            "-sS",
            "-o",
            "/dev/null",
            "-H",
            "x-request-id: json-log-check",
        ])
        .arg(format!("{}/healthz", server.base_url))
        .status()
        .expect("curl runs");
    assert!(curl.success());

    server.signal("INT");

    let status = server.wait();
    let logs = server.logs();
    assert_eq!(status.code(), Some(0), "exit after SIGINT\n{logs}");
    let lines: Vec<serde_json::Value> = logs
        .lines()
        .map(|line| serde_json::from_str(line).expect("every log line is JSON"))
        .collect();
    let request_lines: Vec<&serde_json::Value> = lines
        .iter()
        .filter(|l| l["span"]["request_id"] == "json-log-check")
        .collect();
    assert!(!request_lines.is_empty(), "{logs}");
    assert!(
        request_lines
            .iter()
            .any(|l| l["fields"]["status"] == 200 || l["fields"]["status"] == "200"),
        "{logs}"
    );
    assert!(
        lines
            .iter()
            .any(|l| l["fields"]["message"] == "SIGINT received"),
        "{logs}"
    );
}

#[test]
fn invalid_settings_are_refused_before_listening() {
    let output = Command::new(env!("CARGO_BIN_EXE_qrpose"))
        .args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--queue-length",
            "100000000",
        ])
        .output()
        .expect("qrpose runs");

    assert_eq!(output.status.code(), Some(2), "{output:?}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("--queue-length"), "{stderr}");
    assert!(output.stdout.is_empty(), "nothing listened");
}
