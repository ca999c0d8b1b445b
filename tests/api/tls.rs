//! TLS (docs/security.md) with certificates made here (`rcgen`): HTTPS and `wss://` answer;
//! plain HTTP to the TLS port gets `400 tls_required` and a clean close; a rotated
//! certificate is served to new connections after a reload (what SIGHUP calls) while an open
//! connection keeps working; mutual TLS refuses a client without a certificate; the
//! header-read timeout bounds the handshake.

use crate::helpers::{PHOTO_QUERY, TestApp, blank_png, spawn_app_with};
use futures_util::{SinkExt, StreamExt};
use qrpose::config::{SecuritySettings, Settings, TlsFiles};
use rcgen::{BasicConstraints, CertificateParams, CertifiedIssuer, IsCa, KeyPair};
use rustls::pki_types::{CertificateDer, PrivateKeyDer, PrivatePkcs8KeyDer, ServerName};
use rustls::{ClientConfig, RootCertStore};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_rustls::TlsConnector;
use tokio_rustls::client::TlsStream;
use tokio_tungstenite::tungstenite::Message;

/// A directory of this test binary's own for `name`'s files.
pub(crate) fn dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("qrpose-tls-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a directory");
    dir
}

/// A certificate authority, and the certificates and keys it signs.
pub(crate) struct Pki {
    ca: CertifiedIssuer<'static, KeyPair>,
}

/// A leaf certificate and its key, as DER and as PEM.
pub(crate) struct Leaf {
    pub(crate) der: CertificateDer<'static>,
    key_der: Vec<u8>,
    pub(crate) cert_pem: String,
    pub(crate) key_pem: String,
}

impl Pki {
    pub(crate) fn new(name: &str) -> Self {
        let mut params = CertificateParams::new(Vec::<String>::new()).expect("params");
        params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
        params
            .distinguished_name
            .push(rcgen::DnType::CommonName, format!("qrpose test CA {name}"));
        let key = KeyPair::generate().expect("a key");
        Self {
            ca: CertifiedIssuer::self_signed(params, key).expect("a CA"),
        }
    }

    pub(crate) fn leaf(&self, names: &[&str]) -> Leaf {
        let params =
            CertificateParams::new(names.iter().map(|n| (*n).to_owned()).collect::<Vec<_>>())
                .expect("params");
        let key = KeyPair::generate().expect("a key");
        let cert = params.signed_by(&key, &self.ca).expect("signed");
        Leaf {
            der: cert.der().clone(),
            key_der: key.serialize_der(),
            cert_pem: cert.pem(),
            key_pem: key.serialize_pem(),
        }
    }

    pub(crate) fn ca_pem(&self) -> String {
        self.ca.pem()
    }

    fn roots(&self) -> RootCertStore {
        let mut roots = RootCertStore::empty();
        roots.add(self.ca.der().clone()).expect("a root");
        roots
    }
}

/// The server's files in `dir`: its certificate and key, and optionally a client CA.
pub(crate) fn write_files(dir: &std::path::Path, leaf: &Leaf, client_ca: Option<&Pki>) -> TlsFiles {
    let write = |name: &str, text: &str| {
        let path = dir.join(name);
        let partial = path.with_extension("partial");
        std::fs::write(&partial, text).expect("written");
        std::fs::rename(&partial, &path).expect("renamed");
        path
    };
    TlsFiles {
        cert: write("cert.pem", &leaf.cert_pem),
        key: write("key.pem", &leaf.key_pem),
        client_ca: client_ca.map(|ca| write("client-ca.pem", &ca.ca_pem())),
    }
}

pub(crate) async fn tls_app(files: TlsFiles, header_read_timeout: Option<Duration>) -> TestApp {
    let defaults = Settings::default();
    spawn_app_with(Settings {
        security: SecuritySettings {
            auth_file: None,
            tls: Some(files),
        },
        header_read_timeout: header_read_timeout.unwrap_or(defaults.header_read_timeout),
        ..defaults
    })
    .await
}

pub(crate) fn authority(app: &TestApp) -> String {
    app.address.trim_start_matches("http://").to_owned()
}

fn client_config(pki: &Pki, client: Option<&Leaf>) -> Arc<ClientConfig> {
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let builder = ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .expect("versions")
        .with_root_certificates(pki.roots());
    let config = match client {
        None => builder.with_no_client_auth(),
        Some(leaf) => builder
            .with_client_auth_cert(
                vec![leaf.der.clone()],
                PrivateKeyDer::Pkcs8(PrivatePkcs8KeyDer::from(leaf.key_der.clone())),
            )
            .expect("a client certificate"),
    };
    Arc::new(config)
}

async fn connect(
    app: &TestApp,
    config: Arc<ClientConfig>,
) -> std::io::Result<TlsStream<TcpStream>> {
    let tcp = TcpStream::connect(authority(app)).await?;
    let name = ServerName::try_from("localhost").expect("a name");
    TlsConnector::from(config).connect(name, tcp).await
}

