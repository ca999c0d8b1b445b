//! Who may call the service and over what (docs/security.md): the flags `--auth-file`,
//! `--tls-cert`, `--tls-key` and `--tls-client-ca`, each with its `QRPOSE_*` variable. Both
//! are off by default (the default address is loopback). The files are read by the caller
//! (`qrpose serve` refuses a bad one with exit 2) and again on SIGHUP.

use clap::Args;
use std::path::PathBuf;

/// The security flags of `qrpose serve`.
#[derive(Debug, Clone, Default, Args)]
pub struct SecurityArgs {
    /// An auth file (YAML, docs/security.md): each client's name, the SHA-256 of its bearer
    /// token and its scopes (pose, site, admin, metrics). Without it every route is open.
    /// Reloaded on SIGHUP; a refused file keeps the clients loaded before.
    #[arg(long, env = "QRPOSE_AUTH_FILE")]
    pub auth_file: Option<PathBuf>,
    /// Serve HTTPS (and wss:// for the stream) with this certificate chain (PEM, leaf
    /// first); needs --tls-key. TLS 1.2 and 1.3 only. Reloaded on SIGHUP.
    #[arg(long, env = "QRPOSE_TLS_CERT", requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// The private key of --tls-cert (PEM: PKCS#8, PKCS#1 or SEC1).
    #[arg(long, env = "QRPOSE_TLS_KEY", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// Ask every client for a certificate signed by one of these CAs (PEM) and refuse the
    /// handshake without one (mutual TLS); needs --tls-cert.
    #[arg(long, env = "QRPOSE_TLS_CLIENT_CA", requires = "tls_cert")]
    pub tls_client_ca: Option<PathBuf>,
}

/// The files of TLS.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlsFiles {
    /// The certificate chain, PEM, leaf first.
    pub cert: PathBuf,
    /// Its private key, PEM.
    pub key: PathBuf,
    /// CAs whose client certificates are required (mutual TLS), PEM.
    pub client_ca: Option<PathBuf>,
}

/// The validated security settings.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SecuritySettings {
    /// The auth file; `None`: every route is open.
    pub auth_file: Option<PathBuf>,
    /// TLS; `None`: plain HTTP.
    pub tls: Option<TlsFiles>,
}

impl From<&SecurityArgs> for SecuritySettings {
    fn from(args: &SecurityArgs) -> Self {
        let tls = match (&args.tls_cert, &args.tls_key) {
            (Some(cert), Some(key)) => Some(TlsFiles {
                cert: cert.clone(),
                key: key.clone(),
                client_ca: args.tls_client_ca.clone(),
            }),
            // clap refuses one without the other.
            _ => None,
        };
        Self {
            auth_file: args.auth_file.clone(),
            tls,
        }
    }
}
