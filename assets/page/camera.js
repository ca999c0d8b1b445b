// The setup page's live mode (src/http/routes/page.rs): streams this browser's camera to the
// WebSocket GET /v1/stream (docs/stream.md) and draws every track's filtered pose, id,
// payload and status over the live picture. Runs after app.js and uses its helpers ($, el,
// fixed, cameraFromForm, numberOrNull, projectAxes, project, line, drawAxes, markerSideMm,
// vec, showError, storedToken, withToken, askForToken). A browser's WebSocket cannot send
// headers, so the tab's token goes as the subprotocol `bearer.TOKEN` beside `qrpose`
// (docs/security.md); a stream refused with 401 asks for a token and starts again. Conventions as docs/conventions.md: camera frame x right, y down,
// z forward; pixel centres at integers.
// Flow control: at most FRAMES_IN_FLIGHT frames sent and not yet answered; the next frame is
// grabbed when an answer arrives, so nothing queues, here or in the service.
"use strict";

const STREAM_PATH = "/v1/stream";
/** Frames sent and not answered, at most: the service's default --stream-frames-in-flight,
 * so it never has to drop one. Two let the page encode a frame while the service works. */
const FRAMES_IN_FLIGHT = 2;
const JPEG_QUALITY = 0.85;
/** Wait this long for a new video frame before grabbing the current one anyway, ms. */
const FRAME_WAIT_MS = 200;
/** How each status is drawn (app.css has the same colours for the legend). */
const STATUS_STYLE = {
  new: { colour: "#00e5ff", dashed: false, alpha: 1 },
  tracking: { colour: "#ffff00", dashed: false, alpha: 1 },
  coasting: { colour: "#ffa500", dashed: true, alpha: 1 },
  lost: { colour: "#bbbbbb", dashed: true, alpha: 0.35 },
};
const STATUS_TEXT = {
  new: "new: first seen in this frame",
  tracking: "tracking: seen in this frame",
  coasting: "coasting: not seen in this frame, pose predicted",
  lost: "lost: not seen for too long, given up",
};
/** Close codes in words (docs/stream.md, Close codes; 1006 is the browser's own). */
const CLOSE_TEXT = {
  1000: "the session closed normally",
  1001: "the service is shutting down",
  1006: "the connection ended without a close frame (the service refused the stream, or the network failed)",
  1008: "a limit of the service: a frame over its size limit, or the session stayed idle too long",
  1011: "the service met an internal fault",
  1013: "the service has too many sessions open: try again later",
};

const live = {
  socket: null, media: null, camera: null, query: "", opened: false, stopping: false,
  grabbing: false, inFlight: 0, sent: 0, answered: 0, dropped: 0, problems: 0,
  sentAt: new Map(), sideByTrack: new Map(), answerTimes: [], roundTripMs: null, grabCanvas: null,
};

// ---- the session's address ---------------------------------------------------------------

/** The query string of GET /v1/stream: the fields of the form, as the query parameters of
 * POST /v1/pose/image (an empty field is left out; the service says what is missing). */
function streamQuery() {
  const query = new URLSearchParams();
  if ($("camera-mode-id").checked) {
    query.set("camera_id", $("camera-id").value.trim());
  } else {
    const fields = [["fx-px", "fx_px"], ["fy-px", "fy_px"], ["cx-px", "cx_px"], ["cy-px", "cy_px"],
      ["k1", "k1"], ["k2", "k2"], ["p1", "p1"], ["p2", "p2"], ["k3", "k3"]];
    for (const [id, name] of fields) {
      const text = $(id).value.trim();
      if (text !== "") query.set(name, text);
    }
  }
  const size = $("marker-size-mm").value.trim();
  if (size !== "") query.set("marker_size_mm", size);
  query.set("effort", $("effort").value);
  return query.toString();
}

/** ws:// or wss:// on this page's own host and port (what CSP connect-src 'self' allows). */
function streamUrl(query) {
  return (location.protocol === "https:" ? "wss://" : "ws://") + location.host + STREAM_PATH + "?" + query;
}

/** The camera resolution the intrinsics stand for (principal point at the centre), if any. */
function videoConstraints(camera) {
  if (!camera || !(camera.cx > 8 && camera.cy > 8)) return true;
  return { width: { ideal: Math.round(2 * camera.cx + 1) }, height: { ideal: Math.round(2 * camera.cy + 1) } };
}

