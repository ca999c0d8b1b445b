// The setup page (src/http/routes/page.rs): sends one photo to POST /v1/pose/image and
// shows what came back. Conventions as docs/conventions.md: camera frame x right, y down,
// z forward; pixels with integer coordinates at pixel centres; p_cam = R·p_marker + t.
// Stable hooks for tests and people: ids, and data-field / data-value on every number.
// The live camera mode (GET /v1/stream) is camera.js, which uses the helpers below.
// A code whose payload names a product of the site (pose.object, docs/pick.md) also gets its
// box and each grasp's approach axis drawn, as the server's annotated image draws them
// (src/annotate/overlay.rs), and its grasps listed.
// With an auth file on the service (docs/security.md), a 401 asks for a bearer token, kept
// for this tab only (sessionStorage) and sent with every call after it.
"use strict";

const IMAGE_PATH = "/v1/pose/image";
const ANNOTATED_PATH = "/v1/pose/image/annotated";
const SITE_PATH = "/v1/site";
const AXIS_COLOURS = ["#ff0000", "#00c000", "#0000ff"];
const OUTLINE_COLOUR = "#ffff00";
const CORNER_COLOUR = "#ff00ff";
/** A product's box, and a grasp's approach axis when graspable and when not (the server's
 * overlay colours: src/annotate/overlay.rs BOX, GRASPABLE, NOT_GRASPABLE). */
const BOX_COLOUR = "#00ffff";
const GRASPABLE_COLOUR = "#40ff40";
const NOT_GRASPABLE_COLOUR = "#ff8000";
/** The box's twelve edges as pairs of corner indices; corner k has the sign (−, +) of x, y,
 * z from bits 0, 1, 2 of k (the server's BOX_EDGES and box_corners). */
const BOX_EDGES = [[0, 1], [1, 3], [3, 2], [2, 0], [4, 5], [5, 7], [7, 6], [6, 4], [0, 4], [1, 5], [2, 6], [3, 7]];
const PICK_REASON_TEXT = {
  no_robot_pose: "the camera's pose in the robot frame is unknown (no mount, or a camera on the flange without the arm's pose)",
  pose_ambiguous: "the code's pose cannot be told from its mirror",
  below_probability: "the probability of landing within tolerance is below the least asked for, or unknown",
  not_converged: "the code's pose estimate did not converge",
};
const DEG_PER_RAD = 180 / Math.PI;

const WARNING_TEXT = {
  not_converged: "The solver did not converge: the pose is its last estimate.",
  pose_ambiguous: "Two poses fit these corners almost equally well: use this one only with other evidence (the previous frame, a second code).",
  behind_camera: "The pose puts a corner behind the camera: the corners, intrinsics or marker size are wrong.",
  high_reprojection_error: "The pose does not fit the corners well (high reprojection error): check the intrinsics, the distortion and the marker size.",
  detection_budget_exhausted: "Detection ran out of time before every pass ran: codes may have been missed. Raise the effort or max_detect_ms.",
};

const $ = (id) => document.getElementById(id);
const state = { fileReady: Promise.resolve(), file: null, bitmap: null, response: null, camera: null, siteCameras: null, siteLoaded: false };

// ---- the bearer token (docs/security.md) -------------------------------------------------

/** This tab's token: sessionStorage, which the tab alone sees and which ends with it (never
 * localStorage or a cookie). `memory` stands in when the browser refuses storage. */
const TOKEN_KEY = "qrpose.token";
const token = { memory: "", waiting: null, resolve: null };

function storedToken() {
  try {
    return sessionStorage.getItem(TOKEN_KEY) || token.memory;
  } catch (_) {
    return token.memory;
  }
}

function keepToken(value) {
  token.memory = value;
  try {
    sessionStorage.setItem(TOKEN_KEY, value);
  } catch (_) { /* storage refused: kept in memory for this page */ }
}

