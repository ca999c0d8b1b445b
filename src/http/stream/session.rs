//! One stream session: the WebSocket's reader, the frames waiting in order, the worker that
//! answers them, and the writer (docs/stream.md).
//!
//! - **Reader.** A text message is the next frame's meta (`frame_id`, `capture_time_ms`,
//!   `prior`); a binary message is a frame. A text message that cannot be used is answered
//!   by its problem in its place in the order, and the session goes on. Nothing received for
//!   the idle time closes the session (1008); so does a message over the size limit (1008).
//! - **Waiting frames.** At most `--stream-frames-in-flight` frames are received and not
//!   answered, the one being worked on included; a frame beyond that drops the oldest one
//!   still waiting (never the one being worked on, never itself). Each answer counts the
//!   frames dropped since the previous one (`frame.dropped_before`).
//! - **Worker.** Frames are answered one at a time, in order, each on an estimation worker
//!   behind the service's queue and pixel budget (a full queue answers that frame with 503
//!   `overloaded`; the session goes on). The session's tracks live between frames in the
//!   [`TrackSession`].
//! - **Close.** The client's close ends the session (1000). A shutdown closes it with 1001
//!   once the frame being worked on is answered. A session over `--max-stream-sessions` is
//!   closed at once with 1013.

use super::super::state::AppState;
use crate::api::problem::{ErrorCode, Problem, parse_json};
use crate::api::refusal::problem_from_image_error;
use crate::api::stream::{FrameDto, FrameIdDto, FrameMetaDto, FrameProblem, StreamAnswer};
use crate::app::admission_pixels;
use crate::app::{FrameIn, TrackSession};
use crate::http::metrics::StreamMetrics;
use axum::body::Bytes;
use axum::extract::ws::{CloseFrame, Message, Utf8Bytes, WebSocket, close_code};
use futures_util::{SinkExt, StreamExt};
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;
use tokio::sync::{Notify, mpsc};

/// Close code 1013: try again later (RFC 6455 §7.4.2, IANA registry).
pub const CLOSE_TRY_AGAIN_LATER: u16 = 1013;

/// What waits to be answered, in order.
#[derive(Debug)]
enum Item {
    /// A frame.
    Frame(Box<Frame>),
    /// A text message that could not be used: its problem, answered in its place.
    Refused(Box<FrameProblem>),
}

/// A frame received.
#[derive(Debug)]
struct Frame {
    index: u64,
    id: Option<FrameIdDto>,
    capture_time_ms: f64,
    prior: Option<crate::api::frames::PriorDto>,
    flange_pose: Option<crate::api::robot::RobotPoseDto>,
    bytes: Bytes,
    received: Instant,
}

/// The items waiting, shared by the reader and the worker.
#[derive(Debug, Default)]
struct Waiting {
    items: Mutex<Queue>,
    ready: Notify,
}

#[derive(Debug, Default)]
struct Queue {
    items: VecDeque<Item>,
    /// A frame is being worked on.
    working: bool,
    /// Frames dropped since the last answer.
    dropped: u64,
    /// The reader has ended: answer what waits, then stop.
    closed: bool,
}

impl Waiting {
    fn lock(&self) -> std::sync::MutexGuard<'_, Queue> {
        self.items.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Queues `item`; a frame beyond `in_flight` unanswered frames drops the oldest waiting
    /// one. Returns how many were dropped.
    fn push(&self, item: Item, in_flight: usize) -> u64 {
        let mut q = self.lock();
        q.items.push_back(item);
        let mut dropped = 0;
        loop {
            let frames = q
                .items
                .iter()
                .filter(|i| matches!(i, Item::Frame(_)))
                .count();
            if frames + usize::from(q.working) <= in_flight {
                break;
            }
            // The oldest waiting frame other than the one just queued.
            let newest = q.items.len() - 1;
            let Some(oldest) = q
                .items
                .iter()
                .take(newest)
                .position(|i| matches!(i, Item::Frame(_)))
            else {
                break;
            };
            q.items.remove(oldest);
            q.dropped += 1;
            dropped += 1;
        }
        drop(q);
        self.ready.notify_one();
        dropped
    }

    /// The next item and the frames dropped before it, or `None` once the reader has ended
    /// and nothing waits.
    async fn pop(&self) -> Option<(Item, u64)> {
        loop {
            {
                let mut q = self.lock();
                if let Some(item) = q.items.pop_front() {
                    q.working = matches!(item, Item::Frame(_));
                    let dropped = std::mem::take(&mut q.dropped);
                    return Some((item, dropped));
                }
                if q.closed {
                    return None;
                }
            }
            self.ready.notified().await;
        }
    }

    fn done(&self) {
        self.lock().working = false;
    }

    fn close(&self) {
        self.lock().closed = true;
        self.ready.notify_one();
    }
}

