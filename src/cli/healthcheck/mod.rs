//! `qrpose healthcheck`: exits 0 when the service's `/healthz` answers 200, 1 otherwise.
//!
//! Meant for a container `HEALTHCHECK` in a slim image without curl, so it is a tiny
//! HTTP/1.1 client over `std::net::TcpStream`: one `GET`, read the status line, done. Without
//! `--url` it checks `http://127.0.0.1:PORT/healthz` with the port of `QRPOSE_ADDR`
//! (`--addr`), the variable the container's `serve` reads too.
//!
//! With TLS on (docs/security.md), `https://` URLs go through rustls ([`tls`]): with
//! `QRPOSE_TLS_CERT` set (again the variable `serve` reads) the default URL is `https://`
//! and the service must present exactly that certificate; `--ca-file` checks a chain and a
//! name instead; `--client-cert`/`--client-key` answer a service that requires client
//! certificates. `/healthz` needs no token; for a `--url` that does, the token comes from
//! `QRPOSE_HEALTHCHECK_TOKEN` or `--token-file`, never from the command line (which `ps`
//! shows).

mod tls;

use clap::Args;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// The variable holding a bearer token to send.
const TOKEN_VAR: &str = "QRPOSE_HEALTHCHECK_TOKEN";

/// Arguments of `healthcheck`.
#[derive(Debug, Args)]
pub struct HealthcheckArgs {
    /// The URL to check, `http[s]://HOST[:PORT]/PATH` [default: http://127.0.0.1:PORT/healthz
    /// with the port of --addr; https:// with --tls-cert or --ca-file].
    #[arg(long, env = "QRPOSE_HEALTHCHECK_URL")]
    pub url: Option<String>,
    /// The service's listen address, used when --url is not given.
    #[arg(long, env = "QRPOSE_ADDR", default_value = qrpose::config::DEFAULT_ADDR)]
    pub addr: SocketAddr,
    /// Give up after this long, ms (connect, send and receive each).
    #[arg(long, default_value_t = 2000)]
    pub timeout_ms: u64,
    /// The service's own certificate (PEM), the file `qrpose serve --tls-cert` reads from the
    /// same variable: the default URL becomes https:// and, without --ca-file, the service
    /// must present exactly this certificate (its names and dates are not checked).
    #[arg(long, env = "QRPOSE_TLS_CERT")]
    pub tls_cert: Option<PathBuf>,
    /// CAs (PEM) to check the service's certificate chain against, with the URL's host (or
    /// --server-name) as the name it must carry.
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
    /// A file holding a bearer token to send (`Authorization: Bearer`), for a --url that
    /// needs one (/healthz and /readyz need none); QRPOSE_HEALTHCHECK_TOKEN may hold the
    /// token itself instead.
    #[arg(long, env = "QRPOSE_HEALTHCHECK_TOKEN_FILE")]
    pub token_file: Option<PathBuf>,
}

/// A parsed `http://` or `https://` URL.
#[derive(Debug, Clone, PartialEq, Eq)]
struct HttpUrl {
    /// `https://`.
    tls: bool,
    /// The host, without the brackets of an IPv6 address: the name TLS checks.
    host: String,
    /// `host:port`, also sent as the `Host` header.
    authority: String,
    /// Path and query, starting with `/`.
    path: String,
}

fn parse_url(url: &str) -> Result<HttpUrl, String> {
    let (tls, rest) = if let Some(rest) = url.strip_prefix("http://") {
        (false, rest)
    } else if let Some(rest) = url.strip_prefix("https://") {
        (true, rest)
    } else {
        return Err(format!(
            "{url}: only http:// and https:// URLs are supported"
        ));
    };
    let (authority, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i..]),
        None => (rest, "/"),
    };
    if authority.is_empty() || authority.contains('@') {
        return Err(format!("{url}: expected http[s]://HOST[:PORT]/PATH"));
    }
    let (host, has_port) = match authority.strip_prefix('[') {
        Some(bracketed) => match bracketed.split_once(']') {
            Some((host, port)) => (host, port.starts_with(':')),
            None => return Err(format!("{url}: an unclosed [ in the host")),
        },
        None => match authority.split_once(':') {
            Some((host, _port)) => (host, true),
            None => (authority, false),
        },
    };
    let authority = if has_port {
        authority.to_owned()
    } else {
        format!("{authority}:{}", if tls { 443 } else { 80 })
    };
    Ok(HttpUrl {
        tls,
        host: host.to_owned(),
        authority,
        path: path.to_owned(),
    })
}