/** `init` with `Authorization: Bearer` when the tab has a token. */
function withToken(init) {
  const value = storedToken();
  if (!value) return init || {};
  const headers = new Headers((init && init.headers) || undefined);
  headers.set("Authorization", "Bearer " + value);
  return Object.assign({}, init, { headers });
}

/** Shows the token prompt after a 401 (`problem`: its problem+json, or null); resolves true
 * once a token is given, false when the prompt is cancelled. One prompt at a time. */
function askForToken(problem) {
  if (token.waiting) return token.waiting;
  const refused = storedToken() !== "";
  $("token-reason").textContent = (refused ? "The service refused this tab's token" : "The service asks for a bearer token")
    + (problem && problem.detail ? ": " + problem.detail : ".");
  $("token-input").value = "";
  $("token-panel").hidden = false;
  $("token-input").focus();
  token.waiting = new Promise((resolve) => { token.resolve = resolve; });
  return token.waiting;
}

function closeTokenPrompt(given) {
  $("token-panel").hidden = true;
  const resolve = token.resolve;
  token.waiting = null;
  token.resolve = null;
  if (resolve) resolve(given);
}

function submitToken(event) {
  event.preventDefault();
  const value = $("token-input").value.trim();
  if (!value) {
    $("token-input").focus();
    return;
  }
  keepToken(value);
  $("token-input").value = "";
  closeTokenPrompt(true);
}

/** fetch with this tab's token; a 401 asks for a token and sends the request again, until it
 * passes or the prompt is cancelled (then the 401 is the answer). */
async function apiFetch(url, init) {
  for (;;) {
    const response = await fetch(url, withToken(init));
    if (response.status !== 401) return response;
    const problem = await response.clone().json().catch(() => null);
    if (!(await askForToken(problem))) return response;
  }
}

// ---- the request -------------------------------------------------------------------------

function numberOrNull(id) {
  const text = $(id).value.trim();
  return text === "" ? null : Number(text);
}

/** The camera as the form gives it: {request: the JSON camera, projection: for drawing}. */
function cameraFromForm() {
  if ($("camera-mode-id").checked) {
    const id = $("camera-id").value.trim();
    const known = state.siteCameras && state.siteCameras[id];
    return { request: { id }, projection: known || null };
  }
  const request = {
    fx_px: numberOrNull("fx-px"), fy_px: numberOrNull("fy-px"),
    cx_px: numberOrNull("cx-px"), cy_px: numberOrNull("cy-px"),
  };
  const distortion = {};
  let any = false;
  for (const k of ["k1", "k2", "p1", "p2", "k3"]) {
    const v = numberOrNull(k);
    distortion[k] = v === null ? 0 : v;
    any = any || v !== null;
  }
  if (any) request.distortion = distortion;
  const projection = { fx: request.fx_px, fy: request.fy_px, cx: request.cx_px, cy: request.cy_px, distortion };
  return { request, projection };
}

/** The multipart `request` part. JSON has no ';' outside strings, and inside them it is
 * written \u003b, so the curl command's -F value needs no quoting of its own. */
function requestJson(camera) {
  const body = { camera: camera.request, effort: $("effort").value };
  const size = numberOrNull("marker-size-mm");
  if (size !== null) body.marker = { size_mm: size };
  const least = numberOrNull("min-grasp-probability");
  if (least !== null) body.min_grasp_probability = least;
  return JSON.stringify(body).replace(/;/g, "\\u003b");
}

function formData(json) {
  const data = new FormData();
  data.append("image", state.file, state.file.name);
  data.append("request", new Blob([json], { type: "application/json" }));
  return data;
}

