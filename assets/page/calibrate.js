// The setup page's calibration tab (src/http/routes/page.rs; docs/calibration.md, The setup
// page's calibration tab): sends photos of one printed code to POST /v1/calibrate and shows
// the camera with each parameter's standard deviation, the warnings, every photo's view (used
// or why not), each view's points and residual vectors drawn over its photo, every view's
// points on one image with the answer's coverage grid, and the two files to download. Also
// switches the page's tabs (Pose, Calibration, Hand-eye). Runs after app.js and uses its
// helpers ($, el, fixed, numberOrNull, apiFetch). Pixels as docs/conventions.md: integer
// coordinates at pixel centres, so the pixel (u, v) is drawn at canvas
// ((u + 0.5)·s, (v + 0.5)·s) for a figure drawn s times the photo's size. Stable hooks for
// tests: ids, data-field / data-value (and data-std) on the numbers, data-view-index on each
// view's row and figure, data-state on every canvas once drawn.
"use strict";

const CALIBRATE_PATH = "/v1/calibrate";
const TABS = ["tab-pose", "tab-calibration", "tab-hand-eye"];
/** Largest side a figure is drawn at, px: a 12-megapixel photo need not be kept whole. */
const FIGURE_MAX_PX = 960;
/** Point colours: a full inlier, a point the fit down-weighted, a point of a view without a
 * fit (app.css has the same colours for the legend). */
const POINT_COLOUR = { inlier: "#00c8ff", outlier: "#ff3030", nofit: "#bbbbbb" };
/** The residual scales offered; "auto" takes the largest that draws the 95th percentile
 * residual of the used views at most AUTO_FRACTION of the photo's width long. */
const SCALES = [1, 3, 10, 30, 100, 300, 1000, 3000, 10000];
const AUTO_FRACTION = 0.03;
/** Coefficient names of each lens model, in OpenCV's order. */
const COEFFICIENTS = {
  plumb_bob: ["k1", "k2", "p1", "p2", "k3"],
  rational_polynomial: ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"],
  equidistant: ["k1", "k2", "k3", "k4"],
};

const calib = { files: [], figures: [], answer: null };

// ---- the tabs ----------------------------------------------------------------------------

/** Shows the tab `id` (and its panel), hides the other; focuses it when `focus`. */
function selectTab(id, focus) {
  for (const tabId of TABS) {
    const tab = $(tabId);
    const selected = tabId === id;
    tab.setAttribute("aria-selected", String(selected));
    tab.tabIndex = selected ? 0 : -1;
    $(tab.getAttribute("aria-controls")).hidden = !selected;
  }
  if (focus) $(id).focus();
}

/** Arrow keys, Home and End move between the tabs (the WAI-ARIA tabs pattern). */
function tabKeys(event) {
  const k = TABS.indexOf(event.target.id);
  const n = TABS.length;
  const next = { ArrowRight: (k + 1) % n, ArrowLeft: (k + n - 1) % n, Home: 0, End: n - 1 }[event.key];
  if (next === undefined) return;
  event.preventDefault();
  selectTab(TABS[next], true);
}

// ---- the request -------------------------------------------------------------------------

function chooseCalibrationFiles(files) {
  calib.files = [...(files || [])];
  const n = calib.files.length;
  const names = calib.files.slice(0, 5).map((f) => f.name).join(", ") + (n > 5 ? ", …" : "");
  $("calib-chosen").textContent = n === 0 ? "" : n + (n === 1 ? " photo: " : " photos: ") + names;
  $("calib-chosen").dataset.count = String(n);
}

function showCalibrationError(title, detail, meta) {
  $("calib-error-title").textContent = title;
  $("calib-error-detail").textContent = detail || "";
  $("calib-error-meta").textContent = meta || "";
  $("calib-error").hidden = false;
  $("calib-error").focus();
}

