//! How much work detection may do: the caller's [`Effort`] and deadline, and the record of
//! the passes that ran ([`PassLog`]), so that a response can say what was tried and whether
//! the deadline cut it short.
//!
//! The first pass always runs, whatever the deadline: it is the least any answer costs.
//! Every further pass starts only while the deadline has not passed, so detection ends at
//! most one pass after it; `auto`'s later passes work on small crops, which keeps that
//! overshoot to a few milliseconds.

use crate::cancel::CancelFlag;
use std::time::{Duration, Instant};

/// How hard `auto` looks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Effort {
    /// One pass over the frame (a full-resolution read); nothing more.
    Fast,
    /// The full-resolution and half-scale reads, then more passes only on the places where
    /// a finder-pattern triple was found but not read (the default).
    #[default]
    Balanced,
    /// As balanced, then every backend and every image variant on the whole frame.
    Thorough,
}

impl Effort {
    /// The wire name: "fast", "balanced", "thorough".
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Fast => "fast",
            Self::Balanced => "balanced",
            Self::Thorough => "thorough",
        }
    }

    /// The deadline used when the caller gives none, for an image of `pixels` pixels: a
    /// fixed part plus a part per megapixel, so that a 1920 × 1080 frame at `balanced`
    /// stops within about 85 ms and a 12 MP photo within about 250 ms. The fixed part leaves
    /// a small frame time for rqrr's search of a region (20-45 ms), the last and slowest of
    /// its passes.
    #[must_use]
    pub fn default_deadline(self, pixels: usize) -> Duration {
        let (base_ms, per_mp_ms) = match self {
            Self::Fast => (FAST_BASE_MS, FAST_PER_MP_MS),
            Self::Balanced => (BALANCED_BASE_MS, BALANCED_PER_MP_MS),
            Self::Thorough => (THOROUGH_BASE_MS, THOROUGH_PER_MP_MS),
        };
        // Exact below 2^53 pixels; images are capped far below that.
        #[allow(clippy::cast_precision_loss)]
        let mp = pixels as f64 / 1e6;
        Duration::from_secs_f64((base_ms + per_mp_ms * mp) / 1e3)
    }
}

/// `fast`'s default deadline, fixed part, ms (it runs one pass whatever the deadline).
const FAST_BASE_MS: f64 = 20.0;
/// `fast`'s default deadline, per megapixel, ms.
const FAST_PER_MP_MS: f64 = 10.0;
/// `balanced`'s default deadline, fixed part, ms.
const BALANCED_BASE_MS: f64 = 50.0;
/// `balanced`'s default deadline, per megapixel, ms.
const BALANCED_PER_MP_MS: f64 = 16.0;
/// `thorough`'s default deadline, fixed part, ms.
const THOROUGH_BASE_MS: f64 = 200.0;
/// `thorough`'s default deadline, per megapixel, ms.
const THOROUGH_PER_MP_MS: f64 = 100.0;

/// What detection may spend.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Budget {
    /// How hard to look.
    pub effort: Effort,
    /// Stop starting passes after this long; `None` for the effort's default for the image
    /// ([`Effort::default_deadline`]).
    pub max_detect: Option<Duration>,
    /// Stop starting passes once this flag is raised (nobody waits for the answer any
    /// more); the default flag is never raised.
    pub cancel: CancelFlag,
}

impl Budget {
    /// A budget of `effort` with the deadline `max_detect` (`None`: the effort's default),
    /// never cancelled.
    #[must_use]
    pub fn new(effort: Effort, max_detect: Option<Duration>) -> Self {
        Self {
            effort,
            max_detect,
            cancel: CancelFlag::new(),
        }
    }

    /// The same budget, stopped by `cancel` too.
    #[must_use]
    pub fn cancelled_by(self, cancel: CancelFlag) -> Self {
        Self { cancel, ..self }
    }

    /// The deadline for an image of `pixels` pixels: the one asked for, else the effort's
    /// default ([`Effort::default_deadline`]).
    #[must_use]
    pub fn deadline_for(&self, pixels: usize) -> Duration {
        self.max_detect
            .unwrap_or_else(|| self.effort.default_deadline(pixels))
    }
}

/// One pass that ran.
#[derive(Debug, Clone, PartialEq)]
pub struct PassReport {
    /// What ran, e.g. `rxing full`, `rxing half`, `region 2 global-histogram`.
    pub name: String,
    /// How long it took, ms.
    pub ms: f64,
    /// Symbols it decoded.
    pub decoded: usize,
}

