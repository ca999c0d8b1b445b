//! The HTTPS side of `qrpose healthcheck`: a rustls client (TLS 1.2 and 1.3, ring) that
//! trusts either the CAs of `--ca-file` (the usual chain and name check) or exactly the
//! certificate of `--tls-cert` (the one `qrpose serve` reads from the same variable, so a
//! container's `HEALTHCHECK` dialling loopback needs no name in the certificate), and offers
//! a client certificate when the service asks for one (mutual TLS).

use qrpose::http::tls::{TlsError, certificates, private_key};
use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::crypto::{CryptoProvider, verify_tls12_signature, verify_tls13_signature};
use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use rustls::{ClientConfig, ClientConnection, DigitallySignedStruct, SignatureScheme};
use std::net::TcpStream;
use std::path::PathBuf;
use std::sync::Arc;

/// What the client trusts and shows.
#[derive(Debug, Clone, Default)]
pub struct ClientFiles {
    /// CAs that sign the service's certificate (PEM); the name is checked too.
    pub ca_file: Option<PathBuf>,
    /// The service's own certificate (PEM, leaf first): the service must present exactly
    /// this leaf; names and dates are not checked. Used without `ca_file`.
    pub pinned_cert: Option<PathBuf>,
    /// A client certificate chain and its key, for a service with `--tls-client-ca`.
    pub client_cert: Option<PathBuf>,
    /// The key of `client_cert` (PEM).
    pub client_key: Option<PathBuf>,
}

/// Trusts exactly one certificate: the service's own, read from its file.
#[derive(Debug)]
struct Pinned {
    leaf: CertificateDer<'static>,
    provider: Arc<CryptoProvider>,
}

impl ServerCertVerifier for Pinned {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp_response: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        if end_entity.as_ref() == self.leaf.as_ref() {
            Ok(ServerCertVerified::assertion())
        } else {
            Err(rustls::Error::General(
                "the service presents another certificate than --tls-cert".to_owned(),
            ))
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        verify_tls12_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        verify_tls13_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.provider
            .signature_verification_algorithms
            .supported_schemes()
    }
}

fn tls_error(e: TlsError) -> String {
    e.to_string()
}

/// The client configuration of `files`.
///
/// # Errors
/// A file that is unreadable or not PEM, a client key that does not fit its certificate, or
/// neither a CA file nor a pinned certificate.
pub fn client_config(files: &ClientFiles) -> Result<ClientConfig, String> {
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let builder = ClientConfig::builder_with_provider(Arc::clone(&provider))
        .with_protocol_versions(&[&rustls::version::TLS13, &rustls::version::TLS12])
        .map_err(|e| e.to_string())?;
    let builder = match (&files.ca_file, &files.pinned_cert) {
        (Some(ca_file), _) => {
            let mut roots = rustls::RootCertStore::empty();
            for ca in certificates(ca_file).map_err(tls_error)? {
                roots
                    .add(ca)
                    .map_err(|e| format!("{}: not a CA certificate: {e}", ca_file.display()))?;
            }
            builder.with_root_certificates(roots)
        }
        (None, Some(pinned)) => {
            let leaf = certificates(pinned)
                .map_err(tls_error)?
                .into_iter()
                .next()
                .ok_or_else(|| format!("{}: holds no certificate", pinned.display()))?;
            builder
                .dangerous()
                .with_custom_certificate_verifier(Arc::new(Pinned { leaf, provider }))
        }
        (None, None) => {
            return Err(
                "https:// needs --ca-file (CAs to trust) or --tls-cert (the service's own \
                 certificate)"
                    .to_owned(),
            );
        }
    };
    match (&files.client_cert, &files.client_key) {
        (Some(cert), Some(key)) => {
            let chain = certificates(cert).map_err(tls_error)?;
            let key_der = private_key(key).map_err(tls_error)?;
            builder
                .with_client_auth_cert(chain, key_der)
                .map_err(|e| format!("{}: does not fit the certificate: {e}", key.display()))
        }
        (None, None) => Ok(builder.with_no_client_auth()),
        _ => Err("--client-cert and --client-key go together".to_owned()),
    }
}

/// A TLS session with `server_name` over `tcp`; the handshake runs on the first write.
///
/// # Errors
/// A server name that is neither a DNS name nor an IP address.
pub fn connect(
    config: ClientConfig,
    server_name: &str,
    tcp: TcpStream,
) -> Result<rustls::StreamOwned<ClientConnection, TcpStream>, String> {
    let name = ServerName::try_from(server_name.to_owned())
        .map_err(|e| format!("{server_name}: not a server name: {e}"))?;
    let connection = ClientConnection::new(Arc::new(config), name).map_err(|e| e.to_string())?;
    Ok(rustls::StreamOwned::new(connection, tcp))
}
