//! `qrpose healthcheck`: exits 0 when the service's `/healthz` answers 200, 1 otherwise.
//!
//! Meant for a container `HEALTHCHECK` in a slim image without curl, so it is a tiny
//! HTTP/1.1 client over `std::net::TcpStream` (plain `http://` only): one `GET`, read the
//! status line, done. Without `--url` it checks `http://127.0.0.1:PORT/healthz` with the port
//! of `QRPOSE_ADDR` (`--addr`), the variable the container's `serve` reads too.

use clap::Args;
use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::process::ExitCode;
use std::time::Duration;

/// Arguments of `healthcheck`.
#[derive(Debug, Args)]
pub struct HealthcheckArgs {
    /// The URL to check, `http://HOST[:PORT]/PATH` [default: http://127.0.0.1:PORT/healthz
    /// with the port of --addr].
    #[arg(long, env = "QRPOSE_HEALTHCHECK_URL")]
    pub url: Option<String>,
    /// The service's listen address, used when --url is not given.
    #[arg(long, env = "QRPOSE_ADDR", default_value = qrpose::config::DEFAULT_ADDR)]
    pub addr: SocketAddr,
    /// Give up after this long, ms (connect, send and receive each).
    #[arg(long, default_value_t = 2000)]
    pub timeout_ms: u64,
}

/// A parsed `http://` URL.
#[derive(Debug, Clone, PartialEq, Eq)]
struct HttpUrl {
    /// `host:port`, also sent as the `Host` header.
    authority: String,
    /// Path and query, starting with `/`.
    path: String,
}

fn parse_url(url: &str) -> Result<HttpUrl, String> {
    let rest = url
        .strip_prefix("http://")
        .ok_or_else(|| format!("{url}: only http:// URLs are supported"))?;
    let (authority, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i..]),
        None => (rest, "/"),
    };
    if authority.is_empty() || authority.contains('@') {
        return Err(format!("{url}: expected http://HOST[:PORT]/PATH"));
    }
    let has_port = match authority.strip_prefix('[') {
        Some(bracketed) => bracketed
            .split_once(']')
            .is_some_and(|(_, p)| p.starts_with(':')),
        None => authority.contains(':'),
    };
    let authority = if has_port {
        authority.to_owned()
    } else {
        format!("{authority}:80")
    };
    Ok(HttpUrl {
        authority,
        path: path.to_owned(),
    })
}

fn default_url(addr: SocketAddr) -> String {
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
    format!("http://{ip}:{}/healthz", addr.port())
}

/// The status code of `GET url`.
fn get_status(url: &HttpUrl, timeout: Duration) -> Result<u16, String> {
    let addrs: Vec<SocketAddr> = url
        .authority
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve {}: {e}", url.authority))?
        .collect();
    let mut last_error = format!("{} resolves to no address", url.authority);
    for addr in addrs {
        match TcpStream::connect_timeout(&addr, timeout) {
            Ok(stream) => return exchange(stream, url, timeout),
            Err(e) => last_error = format!("cannot connect to {addr}: {e}"),
        }
    }
    Err(last_error)
}

fn exchange(mut stream: TcpStream, url: &HttpUrl, timeout: Duration) -> Result<u16, String> {
    let io = |e: std::io::Error| format!("{}: {e}", url.authority);
    stream.set_read_timeout(Some(timeout)).map_err(io)?;
    stream.set_write_timeout(Some(timeout)).map_err(io)?;
    let request = format!(
        "GET {} HTTP/1.1\r\nHost: {}\r\nUser-Agent: qrpose-healthcheck\r\nAccept: */*\r\nConnection: close\r\n\r\n",
        url.path, url.authority
    );
    stream.write_all(request.as_bytes()).map_err(io)?;
    let mut status_line = String::new();
    BufReader::new(stream)
        .read_line(&mut status_line)
        .map_err(io)?;
    status_from_line(&status_line)
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
    let url = args.url.clone().unwrap_or_else(|| default_url(args.addr));
    let timeout = Duration::from_millis(args.timeout_ms.max(1));
    let result = parse_url(&url).and_then(|parsed| get_status(&parsed, timeout));
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
                "127.0.0.1:8080",
                "/healthz",
            ),
            ("http://localhost/healthz", "localhost:80", "/healthz"),
            ("http://example:9", "example:9", "/"),
            ("http://[::1]:8080/x?y=1", "[::1]:8080", "/x?y=1"),
            ("http://[::1]/", "[::1]:80", "/"),
        ];
        for (url, authority, path) in cases {
            let parsed = parse_url(url).expect(url);
            assert_eq!(
                (parsed.authority.as_str(), parsed.path.as_str()),
                (authority, path),
                "{url}"
            );
        }
    }

    #[test]
    fn refuses_other_schemes_and_credentials() {
        for url in [
            "https://x/healthz",
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
            ("0.0.0.0:8080", "http://127.0.0.1:8080/healthz"),
            ("127.0.0.1:9000", "http://127.0.0.1:9000/healthz"),
            ("[::]:8080", "http://[::1]:8080/healthz"),
            ("10.1.2.3:80", "http://10.1.2.3:80/healthz"),
        ];
        for (addr, url) in cases {
            let addr: SocketAddr = addr.parse().expect(addr);
            assert_eq!(default_url(addr), url);
        }
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