/// What the writer sends.
#[derive(Debug)]
enum Outgoing {
    Text(String),
    Close(u16, &'static str),
}

/// Runs one session on `socket` until it closes.
pub async fn run(socket: WebSocket, session: TrackSession, state: AppState) {
    let metrics = state.metrics.stream();
    let (sink, source) = socket.split();
    let (out, outgoing) = mpsc::channel::<Outgoing>(4);
    let writer = tokio::spawn(write(sink, outgoing));
    let Some(place) = state.streams.try_open() else {
        metrics.sessions_refused.inc();
        let _ = out
            .send(Outgoing::Close(CLOSE_TRY_AGAIN_LATER, "too many sessions"))
            .await;
        drop(out);
        let _ = writer.await;
        return;
    };
    metrics.sessions_open.inc();
    let waiting = Arc::new(Waiting::default());
    let worker = tokio::spawn(answer_frames(
        Arc::clone(&waiting),
        session,
        state.clone(),
        out.clone(),
    ));
    let close = read(source, &waiting, &state).await;
    waiting.close();
    // The frame being worked on (and what waits) is answered before the close frame.
    let _ = worker.await;
    if let Some((code, reason)) = close {
        let _ = out.send(Outgoing::Close(code, reason)).await;
    }
    drop(out);
    let _ = writer.await;
    metrics.sessions_open.dec();
    drop(place);
}

/// Sends what the session answers, in order; ends after a close frame or when every sender
/// is gone.
async fn write(
    mut sink: futures_util::stream::SplitSink<WebSocket, Message>,
    mut outgoing: mpsc::Receiver<Outgoing>,
) {
    while let Some(message) = outgoing.recv().await {
        let (message, last) = match message {
            Outgoing::Text(json) => (Message::Text(Utf8Bytes::from(json)), false),
            Outgoing::Close(code, reason) => (
                Message::Close(Some(CloseFrame {
                    code,
                    reason: Utf8Bytes::from_static(reason),
                })),
                true,
            ),
        };
        if sink.send(message).await.is_err() || last {
            break;
        }
    }
    let _ = sink.close().await;
}

/// Reads messages until the client closes, a limit is hit or a shutdown begins; returns the
/// close code and reason to send, if the session (not the client) closes it.
async fn read(
    mut source: futures_util::stream::SplitStream<WebSocket>,
    waiting: &Waiting,
    state: &AppState,
) -> Option<(u16, &'static str)> {
    let limits = state.settings.stream;
    let metrics = state.metrics.stream();
    let opened = Instant::now();
    let mut next_index: u64 = 0;
    let mut meta: Option<FrameMetaDto> = None;
    loop {
        let message = tokio::select! {
            () = state.lifecycle.shutdown().cancelled() => {
                return Some((close_code::AWAY, "server shutting down"));
            }
            message = tokio::time::timeout(limits.idle_timeout, source.next()) => message,
        };
        let message = match message {
            Err(_) => return Some((close_code::POLICY, "idle for too long")),
            Ok(None | Some(Ok(Message::Close(_)))) => return None,
            Ok(Some(Err(e))) => {
                tracing::debug!(error = %e, "stream message refused");
                return Some((close_code::POLICY, "message too large or malformed"));
            }
            Ok(Some(Ok(message))) => message,
        };
        match message {
            Message::Text(text) => match parse_json::<FrameMetaDto>(text.as_bytes()) {
                Ok(m) => meta = Some(m),
                Err(problem) => {
                    let frame = frame_dto(next_index, None, f64::NAN, 0);
                    let refused = FrameProblem { frame, problem };
                    waiting.push(Item::Refused(Box::new(refused)), limits.frames_in_flight);
                }
            },
            Message::Binary(bytes) => {
                let m = meta.take().unwrap_or_default();
                let received = Instant::now();
                let capture_time_ms = m
                    .capture_time_ms
                    .unwrap_or_else(|| received.duration_since(opened).as_secs_f64() * 1e3);
                let frame = Frame {
                    index: next_index,
                    id: m.frame_id,
                    capture_time_ms,
                    prior: m.prior,
                    flange_pose: m.flange_pose,
                    bytes,
                    received,
                };
                next_index += 1;
                let dropped = waiting.push(Item::Frame(Box::new(frame)), limits.frames_in_flight);
                metrics.frames_dropped.inc_by(dropped);
            }
            Message::Ping(_) | Message::Pong(_) => {}
            Message::Close(_) => return None,
        }
    }
}

/// The frame's identity in its answer.
fn frame_dto(index: u64, id: Option<FrameIdDto>, capture_time_ms: f64, dropped: u64) -> FrameDto {
    FrameDto {
        index,
        id,
        capture_time_ms: if capture_time_ms.is_finite() {
            capture_time_ms
        } else {
            0.0
        },
        dropped_before: dropped,
    }
}

/// Answers the waiting items one at a time, in order, until the reader has ended and
/// nothing waits.
async fn answer_frames(
    waiting: Arc<Waiting>,
    session: TrackSession,
    state: AppState,
    out: mpsc::Sender<Outgoing>,
) {
    let metrics = state.metrics.stream();
    let session = Arc::new(Mutex::new(session));
    let mut tracks_before = [0i64; 3];
    while let Some((item, dropped)) = waiting.pop().await {
        let (json, received) = match item {
            Item::Refused(mut refused) => {
                refused.frame.dropped_before = dropped;
                (to_json(&*refused), Instant::now())
            }
            Item::Frame(frame) => {
                let received = frame.received;
                let (json, counts) =
                    answer_frame(*frame, dropped, &session, &state, &metrics).await;
                if let Some(counts) = counts {
                    metrics.tracks_changed(tracks_before, counts);
                    tracks_before = counts;
                }
                (json, received)
            }
        };
        waiting.done();
        if out.send(Outgoing::Text(json)).await.is_err() {
            break;
        }
        metrics.answered(received.elapsed());
    }
    metrics.tracks_changed(tracks_before, [0; 3]);
}

/// Answers one frame on an estimation worker: its JSON, and the session's live tracks by
/// status after it (none for a refused frame).
async fn answer_frame(
    frame: Frame,
    dropped: u64,
    session: &Arc<Mutex<TrackSession>>,
    state: &AppState,
    metrics: &StreamMetrics,
) -> (String, Option<[i64; 3]>) {
    let frame_answer = frame_dto(
        frame.index,
        frame.id.clone(),
        frame.capture_time_ms,
        dropped,
    );
    let prior = match frame
        .prior
        .as_ref()
        .map(crate::api::frames::PriorDto::validate)
    {
        Some(Err(problem)) => return (refused(frame_answer, problem), None),
        Some(Ok(p)) => Some(p),
        None => None,
    };
    let flange = match frame
        .flange_pose
        .as_ref()
        .map(|pose| pose.to_rigid("/flange_pose"))
    {
        Some(Err(problem)) => return (refused(frame_answer, problem), None),
        Some(Ok(f)) => Some(f),
        None => None,
    };
    let max_pixels = state.settings.max_image_pixels;
    let pixels = admission_pixels(&frame.bytes, max_pixels);
    let session = Arc::clone(session);
    let job_frame = frame_answer.clone();
    let job = move |cancel| {
        let mut session = session.lock().unwrap_or_else(PoisonError::into_inner);
        let input = FrameIn {
            bytes: &frame.bytes,
            capture_time_ms: frame.capture_time_ms,
            prior,
            flange,
        };
        match session.frame(&input, cancel) {
            Ok(answer) => {
                let setup = &session.setup().image;
                let dto = StreamAnswer::from_answer(&answer, setup, job_frame);
                (to_json(&dto), Some((live_counts(&dto), lost_count(&dto))))
            }
            Err(e) => (refused(job_frame, problem_from_image_error(&e)), None),
        }
    };
    match state.queue.run_image(pixels, job).await {
        Ok((json, Some((counts, lost)))) => {
            metrics.tracks_lost.inc_by(lost);
            (json, Some(counts))
        }
        Ok((json, None)) => (json, None),
        Err(refusal) => (refused(frame_answer, refusal.problem().clone()), None),
    }
}

/// The live tracks of an answer by status: new, tracking, coasting.
fn live_counts(answer: &StreamAnswer) -> [i64; 3] {
    use crate::api::stream::TrackStatusDto as S;
    let count = |s: S| {
        i64::try_from(answer.tracks.iter().filter(|t| t.status == s).count()).unwrap_or(i64::MAX)
    };
    [count(S::New), count(S::Tracking), count(S::Coasting)]
}

/// The tracks an answer reports lost.
fn lost_count(answer: &StreamAnswer) -> u64 {
    let lost = answer
        .tracks
        .iter()
        .filter(|t| t.status == crate::api::stream::TrackStatusDto::Lost)
        .count();
    u64::try_from(lost).unwrap_or(u64::MAX)
}

/// The JSON of a refused frame.
fn refused(frame: FrameDto, problem: Problem) -> String {
    to_json(&FrameProblem { frame, problem })
}

/// `value` as JSON; a value that cannot be serialised (none of ours) is answered as 500
/// `internal`.
fn to_json<T: serde::Serialize>(value: &T) -> String {
    serde_json::to_string(value).unwrap_or_else(|e| {
        tracing::error!(error = %e, "a stream answer could not be serialised");
        let problem = Problem::new(ErrorCode::Internal, "the answer could not be serialised");
        serde_json::to_string(&problem).unwrap_or_default()
    })
}