function shellQuote(text) {
  return "'" + text.replace(/'/g, "'\\''") + "'";
}

/** A curl command that sends the same multipart request. */
function curlCommand(json) {
  const name = state.file.name.replace(/["\\]/g, "\\$&");
  const type = state.file.type || "application/octet-stream";
  // The token itself is never printed: the command reads it from $QRPOSE_TOKEN.
  const auth = storedToken() ? ['  -H "Authorization: Bearer $QRPOSE_TOKEN" \\'] : [];
  return [
    "curl -sS -X POST " + shellQuote(location.origin + IMAGE_PATH) + " \\",
    ...auth,
    "  -F " + shellQuote('image=@"' + name + '";type=' + type) + " \\",
    "  -F " + shellQuote("request=" + json + ";type=application/json"),
  ].join("\n");
}

// ---- projection (docs/conventions.md, Normalised coordinates and distortion) -------------

/** A camera-frame point (mm) to pixels with OpenCV's plumb_bob model; null behind the camera. */
function project(camera, p) {
  if (!(p[2] > 0)) return null;
  const x = p[0] / p[2], y = p[1] / p[2];
  const d = camera.distortion || {};
  const k1 = d.k1 || 0, k2 = d.k2 || 0, p1 = d.p1 || 0, p2 = d.p2 || 0, k3 = d.k3 || 0;
  const r2 = x * x + y * y;
  const radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  return [camera.fx * xd + camera.cx, camera.fy * yd + camera.cy];
}

function vec(v) { return [v.x, v.y, v.z]; }

/** The marker's side, mm: |centre − P2| = l/√2 (docs/conventions.md, Pose). */
function markerSideMm(pose) {
  const c = vec(pose.position_mm), t = vec(pose.reference_point_mm);
  return Math.SQRT2 * Math.hypot(c[0] - t[0], c[1] - t[1], c[2] - t[2]);
}

/** Origin and x, y, z ends (px) of axes of length `length` from `centre` with rotation R. */
function projectAxes(camera, centre, matrix, length) {
  const origin = project(camera, centre);
  if (!origin) return null;
  const ends = [];
  for (let axis = 0; axis < 3; axis++) {
    const end = project(camera, [0, 1, 2].map((row) => centre[row] + matrix[row][axis] * length));
    if (!end) return null;
    ends.push(end);
  }
  return { origin, ends };
}

function axesOf(marker) {
  const pose = marker.pose;
  const camera = state.camera;
  if (!pose || !camera || !(camera.fx > 0 && camera.fy > 0)) return { pose: null, alternative: null };
  const length = markerSideMm(pose);
  const main = projectAxes(camera, vec(pose.position_mm), pose.rotation.matrix, length);
  const amb = pose.diagnostics && pose.diagnostics.ambiguity;
  const alternative = amb
    ? projectAxes(camera, vec(amb.alternative_position_mm), amb.alternative_rotation.matrix, length)
    : null;
  return { pose: main, alternative };
}

/** A product's strokes (src/annotate/overlay.rs, object_segments): its box's edges and each
 * grasp's approach axis, a stroke along the grasp frame's z ending at the grasp point, half
 * the box's longest side long; a stroke with an end behind the camera is left out. */
function objectStrokes(camera, object) {
  const c = vec(object.pose.position_mm), r = object.pose.rotation.matrix, size = object.box_mm;
  const corners = [];
  for (let k = 0; k < 8; k++) {
    const local = [0, 1, 2].map((axis) => ((k >> axis) & 1 ? 0.5 : -0.5) * size[axis]);
    corners.push(project(camera, [0, 1, 2].map((row) => c[row] + r[row][0] * local[0] + r[row][1] * local[1] + r[row][2] * local[2])));
  }
  const edges = BOX_EDGES.filter(([a, b]) => corners[a] && corners[b])
    .map(([a, b]) => ({ corners: [a, b], from: corners[a], to: corners[b] }));
  const length = 0.5 * Math.max(...size);
  const grasps = object.grasps.map((grasp, index) => {
    const m = grasp.pose.rotation.matrix, at = vec(grasp.pose.position_mm);
    const from = project(camera, [0, 1, 2].map((row) => at[row] - m[row][2] * length));
    const to = project(camera, at);
    const colour = grasp.graspable ? GRASPABLE_COLOUR : NOT_GRASPABLE_COLOUR;
    return from && to ? { index, name: grasp.name, from, to, colour } : null;
  }).filter(Boolean);
  return { edges, grasps };
}

// ---- drawing -----------------------------------------------------------------------------

function line(ctx, from, to, colour, width, dashed) {
  ctx.strokeStyle = colour;
  ctx.lineWidth = width;
  ctx.setLineDash(dashed ? [width * 3, width * 2] : []);
  ctx.beginPath();
  ctx.moveTo(from[0] + 0.5, from[1] + 0.5);
  ctx.lineTo(to[0] + 0.5, to[1] + 0.5);
  ctx.stroke();
}

function drawAxes(ctx, axes, width, dashed) {
  for (const axis of [2, 1, 0]) line(ctx, axes.origin, axes.ends[axis], AXIS_COLOURS[axis], width, dashed);
}

/** The photo with every code's outline, corners, payload and axes. Pixel coordinates are
 * pixel centres, so canvas coordinates are the pixel's + 0.5. */
function draw() {
  const canvas = $("overlay");
  const bitmap = state.bitmap, response = state.response;
  if (!response) return;
  const width = bitmap ? bitmap.width : response.image.width_px;
  const height = bitmap ? bitmap.height : response.image.height_px;
  canvas.width = width;
  canvas.height = height;
  const ctx = canvas.getContext("2d");
  if (bitmap) ctx.drawImage(bitmap, 0, 0);
  else { ctx.fillStyle = "#333"; ctx.fillRect(0, 0, width, height); }
  const stroke = Math.max(2, Math.round(Math.min(width, height) / 240));
  const showAlternative = $("show-alternative").checked;
  const drawn = [];
  response.markers.forEach((marker) => {
    const c = marker.corners_px;
    for (let k = 0; k < 4; k++) line(ctx, c[k], c[(k + 1) % 4], OUTLINE_COLOUR, stroke, false);
    const object = marker.pose && marker.pose.object;
    const camera = state.camera;
    const strokes = object && camera && camera.fx > 0 && camera.fy > 0 ? objectStrokes(camera, object) : null;
    if (strokes) {
      for (const edge of strokes.edges) line(ctx, edge.from, edge.to, BOX_COLOUR, stroke, false);
      for (const grasp of strokes.grasps) line(ctx, grasp.from, grasp.to, grasp.colour, stroke, false);
    }
    const axes = axesOf(marker);
    if (axes.pose) drawAxes(ctx, axes.pose, stroke, false);
    const alternativeDrawn = showAlternative && axes.alternative !== null;
    if (alternativeDrawn) drawAxes(ctx, axes.alternative, stroke, true);
    ctx.setLineDash([]);
    ctx.strokeStyle = CORNER_COLOUR;
    ctx.lineWidth = stroke;
    const half = stroke * 2.5;
    for (const p of c) ctx.strokeRect(p[0] + 0.5 - half, p[1] + 0.5 - half, 2 * half, 2 * half);
    const text = marker.payload === null ? "(not decoded)" : marker.payload;
    const fontPx = stroke * 7;
    ctx.font = fontPx + "px system-ui, sans-serif";
    const left = Math.min(...c.map((p) => p[0]));
    const top = Math.min(...c.map((p) => p[1]));
    const boxWidth = ctx.measureText(text).width + stroke * 4;
    const boxTop = top - fontPx * 1.8 < 0 ? Math.max(...c.map((p) => p[1])) + fontPx * 0.5 : top - fontPx * 1.8;
    ctx.fillStyle = "#000";
    ctx.fillRect(left, boxTop, boxWidth, fontPx * 1.4);
    ctx.fillStyle = "#fff";
    ctx.fillText(text, left + stroke * 2, boxTop + fontPx * 1.1);
    drawn.push({ pose: axes.pose, alternative: alternativeDrawn ? axes.alternative : null, object: strokes });
  });
  const missing = response.markers.some((m, k) => m.pose && (!drawn[k].pose || (m.pose.object && !drawn[k].object)));
  $("axes-note").textContent = missing
    ? "Axes (and products' boxes and grasps) are not drawn for this camera: the page knows no intrinsics for it (or its lens model is not plumb_bob). Download the annotated image to see them."
    : "";
  canvas.dataset.axes = JSON.stringify(drawn);
  canvas.dataset.alternativeShown = String(showAlternative);
  canvas.dataset.state = "drawn";
}

// ---- the numbers -------------------------------------------------------------------------

function el(tag, attributes, text) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attributes || {})) node.setAttribute(k, v);
  if (text !== undefined) node.textContent = text;
  return node;
}