/** A warning when the picture's size does not fit the intrinsics' principal point. */
function resolutionNote(camera, width, height) {
  if (!camera) return "No intrinsics known for this camera here: the page lists the tracks but cannot draw them.";
  const offX = Math.abs(camera.cx - (width - 1) / 2) / width;
  const offY = Math.abs(camera.cy - (height - 1) / 2) / height;
  return offX > 0.1 || offY > 0.1
    ? "The camera delivers " + width + " × " + height + " px, and the principal point (" + camera.cx + ", " + camera.cy + ") is far from its centre: are these the intrinsics of this camera at this resolution? If not, the poses are wrong."
    : "";
}

// ---- status and words --------------------------------------------------------------------

function setLiveStatus(text, state) {
  $("live-status").textContent = text;
  $("live").dataset.state = state;
}

function closeWords(event) {
  const words = CLOSE_TEXT[event.code] || "close code " + event.code;
  return words + " (code " + event.code + (event.reason ? ": " + event.reason : "") + ")";
}

function problemWords(problem) {
  const parts = [problem.title || "Problem", problem.detail || ""].filter(Boolean).join(": ");
  return parts + (problem.code ? " (" + problem.code + ")" : "");
}

/** The problem the service gives for this query when it refuses the upgrade (a browser's
 * WebSocket cannot read the refusal): the same URL without the upgrade. Null when the query
 * is fine (426: only the upgrade is missing) or the service cannot be reached. */
async function refusal(query) {
  try {
    const response = await fetch(STREAM_PATH + "?" + query, withToken());
    const type = response.headers.get("content-type") || "";
    if (response.status === 426 || !type.includes("json")) return null;
    return Object.assign({ status: response.status }, await response.json());
  } catch (_) {
    return null;
  }
}

function showStats() {
  const now = performance.now();
  live.answerTimes = live.answerTimes.filter((t) => now - t < 2000);
  const rate = live.answerTimes.length / 2;
  const stats = $("live-stats");
  stats.textContent = "Frames sent " + live.sent + ", answered " + live.answered + ", dropped by the service " + live.dropped
    + (live.problems ? ", not read " + live.problems : "") + "; about " + rate.toFixed(1) + " frames/s"
    + (live.roundTripMs === null ? "" : "; last round trip " + live.roundTripMs.toFixed(0) + " ms") + ".";
  Object.assign(stats.dataset, { sent: String(live.sent), answered: String(live.answered), dropped: String(live.dropped), problems: String(live.problems) });
}

// ---- frames out --------------------------------------------------------------------------

function socketOpen() {
  return live.socket !== null && live.socket.readyState === WebSocket.OPEN;
}

/** Calls `callback` once, at the video's next frame (or after FRAME_WAIT_MS). */
function nextVideoFrame(callback) {
  let done = false;
  const once = () => { if (!done) { done = true; callback(); } };
  const video = $("live-video");
  if (video.requestVideoFrameCallback) video.requestVideoFrameCallback(once);
  setTimeout(once, video.requestVideoFrameCallback ? FRAME_WAIT_MS : 1000 / 30);
}

/** Grabs and sends the next frame unless FRAMES_IN_FLIGHT are out or one is being grabbed. */
function pump() {
  if (!socketOpen() || live.grabbing || live.inFlight >= FRAMES_IN_FLIGHT) return;
  live.grabbing = true;
  nextVideoFrame(grabAndSend);
}

/** The picture as JPEG, after a text message with its id and capture time
 * (performance.now(), ms since the page loaded: increasing, one clock per session). */
async function grabAndSend() {
  try {
    const video = $("live-video");
    if (!socketOpen() || !(video.videoWidth > 0)) return;
    const canvas = live.grabCanvas || (live.grabCanvas = document.createElement("canvas"));
    canvas.width = video.videoWidth;
    canvas.height = video.videoHeight;
    const captureTimeMs = performance.now();
    canvas.getContext("2d").drawImage(video, 0, 0);
    const blob = await new Promise((resolve) => canvas.toBlob(resolve, "image/jpeg", JPEG_QUALITY));
    if (!blob) return;
    const bytes = await blob.arrayBuffer();
    if (!socketOpen()) return;
    const frameId = live.sent;
    live.socket.send(JSON.stringify({ frame_id: frameId, capture_time_ms: captureTimeMs }));
    live.socket.send(bytes);
    live.sent += 1;
    live.inFlight += 1;
    live.sentAt.set(frameId, performance.now());
  } finally {
    live.grabbing = false;
    pump(); // the next frame, if a slot is free (no picture yet: try again at the next one)
  }
}

