//! The metrics of `GET /v1/stream` sessions: sessions open and refused, frames answered and
//! dropped, the time from a frame's arrival to its answer, and the tracks by status.

use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::{
    counter::Counter,
    family::Family,
    gauge::Gauge,
    histogram::{Histogram, exponential_buckets},
};
use prometheus_client::registry::{Registry, Unit};
use std::time::Duration;

/// Labels of the track gauges and counters.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct StatusLabels {
    /// `new`, `tracking`, `coasting` or `lost`.
    pub status: String,
}

/// The statuses a live track has between frames (a lost one is gone).
pub const LIVE_STATUSES: [&str; 3] = ["new", "tracking", "coasting"];

/// The stream's metrics; cheap to clone (clones share the values).
#[derive(Debug, Clone)]
pub struct StreamMetrics {
    /// Sessions open now.
    pub sessions_open: Gauge,
    /// Sessions closed at once with 1013 because `--max-stream-sessions` were open.
    pub sessions_refused: Counter,
    /// Frames answered (with poses or a problem).
    pub frames_answered: Counter,
    /// Frames dropped unanswered (the client sent faster than the service answered).
    pub frames_dropped: Counter,
    /// Time from a frame's arrival to its answer being sent, seconds.
    pub frame_latency: Histogram,
    /// Live tracks by status after each session's latest frame, over every session.
    pub tracks: Family<StatusLabels, Gauge>,
    /// Tracks lost.
    pub tracks_lost: Counter,
}

impl Default for StreamMetrics {
    fn default() -> Self {
        Self {
            sessions_open: Gauge::default(),
            sessions_refused: Counter::default(),
            frames_answered: Counter::default(),
            frames_dropped: Counter::default(),
            // 1 ms to about 16 s.
            frame_latency: Histogram::new(exponential_buckets(0.001, 2.0, 15)),
            tracks: Family::default(),
            tracks_lost: Counter::default(),
        }
    }
}

impl StreamMetrics {
    /// Registers every metric in `registry`.
    pub fn register(&self, registry: &mut Registry) {
        registry.register(
            "stream_sessions_open",
            "Stream sessions (GET /v1/stream) open now",
            self.sessions_open.clone(),
        );
        registry.register(
            "stream_sessions_refused",
            "Stream sessions closed with 1013 at --max-stream-sessions",
            self.sessions_refused.clone(),
        );
        registry.register(
            "stream_frames_answered",
            "Stream frames answered (poses, or a problem)",
            self.frames_answered.clone(),
        );
        registry.register(
            "stream_frames_dropped",
            "Stream frames dropped unanswered because the client sent faster than they were answered",
            self.frames_dropped.clone(),
        );
        registry.register_with_unit(
            "stream_frame_duration",
            "Time from a stream frame's arrival to its answer",
            Unit::Seconds,
            self.frame_latency.clone(),
        );
        registry.register(
            "stream_tracks",
            "Live tracks by status (new, tracking, coasting) after each session's latest frame",
            self.tracks.clone(),
        );
        registry.register(
            "stream_tracks_lost",
            "Tracks lost (not seen for longer than the coast time)",
            self.tracks_lost.clone(),
        );
    }

    /// Records an answered frame that took `latency` from arrival.
    pub fn answered(&self, latency: Duration) {
        self.frames_answered.inc();
        self.frame_latency.observe(latency.as_secs_f64());
    }

    /// Moves one session's share of the track gauges from `before` to `after` (counts of
    /// [`LIVE_STATUSES`], in that order).
    pub fn tracks_changed(&self, before: [i64; 3], after: [i64; 3]) {
        for ((status, b), a) in LIVE_STATUSES.iter().zip(before).zip(after) {
            if a != b {
                self.tracks
                    .get_or_create(&StatusLabels {
                        status: (*status).to_owned(),
                    })
                    .inc_by(a - b);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_session_s_tracks_move_the_gauges_by_the_difference() {
        let m = StreamMetrics::default();
        m.tracks_changed([0, 0, 0], [1, 2, 0]);
        m.tracks_changed([1, 2, 0], [0, 2, 1]);
        let value = |s: &str| {
            m.tracks
                .get_or_create(&StatusLabels {
                    status: s.to_owned(),
                })
                .get()
        };
        assert_eq!(
            (value("new"), value("tracking"), value("coasting")),
            (0, 2, 1)
        );
        m.tracks_changed([0, 2, 1], [0, 0, 0]);
        assert_eq!(value("tracking") + value("coasting"), 0);
    }
}
