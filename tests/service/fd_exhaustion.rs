//! The real binary under a small open-file limit (`ulimit -n 64`) with more client sockets
//! than it has descriptors: the accept loop backs off instead of spinning, logs the failure
//! at most once a minute instead of once per attempt, and `/healthz` answers as soon as a
//! descriptor can be had (at once when the sockets are idle: the longest-idle one is closed
//! to make room). The issue this guards against: 300 idle sockets under `ulimit -n 256` made
//! `/healthz` time out and the log repeat "accept error: Too many open files".
//!
//! Needs `sh` (for `ulimit`) and Linux's `/proc` (for the server's CPU time).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const PATIENCE: Duration = Duration::from_secs(30);
/// The server's open-file limit; about a dozen go to the process itself.
const FD_LIMIT: u32 = 64;
/// Client sockets opened against it.
const CLIENTS: usize = 100;
/// What the server logs when an accept fails.
const ACCEPT_ERROR: &str = "cannot accept connections";

struct Server {
    child: Child,
    address: String,
    log: PathBuf,
}

impl Server {
    /// `qrpose serve` under `ulimit -n FD_LIMIT`, with a connection limit above it.
    fn start(name: &str) -> Self {
        let log = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("fd-exhaustion-{name}.log"));
        let log_file = std::fs::File::create(&log).expect("a log file");
        let mut child = Command::new("sh")
            .arg("-c")
            .arg(format!("ulimit -n {FD_LIMIT} && exec \"$0\" \"$@\""))
            .arg(env!("CARGO_BIN_EXE_qrpose"))
            .args([
                "serve",
                "--addr",
                "127.0.0.1:0",
                "--max-connections",
                "1000",
                "--header-read-timeout-ms",
                "600000",
                "--idle-timeout-ms",
                "600000",
                "--request-timeout-ms",
                "600000",
            ])
            .env("RUST_LOG", "info")
            .env_remove("QRPOSE_ADDR")
            .env_remove("QRPOSE_LOG_FORMAT")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(log_file)
            .spawn()
            .expect("sh starts");
        let line = crate::support::first_stdout_line(&mut child, PATIENCE);
        let address = line
            .trim()
            .strip_prefix("listening on http://")
            .unwrap_or_else(|| panic!("no address printed: {line:?}"))
            .to_owned();
        Self {
            child,
            address,
            log,
        }
    }

    fn logs(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    fn accept_error_lines(&self) -> usize {
        self.logs()
            .lines()
            .filter(|l| l.contains(ACCEPT_ERROR) || l.contains("accept error"))
            .count()
    }

    /// The server's CPU time so far (user + system), in clock ticks.
    fn cpu_ticks(&self) -> u64 {
        let stat = std::fs::read_to_string(format!("/proc/{}/stat", self.child.id()))
            .expect("the server's /proc entry");
        // Fields after the command name (which is in parentheses): state is field 3, utime
        // field 14 and stime field 15.
        let after = &stat[stat.rfind(')').expect("a command name") + 2..];
        let fields: Vec<&str> = after.split_whitespace().collect();
        let field = |n: usize| fields[n - 3].parse::<u64>().expect("a number");
        field(14) + field(15)
    }

    fn connect(&self) -> TcpStream {
        TcpStream::connect(&self.address).expect("the kernel accepts into the backlog")
    }

    /// `GET /healthz` on a fresh connection; the status line, or why there was none.
    fn healthz(&self, within: Duration) -> Result<String, String> {
        let mut stream = self.connect();
        stream
            .set_read_timeout(Some(within))
            .map_err(|e| e.to_string())?;
        stream
            .write_all(b"GET /healthz HTTP/1.1\r\nHost: qrpose.test\r\nConnection: close\r\n\r\n")
            .map_err(|e| e.to_string())?;
        let mut answer = String::new();
        stream
            .read_to_string(&mut answer)
            .map_err(|e| format!("{e} after {answer:?}"))?;
        Ok(answer.lines().next().unwrap_or_default().to_owned())
    }

    /// Keeps asking `/healthz` until it answers 200; panics after [`PATIENCE`].
    fn healthz_eventually(&self) -> Duration {
        let started = Instant::now();
        loop {
            match self.healthz(Duration::from_secs(2)) {
                Ok(status) if status.starts_with("HTTP/1.1 200") => return started.elapsed(),
                other => assert!(
                    started.elapsed() < PATIENCE,
                    "/healthz never answered: {other:?}\n{}",
                    self.logs()
                ),
            }
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn idle_sockets_beyond_the_open_file_limit_do_not_lock_out_healthz() {
    // Arrange: more silent sockets than the server has descriptors.
    let server = Server::start("idle");
    let clients: Vec<TcpStream> = (0..CLIENTS).map(|_| server.connect()).collect();
    std::thread::sleep(Duration::from_millis(500));

    // Act
    let waited = server.healthz_eventually();

    // Assert: answered promptly; the log has one line about the failing accepts, not one
    // per attempt.
    assert!(waited < Duration::from_secs(5), "{waited:?}");
    let lines = server.accept_error_lines();
    assert!(lines <= 1, "{lines} accept error lines:\n{}", server.logs());
    drop(clients);
}

#[test]
fn busy_sockets_beyond_the_open_file_limit_neither_spin_nor_flood_the_log() {
    // Arrange: more sockets than descriptors, each with a request in progress (a body that
    // never comes, under a 10-minute request timeout), so none can be closed to make room
    // and every accept fails.
    let server = Server::start("busy");
    let head = "POST /v1/pose/corners HTTP/1.1\r\nHost: qrpose.test\r\n\
                Content-Type: application/json\r\nContent-Length: 100\r\n\r\n";
    let mut clients: Vec<TcpStream> = Vec::new();
    for _ in 0..CLIENTS {
        let mut stream = server.connect();
        stream.write_all(head.as_bytes()).expect("sent");
        clients.push(stream);
    }
    std::thread::sleep(Duration::from_secs(2));

    // Act: measure the server's CPU while it cannot accept.
    let before = server.cpu_ticks();
    std::thread::sleep(Duration::from_secs(2));
    let spent = server.cpu_ticks() - before;

    // Assert: backing off (at most a second between tries), not spinning: well under a
    // tenth of a core over 2 s (ticks are 10 ms).
    assert!(
        spent <= 20,
        "{spent} ticks of CPU in 2 s while out of descriptors"
    );
    let lines = server.accept_error_lines();
    assert_eq!(lines, 1, "one rate-limited line:\n{}", server.logs());
    assert!(
        server.logs().contains("Too many open files"),
        "{}",
        server.logs()
    );

    // Once the clients go, descriptors are free and the server serves again.
    drop(clients);
    let waited = server.healthz_eventually();
    assert!(waited < Duration::from_secs(5), "{waited:?}");
}