function fixed(value, digits) {
  return value === null || value === undefined ? "—" : Number(value).toFixed(digits);
}

/** A row of the marker's list: the label, and the value shown with its unit; the exact
 * number is in data-value. */
function row(dl, field, label, value, digits, unit) {
  dl.append(el("dt", {}, label));
  const dd = el("dd", { "data-field": field }, fixed(value, digits) + (unit ? " " + unit : ""));
  if (value !== null && value !== undefined) dd.dataset.value = String(value);
  dl.append(dd);
}

function textRow(dl, field, label, text) {
  dl.append(el("dt", {}, label));
  dl.append(el("dd", { "data-field": field }, text));
}

function warningList(codes, className) {
  const list = el("ul", { class: className || "warnings" });
  for (const code of codes) list.append(el("li", { "data-code": code }, WARNING_TEXT[code] || code));
  return list;
}

function standardDeviations(covariance) {
  if (!covariance) return null;
  const m = covariance.matrix;
  const sd = (i) => Math.sqrt(Math.max(0, m[i][i]));
  return { rx_deg: sd(0) * DEG_PER_RAD, ry_deg: sd(1) * DEG_PER_RAD, rz_deg: sd(2) * DEG_PER_RAD, x_mm: sd(3), y_mm: sd(4), z_mm: sd(5) };
}

