//! Tests of the connection phases and the accept loop's helpers.

use super::*;

#[test]
fn accept_backoff_doubles_to_a_second_and_resets() {
    let mut backoff = AcceptBackoff::default();
    let error = io::Error::other("too many open files");
    let pauses: Vec<u128> = (0..12)
        .map(|_| backoff.failed(&error).as_millis())
        .collect();
    assert_eq!(
        pauses,
        [5, 10, 20, 40, 80, 160, 320, 640, 1000, 1000, 1000, 1000]
    );
    backoff.succeeded();
    assert_eq!(backoff.failed(&error), ACCEPT_BACKOFF_MIN);
}

#[test]
fn deadlines_follow_the_phase() {
    let limits = ConnectionLimits {
        header_read_timeout: Duration::from_secs(2),
        idle_timeout: Duration::from_secs(7),
        max_connections: 1,
        shutdown_grace: Duration::ZERO,
    };
    let t = Instant::now();
    let cases = [
        (
            Phase::Fresh { since: t },
            Some((t + Duration::from_secs(2), CloseReason::HeaderTimeout)),
        ),
        (
            Phase::Head { since: t },
            Some((t + Duration::from_secs(2), CloseReason::HeaderTimeout)),
        ),
        (
            Phase::Idle { since: t },
            Some((t + Duration::from_secs(7), CloseReason::IdleTimeout)),
        ),
        (Phase::Busy { requests: 1 }, None),
    ];
    for (phase, want) in cases {
        assert_eq!(phase.deadline(&limits), want, "{phase:?}");
    }
}

#[test]
fn the_longest_waiting_connection_is_evicted_never_a_busy_one() {
    let registry = Arc::new(Registry::default());
    let t = Instant::now();
    let phase = |p: Phase| Arc::new(Activity(Mutex::new(p)));
    let busy = registry.add(phase(Phase::Busy { requests: 1 }));
    let old = registry.add(phase(Phase::Idle { since: t }));
    let new = registry.add(phase(Phase::Head {
        since: t + Duration::from_secs(1),
    }));
    assert!(registry.evict_longest_waiting());
    assert!(old.evict.is_cancelled());
    assert!(!busy.evict.is_cancelled() && !new.evict.is_cancelled());
    assert!(registry.evict_longest_waiting());
    assert!(new.evict.is_cancelled());
    assert!(!registry.evict_longest_waiting(), "only a busy one is left");
    assert!(!busy.evict.is_cancelled());
    drop((old, new));
    assert_eq!(registry.lock().len(), 1);
}