// ---- answers in --------------------------------------------------------------------------

/** One answer: a frame's tracks, or a frame's problem. Either frees its frame's slot, and
 * the frames the service dropped before it (`frame.dropped_before`) free theirs. */
function onAnswer(data) {
  let answer;
  try {
    answer = JSON.parse(data);
  } catch (_) {
    $("live-problem").textContent = "The service sent something that is not JSON.";
    return;
  }
  const frame = answer.frame || {};
  live.inFlight = Math.max(0, live.inFlight - 1 - (frame.dropped_before || 0));
  live.answered += 1;
  live.dropped += frame.dropped_before || 0;
  live.answerTimes.push(performance.now());
  if (live.sentAt.has(frame.id)) {
    live.roundTripMs = performance.now() - live.sentAt.get(frame.id);
    for (const id of live.sentAt.keys()) if (id <= frame.id) live.sentAt.delete(id);
  }
  if (Array.isArray(answer.tracks)) {
    $("live-problem").textContent = "";
    showAnswer(answer);
  } else {
    live.problems += 1;
    $("live-problem").textContent = "Frame " + frame.index + " was not read: " + problemWords(answer);
  }
  showStats();
  pump();
}

function showAnswer(answer) {
  for (const marker of answer.markers) {
    if (marker.track_id && marker.pose) live.sideByTrack.set(marker.track_id, markerSideMm(marker.pose));
  }
  drawTracks(answer);
  $("tracks").tBodies[0].replaceChildren(...answer.tracks.map(trackRow));
  $("tracks").dataset.frame = String(answer.frame.index);
  $("tracks-summary").textContent = answer.tracks.length === 0
    ? "No tracks: no code seen yet in frame " + answer.frame.index + "."
    : answer.tracks.length + (answer.tracks.length === 1 ? " track" : " tracks") + " after frame " + answer.frame.index + ".";
  $("live-json").textContent = JSON.stringify(answer, null, 2);
  for (const track of answer.tracks) if (track.status === "lost") live.sideByTrack.delete(track.id);
}

/** A track's outline (top-left, top-right, bottom-right, bottom-left: centre + R·(±l/2,
 * ±l/2, 0), docs/conventions.md, Marker frame) and axes, px; null parts when unknown. */
function trackFigure(track, sideMm) {
  const camera = live.camera;
  if (!camera || !(camera.fx > 0 && camera.fy > 0) || !(sideMm > 0)) return { outline: null, axes: null };
  const centre = vec(track.pose.position_mm), r = track.pose.rotation.matrix, h = sideMm / 2;
  const outline = [[-h, -h], [h, -h], [h, h], [-h, h]].map(([x, y]) =>
    project(camera, [0, 1, 2].map((i) => centre[i] + r[i][0] * x + r[i][1] * y)));
  return {
    outline: outline.every((p) => p !== null) ? outline : null,
    axes: projectAxes(camera, centre, r, sideMm),
  };
}

function labelTrack(ctx, text, anchor, stroke, style) {
  const fontPx = stroke * 7;
  ctx.setLineDash([]);
  ctx.font = fontPx + "px system-ui, sans-serif";
  const width = ctx.measureText(text).width + stroke * 4;
  const top = anchor[1] - fontPx * 1.8 < 0 ? anchor[1] + fontPx * 0.5 : anchor[1] - fontPx * 1.8;
  ctx.fillStyle = style.colour;
  ctx.fillRect(anchor[0], top, width, fontPx * 1.4);
  ctx.fillStyle = "#000";
  ctx.fillText(text, anchor[0] + stroke * 2, top + fontPx * 1.1);
}