function markerCard(marker, index) {
  const card = el("article", { class: "marker", "data-marker-index": String(index) });
  const name = marker.payload === null ? "(not decoded)" : marker.payload;
  card.append(el("h3", {}, "Code " + (index + 1) + ": " + name));
  const dl = el("dl");
  textRow(dl, "payload", "payload", name);
  textRow(dl, "detector", "detector", marker.detector + (marker.corners_refined ? ", corners refined" : ", corners not refined (" + marker.refinement + ")"));
  const pose = marker.pose;
  if (!pose) {
    card.append(dl);
    const problem = marker.problem || { title: "No pose", detail: "" };
    const p = el("p", { class: "warnings", "data-field": "problem" });
    p.append(el("strong", {}, problem.title + ": "), document.createTextNode(problem.detail || ""));
    card.append(p);
    return card;
  }
  const pos = pose.position_mm, euler = pose.rotation.euler_xyz_deg, diag = pose.diagnostics;
  row(dl, "position_mm.x", "x (right)", pos.x, 1, "mm");
  row(dl, "position_mm.y", "y (down)", pos.y, 1, "mm");
  row(dl, "position_mm.z", "z (forward)", pos.z, 1, "mm");
  row(dl, "distance_mm", "distance", pose.distance_mm, 1, "mm");
  row(dl, "euler_xyz_deg.alpha", "α (about x)", euler.alpha, 2, "°");
  row(dl, "euler_xyz_deg.beta", "β (about y)", euler.beta, 2, "°");
  row(dl, "euler_xyz_deg.gamma", "γ (about z)", euler.gamma, 2, "°");
  row(dl, "reprojection_rms_px", "reprojection RMS", diag.reprojection_rms_px, 3, "px");
  textRow(dl, "method", "method", diag.method + (diag.converged ? "" : " (not converged)") + ", " + diag.iterations + " iterations");
  const sd = standardDeviations(diag.covariance);
  if (sd) {
    row(dl, "sigma.x_mm", "σ x", sd.x_mm, 2, "mm");
    row(dl, "sigma.y_mm", "σ y", sd.y_mm, 2, "mm");
    row(dl, "sigma.z_mm", "σ z", sd.z_mm, 2, "mm");
    row(dl, "sigma.rx_deg", "σ rotation about x", sd.rx_deg, 3, "°");
    row(dl, "sigma.ry_deg", "σ rotation about y", sd.ry_deg, 3, "°");
    row(dl, "sigma.rz_deg", "σ rotation about z", sd.rz_deg, 3, "°");
  }
  const amb = diag.ambiguity;
  if (amb) {
    dl.append(el("dt", {}, "ambiguous"));
    dl.append(el("dd", { "data-field": "ambiguous", "data-value": String(amb.ambiguous), class: amb.ambiguous ? "flag-yes" : "" },
      amb.ambiguous ? "yes: the alternative pose may be the true one" : "no"));
    const probability = amb.alternative_probability;
    row(dl, "alternative_probability", "alternative's probability", probability === null ? null : probability * 100, 2, "%");
    if (probability !== null) dl.lastChild.dataset.value = String(probability);
    const ap = amb.alternative_position_mm, ae = amb.alternative_rotation.euler_xyz_deg;
    row(dl, "alternative_position_mm.x", "alternative x", ap.x, 1, "mm");
    row(dl, "alternative_position_mm.y", "alternative y", ap.y, 1, "mm");
    row(dl, "alternative_position_mm.z", "alternative z", ap.z, 1, "mm");
    row(dl, "alternative_euler_xyz_deg.alpha", "alternative α", ae.alpha, 2, "°");
    row(dl, "alternative_euler_xyz_deg.beta", "alternative β", ae.beta, 2, "°");
    row(dl, "alternative_euler_xyz_deg.gamma", "alternative γ", ae.gamma, 2, "°");
    row(dl, "alternative_rms_px", "alternative's RMS", amb.alternative_rms_px, 3, "px");
    row(dl, "rotation_difference_deg", "rotation between the two", amb.rotation_difference_deg, 1, "°");
  }
  card.append(dl);
  if (diag.warnings.length > 0) card.append(warningList(diag.warnings));
  else card.append(el("p", { class: "hint", "data-field": "warnings" }, "No warnings."));
  if (pose.object) card.append(productSection(pose.object));
  return card;
}

