//! `spawn_app()`: the service on `127.0.0.1:0` in this test's runtime, and a client for it.

use qrpose::api::problem::operations::Operation;
use qrpose::api::problem::{ErrorCode, Problem};
use qrpose::config::{LogFormat, Settings};
use qrpose::geometry::{camera::Camera, euler::EulerXyz, marker::Marker};
use qrpose::http::{self, AppState};
use qrpose_sim::render::{EcLevel, Effects, Encoding, Rendered, Scene, render};
use reqwest::{Response, StatusCode, header};
use serde_json::{Value, json};
use std::future::Future;
use std::sync::LazyLock;
use std::time::Duration;
use tokio::task::JoinHandle;
use tokio_util::sync::CancellationToken;

/// Set `TEST_LOG=1` to see the service's logs in a failing test's output.
static TRACING: LazyLock<()> = LazyLock::new(|| {
    if std::env::var_os("TEST_LOG").is_some() {
        qrpose::telemetry::init_with_writer(LogFormat::Text, std::io::stdout, false)
            .expect("the only subscriber");
    }
});

/// How long a test waits for a condition that must come true before declaring it never did.
pub const PATIENCE: Duration = Duration::from_secs(20);

/// A running service.
pub struct TestApp {
    /// `http://127.0.0.1:PORT`.
    pub address: String,
    /// A client without proxies.
    pub client: reqwest::Client,
    /// The server's state: its queue, metrics and lifecycle.
    pub state: AppState,
    shutdown: CancellationToken,
    server: JoinHandle<std::io::Result<()>>,
}

/// The service with default settings.
pub async fn spawn_app() -> TestApp {
    spawn_app_with(Settings::default()).await
}

/// The service with `settings` (its `addr` is ignored: the app binds `127.0.0.1:0`).
pub async fn spawn_app_with(settings: Settings) -> TestApp {
    LazyLock::force(&TRACING);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("a free port");
    let address = format!("http://{}", listener.local_addr().expect("a bound address"));
    let state = AppState::new(settings).expect("state");
    let shutdown = CancellationToken::new();
    let server = tokio::spawn(http::serve(
        listener,
        state.clone(),
        shutdown.clone().cancelled_owned(),
    ));
    crate::support::tls_provider();
    let client = reqwest::Client::builder()
        .no_proxy()
        .build()
        .expect("a client");
    TestApp {
        address,
        client,
        state,
        shutdown,
        server,
    }
}

impl TestApp {
    /// `GET path`.
    pub async fn get(&self, path: &str) -> Response {
        self.client
            .get(format!("{}{path}", self.address))
            .send()
            .await
            .expect("the server answers")
    }

    /// `method path` without a body.
    pub async fn request(&self, method: reqwest::Method, path: &str) -> Response {
        self.client
            .request(method, format!("{}{path}", self.address))
            .send()
            .await
            .expect("the server answers")
    }

    /// `POST /v1/pose/corners` with a JSON body.
    pub async fn post_corners(&self, body: &Value) -> Response {
        self.client
            .post(format!("{}/v1/pose/corners", self.address))
            .json(body)
            .send()
            .await
            .expect("the server answers")
    }

    /// `POST /v1/pose/corners` with raw bytes and an optional content type.
    pub async fn post_corners_raw(&self, body: Vec<u8>, content_type: Option<&str>) -> Response {
        let mut request = self
            .client
            .post(format!("{}/v1/pose/corners", self.address))
            .body(body);
        if let Some(content_type) = content_type {
            request = request.header(header::CONTENT_TYPE, content_type);
        }
        request.send().await.expect("the server answers")
    }

    /// `POST /v1/pose/image?QUERY` with a raw body and an optional content type (`query`
    /// without the `?`; empty for none).
    pub async fn post_image(
        &self,
        query: &str,
        body: Vec<u8>,
        content_type: Option<&str>,
    ) -> Response {
        let mut url = format!("{}/v1/pose/image", self.address);
        if !query.is_empty() {
            url = format!("{url}?{query}");
        }
        let mut request = self.client.post(url).body(body);
        if let Some(content_type) = content_type {
            request = request.header(header::CONTENT_TYPE, content_type);
        }
        request.send().await.expect("the server answers")
    }

    /// `POST /v1/pose/image` with a multipart body built by [`multipart_body`].
    pub async fn post_image_multipart(&self, body: Vec<u8>) -> Response {
        self.post_image(
            "",
            body,
            Some(&format!("multipart/form-data; boundary={BOUNDARY}")),
        )
        .await
    }

