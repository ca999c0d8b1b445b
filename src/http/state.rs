//! [`AppState`]: what every handler shares, passed with axum's `State`.

use super::auth::AuthStore;
use super::metrics::Metrics;
use super::queue::EstimationQueue;
use super::reload::Reloadable;
use crate::app::{Site, SiteError};
use crate::config::Settings;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tokio_util::sync::CancellationToken;

/// Whether the service still takes new work.
#[derive(Debug, Clone, Default)]
pub struct Lifecycle {
    draining: Arc<AtomicBool>,
    shutdown: CancellationToken,
}

impl Lifecycle {
    /// From now on `/readyz` answers 503 `shutting_down`, and open stream sessions close
    /// (1001).
    pub fn start_draining(&self) {
        self.draining.store(true, Ordering::Relaxed);
        self.shutdown.cancel();
    }

    /// Cancelled when a shutdown begins.
    pub fn shutdown(&self) -> &CancellationToken {
        &self.shutdown
    }

    /// Whether a shutdown has begun.
    pub fn is_draining(&self) -> bool {
        self.draining.load(Ordering::Relaxed)
    }
}

/// The loaded site, swapped whole on reload: a request takes one snapshot
/// ([`SiteStore::current`]) and uses it throughout, so it never sees half of a reload.
#[derive(Debug, Clone)]
pub struct SiteStore {
    path: Option<PathBuf>,
    current: Arc<Reloadable<Option<Arc<Site>>>>,
}

impl Default for SiteStore {
    fn default() -> Self {
        Self::new(None, None)
    }
}

/// Why a reload did not change the site.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReloadError {
    /// The service runs without `--site`.
    #[error("no site file is configured (qrpose serve --site FILE)")]
    NoSite,
    /// The file on disk was refused; the previous site stays loaded.
    #[error(transparent)]
    Invalid(#[from] SiteError),
}

impl SiteStore {
    /// A store for the site file `path`, holding `site` (already loaded from it).
    pub fn new(path: Option<PathBuf>, site: Option<Site>) -> Self {
        Self {
            path,
            current: Arc::new(Reloadable::new(site.map(Arc::new))),
        }
    }

    /// The site file, if one is configured.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The site loaded now, if any.
    pub fn current(&self) -> Option<Arc<Site>> {
        self.current.get()
    }

    /// Reads and validates the site file again and, when it is valid, swaps it in. Blocking
    /// (file I/O): call it off the async threads.
    ///
    /// # Errors
    /// [`ReloadError`]; the site loaded before stays in use.
    pub fn reload(&self) -> Result<Arc<Site>, ReloadError> {
        let path = self.path.as_deref().ok_or(ReloadError::NoSite)?;
        let load = || Site::load(path).map(Arc::new);
        Ok(self.current.reload(load, |site| Some(Arc::clone(site)))?)
    }
}

/// The stream sessions open: at most `--max-stream-sessions`, each holding a place until
/// it ends, and a shutdown waits for the last place to come back.
#[derive(Debug, Clone)]
pub struct StreamSessions {
    places: Arc<Semaphore>,
    max: usize,
}

impl StreamSessions {
    /// Room for `max` sessions.
    pub fn new(max: usize) -> Self {
        Self {
            places: Arc::new(Semaphore::new(max)),
            max,
        }
    }

    /// A place for one more session, or `None` when `max` are open.
    pub fn try_open(&self) -> Option<OwnedSemaphorePermit> {
        Arc::clone(&self.places).try_acquire_owned().ok()
    }

    /// Sessions open now.
    pub fn open(&self) -> usize {
        self.max - self.places.available_permits()
    }

    /// Waits until no session is open.
    pub async fn all_closed(&self) {
        let count = u32::try_from(self.max).unwrap_or(u32::MAX);
        if let Ok(all) = self.places.acquire_many(count).await {
            drop(all);
        }
    }
}

