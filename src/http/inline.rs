//! When a corners request runs on the async thread instead of behind the estimation queue:
//! only when the queue has no free place (so that corners requests are answered while image
//! jobs fill every worker and waiting place) and the estimate is short. Otherwise it goes to
//! the queue, which on this 2-core machine costs less CPU per request than running inline
//! (`docs/service.md`, "Load test": the workers keep the estimator's code and data in their
//! caches, the async threads the network's).

use super::error::ApiError;
use super::queue::EstimationQueue;
use crate::api::problem::parse_json;
use crate::api::request::CornersRequest;
use crate::app::contain;

/// Bodies up to this size may be parsed on the async thread (a few µs); larger ones, which
/// only padding or a long unknown field can make, are parsed on an estimation worker.
pub const INLINE_MAX_BODY_BYTES: usize = 16 * 1024;

/// Estimates with at most this many iterations and no trace may run on the async thread.
/// Measured at the limit: 35 µs for `paper` running all 1000 iterations (`docs/service.md`,
/// "Saturation").
pub const INLINE_MAX_ITERATIONS: u64 = 1000;

/// The request to estimate right here, on the async thread, parsed; `None` when it goes to
/// the queue.
///
/// # Errors
/// The request's parse problem, when it was parsed here.
pub fn parsed_if_inline(
    queue: &EstimationQueue,
    body: &[u8],
) -> Result<Option<CornersRequest>, ApiError> {
    let o = queue.occupancy();
    if o.running + o.waiting < o.capacity || body.len() > INLINE_MAX_BODY_BYTES {
        return Ok(None);
    }
    let request = contained(|| parse_json::<CornersRequest>(body))??;
    Ok(runs_inline(&request).then_some(request))
}

/// Whether a parsed request's estimate is short enough to run on an async thread: at most
/// [`INLINE_MAX_ITERATIONS`] and no trace to serialise. Long ones (up to 10 000 iterations)
/// always go to the workers, so that no request blocks an async thread for long.
pub fn runs_inline(request: &CornersRequest) -> bool {
    request.solver.max_iterations <= INLINE_MAX_ITERATIONS && !request.solver.trace
}

/// Runs `f` with panics contained: a panic is a 500 `internal` (logged), as on a worker.
///
/// # Errors
/// 500 `internal` when `f` panics.
pub fn contained<T>(f: impl FnOnce() -> T) -> Result<T, ApiError> {
    contain(f).map_err(|panic| ApiError::internal(format!("estimation panicked: {panic}")))
}