    /// Sends a request that goes through the estimation queue ([`blank_png`] to the image
    /// endpoint; corners requests run inline) from a task of its own, for a test that must
    /// act while the request waits or runs.
    pub fn post_queued_in_background(&self) -> JoinHandle<reqwest::Result<Response>> {
        let request = self
            .client
            .post(format!("{}/v1/pose/image?{PHOTO_QUERY}", self.address))
            .header(header::CONTENT_TYPE, "image/png")
            .body(blank_png());
        tokio::spawn(request.send())
    }

    /// Sends a request that goes through the estimation queue (see
    /// [`TestApp::post_queued_in_background`]) and waits for the answer.
    pub async fn post_queued(&self) -> Response {
        self.post_queued_in_background()
            .await
            .expect("the task")
            .expect("the server answers")
    }

    /// Panics unless a valid corners request is answered 200.
    pub async fn assert_serves_corners(&self, after: &str) {
        let status = self.post_corners(&valid_request()).await.status();
        assert_eq!(status, StatusCode::OK, "corners after {after}");
    }

    /// `GET /healthz`.
    pub async fn healthz(&self) -> Response {
        self.get("/healthz").await
    }

    /// Panics unless `/healthz` answers 200.
    pub async fn assert_up(&self, after: &str) {
        let status = self.healthz().await.status();
        assert_eq!(status, StatusCode::OK, "healthz after {after}");
    }

    /// Starts a graceful shutdown, as SIGTERM does.
    pub fn trigger_shutdown(&self) {
        self.shutdown.cancel();
    }

    /// Waits for the server to stop after [`TestApp::trigger_shutdown`].
    pub async fn stopped(self) -> std::io::Result<()> {
        tokio::time::timeout(PATIENCE, self.server)
            .await
            .expect("the server stops within the test's patience")
            .expect("the server task does not panic")
    }
}

/// Waits until `condition` holds, checking every few milliseconds; panics after [`PATIENCE`].
pub async fn eventually<F, Fut>(what: &str, mut condition: F)
where
    F: FnMut() -> Fut,
    Fut: Future<Output = bool>,
{
    let waited = tokio::time::timeout(PATIENCE, async {
        while !condition().await {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await;
    assert!(waited.is_ok(), "never happened: {what}");
}

/// Asserts a problem+json answer with this status and code, and returns the document.
pub async fn assert_problem(response: Response, status: u16, code: ErrorCode) -> Problem {
    let context = format!("{} {}", response.url().path(), response.status());
    // Every refusal the tests see is one the document lists for its operation.
    if status == 422
        && let Some(operation) = Operation::of_path(response.url().path())
    {
        assert!(
            operation.unprocessable().contains(&code),
            "{context}: {code:?} is not in the document's list for {operation:?}"
        );
    }
    assert_eq!(response.status().as_u16(), status, "{context}");
    assert_eq!(
        response.headers()[header::CONTENT_TYPE],
        "application/problem+json",
        "{context}"
    );
    assert!(
        response.headers().contains_key("x-request-id"),
        "{context}: no x-request-id"
    );
    let problem: Problem = response.json().await.expect("a problem document");
    assert_eq!(problem.code, code, "{context}: {problem:?}");
    assert_eq!(problem.status, status, "{context}");
    assert_eq!(
        problem.type_uri,
        format!("urn:qrpose:problem:{}", code.as_str())
    );
    assert!(!problem.title.is_empty() && !problem.detail.is_empty());
    problem
}

/// A valid corners request: a 50 mm code about half a metre in front of a 1280x720 camera.
pub fn valid_request() -> Value {
    json!({
        "corners_px": [[589.2, 309.8], [689.9, 311.4], [688.1, 411.6], [588.0, 409.5]],
        "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
        "marker": {"size_mm": 50.0}
    })
}

/// A 32x32 white PNG: an image request that the estimation queue runs in a few ms and that
/// is answered 200 with no markers.
pub fn blank_png() -> Vec<u8> {
    let image = image::GrayImage::from_pixel(32, 32, image::Luma([255u8]));
    let mut out = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .expect("a PNG encodes");
    out
}

/// One estimation worker held busy by the test until [`Gate::release`] (or drop).
pub struct Gate {
    open: std::sync::mpsc::Sender<()>,
    job: JoinHandle<Result<(), qrpose::http::error::ApiError>>,
}

impl Gate {
    /// Lets the job finish and waits for it.
    pub async fn release(self) {
        self.open.send(()).expect("the job is waiting for the gate");
        self.job
            .await
            .expect("the job's task")
            .expect("the job ran");
    }
}

/// Takes one estimation worker through the server's own queue: a job that waits for the
/// test. Returns once the job runs.
pub async fn occupy_worker(app: &TestApp) -> Gate {
    let (open, gate) = std::sync::mpsc::channel::<()>();
    let queue = app.state.queue.clone();
    let running_before = queue.occupancy().running;
    let job = tokio::spawn({
        let queue = queue.clone();
        async move {
            queue
                .run(move || {
                    let _ = gate.recv();
                })
                .await
        }
    });
    eventually("the test's job runs", || {
        let running = queue.occupancy().running;
        async move { running == running_before + 1 }
    })
    .await;
    Gate { open, job }
}

/// Waits until the queue has `running` jobs running and `waiting` waiting.
pub async fn queue_reaches(app: &TestApp, running: usize, waiting: usize) {
    let queue = app.state.queue.clone();
    eventually(&format!("{running} running, {waiting} waiting"), || {
        let o = queue.occupancy();
        async move { (o.running, o.waiting) == (running, waiting) }
    })
    .await;
}

/// Settings with one estimation worker and `queue_length` waiting places.
pub fn one_worker(queue_length: usize) -> Settings {
    Settings {
        max_concurrent_estimations: std::num::NonZeroUsize::MIN,
        queue_length,
        ..Settings::default()
    }
}

/// The boundary of the multipart bodies of [`multipart_body`].
pub const BOUNDARY: &str = "qrpose-test-boundary-7MA4YWxkTrZu0gW";

/// One part of a multipart body: its name (`None`: no name), content type and bytes.
pub struct Part<'a> {
    pub name: Option<&'a str>,
    pub content_type: &'a str,
    pub bytes: &'a [u8],
}

/// The `image` part with these bytes.
pub fn image_part(bytes: &[u8]) -> Part<'_> {
    Part {
        name: Some("image"),
        content_type: "image/jpeg",
        bytes,
    }
}

/// The `request` part with this JSON.
pub fn request_part(json: &[u8]) -> Part<'_> {
    Part {
        name: Some("request"),
        content_type: "application/json",
        bytes: json,
    }
}

