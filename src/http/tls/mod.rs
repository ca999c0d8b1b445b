//! TLS (docs/security.md): `--tls-cert` / `--tls-key` (PEM) served with rustls on the ring
//! provider, TLS 1.2 and 1.3 only, ALPN `http/1.1`; optional client certificates
//! (`--tls-client-ca`, mutual TLS: a client without a certificate signed by one of those
//! CAs is refused at the handshake).
//!
//! [`TlsStore`] holds the configuration in use and swaps it whole on [`TlsStore::reload`]
//! (SIGHUP): each new connection takes the configuration of its accept, so connections
//! already open keep theirs and are not dropped; a refused file keeps the one in use.
//!
//! The handshake runs inside the connection's header-read timeout ([`handshake`]), so the
//! limits of the plain listener (`http::conn`) apply unchanged: a client that stalls its
//! handshake is closed like one that stalls its request head, and a connection in its
//! handshake may be closed to make room or at shutdown like any connection that has sent
//! no request. A plain-HTTP request to the TLS port is answered `400 tls_required` in
//! plain HTTP and closed.

mod accept;
mod stream;

pub use accept::handshake;
pub use stream::ServerStream;

use super::reload::Reloadable;
use crate::config::TlsFiles;
use crate::http::metrics::AuthMetrics;
use rustls::ServerConfig;
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use rustls::server::WebPkiClientVerifier;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tokio_rustls::TlsAcceptor;

/// Why a TLS file was refused: `FILE: reason`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: {reason}", file.display())]
pub struct TlsError {
    /// The file at fault.
    pub file: PathBuf,
    /// What is wrong.
    pub reason: String,
}

impl TlsError {
    fn new(file: &Path, reason: impl Into<String>) -> Self {
        Self {
            file: file.to_owned(),
            reason: reason.into(),
        }
    }
}

/// The certificates of the PEM file `file`, in order (a chain: leaf first).
///
/// # Errors
/// [`TlsError`] when the file is unreadable, not PEM, or holds no certificate.
pub fn certificates(file: &Path) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let certificates = CertificateDer::pem_file_iter(file)
        .map_err(|e| TlsError::new(file, format!("cannot read: {e}")))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| TlsError::new(file, format!("not a PEM certificate list: {e}")))?;
    if certificates.is_empty() {
        return Err(TlsError::new(file, "holds no CERTIFICATE block"));
    }
    Ok(certificates)
}

/// The private key of the PEM file `file` (PKCS#8, PKCS#1 or SEC1).
///
/// # Errors
/// [`TlsError`] when the file is unreadable or holds no private key.
pub fn private_key(file: &Path) -> Result<PrivateKeyDer<'static>, TlsError> {
    PrivateKeyDer::from_pem_file(file)
        .map_err(|e| TlsError::new(file, format!("no usable private key: {e}")))
}

/// The server configuration of `files`: TLS 1.2 and 1.3, ALPN `http/1.1`, client
/// certificates required when `files.client_ca` is given.
///
/// # Errors
/// [`TlsError`] naming the file that is unreadable, not PEM, or refused by rustls (a key
/// that does not match the certificate, say).
pub fn server_config(files: &TlsFiles) -> Result<ServerConfig, TlsError> {
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let chain = certificates(&files.cert)?;
    let key = private_key(&files.key)?;
    let builder = ServerConfig::builder_with_provider(Arc::clone(&provider))
        .with_protocol_versions(&[&rustls::version::TLS13, &rustls::version::TLS12])
        .map_err(|e| TlsError::new(&files.cert, e.to_string()))?;
    let builder = match &files.client_ca {
        None => builder.with_no_client_auth(),
        Some(ca_file) => {
            let mut roots = rustls::RootCertStore::empty();
            for ca in certificates(ca_file)? {
                roots
                    .add(ca)
                    .map_err(|e| TlsError::new(ca_file, format!("not a CA certificate: {e}")))?;
            }
            let verifier =
                WebPkiClientVerifier::builder_with_provider(Arc::new(roots), Arc::clone(&provider))
                    .build()
                    .map_err(|e| TlsError::new(ca_file, e.to_string()))?;
            builder.with_client_cert_verifier(verifier)
        }
    };
    let mut config = builder
        .with_single_cert(chain, key)
        .map_err(|e| TlsError::new(&files.key, format!("does not fit the certificate: {e}")))?;
    config.alpn_protocols = vec![b"http/1.1".to_vec()];
    Ok(config)
}

/// The TLS configuration in use, swapped whole on reload; cheap to clone.
#[derive(Clone)]
pub struct TlsStore(Arc<Inner>);

struct Inner {
    files: TlsFiles,
    current: Reloadable<TlsAcceptor>,
    metrics: AuthMetrics,
}

impl std::fmt::Debug for TlsStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TlsStore")
            .field("files", &self.0.files)
            .finish_non_exhaustive()
    }
}

impl TlsStore {
    /// Loads `files`, counting reloads and refused connections into `metrics`.
    ///
    /// # Errors
    /// [`TlsError`] as [`server_config`].
    pub fn load(files: TlsFiles, metrics: AuthMetrics) -> Result<Self, TlsError> {
        let config = server_config(&files)?;
        Ok(Self(Arc::new(Inner {
            files,
            current: Reloadable::new(TlsAcceptor::from(Arc::new(config))),
            metrics,
        })))
    }

    /// The files in use.
    pub fn files(&self) -> &TlsFiles {
        &self.0.files
    }

    /// The acceptor for a new connection: the configuration in use now.
    pub fn acceptor(&self) -> TlsAcceptor {
        self.0.current.get()
    }

    /// The metrics of refused connections and reloads.
    pub fn metrics(&self) -> &AuthMetrics {
        &self.0.metrics
    }

    /// Reads the certificate, key and client CA files again and, when they are valid,
    /// serves them to every new connection; open connections keep theirs. Logs the outcome
    /// and counts it in `qrpose_tls_reloads_total{outcome}`. Blocking (file I/O): call it off
    /// the async threads.
    ///
    /// # Errors
    /// [`TlsError`]; the configuration in use stays.
    pub fn reload(&self) -> Result<(), TlsError> {
        let load = || server_config(&self.0.files).map(|c| TlsAcceptor::from(Arc::new(c)));
        match self.0.current.reload(load, TlsAcceptor::clone) {
            Ok(_) => {
                self.0.metrics.observe_tls_reload(true);
                tracing::info!(cert = %self.0.files.cert.display(), "TLS certificate reloaded");
                Ok(())
            }
            Err(e) => {
                self.0.metrics.observe_tls_reload(false);
                tracing::warn!(error = %e, "TLS reload refused; the certificate in use stays");
                Err(e)
            }
        }
    }
}