fn default_url(addr: SocketAddr, tls: bool) -> String {
    let ip = if addr.ip().is_unspecified() {
        if addr.is_ipv4() {
            "127.0.0.1".to_owned()
        } else {
            "[::1]".to_owned()
        }
    } else {
        match addr {
            SocketAddr::V4(a) => a.ip().to_string(),
            SocketAddr::V6(a) => format!("[{}]", a.ip()),
        }
    };
    let scheme = if tls { "https" } else { "http" };
    format!("{scheme}://{ip}:{}/healthz", addr.port())
}

/// How to reach the service beyond its URL: TLS files and a token.
#[derive(Debug, Default)]
struct Client {
    /// The TLS files, for an `https://` URL.
    tls: tls::ClientFiles,
    /// The name the certificate must carry (with a CA file) instead of the URL's host.
    server_name: Option<String>,
    /// A bearer token to send.
    token: Option<String>,
}

/// The status code of `GET url`.
fn get_status(url: &HttpUrl, client: &Client, timeout: Duration) -> Result<u16, String> {
    // The TLS files are read before dialling, so that a bad file is named as such.
    let tls_config = if url.tls {
        Some(tls::client_config(&client.tls)?)
    } else {
        None
    };
    let addrs: Vec<SocketAddr> = url
        .authority
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve {}: {e}", url.authority))?
        .collect();
    let mut last_error = format!("{} resolves to no address", url.authority);
    for addr in addrs {
        match TcpStream::connect_timeout(&addr, timeout) {
            Ok(stream) => {
                let io = |e: std::io::Error| format!("{}: {e}", url.authority);
                stream.set_read_timeout(Some(timeout)).map_err(io)?;
                stream.set_write_timeout(Some(timeout)).map_err(io)?;
                let token = client.token.as_deref();
                return match tls_config {
                    None => exchange(stream, url, token),
                    Some(config) => {
                        let name = client.server_name.as_deref().unwrap_or(&url.host);
                        exchange(tls::connect(config, name, stream)?, url, token)
                    }
                };
            }
            Err(e) => last_error = format!("cannot connect to {addr}: {e}"),
        }
    }
    Err(last_error)
}

/// The request head of `GET url`, with `token` as a bearer token.
fn request_head(url: &HttpUrl, token: Option<&str>) -> String {
    let authorization = token
        .map(|t| format!("Authorization: Bearer {t}\r\n"))
        .unwrap_or_default();
    format!(
        "GET {} HTTP/1.1\r\nHost: {}\r\nUser-Agent: qrpose-healthcheck\r\nAccept: */*\r\n\
         {authorization}Connection: close\r\n\r\n",
        url.path, url.authority
    )
}

fn exchange<S: Read + Write>(
    mut stream: S,
    url: &HttpUrl,
    token: Option<&str>,
) -> Result<u16, String> {
    let io = |e: std::io::Error| format!("{}: {e}", url.authority);
    stream
        .write_all(request_head(url, token).as_bytes())
        .map_err(io)?;
    stream.flush().map_err(io)?;
    let mut status_line = String::new();
    BufReader::new(stream)
        .read_line(&mut status_line)
        .map_err(io)?;
    status_from_line(&status_line)
}

/// The token to send: `--token-file`'s content, else `QRPOSE_HEALTHCHECK_TOKEN`, trimmed;
/// refused unless it is visible ASCII (no header can be smuggled in).
fn token(args: &HealthcheckArgs) -> Result<Option<String>, String> {
    let raw = match &args.token_file {
        Some(file) => Some(
            std::fs::read_to_string(file)
                .map_err(|e| format!("{}: cannot read: {e}", file.display()))?,
        ),
        None => std::env::var(TOKEN_VAR).ok(),
    };
    let Some(token) = raw.map(|t| t.trim().to_owned()) else {
        return Ok(None);
    };
    if token.is_empty() {
        return Ok(None);
    }
    if !token.bytes().all(|b| b.is_ascii_graphic()) {
        return Err("the token has characters other than visible ASCII".to_owned());
    }
    Ok(Some(token))
}

/// The status code of an HTTP/1.x status line (`HTTP/1.1 200 OK`).
fn status_from_line(line: &str) -> Result<u16, String> {
    let mut parts = line.split_whitespace();
    match (parts.next(), parts.next()) {
        (Some(version), Some(code)) if version.starts_with("HTTP/1.") => code
            .parse()
            .map_err(|_| format!("bad status line {line:?}")),
        _ => Err(format!("not an HTTP/1 response: {line:?}")),
    }
}