/** Every track over the picture, styled by status; what was drawn goes to data-tracks. */
function drawTracks(answer) {
  const canvas = $("live-overlay");
  const width = answer.image.width_px, height = answer.image.height_px;
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width;
    canvas.height = height;
  }
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, width, height);
  const stroke = Math.max(2, Math.round(Math.min(width, height) / 240));
  const fallbackSideMm = numberOrNull("marker-size-mm");
  const drawn = answer.tracks.map((track) => {
    const style = STATUS_STYLE[track.status] || STATUS_STYLE.tracking;
    const sideMm = live.sideByTrack.get(track.id) || fallbackSideMm;
    const figure = trackFigure(track, sideMm);
    ctx.globalAlpha = style.alpha;
    if (figure.outline) {
      for (let k = 0; k < 4; k++) line(ctx, figure.outline[k], figure.outline[(k + 1) % 4], style.colour, stroke, style.dashed);
    }
    if (figure.axes) drawAxes(ctx, figure.axes, stroke, style.dashed);
    const anchor = figure.outline
      ? [Math.min(...figure.outline.map((p) => p[0])), Math.min(...figure.outline.map((p) => p[1]))]
      : live.camera && project(live.camera, vec(track.pose.position_mm));
    if (anchor) labelTrack(ctx, track.id + " " + track.payload + " · " + track.status, anchor, stroke, style);
    ctx.globalAlpha = 1;
    return { id: track.id, status: track.status, side_mm: sideMm, outline: figure.outline, axes: figure.axes };
  });
  canvas.dataset.tracks = JSON.stringify(drawn);
  canvas.dataset.frame = String(answer.frame.index);
  canvas.dataset.state = "drawn";
}

/** A number of a track's row, shown rounded; the exact number in data-value. */
function numberSpan(field, value, digits) {
  const node = el("span", { "data-field": field }, fixed(value, digits));
  if (value !== null && value !== undefined) node.dataset.value = String(value);
  return node;
}

/** A cell of one or more numbers, comma-separated: [[field, value, digits], …]. */
function numberCell(numbers) {
  const td = el("td", { class: "num" });
  numbers.forEach(([field, value, digits], k) => {
    if (k > 0) td.append(", ");
    td.append(numberSpan(field, value, digits));
  });
  return td;
}

/** A track's row: status, ambiguity_resolved, frames, distance, position, angles, speed
 * (data-field / data-value on each, as on the photo's cards; the covariance is in the raw
 * JSON). */
function trackRow(track) {
  const pose = track.pose, p = pose.position_mm, euler = pose.rotation.euler_xyz_deg, v = pose.velocity_mm_per_s;
  const tr = el("tr", { class: "track", "data-track-id": track.id, "data-status": track.status });
  const status = el("td", { "data-field": "status", "data-value": track.status, title: STATUS_TEXT[track.status] || "" }, track.status);
  const resolved = el("td", { "data-field": "ambiguity_resolved", "data-value": String(track.ambiguity_resolved) },
    track.ambiguity_resolved ? "yes" : "no");
  tr.append(
    el("th", { scope: "row", "data-field": "id" }, track.id),
    el("td", { "data-field": "payload" }, track.payload),
    status,
    resolved,
    numberCell([["frames_seen", track.frames_seen, 0]]),
    numberCell([["distance_mm", Math.hypot(p.x, p.y, p.z), 1]]),
    numberCell([["position_mm.x", p.x, 1], ["position_mm.y", p.y, 1], ["position_mm.z", p.z, 1]]),
    numberCell([["euler_xyz_deg.alpha", euler.alpha, 1], ["euler_xyz_deg.beta", euler.beta, 1], ["euler_xyz_deg.gamma", euler.gamma, 1]]),
    numberCell([["speed_mm_per_s", Math.hypot(v.x, v.y, v.z), 1]]),
  );
  return tr;
}

// ---- start and stop ----------------------------------------------------------------------

function setButtons(running) {
  $("camera-start").disabled = running;
  $("camera-stop").disabled = !running;
}

function stopMedia() {
  if (live.media) for (const track of live.media.getTracks()) track.stop();
  live.media = null;
  $("live-video").srcObject = null;
}

function cameraError(err) {
  const name = err && err.name;
  if (name === "NotAllowedError") return "The camera was not allowed: allow this page to use it (the browser's address bar) and try again.";
  if (name === "NotFoundError" || name === "OverconstrainedError") return "No camera found.";
  if (name === "NotReadableError") return "The camera is in use by another program, or the system refused it.";
  return "The camera could not be opened: " + err;
}