async function showCalibrationProblem(response) {
  const type = response.headers.get("content-type") || "";
  if (!type.includes("json")) {
    showCalibrationError("HTTP " + response.status, await response.text());
    return;
  }
  const problem = await response.json();
  const meta = [problem.code && "code: " + problem.code, problem.field && "field: " + problem.field, "HTTP " + response.status].filter(Boolean).join(" · ");
  showCalibrationError(problem.title || "Request refused", problem.detail, meta);
}

async function sendCalibration(event) {
  event.preventDefault();
  if (calib.files.length === 0) {
    showCalibrationError("No photos", "Choose or drop 3 to 100 photos of the printed code first.");
    return;
  }
  const size = numberOrNull("calib-size-mm");
  if (!(size > 0)) {
    showCalibrationError("No marker size", "Give the printed code's side in mm.");
    return;
  }
  const data = new FormData();
  const json = JSON.stringify({ marker: { size_mm: size }, model: $("calib-model").value });
  data.append("request", new Blob([json], { type: "application/json" }));
  for (const file of calib.files) data.append("image", file, file.name);
  const files = calib.files.slice();
  $("calib-send").disabled = true;
  $("calib-status").textContent = "Calibrating from " + files.length + " photos…";
  const started = performance.now();
  try {
    const response = await apiFetch(CALIBRATE_PATH, { method: "POST", body: data });
    if (response.ok) {
      await showCalibration(await response.json(), files);
      $("calib-status").textContent = "Done in " + ((performance.now() - started) / 1000).toFixed(1) + " s.";
    } else {
      $("calib-status").textContent = "Refused.";
      await showCalibrationProblem(response);
    }
  } catch (err) {
    $("calib-status").textContent = "";
    showCalibrationError("The server could not be reached", String(err));
  } finally {
    $("calib-send").disabled = false;
  }
}

// ---- the numbers -------------------------------------------------------------------------

/** A parameter's row: its value ± its standard deviation (exact numbers in data-value and
 * data-std; "undetermined" where the answer has none). */
function parameterRow(dl, field, label, value, std, digits, unit) {
  dl.append(el("dt", {}, label));
  const spread = std === null || std === undefined ? " (σ undetermined)" : " ± " + fixed(std, digits);
  const dd = el("dd", { "data-field": field, "data-value": String(value) }, fixed(value, digits) + spread + (unit ? " " + unit : ""));
  if (std !== null && std !== undefined) dd.dataset.std = String(std);
  dl.append(dd);
}

function cameraList(answer) {
  const dl = $("calib-camera");
  dl.replaceChildren();
  const c = answer.camera, s = answer.std;
  parameterRow(dl, "fx_px", "fx", c.fx_px, s.fx_px, 2, "px");
  parameterRow(dl, "fy_px", "fy", c.fy_px, s.fy_px, 2, "px");
  parameterRow(dl, "cx_px", "cx", c.cx_px, s.cx_px, 2, "px");
  parameterRow(dl, "cy_px", "cy", c.cy_px, s.cy_px, 2, "px");
  const model = c.distortion.model;
  dl.append(el("dt", {}, "lens model"), el("dd", { "data-field": "model" }, model));
  const names = COEFFICIENTS[model] || [];
  for (const name of names) {
    parameterRow(dl, "distortion." + name, name, c.distortion[name] || 0, s.distortion[name], 5, "");
  }
  const rms = answer.reprojection_rms_px;
  dl.append(el("dt", {}, "reprojection RMS"),
    el("dd", { "data-field": "reprojection_rms_px", "data-value": String(rms) }, fixed(rms, 3) + " px"));
}