/// A `multipart/form-data` body with [`BOUNDARY`], written by hand so that tests can also
/// send what no well-behaved client library would (a part without a name, a part twice).
pub fn multipart_body(parts: &[Part<'_>]) -> Vec<u8> {
    let mut body = Vec::new();
    for part in parts {
        body.extend_from_slice(format!("--{BOUNDARY}\r\n").as_bytes());
        match part.name {
            Some(name) => body.extend_from_slice(
                format!("Content-Disposition: form-data; name=\"{name}\"\r\n").as_bytes(),
            ),
            None => body.extend_from_slice(b"Content-Disposition: form-data\r\n"),
        }
        body.extend_from_slice(format!("Content-Type: {}\r\n\r\n", part.content_type).as_bytes());
        body.extend_from_slice(part.bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{BOUNDARY}--\r\n").as_bytes());
    body
}

/// The payload of the test photos.
pub const PHOTO_PAYLOAD: &str = "SKU-1";

/// The camera and marker of the test photos as query parameters: 1280x720, f = 1000 px,
/// principal point at the centre, a 50 mm code.
pub const PHOTO_QUERY: &str = "fx_px=1000&fy_px=1000&cx_px=639.5&cy_px=359.5&marker_size_mm=50";

/// The same camera and marker as the JSON `request` part.
pub fn photo_request() -> Value {
    json!({
        "camera": {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5},
        "marker": {"size_mm": 50.0}
    })
}

/// A 1280x720 photo of a 50 mm code 400 mm away, tilted, with blur, noise, uneven lighting
/// and clutter, rendered by the library with its ground truth; centred at `centre_mm` in the
/// camera frame.
pub fn render_photo(encoding: Encoding, centre_mm: [f64; 3]) -> Rendered {
    let marker = Marker::try_new(50.0).expect("a valid size");
    let r = EulerXyz::from_degrees(10.0, -15.0, 5.0).to_rotation();
    let centre = nalgebra::Vector3::new(centre_mm[0], centre_mm[1], centre_mm[2]);
    let scene = Scene {
        payload: PHOTO_PAYLOAD.as_bytes().to_vec(),
        ec_level: EcLevel::M,
        marker,
        camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a valid camera"),
        width_px: 1280,
        height_px: 720,
        pose: marker.pose_centred_at(r, centre),
    };
    let effects = Effects {
        supersample: 2,
        blur_px: 0.8,
        noise: 2.0,
        lighting: 0.2,
        clutter: 10,
        encoding,
        seed: 7,
        ..Effects::default()
    };
    render(&scene, &effects).expect("renders")
}

/// The JPEG test photo (rendered once per test binary).
pub static PHOTO: LazyLock<Rendered> =
    LazyLock::new(|| render_photo(Encoding::Jpeg(90), [20.0, -10.0, 400.0]));

/// The JPEG test photo's bytes.
pub fn photo_jpeg() -> Vec<u8> {
    PHOTO.encoded.clone()
}