/** The product a code names (docs/pick.md): its rule, box and one row per grasp (name, kind,
 * probability of landing within tolerance, graspable, and what forbids it). */
function productSection(object) {
  const section = el("section", { class: "product", "data-field": "object", "data-rule": object.rule });
  section.append(el("h4", {}, "Product (" + object.rule + "), box " + object.box_mm.map((v) => fixed(v, 0)).join(" × ") + " mm"));
  const legend = el("p", { class: "hint legend" });
  legend.append(el("span", { class: "swatch box" }), " box ", el("span", { class: "swatch graspable" }), " graspable ",
    el("span", { class: "swatch not-graspable" }), " not graspable: each grasp's approach axis, ending at the grasp point.");
  section.append(legend);
  const table = el("table", { class: "grasps" });
  const head = el("tr");
  for (const name of ["grasp", "kind", "within tolerance", "graspable", "why not"]) head.append(el("th", { scope: "col" }, name));
  table.append(el("thead"), el("tbody"));
  table.tHead.append(head);
  object.grasps.forEach((grasp, index) => {
    const tr = el("tr", { "data-grasp-index": String(index), "data-graspable": String(grasp.graspable) });
    const p = grasp.within_tolerance_probability;
    const probability = el("td", { class: "num", "data-field": "within_tolerance_probability" },
      p === null ? "unknown" : fixed(p * 100, 2) + " %");
    if (p !== null) probability.dataset.value = String(p);
    tr.append(
      el("td", { "data-field": "name" }, grasp.name),
      el("td", {}, grasp.kind + (grasp.width_mm === null ? "" : ", " + fixed(grasp.width_mm, 1) + " mm")),
      probability,
      el("td", { "data-field": "graspable", class: grasp.graspable ? "" : "flag-yes" }, grasp.graspable ? "yes" : "no"),
      el("td", { "data-field": "reasons", "data-codes": grasp.reasons.join(" ") },
        grasp.reasons.map((code) => PICK_REASON_TEXT[code] || code).join("; ")),
    );
    table.tBodies[0].append(tr);
  });
  const wrap = el("div", { class: "table-wrap" });
  wrap.append(table);
  section.append(wrap);
  return section;
}