function viewsTable(answer, files) {
  const body = $("calib-views").tBodies[0];
  body.replaceChildren();
  for (const view of answer.views) {
    const tr = el("tr", { "data-view-index": String(view.index), "data-used": String(view.used) });
    const file = files[view.index];
    const outliers = view.image_points.filter((p) => p.weight !== null && p.weight < 1).length;
    const fitted = view.image_points.some((p) => p.weight !== null);
    const used = el("td", { "data-field": "used" }, view.used ? "yes" : "no: " + (view.detail || view.dropped));
    if (!view.used) {
      used.dataset.dropped = view.dropped;
      used.className = "flag-yes";
    }
    tr.append(
      el("td", {}, String(view.index + 1)),
      el("td", { class: "file" }, file ? file.name : ""),
      used,
      el("td", { class: "num", "data-field": "points" }, String(view.points)),
      el("td", { class: "num", "data-field": "rms_px" }, fixed(view.rms_px, 3)),
      el("td", { class: "num", "data-field": "median_px" }, fixed(view.median_px, 3)),
      el("td", { class: "num", "data-field": "down_weighted" }, fitted ? String(outliers) : "—"),
    );
    body.append(tr);
  }
}

function downloadLink(id, text) {
  $(id).href = "data:application/x-yaml;charset=utf-8," + encodeURIComponent(text);
}

async function showCalibration(answer, files) {
  calib.answer = answer;
  $("calib-error").hidden = true;
  const used = answer.views.filter((v) => v.used);
  const points = used.reduce((n, v) => n + v.points, 0);
  $("calib-summary").textContent = used.length + " of " + answer.views.length + " photos used, "
    + points + " points, " + answer.image.width_px + " × " + answer.image.height_px + " px.";
  $("calib-summary").dataset.used = String(used.length);
  cameraList(answer);
  const details = answer.warning_details || [];
  $("calib-warnings").replaceChildren(...details.map((w) => el("li", { "data-code": w.code }, w.code + ": " + w.detail)));
  if (details.length === 0) $("calib-warnings").append(el("li", { class: "ok" }, "No warnings: the photos constrain the camera."));
  downloadLink("calib-download-opencv", answer.opencv_yaml);
  downloadLink("calib-download-ros", answer.ros_camera_info_yaml);
  viewsTable(answer, files);
  $("calib-json").textContent = JSON.stringify(answer, null, 2);
  $("calib-results").hidden = false;
  await loadFigures(answer, files);
  drawCalibration();
  $("calib-heading").focus();
}

// ---- drawing -----------------------------------------------------------------------------

/** The factor a figure is drawn at: the photo, at most FIGURE_MAX_PX on its longer side. */
function figureScale(image) {
  return Math.min(1, FIGURE_MAX_PX / Math.max(image.width_px, image.height_px));
}

/** Each photo decoded at its figure's size (null where this browser cannot read it), and
 * one figure (canvas and caption) per view. */
async function loadFigures(answer, files) {
  for (const figure of calib.figures) if (figure.bitmap) figure.bitmap.close();
  const s = figureScale(answer.image);
  const width = Math.max(1, Math.round(answer.image.width_px * s));
  const height = Math.max(1, Math.round(answer.image.height_px * s));
  calib.figures = [];
  const holder = $("calib-figures");
  holder.replaceChildren();
  for (const view of answer.views) {
    let bitmap = null;
    try {
      bitmap = await createImageBitmap(files[view.index], { resizeWidth: width, resizeHeight: height, resizeQuality: "medium" });
    } catch (_) { /* not an image this browser reads: the points are drawn on grey */ }
    const canvas = el("canvas", { id: "calib-view-" + view.index, "data-view-index": String(view.index), role: "img",
      "aria-label": "Photo " + (view.index + 1) + " with its calibration points and their residual vectors" });
    const name = files[view.index] ? files[view.index].name : "";
    const caption = el("figcaption", {}, "Photo " + (view.index + 1) + (name ? " (" + name + ")" : "") + ": "
      + (view.used ? view.points + " points, RMS " + fixed(view.rms_px, 3) + " px" : "not used: " + (view.detail || view.dropped)));
    const figure = el("figure", { "data-view-index": String(view.index) });
    const enlarge = el("button", { type: "button", class: "small", "aria-pressed": "false",
      "aria-label": "Photo " + (view.index + 1) + " at full width" }, "Enlarge");
    enlarge.addEventListener("click", () => {
      const wide = figure.classList.toggle("wide");
      enlarge.setAttribute("aria-pressed", String(wide));
      enlarge.textContent = wide ? "Shrink" : "Enlarge";
    });
    caption.append(" ", enlarge);
    figure.append(canvas, caption);
    holder.append(figure);
    calib.figures.push({ view, bitmap, canvas });
  }
}

