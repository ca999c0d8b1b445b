//! `qrpose healthcheck`: exits 0 when the service's `/healthz` answers 200, 1 otherwise.
//!
//! For a container `HEALTHCHECK` without curl: one `GET` by reqwest, to `--url` or to
//! `http(s)://127.0.0.1:PORT/healthz` with the port of `QRPOSE_ADDR`, as `serve` reads it.
//! Over TLS the service must show exactly the leaf of `QRPOSE_TLS_CERT` (a loopback dial needs
//! no name in it) or a chain to `--ca-file`. Tokens: `QRPOSE_HEALTHCHECK_TOKEN`, `--token-file`.

use qrpose::http::tls::certificates;
use reqwest::blocking::Client;
use reqwest::tls::{Certificate, Identity, TlsInfo};
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr};
use std::{path::Path, path::PathBuf, process::ExitCode, time::Duration};

/// Arguments of `healthcheck`.
#[derive(Debug, clap::Args)]
pub struct HealthcheckArgs {
    /// The URL to check [default: http(s)://127.0.0.1:PORT/healthz, PORT from --addr].
    #[arg(long, env = "QRPOSE_HEALTHCHECK_URL")]
    pub url: Option<String>,
    /// The service's listen address, used when --url is not given.
    #[arg(long, env = "QRPOSE_ADDR", default_value = qrpose::config::DEFAULT_ADDR)]
    pub addr: SocketAddr,
    /// Give up after this long, ms.
    #[arg(long, default_value_t = 2000)]
    pub timeout_ms: u64,
    /// The service's own certificate (PEM): without --ca-file it must present exactly it.
    #[arg(long, env = "QRPOSE_TLS_CERT")]
    pub tls_cert: Option<PathBuf>,
    /// CAs (PEM) to check the service's chain against, with the URL's host as the name.
    #[arg(long, env = "QRPOSE_HEALTHCHECK_CA_FILE")]
    pub ca_file: Option<PathBuf>,
    /// The name the certificate must carry with --ca-file [default: the URL's host].
    #[arg(long)]
    pub server_name: Option<String>,
    /// A client certificate chain (PEM), for a service started with --tls-client-ca.
    #[arg(long, env = "QRPOSE_HEALTHCHECK_CLIENT_CERT", requires = "client_key")]
    pub client_cert: Option<PathBuf>,
    /// The private key of --client-cert (PEM).
    #[arg(long, env = "QRPOSE_HEALTHCHECK_CLIENT_KEY", requires = "client_cert")]
    pub client_key: Option<PathBuf>,
    /// A file holding a bearer token (or QRPOSE_HEALTHCHECK_TOKEN the token itself).
    #[arg(long, env = "QRPOSE_HEALTHCHECK_TOKEN_FILE")]
    pub token_file: Option<PathBuf>,
}

/// Runs `healthcheck`.
pub fn run(args: &HealthcheckArgs) -> ExitCode {
    let mut addr = args.addr;
    if addr.ip().is_unspecified() {
        addr.set_ip(match addr {
            SocketAddr::V4(_) => Ipv4Addr::LOCALHOST.into(),
            SocketAddr::V6(_) => Ipv6Addr::LOCALHOST.into(),
        });
    }
    let tls = args.tls_cert.is_some() || args.ca_file.is_some();
    let scheme = if tls { "https" } else { "http" };
    let url = (args.url.clone()).unwrap_or_else(|| format!("{scheme}://{addr}/healthz"));
    // reqwest builds its TLS on the process's provider: the service's own, ring.
    let _ = rustls::crypto::ring::default_provider().install_default();
    match status(args, &url) {
        Ok(200) => {
            println!("healthy: {url} answered 200");
            return ExitCode::SUCCESS;
        }
        Ok(status) => eprintln!("unhealthy: {url} answered {status}"),
        Err(e) => eprintln!("unhealthy: {e}"),
    }
    ExitCode::FAILURE
}

/// The status code of `GET url`.
fn status(args: &HealthcheckArgs, url: &str) -> Result<u16, String> {
    let timeout = Duration::from_millis(args.timeout_ms.max(1));
    let mut url = reqwest::Url::parse(url).map_err(text)?;
    let mut client = Client::builder().timeout(timeout).no_proxy();
    let mut pinned = None;
    match (url.scheme(), &args.ca_file, &args.tls_cert) {
        ("http", ..) => {}
        ("https", Some(ca_file), _) => {
            let cas = Certificate::from_pem_bundle(&read(ca_file)?).map_err(text)?;
            client = client.tls_certs_only(cas);
            if let Some(name) = &args.server_name {
                // Dial the URL's address, check the certificate for `name`.
                let addrs = url.socket_addrs(|| None).map_err(text)?;
                client = client.resolve_to_addrs(name, &addrs);
                url.set_host(Some(name)).map_err(text)?;
            }
        }
        // Exactly the service's own leaf, compared on each answer's connection below.
        ("https", None, Some(cert)) => {
            let leaf = certificates(cert).map_err(text)?.into_iter().next();
            pinned = Some(leaf.ok_or_else(|| format!("{}: no certificate", cert.display()))?);
            client = client.tls_danger_accept_invalid_certs(true).tls_info(true);
        }
        ("https", None, None) => return Err("https:// needs --ca-file or --tls-cert".into()),
        _ => return Err(format!("{url}: not an http:// or https:// URL")),
    }
    if let (Some(cert), Some(key)) = (&args.client_cert, &args.client_key) {
        let pem = [read(cert)?, read(key)?].concat();
        client = client.identity(Identity::from_pem(&pem).map_err(text)?);
    }
    let client = client.build().map_err(text)?;
    let get = |token: Option<&str>| {
        let mut request = client.get(url.clone());
        if let Some(token) = token {
            request = request.bearer_auth(token);
        }
        let response = request.send().map_err(text)?;
        let tls = response.extensions().get::<TlsInfo>();
        match (&pinned, tls.and_then(TlsInfo::peer_certificate)) {
            (Some(leaf), presented) if presented != Some(leaf.as_ref()) => {
                Err("the service presents another certificate than --tls-cert".to_owned())
            }
            _ => Ok(response.status().as_u16()),
        }
    };
    match token(args)? {
        // A token goes out only once the pooled connection's certificate was checked.
        Some(token) if pinned.is_some() => get(None).and_then(|_| get(Some(&token))),
        token => get(token.as_deref()),
    }
}

/// A file's bytes.
fn read(file: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(file).map_err(|e| format!("{}: cannot read: {e}", file.display()))
}

/// An error and its sources, `: `-separated.
fn text(error: impl std::error::Error) -> String {
    let errors = std::iter::successors(Some(&error as &dyn std::error::Error), |e| e.source());
    errors
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(": ")
}

/// `--token-file`'s content, else `QRPOSE_HEALTHCHECK_TOKEN`, trimmed; refused unless it is
/// visible ASCII (no header can be smuggled in).
fn token(args: &HealthcheckArgs) -> Result<Option<String>, String> {
    let raw = match &args.token_file {
        Some(file) => String::from_utf8_lossy(&read(file)?).into_owned(),
        None => std::env::var("QRPOSE_HEALTHCHECK_TOKEN").unwrap_or_default(),
    };
    let token = raw.trim();
    if !token.bytes().all(|b| b.is_ascii_graphic()) {
        return Err("the token has characters other than visible ASCII".to_owned());
    }
    Ok((!token.is_empty()).then(|| token.to_owned()))
}