function timingTable(timing) {
  const body = $("timing").tBodies[0];
  body.replaceChildren();
  const add = (stage, ms) => {
    const tr = el("tr", { "data-stage": stage });
    tr.append(el("td", {}, stage), el("td", { class: "ms", "data-value": String(ms) }, fixed(ms, 2)));
    body.append(tr);
  };
  add("decode", timing.decode);
  add("detect", timing.detect);
  for (const pass of timing.detect_passes || []) add("  pass: " + pass.pass + " (" + pass.decoded + " read)", pass.ms);
  add("estimate", timing.estimate);
  if (state.roundTripMs !== undefined) add("round trip seen by this page", state.roundTripMs);
}

function showResults(response, json) {
  state.response = response;
  $("error").hidden = true;
  const n = response.markers.length;
  $("summary").textContent = n === 0
    ? "No QR code found in this " + response.image.width_px + " × " + response.image.height_px + " photo."
    : n + (n === 1 ? " code" : " codes") + " found in this " + response.image.width_px + " × " + response.image.height_px + " photo.";
  $("summary").dataset.markers = String(n);
  $("image-warnings").replaceChildren(...(response.warnings || []).map((code) => el("li", { "data-code": code }, WARNING_TEXT[code] || code)));
  $("markers").replaceChildren(...response.markers.map(markerCard));
  timingTable(response.timing_ms);
  $("curl").textContent = curlCommand(json);
  $("raw-json").textContent = JSON.stringify(response, null, 2);
  $("results").hidden = false;
  $("download-annotated").disabled = false;
  draw();
  $("results-heading").focus();
}

function showError(title, detail, meta) {
  $("error-title").textContent = title;
  $("error-detail").textContent = detail || "";
  $("error-meta").textContent = meta || "";
  $("error").hidden = false;
  $("error").focus();
}

async function showProblem(response) {
  const type = response.headers.get("content-type") || "";
  if (type.includes("json")) {
    const problem = await response.json();
    const meta = [problem.code && "code: " + problem.code, problem.field && "field: " + problem.field, "HTTP " + response.status].filter(Boolean).join(" · ");
    showError(problem.title || "Request refused", problem.detail, meta);
  } else {
    showError("HTTP " + response.status, await response.text());
  }
}

// ---- events ------------------------------------------------------------------------------

async function chooseFile(file) {
  state.file = file || null;
  state.bitmap = null;
  $("download-annotated").disabled = true;
  if (!file) return;
  $("status").textContent = "Photo: " + file.name + " (" + Math.round(file.size / 1024) + " KiB)";
  try {
    state.bitmap = await createImageBitmap(file);
  } catch (_) {
    state.bitmap = null; // not an image this browser reads; the server will say why
  }
}

async function send(event) {
  event.preventDefault();
  await state.fileReady;
  if (!state.file) {
    showError("No photo", "Choose a JPEG or PNG photo first, or drop one on the photo box.");
    return;
  }
  const camera = cameraFromForm();
  const json = requestJson(camera);
  state.camera = camera.projection;
  $("send").disabled = true;
  $("status").textContent = "Estimating…";
  const started = performance.now();
  try {
    const response = await apiFetch(IMAGE_PATH, { method: "POST", body: formData(json) });
    state.roundTripMs = performance.now() - started;
    if (response.ok) {
      showResults(await response.json(), json);
      $("status").textContent = "Done in " + state.roundTripMs.toFixed(0) + " ms.";
    } else {
      $("status").textContent = "Refused.";
      await showProblem(response);
    }
  } catch (err) {
    $("status").textContent = "";
    showError("The server could not be reached", String(err));
  } finally {
    $("send").disabled = false;
  }
}