/** The residual scale: the one chosen, or the auto one (see SCALES). */
function residualScale(answer) {
  const chosen = $("calib-scale").value;
  if (chosen !== "auto") return Number(chosen);
  const lengths = answer.views.filter((v) => v.used).flatMap((v) => v.image_points)
    .filter((p) => p.residual_px !== null).map((p) => Math.hypot(p.residual_px[0], p.residual_px[1]))
    .sort((a, b) => a - b);
  if (lengths.length === 0) return 1;
  const p95 = lengths[Math.min(lengths.length - 1, Math.floor(0.95 * lengths.length))];
  const fitting = SCALES.filter((k) => k * p95 <= AUTO_FRACTION * answer.image.width_px);
  return fitting.length > 0 ? fitting[fitting.length - 1] : 1;
}

function pointColour(point) {
  if (point.weight === null) return POINT_COLOUR.nofit;
  return point.weight < 1 ? POINT_COLOUR.outlier : POINT_COLOUR.inlier;
}

/** A canvas the photo's size times `s`, with `bitmap` (or grey) under it. */
function startCanvas(canvas, image, s, bitmap) {
  canvas.width = Math.max(1, Math.round(image.width_px * s));
  canvas.height = Math.max(1, Math.round(image.height_px * s));
  const ctx = canvas.getContext("2d");
  if (bitmap) ctx.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
  else { ctx.fillStyle = "#333"; ctx.fillRect(0, 0, canvas.width, canvas.height); }
  return ctx;
}

/** One view: each point as a dot, its residual vector (reprojected minus measured, times
 * `scale`) as a line from it; down-weighted points last, so that they show. */
function drawView(figure, image, s, scale) {
  const ctx = startCanvas(figure.canvas, image, s, figure.bitmap);
  const radius = Math.max(1.5, figure.canvas.width / 400);
  const ordered = figure.view.image_points.slice().sort((a, b) => (b.weight ?? 2) - (a.weight ?? 2));
  ctx.lineWidth = Math.max(1, radius / 1.5);
  for (const point of ordered) {
    const x = (point.image_px[0] + 0.5) * s, y = (point.image_px[1] + 0.5) * s;
    const colour = pointColour(point);
    ctx.strokeStyle = colour;
    ctx.fillStyle = colour;
    if (point.residual_px !== null) {
      ctx.beginPath();
      ctx.moveTo(x, y);
      ctx.lineTo(x + point.residual_px[0] * scale * s, y + point.residual_px[1] * scale * s);
      ctx.stroke();
    }
    ctx.beginPath();
    ctx.arc(x, y, radius, 0, 2 * Math.PI);
    ctx.fill();
  }
  figure.canvas.dataset.points = String(ordered.length);
  figure.canvas.dataset.scale = String(s);
  figure.canvas.dataset.residualScale = String(scale);
  figure.canvas.dataset.state = "drawn";
}

/** Every view's points on one image (used views' in the inlier colour, the others' grey),
 * over the answer's coverage grid, each cell shaded by its count of used points. */