async function startCamera() {
  if (live.socket || live.media) return;
  $("live").hidden = false;
  $("live-problem").textContent = "";
  $("error").hidden = true;
  if (!navigator.mediaDevices || !navigator.mediaDevices.getUserMedia) {
    setLiveStatus("This browser gives a page the camera only over HTTPS or from localhost: open the page at https://… or http://localhost:….", "failed");
    return;
  }
  const camera = cameraFromForm();
  live.camera = camera.projection;
  live.query = streamQuery();
  live.stopping = false;
  setButtons(true);
  setLiveStatus("Asking for the camera…", "starting");
  try {
    live.media = await navigator.mediaDevices.getUserMedia({ video: videoConstraints(live.camera), audio: false });
  } catch (err) {
    setButtons(false);
    setLiveStatus(cameraError(err), "failed");
    return;
  }
  if (live.stopping) {
    stopMedia();
    return;
  }
  for (const track of live.media.getVideoTracks()) track.addEventListener("ended", cameraEnded);
  const video = $("live-video");
  video.srcObject = live.media;
  await new Promise((resolve) => (video.videoWidth > 0 ? resolve() : video.addEventListener("loadedmetadata", resolve, { once: true })));
  await video.play().catch(() => undefined);
  $("live-note").textContent = resolutionNote(live.camera, video.videoWidth, video.videoHeight);
  $("live-command").textContent = "websocat " + (storedToken() ? '-H "Authorization: Bearer $QRPOSE_TOKEN" ' : "")
    + "'" + streamUrl(live.query) + "'";
  $("live-heading").focus();
  if (live.media) openSocket(); // else Stop was pressed meanwhile
}

function openSocket() {
  Object.assign(live, { opened: false, inFlight: 0, sent: 0, answered: 0, dropped: 0, problems: 0, roundTripMs: null, answerTimes: [] });
  live.sentAt.clear();
  live.sideByTrack.clear();
  setLiveStatus("Opening the stream…", "connecting");
  const value = storedToken();
  const socket = value ? new WebSocket(streamUrl(live.query), ["qrpose", "bearer." + value]) : new WebSocket(streamUrl(live.query));
  live.socket = socket;
  socket.addEventListener("open", () => {
    live.opened = true;
    setLiveStatus("Streaming: " + $("live-video").videoWidth + " × " + $("live-video").videoHeight + " px.", "streaming");
    pump();
  });
  socket.addEventListener("message", (event) => onAnswer(event.data));
  socket.addEventListener("close", (event) => onClose(socket, event));
}

async function onClose(socket, event) {
  if (live.socket === socket) live.socket = null;
  stopMedia();
  setButtons(false);
  const canvas = $("live-overlay");
  canvas.getContext("2d").clearRect(0, 0, canvas.width, canvas.height);
  canvas.dataset.state = "cleared";
  $("live").dataset.closeCode = String(event.code);
  if (live.stopping) {
    setLiveStatus("Stopped: " + closeWords(event) + ". The tracks below are those of the last answer.", "closed");
    return;
  }
  const problem = live.opened ? null : await refusal(live.query);
  if (problem && problem.status === 401 && await askForToken(problem)) {
    startCamera();
    return;
  }
  if (problem) {
    setLiveStatus("The service refused the stream: " + problemWords(problem) + ".", "refused");
    showError(problem.title || "Stream refused", problem.detail,
      [problem.code && "code: " + problem.code, problem.field && "field: " + problem.field, "HTTP " + problem.status].filter(Boolean).join(" · "));
  } else {
    setLiveStatus("The stream ended: " + closeWords(event) + ".", "closed");
  }
}

/** The camera went away (unplugged, or taken by the system): the session ends too. */
function cameraEnded() {
  $("live-problem").textContent = "The camera stopped delivering pictures.";
  stopCamera();
}

function stopCamera() {
  live.stopping = true;
  setButtons(false);
  if (live.socket) live.socket.close(1000, "stopped by the user");
  stopMedia();
  if (!live.socket) setLiveStatus("Stopped.", "closed");
}

document.addEventListener("DOMContentLoaded", () => {
  $("camera-start").addEventListener("click", startCamera);
  $("camera-stop").addEventListener("click", stopCamera);
});