/// Runs `healthcheck`.
pub fn run(args: &HealthcheckArgs) -> ExitCode {
    let tls_on = args.tls_cert.is_some() || args.ca_file.is_some();
    let url = args
        .url
        .clone()
        .unwrap_or_else(|| default_url(args.addr, tls_on));
    let timeout = Duration::from_millis(args.timeout_ms.max(1));
    let result = token(args).and_then(|token| {
        let client = Client {
            tls: tls::ClientFiles {
                ca_file: args.ca_file.clone(),
                pinned_cert: args.tls_cert.clone(),
                client_cert: args.client_cert.clone(),
                client_key: args.client_key.clone(),
            },
            server_name: args.server_name.clone(),
            token,
        };
        parse_url(&url).and_then(|parsed| get_status(&parsed, &client, timeout))
    });
    match result {
        Ok(200) => {
            println!("healthy: {url} answered 200");
            ExitCode::SUCCESS
        }
        Ok(status) => {
            eprintln!("unhealthy: {url} answered {status}");
            ExitCode::FAILURE
        }
        Err(e) => {
            eprintln!("unhealthy: {e}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_http_urls_with_and_without_port_and_path() {
        let cases = [
            (
                "http://127.0.0.1:8080/healthz",
                false,
                "127.0.0.1",
                "127.0.0.1:8080",
                "/healthz",
            ),
            (
                "http://localhost/healthz",
                false,
                "localhost",
                "localhost:80",
                "/healthz",
            ),
            ("http://example:9", false, "example", "example:9", "/"),
            (
                "http://[::1]:8080/x?y=1",
                false,
                "::1",
                "[::1]:8080",
                "/x?y=1",
            ),
            ("http://[::1]/", false, "::1", "[::1]:80", "/"),
            (
                "https://qrpose.internal/healthz",
                true,
                "qrpose.internal",
                "qrpose.internal:443",
                "/healthz",
            ),
            ("https://[::1]:8443/", true, "::1", "[::1]:8443", "/"),
        ];
        for (url, tls, host, authority, path) in cases {
            let parsed = parse_url(url).expect(url);
            assert_eq!(
                (
                    parsed.tls,
                    parsed.host.as_str(),
                    parsed.authority.as_str(),
                    parsed.path.as_str()
                ),
                (tls, host, authority, path),
                "{url}"
            );
        }
    }

    #[test]
    fn refuses_other_schemes_and_credentials() {
        for url in [
            "ftp://x/healthz",
            "http://[::1/",
            "x:80/healthz",
            "http:///healthz",
            "http://u@x/",
        ] {
            assert!(parse_url(url).is_err(), "{url}");
        }
    }

    #[test]
    fn the_default_url_checks_loopback_on_the_service_port() {
        let cases = [
            ("0.0.0.0:8080", false, "http://127.0.0.1:8080/healthz"),
            ("127.0.0.1:9000", false, "http://127.0.0.1:9000/healthz"),
            ("[::]:8080", false, "http://[::1]:8080/healthz"),
            ("10.1.2.3:80", false, "http://10.1.2.3:80/healthz"),
            ("0.0.0.0:8443", true, "https://127.0.0.1:8443/healthz"),
        ];
        for (addr, tls, url) in cases {
            let addr: SocketAddr = addr.parse().expect(addr);
            assert_eq!(default_url(addr, tls), url);
        }
    }

    #[test]
    fn sends_the_token_as_a_bearer_header_only_when_given() {
        let url = parse_url("http://127.0.0.1:8080/metrics").expect("a URL");
        let with = request_head(&url, Some("abc.DEF-123"));
        assert!(
            with.contains("\r\nAuthorization: Bearer abc.DEF-123\r\n"),
            "{with}"
        );
        assert!(with.ends_with("\r\n\r\n"), "{with}");
        assert!(!request_head(&url, None).contains("Authorization"));
    }

    #[test]
    fn reads_the_status_of_http1_status_lines_only() {
        assert_eq!(status_from_line("HTTP/1.1 200 OK\r\n"), Ok(200));
        assert_eq!(
            status_from_line("HTTP/1.0 503 Service Unavailable\r\n"),
            Ok(503)
        );
        assert!(status_from_line("").is_err());
        assert!(status_from_line("SSH-2.0-OpenSSH\r\n").is_err());
        assert!(status_from_line("HTTP/1.1 abc\r\n").is_err());
    }
}