/// The passes of one detection, and whether the deadline or a cancellation stopped it.
#[derive(Debug, Clone)]
pub struct PassLog {
    deadline: Instant,
    cancel: CancelFlag,
    /// The passes, in the order they ran.
    pub passes: Vec<PassReport>,
    /// A pass was skipped because the deadline had passed.
    pub budget_exhausted: bool,
    /// A pass was skipped because the caller cancelled the detection
    /// ([`Budget::cancel`]): nobody waits for the answer any more.
    pub cancelled: bool,
}

impl PassLog {
    /// A log whose deadline is `max_detect` from now, never cancelled.
    #[must_use]
    #[cfg(test)]
    pub(crate) fn new(max_detect: Duration) -> Self {
        Self::with_cancel(max_detect, CancelFlag::new())
    }

    /// A log whose deadline is `max_detect` from now and that stops once `cancel` is
    /// raised.
    #[must_use]
    pub(crate) fn with_cancel(max_detect: Duration, cancel: CancelFlag) -> Self {
        Self {
            deadline: Instant::now() + max_detect,
            cancel,
            passes: Vec::new(),
            budget_exhausted: false,
            cancelled: false,
        }
    }

    /// Whether another pass may start; when not, the log records why work was skipped (the
    /// deadline, or the budget's [`CancelFlag`]).
    pub(crate) fn may_continue(&mut self) -> bool {
        if self.cancel.is_cancelled() {
            self.cancelled = true;
            false
        } else if Instant::now() < self.deadline {
            true
        } else {
            self.budget_exhausted = true;
            false
        }
    }

    /// Runs `pass`, records its time and how many symbols it decoded (counted by
    /// `decoded`), and returns its result.
    pub(crate) fn run<T>(
        &mut self,
        name: impl Into<String>,
        decoded: impl Fn(&T) -> usize,
        pass: impl FnOnce() -> T,
    ) -> T {
        self.run_since(Instant::now(), name, decoded, pass)
    }

    /// [`Self::run`] for a pass whose preparation (building its image variant) began at
    /// `started`: the report's time covers both.
    pub(crate) fn run_since<T>(
        &mut self,
        started: Instant,
        name: impl Into<String>,
        decoded: impl Fn(&T) -> usize,
        pass: impl FnOnce() -> T,
    ) -> T {
        let out = pass();
        self.passes.push(PassReport {
            name: name.into(),
            ms: started.elapsed().as_secs_f64() * 1e3,
            decoded: decoded(&out),
        });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_deadlines_grow_with_the_image_and_the_effort() {
        let hd = 1920 * 1080;
        let balanced = Effort::Balanced.default_deadline(hd).as_secs_f64() * 1e3;
        assert!((75.0..95.0).contains(&balanced), "{balanced} ms");
        let photo = Effort::Balanced.default_deadline(4032 * 3024).as_secs_f64() * 1e3;
        assert!(photo > 2.0 * balanced, "{photo} ms");
        assert!(Effort::Thorough.default_deadline(hd) > Effort::Balanced.default_deadline(hd));
    }

    #[test]
    fn a_spent_deadline_stops_further_passes_and_says_so() {
        let mut log = PassLog::new(Duration::ZERO);
        let n = log.run("first", |v: &Vec<u8>| v.len(), || vec![1, 2]);
        assert_eq!(n.len(), 2);
        assert!(!log.may_continue());
        assert!(log.budget_exhausted);
        assert_eq!(log.passes.len(), 1);
        assert_eq!(log.passes[0].decoded, 2);
        let mut roomy = PassLog::new(Duration::from_secs(60));
        assert!(roomy.may_continue() && !roomy.budget_exhausted);
    }

    #[test]
    fn a_raised_flag_stops_further_passes_however_roomy_the_deadline() {
        let flag = CancelFlag::new();
        let mut log = PassLog::with_cancel(Duration::from_secs(60), flag.clone());
        assert!(log.may_continue());
        flag.cancel();
        assert!(!log.may_continue());
        assert!(log.cancelled && !log.budget_exhausted);
    }

    #[test]
    fn a_budget_without_a_deadline_takes_the_effort_default() {
        let hd = 1920 * 1080;
        let budget = Budget::new(Effort::Fast, None);
        assert_eq!(budget.deadline_for(hd), Effort::Fast.default_deadline(hd));
        let capped = Budget::new(Effort::Fast, Some(Duration::from_millis(7)));
        assert_eq!(capped.deadline_for(hd), Duration::from_millis(7));
    }
}