/// `GET path` on a kept-alive connection: the status and the body.
async fn get<S: AsyncRead + AsyncWrite + Unpin>(stream: &mut S, path: &str) -> (u16, String) {
    let request = format!("GET {path} HTTP/1.1\r\nHost: localhost\r\n\r\n");
    stream.write_all(request.as_bytes()).await.expect("sent");
    let mut received = Vec::new();
    let mut chunk = [0u8; 4096];
    let head_end = loop {
        if let Some(i) = received.windows(4).position(|w| w == b"\r\n\r\n") {
            break i + 4;
        }
        let n = stream.read(&mut chunk).await.expect("an answer");
        assert!(n > 0, "closed before an answer: {received:?}");
        received.extend_from_slice(&chunk[..n]);
    };
    let head = String::from_utf8_lossy(&received[..head_end]).to_lowercase();
    let status = head[9..12].parse().expect("a status");
    let length: usize = head
        .lines()
        .find_map(|l| l.strip_prefix("content-length:"))
        .map_or(0, |v| v.trim().parse().expect("a length"));
    while received.len() < head_end + length {
        let n = stream.read(&mut chunk).await.expect("the body");
        assert!(n > 0, "closed inside the body");
        received.extend_from_slice(&chunk[..n]);
    }
    let body = String::from_utf8_lossy(&received[head_end..head_end + length]).into_owned();
    (status, body)
}

fn peer_certificate(stream: &TlsStream<TcpStream>) -> CertificateDer<'static> {
    stream
        .get_ref()
        .1
        .peer_certificates()
        .expect("certificates")[0]
        .clone()
}

#[tokio::test]
async fn https_and_wss_answer_with_the_configured_certificate() {
    let pki = Pki::new("https");
    let leaf = pki.leaf(&["localhost", "127.0.0.1"]);
    let app = tls_app(write_files(&dir("https"), &leaf, None), None).await;

    let mut stream = connect(&app, client_config(&pki, None))
        .await
        .expect("a handshake");
    assert_eq!(peer_certificate(&stream), leaf.der);
    let connection = stream.get_ref().1;
    assert!(
        matches!(
            connection.protocol_version(),
            Some(rustls::ProtocolVersion::TLSv1_3 | rustls::ProtocolVersion::TLSv1_2)
        ),
        "{:?}",
        connection.protocol_version()
    );
    assert_eq!(
        connection.alpn_protocol(),
        None,
        "no ALPN asked, none chosen"
    );
    let (status, body) = get(&mut stream, "/healthz").await;
    assert_eq!((status, body.contains("\"ok\"")), (200, true), "{body}");

    // TLS 1.2 alone is served too.
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let tls12 = ClientConfig::builder_with_provider(provider)
        .with_protocol_versions(&[&rustls::version::TLS12])
        .expect("TLS 1.2")
        .with_root_certificates(pki.roots())
        .with_no_client_auth();
    let mut old = connect(&app, Arc::new(tls12))
        .await
        .expect("a TLS 1.2 handshake");
    assert_eq!(
        old.get_ref().1.protocol_version(),
        Some(rustls::ProtocolVersion::TLSv1_2)
    );
    assert_eq!(get(&mut old, "/readyz").await.0, 200);

    // wss:// for the stream: one frame in, its answer out.
    let tls = connect(&app, client_config(&pki, None))
        .await
        .expect("a handshake");
    let url = format!("wss://localhost/v1/stream?{PHOTO_QUERY}");
    let (mut socket, response) = tokio_tungstenite::client_async(url, tls)
        .await
        .expect("the upgrade over TLS");
    assert_eq!(response.status().as_u16(), 101);
    socket
        .send(Message::Binary(blank_png().into()))
        .await
        .expect("a frame sent");
    let answer = loop {
        match socket.next().await.expect("a message").expect("no error") {
            Message::Text(text) => break text.to_string(),
            Message::Ping(_) | Message::Pong(_) => {}
            other => panic!("unexpected {other:?}"),
        }
    };
    let answer: serde_json::Value = serde_json::from_str(&answer).expect("JSON");
    assert!(answer["frame"].is_object(), "{answer}");
}

