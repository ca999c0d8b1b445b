//! Tests of the estimation queue: admission, cancellation, the pixel and body budgets.

use super::*;
use crate::api::problem::ErrorCode;
use std::sync::mpsc;
use std::time::Duration;

const PATIENCE: Duration = Duration::from_secs(20);

async fn until(what: &str, queue: &EstimationQueue, want: (usize, usize)) {
    let waited = tokio::time::timeout(PATIENCE, async {
        loop {
            let o = queue.occupancy();
            if (o.running, o.waiting) == want {
                return;
            }
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
    })
    .await;
    assert!(waited.is_ok(), "never reached {want:?}: {what}");
}

/// A job that runs until the returned sender sends (or is dropped).
fn gate() -> (mpsc::Sender<()>, impl FnOnce() + Send + 'static) {
    let (open, gate) = mpsc::channel::<()>();
    (open, move || {
        let _ = gate.recv();
    })
}

#[tokio::test]
async fn refuses_at_once_when_running_and_waiting_fill_the_capacity() {
    let queue = EstimationQueue::new(1, 1, QueueMetrics::default()).expect("threads");
    let (open_running, running) = gate();
    let (open_waiting, waiting) = gate();
    let first = tokio::spawn({
        let queue = queue.clone();
        async move { queue.run(running).await }
    });
    until("one running", &queue, (1, 0)).await;
    let second = tokio::spawn({
        let queue = queue.clone();
        async move { queue.run(waiting).await }
    });
    until("one waiting", &queue, (1, 1)).await;

    let refused = queue.run(|| ()).await.expect_err("full");
    assert_eq!(refused.code(), ErrorCode::Overloaded);

    open_running.send(()).expect("the first job waits");
    first.await.expect("task").expect("first job");
    open_waiting.send(()).expect("the second job waits");
    second.await.expect("task").expect("second job");
    until("empty", &queue, (0, 0)).await;
    assert_eq!(queue.run(|| 7).await.expect("room again"), 7);
}

#[tokio::test]
async fn a_job_whose_request_gave_up_is_dropped_unrun() {
    let queue = EstimationQueue::new(1, 1, QueueMetrics::default()).expect("threads");
    let (open, blocker) = gate();
    let blocked = tokio::spawn({
        let queue = queue.clone();
        async move { queue.run(blocker).await }
    });
    until("one running", &queue, (1, 0)).await;
    let ran = Arc::new(AtomicUsize::new(0));
    let abandoned = {
        let ran = Arc::clone(&ran);
        queue.run(move || ran.fetch_add(1, Ordering::Relaxed))
    };
    let gave_up = tokio::time::timeout(Duration::from_millis(20), abandoned).await;
    assert!(gave_up.is_err(), "the job could not have run yet");

    open.send(()).expect("the blocker waits");
    blocked.await.expect("task").expect("blocker");
    until("empty", &queue, (0, 0)).await;
    assert_eq!(queue.run(|| ()).await.ok(), Some(()));
    assert_eq!(
        ran.load(Ordering::Relaxed),
        0,
        "the abandoned job never ran"
    );
}

#[tokio::test]
async fn a_panicking_job_is_a_500_and_the_worker_lives_on() {
    let queue = EstimationQueue::new(1, 0, QueueMetrics::default()).expect("threads");
    let err = queue
        .run(|| -> u8 { panic!("secret detail") })
        .await
        .expect_err("a panic");
    assert_eq!(err.code(), ErrorCode::Internal);
    assert!(!err.problem().detail.contains("secret"));
    assert_eq!(queue.run(|| 1).await.expect("the worker lives on"), 1);
}

#[tokio::test]
async fn a_request_that_gives_up_while_its_job_runs_cancels_the_detection() {
    let queue = EstimationQueue::new(1, 0, QueueMetrics::default()).expect("threads");
    let (seen, saw) = mpsc::channel::<Duration>();
    let (running, has_run) = tokio::sync::oneshot::channel::<std::time::Instant>();
    let job = move |cancel: crate::app::CancelFlag| {
        let started = std::time::Instant::now();
        let _ = running.send(started);
        // Stands for detection: a pass, then the check before the next one.
        while !cancel.is_cancelled() {
            std::thread::sleep(Duration::from_millis(1));
            assert!(started.elapsed() < PATIENCE, "never cancelled");
        }
        let _ = seen.send(started.elapsed());
    };
    // Boxed, so that the timeout below takes it and drops it (the cancellation) when it
    // gives up.
    let mut run = Box::pin(queue.run_cancellable(job));
    // Give up only once the job runs (on a loaded machine a worker may take a while to
    // pick it up, and a job given up before it starts is dropped unrun, another case).
    let started = tokio::select! {
        _ = &mut run => panic!("the job ended by itself"),
        started = has_run => started.expect("the job started"),
    };
    let gave_up = tokio::time::timeout(Duration::from_millis(50), run).await;
    assert!(gave_up.is_err(), "the job runs until cancelled");
    let given_up_after = started.elapsed();
    let after = saw
        .recv_timeout(PATIENCE)
        .expect("the job saw the cancellation");
    assert!(after >= Duration::from_millis(50), "{after:?}");
    assert!(after <= given_up_after + PATIENCE, "{after:?}");
    until("the worker is free again", &queue, (0, 0)).await;
    assert_eq!(queue.run(|| 3).await.expect("the worker takes new work"), 3);
}

#[tokio::test]
async fn image_jobs_beyond_the_pixel_budget_are_refused_at_once() {
    let queue = EstimationQueue::new(2, 4, QueueMetrics::default())
        .expect("threads")
        .with_pixel_budget(1_000);
    let (open, big) = gate();
    let running = tokio::spawn({
        let queue = queue.clone();
        async move { queue.run_image(700, |_| big()).await }
    });
    until("one running", &queue, (1, 0)).await;
    let refused = queue
        .run_image(400, |_| ())
        .await
        .expect_err("700 + 400 > 1000");
    assert_eq!(refused.code(), ErrorCode::Overloaded);
    assert!(refused.problem().detail.contains("max-inflight-pixels"));
    assert_eq!(queue.run_image(300, |_| 1).await.expect("700 + 300 fit"), 1);
    assert_eq!(
        queue.run_image(5_000, |_| 2).await.ok(),
        None,
        "still 700 held"
    );
    open.send(()).expect("the big job waits");
    running.await.expect("task").expect("big job");
    assert_eq!(
        queue
            .run_image(5_000, |_| 2)
            .await
            .expect("alone, a job over the budget runs"),
        2
    );
}

#[tokio::test]
async fn body_bytes_are_held_until_the_permit_drops() {
    let queue = EstimationQueue::new(1, 0, QueueMetrics::default())
        .expect("threads")
        .with_body_budget(100);
    let first = queue.take_body_bytes(60).expect("60 of 100");
    let refused = queue.take_body_bytes(50).expect_err("60 + 50 > 100");
    assert_eq!(refused.code(), ErrorCode::Overloaded);
    assert!(refused.problem().detail.contains("max-inflight-body-bytes"));
    drop(first);
    let _second = queue.take_body_bytes(50).expect("freed");
}