function drawCoverage(answer) {
  const canvas = $("calib-coverage");
  const s = figureScale(answer.image);
  const ctx = startCanvas(canvas, answer.image, s, null);
  const { grid, counts } = answer.coverage;
  const most = Math.max(1, ...counts);
  const cw = canvas.width / grid, ch = canvas.height / grid;
  ctx.font = Math.max(11, Math.round(ch / 6)) + "px system-ui, sans-serif";
  for (let row = 0; row < grid; row++) {
    for (let col = 0; col < grid; col++) {
      const n = counts[row * grid + col];
      ctx.fillStyle = "rgba(11, 92, 173, " + (0.6 * n / most).toFixed(3) + ")";
      ctx.fillRect(col * cw, row * ch, cw, ch);
      ctx.strokeStyle = "#888";
      ctx.lineWidth = 1;
      ctx.strokeRect(col * cw, row * ch, cw, ch);
      ctx.fillStyle = n === 0 ? "#ff8080" : "#fff";
      ctx.fillText(String(n), col * cw + 6, row * ch + ch / 5 + 6);
    }
  }
  let drawn = 0;
  for (const view of answer.views.slice().sort((a, b) => Number(a.used) - Number(b.used))) {
    ctx.fillStyle = view.used ? POINT_COLOUR.inlier : POINT_COLOUR.nofit;
    for (const point of view.image_points) {
      ctx.fillRect((point.image_px[0] + 0.5) * s - 1, (point.image_px[1] + 0.5) * s - 1, 2, 2);
      if (view.used) drawn += 1;
    }
  }
  const covered = counts.filter((n) => n > 0).length;
  const corner = (row, col) => counts[row * grid + col];
  $("calib-coverage-note").textContent = "Used points per cell of the answer's " + grid + " × " + grid
    + " grid (coverage.counts): " + covered + " of " + counts.length + " cells hold points; the corner cells "
    + [corner(0, 0), corner(0, grid - 1), corner(grid - 1, 0), corner(grid - 1, grid - 1)].join(", ")
    + " (top left, top right, bottom left, bottom right). Grey points: views not used.";
  $("calib-coverage-note").dataset.covered = String(covered);
  canvas.dataset.points = String(drawn);
  canvas.dataset.state = "drawn";
}

function drawCalibration() {
  const answer = calib.answer;
  if (!answer) return;
  const s = figureScale(answer.image);
  const scale = residualScale(answer);
  for (const figure of calib.figures) drawView(figure, answer.image, s, scale);
  drawCoverage(answer);
  $("calib-scale-note").textContent = "Residual vectors (the calibrated camera's projection of each point minus where it "
    + "was measured) are drawn " + scale + " times their length: a line " + scale + " px long on the photo is a residual of 1 px. "
    + "Cyan: full inliers; red: points the fit down-weighted as outliers; grey: views without a fit.";
  $("calib-scale-note").dataset.residualScale = String(scale);
}

// ---- events ------------------------------------------------------------------------------

function setUpCalibrationDrop() {
  const zone = $("calib-drop-zone");
  const stop = (event) => { event.preventDefault(); event.stopPropagation(); };
  for (const name of ["dragenter", "dragover"]) zone.addEventListener(name, (e) => { stop(e); zone.classList.add("over"); });
  for (const name of ["dragleave", "drop"]) zone.addEventListener(name, (e) => { stop(e); zone.classList.remove("over"); });
  zone.addEventListener("drop", (event) => {
    const files = event.dataTransfer && event.dataTransfer.files;
    if (files && files.length > 0) chooseCalibrationFiles(files);
  });
}

document.addEventListener("DOMContentLoaded", () => {
  for (const id of TABS) {
    $(id).addEventListener("click", () => selectTab(id, false));
    $(id).addEventListener("keydown", tabKeys);
  }
  if (location.hash === "#calibration") selectTab("tab-calibration", false);
  $("calib-setup").addEventListener("submit", sendCalibration);
  $("calib-photos").addEventListener("change", () => chooseCalibrationFiles($("calib-photos").files));
  $("calib-scale").addEventListener("change", drawCalibration);
  setUpCalibrationDrop();
  document.body.dataset.calibrationReady = "true";
});