#[tokio::test]
async fn plain_http_to_the_tls_port_gets_400_tls_required_and_a_clean_close() {
    let pki = Pki::new("plain");
    let app = tls_app(
        write_files(&dir("plain"), &pki.leaf(&["localhost"]), None),
        None,
    )
    .await;
    let mut tcp = TcpStream::connect(authority(&app)).await.expect("connects");
    tcp.write_all(b"GET /healthz HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .await
        .expect("sent");
    let mut answer = Vec::new();
    tokio::time::timeout(Duration::from_secs(5), tcp.read_to_end(&mut answer))
        .await
        .expect("closed in time")
        .expect("a clean close, no reset");
    let answer = String::from_utf8_lossy(&answer);
    assert!(
        answer.starts_with("HTTP/1.1 400 Bad Request\r\n"),
        "{answer}"
    );
    assert!(answer.contains("application/problem+json"), "{answer}");
    assert!(answer.contains("\"code\":\"tls_required\""), "{answer}");
    assert!(answer.contains("https://"), "{answer}");
    let metrics = app.state.metrics.encode().expect("metrics");
    assert!(
        metrics.contains("qrpose_tls_connections_refused_total{reason=\"plain_http\"} 1"),
        "{metrics}"
    );
}

#[tokio::test]
async fn a_rotated_certificate_is_served_to_new_connections_while_an_open_one_keeps_working() {
    let pki = Pki::new("rotate");
    let first = pki.leaf(&["localhost"]);
    let dir = dir("rotate");
    let app = tls_app(write_files(&dir, &first, None), None).await;
    let config = client_config(&pki, None);

    let mut open = connect(&app, Arc::clone(&config))
        .await
        .expect("a handshake");
    assert_eq!(get(&mut open, "/healthz").await.0, 200);
    assert_eq!(peer_certificate(&open), first.der);

    let second = pki.leaf(&["localhost"]);
    write_files(&dir, &second, None);
    let tls = app.state.tls.as_ref().expect("TLS is on");
    tls.reload().expect("the rotated files load");

    assert_eq!(
        get(&mut open, "/healthz").await.0,
        200,
        "the open connection goes on"
    );
    assert_eq!(get(&mut open, "/readyz").await.0, 200);
    let fresh = connect(&app, Arc::clone(&config))
        .await
        .expect("a handshake");
    assert_eq!(peer_certificate(&fresh), second.der, "the new certificate");

    // A key that does not fit is refused; the rotated certificate stays in use.
    let third = pki.leaf(&["localhost"]);
    std::fs::write(dir.join("key.pem"), &third.key_pem).expect("written");
    let refused = tls.reload().expect_err("a key of another certificate");
    assert!(refused.to_string().contains("key.pem"), "{refused}");
    let after = connect(&app, config).await.expect("a handshake");
    assert_eq!(peer_certificate(&after), second.der);
    let metrics = app.state.metrics.encode().expect("metrics");
    for line in [
        "qrpose_tls_reloads_total{outcome=\"ok\"} 1",
        "qrpose_tls_reloads_total{outcome=\"failed\"} 1",
    ] {
        assert!(metrics.contains(line), "{line} in\n{metrics}");
    }
}

/// Whether a request over `stream` gets an answer (a client whose certificate the server
/// refused learns it at the handshake or, in TLS 1.3, at its first read).
async fn answers(stream: std::io::Result<TlsStream<TcpStream>>) -> bool {
    let Ok(mut stream) = stream else {
        return false;
    };
    if stream
        .write_all(b"GET /healthz HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .await
        .is_err()
    {
        return false;
    }
    let mut buffer = [0u8; 64];
    matches!(
        tokio::time::timeout(Duration::from_secs(5), stream.read(&mut buffer)).await,
        Ok(Ok(n)) if n > 0 && buffer.starts_with(b"HTTP/1.1 200")
    )
}

#[tokio::test]
async fn mutual_tls_refuses_a_client_without_a_certificate_of_the_client_ca() {
    let server_pki = Pki::new("mtls-server");
    let client_pki = Pki::new("mtls-clients");
    let stranger_pki = Pki::new("mtls-stranger");
    let files = write_files(
        &dir("mtls"),
        &server_pki.leaf(&["localhost"]),
        Some(&client_pki),
    );
    let app = tls_app(files, None).await;

    let robot = client_pki.leaf(&["robot-7"]);
    let with_cert = connect(&app, client_config(&server_pki, Some(&robot))).await;
    assert!(answers(with_cert).await, "a client of the CA is served");

    let without = connect(&app, client_config(&server_pki, None)).await;
    assert!(!answers(without).await, "no certificate: refused");

    let stranger = stranger_pki.leaf(&["intruder"]);
    let foreign = connect(&app, client_config(&server_pki, Some(&stranger))).await;
    assert!(!answers(foreign).await, "another CA's certificate: refused");

    let metrics = app.state.metrics.encode().expect("metrics");
    assert!(
        metrics.contains("qrpose_tls_connections_refused_total{reason=\"handshake\"} 2"),
        "{metrics}"
    );
}

#[tokio::test]
async fn the_header_read_timeout_bounds_the_handshake() {
    let pki = Pki::new("slow");
    let files = write_files(&dir("slow"), &pki.leaf(&["localhost"]), None);
    let app = tls_app(files, Some(Duration::from_millis(300))).await;
    // The first byte of a handshake, then nothing.
    let mut tcp = TcpStream::connect(authority(&app)).await.expect("connects");
    tcp.write_all(&[0x16]).await.expect("sent");
    let mut rest = Vec::new();
    let closed = tokio::time::timeout(Duration::from_secs(5), tcp.read_to_end(&mut rest)).await;
    assert!(closed.is_ok(), "closed by the header-read timeout");
    let metrics = app.state.metrics.encode().expect("metrics");
    assert!(
        metrics.contains("qrpose_tls_connections_refused_total{reason=\"timeout\"} 1"),
        "{metrics}"
    );
}
