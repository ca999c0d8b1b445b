//! [`AuthStore`]: the clients of the auth file, swapped whole on reload (SIGHUP), like the
//! site: a request reads one snapshot, and a refused file keeps the clients loaded before.

use crate::config::auth::{AuthFileError, Clients};
use crate::http::metrics::AuthMetrics;
use crate::http::reload::Reloadable;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The loaded clients, or none (every route open); cheap to clone.
#[derive(Debug, Clone)]
pub struct AuthStore(Arc<Inner>);

#[derive(Debug)]
struct Inner {
    file: Option<PathBuf>,
    current: Reloadable<Option<Arc<Clients>>>,
    metrics: AuthMetrics,
}

impl Default for AuthStore {
    fn default() -> Self {
        Self(Arc::new(Inner {
            file: None,
            current: Reloadable::new(None),
            metrics: AuthMetrics::default(),
        }))
    }
}

/// Why a reload did not change the clients.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AuthReloadError {
    /// The service runs without `--auth-file`.
    #[error("no auth file is configured (qrpose serve --auth-file FILE)")]
    NoFile,
    /// The file on disk was refused; the clients loaded before stay in use.
    #[error(transparent)]
    Invalid(#[from] AuthFileError),
}

impl AuthStore {
    /// Loads the auth file `file` (no file: every route open), counting into `metrics`.
    ///
    /// # Errors
    /// [`AuthFileError`] when the file is refused.
    pub fn load(file: Option<PathBuf>, metrics: AuthMetrics) -> Result<Self, AuthFileError> {
        let clients = file.as_deref().map(Clients::load).transpose()?;
        if let Some(clients) = &clients {
            metrics.clients.set(gauge_value(clients));
        }
        Ok(Self(Arc::new(Inner {
            file,
            current: Reloadable::new(clients.map(Arc::new)),
            metrics,
        })))
    }

    /// The auth file, if one is configured.
    pub fn file(&self) -> Option<&Path> {
        self.0.file.as_deref()
    }

    /// Whether tokens are checked (an auth file is loaded).
    pub fn is_on(&self) -> bool {
        self.0.file.is_some()
    }

    /// The clients loaded now; `None`: auth is off.
    pub fn current(&self) -> Option<Arc<Clients>> {
        self.0.current.get()
    }

    /// The metrics the auth layer counts into.
    pub fn metrics(&self) -> &AuthMetrics {
        &self.0.metrics
    }

    /// Reads and validates the auth file again and, when it is valid, swaps it in; logs the
    /// outcome (never a token: the file holds none) and counts it in
    /// `qrpose_auth_reloads_total{outcome}`. Blocking (file I/O): call it off the async
    /// threads.
    ///
    /// # Errors
    /// [`AuthReloadError`]; the clients loaded before stay in use.
    pub fn reload(&self) -> Result<Arc<Clients>, AuthReloadError> {
        let file = self.0.file.as_deref().ok_or(AuthReloadError::NoFile)?;
        let load = || Clients::load(file).map(Arc::new);
        match self
            .0
            .current
            .reload(load, |clients| Some(Arc::clone(clients)))
        {
            Ok(clients) => {
                self.0.metrics.clients.set(gauge_value(&clients));
                self.0.metrics.observe_auth_reload(true);
                tracing::info!(
                    file = %file.display(),
                    sha256 = clients.file_sha256_hex(),
                    clients = clients.len(),
                    "auth file reloaded"
                );
                Ok(clients)
            }
            Err(e) => {
                self.0.metrics.observe_auth_reload(false);
                tracing::warn!(error = %e, "auth file reload refused; the clients loaded before stay in use");
                Err(e.into())
            }
        }
    }
}

fn gauge_value(clients: &Clients) -> i64 {
    i64::try_from(clients.len()).unwrap_or(i64::MAX)
}
