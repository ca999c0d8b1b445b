//! The limits of `GET /v1/stream` sessions (docs/stream.md, Limits): how many at once, how
//! long one may stay silent, and how many frames of one may wait. The largest message is the
//! body limit (`--body-limit-bytes`), as for a photo.

use super::{ConfigError, in_range};
use clap::Args;
use std::time::Duration;

/// Default number of stream sessions open at once; one more is closed with 1013.
pub const DEFAULT_MAX_STREAM_SESSIONS: usize = 64;
/// Largest accepted session limit.
pub const MAX_MAX_STREAM_SESSIONS: usize = 100_000;
/// Default time a session may send nothing, ms (then it is closed with 1008): a camera at
/// 1 fps stays well inside it.
pub const DEFAULT_STREAM_IDLE_TIMEOUT_MS: u64 = 30_000;
/// Largest accepted idle time, ms (1 hour).
pub const MAX_STREAM_IDLE_TIMEOUT_MS: u64 = 3_600_000;
/// Default number of a session's frames received but not answered, the one being worked on
/// included: at two, the next frame waits while one is worked on, and a third drops the
/// oldest waiting one (answers stay current when the client sends faster than the service).
pub const DEFAULT_STREAM_FRAMES_IN_FLIGHT: usize = 2;
/// Largest accepted frames in flight per session.
pub const MAX_STREAM_FRAMES_IN_FLIGHT: usize = 64;

/// The flags of the stream's limits (part of `qrpose serve`).
#[derive(Debug, Clone, Args)]
pub struct StreamArgs {
    /// Stream sessions (`GET /v1/stream`) open at once; one more is closed with 1013 (try
    /// again later).
    #[arg(long, env = "QRPOSE_MAX_STREAM_SESSIONS", default_value_t = DEFAULT_MAX_STREAM_SESSIONS)]
    pub max_stream_sessions: usize,
    /// Time a stream session may send nothing, ms; then it is closed with 1008.
    #[arg(long, env = "QRPOSE_STREAM_IDLE_TIMEOUT_MS", default_value_t = DEFAULT_STREAM_IDLE_TIMEOUT_MS)]
    pub stream_idle_timeout_ms: u64,
    /// A session's frames received and not yet answered, at most; a frame beyond it drops the
    /// oldest one waiting (counted in the next answer's `frame.dropped_before`).
    #[arg(long, env = "QRPOSE_STREAM_FRAMES_IN_FLIGHT", default_value_t = DEFAULT_STREAM_FRAMES_IN_FLIGHT)]
    pub stream_frames_in_flight: usize,
}

impl Default for StreamArgs {
    fn default() -> Self {
        Self {
            max_stream_sessions: DEFAULT_MAX_STREAM_SESSIONS,
            stream_idle_timeout_ms: DEFAULT_STREAM_IDLE_TIMEOUT_MS,
            stream_frames_in_flight: DEFAULT_STREAM_FRAMES_IN_FLIGHT,
        }
    }
}

/// The validated limits of stream sessions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamSettings {
    /// Sessions open at once.
    pub max_sessions: usize,
    /// Time a session may send nothing.
    pub idle_timeout: Duration,
    /// A session's frames received and not answered, at most (at least 1).
    pub frames_in_flight: usize,
}

impl Default for StreamSettings {
    fn default() -> Self {
        Self {
            max_sessions: DEFAULT_MAX_STREAM_SESSIONS,
            idle_timeout: Duration::from_millis(DEFAULT_STREAM_IDLE_TIMEOUT_MS),
            frames_in_flight: DEFAULT_STREAM_FRAMES_IN_FLIGHT,
        }
    }
}

impl TryFrom<&StreamArgs> for StreamSettings {
    type Error = ConfigError;

    fn try_from(args: &StreamArgs) -> Result<Self, ConfigError> {
        Ok(Self {
            max_sessions: in_range(
                "max-stream-sessions",
                args.max_stream_sessions,
                1,
                MAX_MAX_STREAM_SESSIONS,
            )?,
            idle_timeout: Duration::from_millis(in_range(
                "stream-idle-timeout-ms",
                args.stream_idle_timeout_ms,
                1,
                MAX_STREAM_IDLE_TIMEOUT_MS,
            )?),
            frames_in_flight: in_range(
                "stream-frames-in-flight",
                args.stream_frames_in_flight,
                1,
                MAX_STREAM_FRAMES_IN_FLIGHT,
            )?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_validate_and_every_limit_is_range_checked() {
        let valid = StreamSettings::try_from(&StreamArgs::default()).expect("defaults");
        assert_eq!(valid, StreamSettings::default());
        let cases = [
            StreamArgs {
                max_stream_sessions: 0,
                ..StreamArgs::default()
            },
            StreamArgs {
                stream_idle_timeout_ms: 0,
                ..StreamArgs::default()
            },
            StreamArgs {
                stream_frames_in_flight: MAX_STREAM_FRAMES_IN_FLIGHT + 1,
                ..StreamArgs::default()
            },
        ];
        let flags: Vec<&str> = cases
            .iter()
            .map(|args| StreamSettings::try_from(args).expect_err("refused").flag)
            .collect();
        assert_eq!(
            flags,
            [
                "max-stream-sessions",
                "stream-idle-timeout-ms",
                "stream-frames-in-flight"
            ]
        );
    }
}
