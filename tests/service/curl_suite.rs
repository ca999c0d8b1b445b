//! The curl suite (`tests/curl/*.sh`, the README's examples) against the real binary, with
//! a photo the binary renders itself for `image.sh`, and the binary's shutdown on SIGTERM
//! and SIGINT. The suite runs twice: plain, and with auth and TLS on (a token made by
//! `qrpose auth add`, a certificate made here with `rcgen`), where the certificate is then
//! rotated by SIGHUP under an open connection.
//!
//! Needs `bash` and `curl` on the PATH (CI's image has both).

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
        let line = crate::support::first_stdout_line(&mut server.child, PATIENCE);
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

/// Renders the photo that `tests/curl/image.sh` sends, with `qrpose-sim render`: a
/// 1280x720 JPEG of a 50 mm code 400 mm away (f = 1000 px), tilted, blurred and noisy.
fn render_photo(name: &str) -> PathBuf {
    let photo = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("curl-suite-{name}.jpg"));
    let flags = [
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
    ];
    let mut args = vec!["--out".as_ref(), photo.as_os_str()];
    args.extend(flags.iter().map(std::ffi::OsStr::new));
    crate::support::render(&args);
    photo
}

/// Runs every script against `server` with `env` added; fails on the first that fails.
fn run_scripts(server: &Server, photo: &Path, env: &[(&str, &str)]) {
    let scripts = scripts();
    assert!(scripts.len() >= 4, "scripts: {scripts:?}");
    for script in &scripts {
        let output = Command::new("bash")
            .arg(script)
            .env("BASE_URL", &server.base_url)
            .env("IMAGE_PATH", photo)
            .env_remove("TOKEN")
            .env_remove("CACERT")
            .envs(env.iter().copied())
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
}

#[test]
fn every_curl_script_passes_against_the_real_binary() {
    let mut server = Server::start("scripts");
    let photo = render_photo("photo");
    run_scripts(&server, &photo, &[]);

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

/// A CA and a server certificate for `localhost` and `127.0.0.1` it signs, written in `dir`
/// as `ca.pem`, `cert.pem` and `key.pem`; the certificate's DER.
fn issue_certificate(dir: &Path, ca: &rcgen::CertifiedIssuer<'static, rcgen::KeyPair>) -> Vec<u8> {
    let params =
        rcgen::CertificateParams::new(vec!["localhost".to_owned(), "127.0.0.1".to_owned()])
            .expect("params");
    let key = rcgen::KeyPair::generate().expect("a key");
    let cert = params.signed_by(&key, ca).expect("signed");
    for (name, text) in [
        ("cert.pem", cert.pem()),
        ("key.pem", key.serialize_pem()),
        ("ca.pem", ca.pem()),
    ] {
        // Written beside and renamed over, as a rotation should be.
        let partial = dir.join(format!("{name}.partial"));
        std::fs::write(&partial, text).expect("written");
        std::fs::rename(&partial, dir.join(name)).expect("renamed");
    }
    cert.der().to_vec()
}

/// A kept-alive HTTPS connection to `authority` trusting `ca_pem`.
fn open_tls(
    authority: &str,
    ca_pem: &Path,
) -> rustls::StreamOwned<rustls::ClientConnection, std::net::TcpStream> {
    use rustls::pki_types::{CertificateDer, pem::PemObject};
    let mut roots = rustls::RootCertStore::empty();
    for ca in CertificateDer::pem_file_iter(ca_pem).expect("a CA file") {
        roots.add(ca.expect("a CA")).expect("a root");
    }
    let config = rustls::ClientConfig::builder_with_provider(std::sync::Arc::new(
        rustls::crypto::ring::default_provider(),
    ))
    .with_safe_default_protocol_versions()
    .expect("versions")
    .with_root_certificates(roots)
    .with_no_client_auth();
    let name = rustls::pki_types::ServerName::try_from("localhost").expect("a name");
    let connection =
        rustls::ClientConnection::new(std::sync::Arc::new(config), name).expect("a client");
    let tcp = std::net::TcpStream::connect(authority).expect("connects");
    tcp.set_read_timeout(Some(PATIENCE)).expect("a timeout");
    rustls::StreamOwned::new(connection, tcp)
}

/// `GET /healthz` on `stream`, kept alive: the status line.
fn get_healthz<S: std::io::Read + std::io::Write>(stream: &mut S) -> String {
    stream
        .write_all(b"GET /healthz HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .expect("sent");
    let mut received = Vec::new();
    let mut chunk = [0u8; 1024];
    // /healthz's body is small JSON: the answer is whole once its closing brace is in.
    while !received.ends_with(b"}") {
        let n = stream.read(&mut chunk).expect("an answer");
        assert!(n > 0, "closed: {}", String::from_utf8_lossy(&received));
        received.extend_from_slice(&chunk[..n]);
    }
    let text = String::from_utf8_lossy(&received);
    text.lines().next().unwrap_or_default().to_owned()
}

/// `qrpose healthcheck` pinned to the certificate file `cert`: whether the service presents
/// exactly it.
fn serves_certificate(authority: &str, cert: &Path) -> bool {
    Command::new(env!("CARGO_BIN_EXE_qrpose"))
        .args(["healthcheck", "--addr", authority, "--tls-cert"])
        .arg(cert)
        .env_remove("QRPOSE_HEALTHCHECK_URL")
        .env_remove("QRPOSE_HEALTHCHECK_CA_FILE")
        .output()
        .expect("qrpose healthcheck runs")
        .status
        .success()
}

#[test]
fn the_curl_suite_passes_with_auth_and_tls_on_and_sighup_rotates_the_certificate() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("curl-suite-secure");
    std::fs::create_dir_all(&dir).expect("a directory");
    let auth_file = dir.join("auth.yaml");
    let _ = std::fs::remove_file(&auth_file);
    let added = Command::new(env!("CARGO_BIN_EXE_qrpose"))
        .args([
            "auth",
            "add",
            "curl-suite",
            "--scopes",
            "pose,site,admin,metrics",
            "--file",
        ])
        .arg(&auth_file)
        .output()
        .expect("qrpose auth add runs");
    assert!(added.status.success(), "{added:?}");
    let token = String::from_utf8(added.stdout)
        .expect("UTF-8")
        .trim()
        .to_owned();
    let mut ca_params = rcgen::CertificateParams::new(Vec::<String>::new()).expect("params");
    ca_params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    // A subject of its own: OpenSSL (curl) takes a leaf named like its issuer for self-signed.
    ca_params
        .distinguished_name
        .push(rcgen::DnType::CommonName, "qrpose curl suite CA");
    let ca =
        rcgen::CertifiedIssuer::self_signed(ca_params, rcgen::KeyPair::generate().expect("a key"))
            .expect("a CA");
    issue_certificate(&dir, &ca);
    let (cert, key, ca_file) = (
        dir.join("cert.pem"),
        dir.join("key.pem"),
        dir.join("ca.pem"),
    );

    let mut server = Server::start_with(
        "secure",
        &[
            "--auth-file",
            auth_file.to_str().expect("UTF-8"),
            "--tls-cert",
            cert.to_str().expect("UTF-8"),
            "--tls-key",
            key.to_str().expect("UTF-8"),
        ],
    );
    assert!(
        server.base_url.starts_with("https://"),
        "{}",
        server.base_url
    );
    let authority = server.base_url.trim_start_matches("https://").to_owned();
    let photo = render_photo("photo-secure");
    run_scripts(
        &server,
        &photo,
        &[
            ("TOKEN", token.as_str()),
            ("CACERT", ca_file.to_str().expect("UTF-8")),
        ],
    );

    // Without the token: 401; plain HTTP to the port: 400 tls_required.
    let status = |args: &[&str]| {
        let output = Command::new("curl")
            .args(["-sS", "-o", "/dev/null", "-w", "%{http_code}"])
            .args(args)
            .output()
            .expect("curl runs");
        String::from_utf8_lossy(&output.stdout).into_owned()
    };
    let site = format!("{}/v1/site", server.base_url);
    assert_eq!(
        status(&["--cacert", ca_file.to_str().expect("UTF-8"), &site]),
        "401"
    );
    assert_eq!(status(&[&format!("http://{authority}/healthz")]), "400");

    // Rotation: new files, then SIGHUP; an open connection goes on meanwhile.
    let mut open = open_tls(&authority, &ca_file);
    assert!(get_healthz(&mut open).starts_with("HTTP/1.1 200"));
    assert!(
        serves_certificate(&authority, &cert),
        "the first certificate"
    );
    issue_certificate(&dir, &ca);
    assert!(
        !serves_certificate(&authority, &cert),
        "not reloaded before SIGHUP"
    );
    server.signal("HUP");
    let started = Instant::now();
    while !serves_certificate(&authority, &cert) {
        assert!(
            started.elapsed() < PATIENCE,
            "not reloaded\n{}",
            server.logs()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        get_healthz(&mut open).starts_with("HTTP/1.1 200"),
        "the connection opened before the rotation still answers"
    );
    run_scripts(
        &server,
        &photo,
        &[
            ("TOKEN", token.as_str()),
            ("CACERT", ca_file.to_str().expect("UTF-8")),
        ],
    );

    server.signal("TERM");
    assert_eq!(server.wait().code(), Some(0), "{}", server.logs());
    let logs = server.logs();
    assert!(logs.contains("TLS certificate reloaded"), "{logs}");
    assert!(!logs.contains(&token), "the token is never logged");
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