/// Why the state could not be built.
#[derive(Debug, thiserror::Error)]
pub enum StateError {
    /// An estimation worker thread could not be spawned.
    #[error("cannot start the estimation workers: {0}")]
    Workers(#[from] std::io::Error),
    /// The site file was refused.
    #[error(transparent)]
    Site(#[from] SiteError),
    /// The auth file was refused.
    #[error(transparent)]
    Auth(#[from] crate::config::auth::AuthFileError),
    /// A TLS file was refused.
    #[error(transparent)]
    Tls(#[from] super::tls::TlsError),
}

/// The state shared by all handlers; cheap to clone.
#[derive(Debug, Clone)]
pub struct AppState {
    /// The validated configuration.
    pub settings: Arc<Settings>,
    /// The bounded queue in front of every CPU-bound job.
    pub queue: EstimationQueue,
    /// The metrics registry.
    pub metrics: Arc<Metrics>,
    /// Ready or draining.
    pub lifecycle: Lifecycle,
    /// The loaded site.
    pub site: SiteStore,
    /// The stream sessions open.
    pub streams: StreamSessions,
    /// The clients of the auth file, when one is loaded (docs/security.md).
    pub auth: AuthStore,
    /// TLS, when configured: the certificate in use, reloaded on SIGHUP.
    pub tls: Option<super::tls::TlsStore>,
}

impl AppState {
    /// What an image request may cost, from the settings.
    pub fn image_limits(&self) -> crate::app::ImageLimits {
        crate::app::ImageLimits::from(&*self.settings)
    }

    /// Fresh state for `settings`: an empty queue, zeroed metrics, and the site file of
    /// `settings.site` and the auth and TLS files of `settings.security` loaded.
    ///
    /// # Errors
    /// [`StateError`] when a worker thread cannot be spawned or a file is refused.
    pub fn new(settings: Settings) -> Result<Self, StateError> {
        let site = settings.site.as_deref().map(Site::load).transpose()?;
        Self::with_site(settings, site)
    }

    /// [`AppState::new`] with the site already loaded from `settings.site` (`qrpose serve`
    /// loads it before starting, to exit 2 on a bad file). The auth and TLS files of
    /// `settings.security` are loaded here.
    ///
    /// # Errors
    /// [`StateError`] when a worker thread cannot be spawned or the auth or a TLS file is
    /// refused.
    pub fn with_site(settings: Settings, site: Option<Site>) -> Result<Self, StateError> {
        let metrics = Arc::new(Metrics::new());
        let queue = EstimationQueue::new(
            settings.max_concurrent_estimations.get(),
            settings.queue_length,
            metrics.queue(),
        )?
        .with_pixel_budget(settings.max_inflight_pixels)
        .with_body_budget(settings.max_inflight_body_bytes);
        let site = SiteStore::new(settings.site.clone(), site);
        let streams = StreamSessions::new(settings.stream.max_sessions);
        let auth = AuthStore::load(settings.security.auth_file.clone(), metrics.auth())?;
        let tls = (settings.security.tls.clone())
            .map(|files| super::tls::TlsStore::load(files, metrics.auth()))
            .transpose()?;
        Ok(Self {
            auth,
            tls,
            settings: Arc::new(settings),
            queue,
            metrics,
            lifecycle: Lifecycle::default(),
            site,
            streams,
        })
    }

    /// Reloads the site file ([`SiteStore::reload`]), logs the outcome and counts it in
    /// `qrpose_site_reloads_total{outcome}`. Blocking: call it off the async threads.
    ///
    /// # Errors
    /// [`ReloadError`]; the site loaded before stays in use.
    pub fn reload_site(&self) -> Result<Arc<Site>, ReloadError> {
        let outcome = self.site.reload();
        match &outcome {
            Ok(site) => {
                self.metrics.observe_site_reload(true);
                tracing::info!(
                    file = %site.file().display(),
                    sha256 = site.sha256_hex(),
                    "site reloaded"
                );
            }
            Err(ReloadError::NoSite) => {
                tracing::warn!("site reload asked for, but no site file is configured");
            }
            Err(ReloadError::Invalid(e)) => {
                self.metrics.observe_site_reload(false);
                tracing::warn!(error = %e, "site reload refused; the previous site stays loaded");
            }
        }
        outcome
    }
}