async function downloadAnnotated() {
  if (!state.file) return;
  const response = await apiFetch(ANNOTATED_PATH, { method: "POST", body: formData(requestJson(cameraFromForm())) });
  if (!response.ok) { await showProblem(response); return; }
  const url = URL.createObjectURL(await response.blob());
  const link = el("a", { href: url, download: state.file.name.replace(/\.[^.]*$/, "") + "-annotated.jpg" });
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

/** Camera ids from GET /v1/site, fetched once, when the named-camera mode is first chosen. */
async function loadSite() {
  if (state.siteLoaded) return;
  state.siteLoaded = true;
  try {
    const response = await apiFetch(SITE_PATH);
    if (!response.ok) {
      $("site-status").textContent = "This server has no site file (GET " + SITE_PATH + " answered " + response.status + "): type the camera id.";
      return;
    }
    const site = await response.json();
    const cameras = site.cameras || {};
    const entries = Array.isArray(cameras) ? cameras.map((c) => [c.id, c]) : Object.entries(cameras);
    state.siteCameras = {};
    for (const [id, c] of entries) {
      // The camera as a pose request takes it. The page projects with plumb_bob only;
      // other lenses get no axes here (the annotated image of the server draws them).
      const k = c.camera || {};
      const d = k.distortion || {};
      if (k.fx_px > 0 && (!d.model || d.model === "plumb_bob")) {
        state.siteCameras[id] = { fx: k.fx_px, fy: k.fy_px, cx: k.cx_px, cy: k.cy_px, distortion: d };
      }
      $("camera-ids").append(el("option", { value: id }));
    }
    $("site-status").textContent = entries.length + " camera(s) in the site file.";
  } catch (err) {
    $("site-status").textContent = "Could not read the site file: " + err;
  }
}

function cameraModeChanged() {
  const named = $("camera-mode-id").checked;
  $("named-camera").hidden = !named;
  $("intrinsics").hidden = named;
  if (named) loadSite();
}

function setUpDrop() {
  const zone = $("drop-zone");
  const stop = (event) => { event.preventDefault(); event.stopPropagation(); };
  for (const name of ["dragenter", "dragover"]) zone.addEventListener(name, (e) => { stop(e); zone.classList.add("over"); });
  for (const name of ["dragleave", "drop"]) zone.addEventListener(name, (e) => { stop(e); zone.classList.remove("over"); });
  zone.addEventListener("drop", (event) => {
    const files = event.dataTransfer && event.dataTransfer.files;
    if (files && files.length > 0) {
      $("photo").files = files;
      state.fileReady = chooseFile(files[0]);
    }
  });
  // A photo dropped next to the box must not replace the page.
  window.addEventListener("dragover", (e) => e.preventDefault());
  window.addEventListener("drop", (e) => e.preventDefault());
}

async function copyCurl() {
  try {
    await navigator.clipboard.writeText($("curl").textContent);
    $("status").textContent = "curl command copied.";
  } catch (_) {
    $("status").textContent = "Select the command and copy it by hand (the clipboard is not available here).";
  }
}

document.addEventListener("DOMContentLoaded", () => {
  $("setup").addEventListener("submit", send);
  $("photo").addEventListener("change", () => { state.fileReady = chooseFile($("photo").files[0]); });
  $("show-alternative").addEventListener("change", draw);
  $("camera-mode-intrinsics").addEventListener("change", cameraModeChanged);
  $("camera-mode-id").addEventListener("change", cameraModeChanged);
  $("download-annotated").addEventListener("click", downloadAnnotated);
  $("copy-curl").addEventListener("click", copyCurl);
  $("token-form").addEventListener("submit", submitToken);
  $("token-cancel").addEventListener("click", () => closeTokenPrompt(false));
  setUpDrop();
  document.body.dataset.ready = "true";
});
