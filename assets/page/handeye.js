// The setup page's hand-eye tab (src/http/routes/page.rs; docs/hand-eye.md): sends photos of
// one printed code and the robot's flange pose of each to POST /v1/calibrate/hand-eye and
// shows the camera's pose on the robot (T_flange←camera or T_robot←camera), the code's, one
// standard deviation per axis, the reprojection RMS, every photo's residuals, the warnings
// in words and the site file's `mount:` to copy. The poses are pasted one line per photo as
// the controller gives them (docs/hand-eye.md, The controllers' pose conventions) and checked
// here before anything is sent. Runs after app.js and calibrate.js and uses their helpers
// ($, el, fixed, numberOrNull, apiFetch, selectTab). Stable hooks for tests: ids, data-field
// / data-value on the numbers, data-view-index on each view's row, data-code on warnings.
"use strict";

const HAND_EYE_PATH = "/v1/calibrate/hand-eye";
/** The server's limits on the photos (crate::app::MIN_HAND_EYE_VIEWS, MAX_HAND_EYE_PHOTOS). */
const HAND_EYE_MIN_PHOTOS = 4;
const HAND_EYE_MAX_PHOTOS = 100;
/** How far |q| may be from 1 (the server's QUATERNION_NORM_TOLERANCE). */
const QUATERNION_NORM_TOL = 1e-3;
/** Numbers per line of each rotation form: the position, then the rotation. */
const POSE_FORMS = {
  quaternion_wxyz: { count: 7, names: "x y z w qx qy qz" },
  rotation_vector_rad: { count: 6, names: "x y z rx ry rz" },
  euler_zyx_deg: { count: 6, names: "x y z a b c" },
};
const HAND_EYE_WARNING_TEXT = {
  few_views: "Few photos were used: take 8 or more for a mount you can rely on.",
  small_rotations: "The photos turn little between them: the mount is poorly constrained. Turn the flange 20-40° about different axes.",
  outlier_view: "A photo disagreed with the others and was left out: a pose from the wrong line, or the arm still moving?",
  little_image_coverage: "The code is small in some photos: their distance is poorly measured. Bring the camera closer.",
  not_converged: "The fit stopped on its iteration budget: the answer may not be the best one.",
};

const handEye = { files: [] };

// ---- the poses ---------------------------------------------------------------------------

/** A refusal of the pasted poses, shown before anything is sent. */
class PoseTextError extends Error {
  constructor(detail, line) {
    super(detail);
    this.line = line;
  }
}

/** The poses pasted in `text`, one non-empty line each, as the wire's robot poses in `form`
 * (a key of POSE_FORMS), the positions multiplied by `toMm`. Brackets, parentheses and
 * braces are ignored; numbers are separated by spaces, tabs, commas or semicolons.
 * Throws PoseTextError naming the line of the first problem. */
function parsePoses(text, form, toMm) {
  const expected = POSE_FORMS[form];
  const poses = [];
  text.split(/\r?\n/).forEach((raw, k) => {
    const line = raw.replace(/[[\](){}]/g, " ").trim();
    if (line === "") return;
    const where = "Line " + (k + 1);
    const words = line.split(/[\s,;]+/).filter((w) => w !== "");
    if (words.length !== expected.count) {
      throw new PoseTextError(where + " has " + words.length + " numbers; this form takes " + expected.count + " (" + expected.names + ").", k + 1);
    }
    const numbers = words.map(Number);
    const bad = words.findIndex((w, i) => !/^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/.test(w) || !Number.isFinite(numbers[i]));
    if (bad >= 0) throw new PoseTextError(where + ": \"" + words[bad] + "\" is not a number.", k + 1);
    const pose = { translation_mm: numbers.slice(0, 3).map((v) => v * toMm) };
    const rotation = numbers.slice(3);
    if (form === "quaternion_wxyz") {
      const norm = Math.hypot(...rotation);
      if (Math.abs(norm - 1) > QUATERNION_NORM_TOL) {
        throw new PoseTextError(where + ": the quaternion's norm is " + norm.toPrecision(6) + ", not 1: is it w, x, y, z (w first)?", k + 1);
      }
    }
    pose[form] = rotation;
    poses.push(pose);
  });
  return poses;
}

/** Checks the pasted poses as they are typed: how many, against the photos. */
function checkPoses() {
  const status = $("he-poses-status");
  try {
    const poses = parsePoses($("he-poses").value, $("he-pose-form").value, Number($("he-pose-unit").value));
    const n = handEye.files.length;
    status.textContent = poses.length + (poses.length === 1 ? " pose" : " poses") + (n > 0 ? " for " + n + (n === 1 ? " photo." : " photos.") : ".");
    status.dataset.count = String(poses.length);
    status.classList.toggle("flag-yes", n > 0 && poses.length !== n);
  } catch (err) {
    if (!(err instanceof PoseTextError)) throw err;
    status.textContent = err.message;
    status.dataset.count = "";
    status.classList.add("flag-yes");
  }
}

// ---- the request -------------------------------------------------------------------------

function chooseHandEyeFiles(files) {
  handEye.files = [...(files || [])];
  const n = handEye.files.length;
  const names = handEye.files.slice(0, 5).map((f) => f.name).join(", ") + (n > 5 ? ", …" : "");
  $("he-chosen").textContent = n === 0 ? "" : n + (n === 1 ? " photo: " : " photos: ") + names;
  $("he-chosen").dataset.count = String(n);
  checkPoses();
}

/** The camera as the tab's form gives it: intrinsics, or a site camera's id. */
function handEyeCamera() {
  if ($("he-camera-mode-id").checked) return { id: $("he-camera-id").value.trim() };
  const camera = {
    fx_px: numberOrNull("he-fx-px"), fy_px: numberOrNull("he-fy-px"),
    cx_px: numberOrNull("he-cx-px"), cy_px: numberOrNull("he-cy-px"),
  };
  const distortion = { model: "plumb_bob" };
  let any = false;
  for (const k of ["k1", "k2", "p1", "p2", "k3"]) {
    const v = numberOrNull("he-" + k);
    distortion[k] = v === null ? 0 : v;
    any = any || v !== null;
  }
  if (any) camera.distortion = distortion;
  return camera;
}

function showHandEyeError(title, detail, meta) {
  $("he-error-title").textContent = title;
  $("he-error-detail").textContent = detail || "";
  $("he-error-meta").textContent = meta || "";
  $("he-error").hidden = false;
  $("he-error").focus();
}

/** A refusal of the server: its title, detail, code and field; a field inside
 * `flange_poses` is also named by the line it came from. */
async function showHandEyeProblem(response, lines) {
  const type = response.headers.get("content-type") || "";
  if (!type.includes("json")) {
    showHandEyeError("HTTP " + response.status, await response.text());
    return;
  }
  const problem = await response.json();
  const pose = /^\/flange_poses\/(\d+)/.exec(problem.field || "");
  const line = pose ? lines[Number(pose[1])] : undefined;
  const meta = [problem.code && "code: " + problem.code, problem.field && "field: " + problem.field,
    line !== undefined && "the pose on line " + line, "HTTP " + response.status].filter(Boolean).join(" · ");
  showHandEyeError(problem.title || "Request refused", problem.detail, meta);
}

/** The 1-based line of each pasted pose, in order. */
function poseLines(text) {
  const lines = [];
  text.split(/\r?\n/).forEach((raw, k) => {
    if (raw.replace(/[[\](){}]/g, " ").trim() !== "") lines.push(k + 1);
  });
  return lines;
}

async function sendHandEye(event) {
  event.preventDefault();
  const n = handEye.files.length;
  if (n < HAND_EYE_MIN_PHOTOS || n > HAND_EYE_MAX_PHOTOS) {
    showHandEyeError("Photos", "Choose " + HAND_EYE_MIN_PHOTOS + " to " + HAND_EYE_MAX_PHOTOS + " photos of the printed code (" + n + " chosen).");
    return;
  }
  const text = $("he-poses").value;
  let poses;
  try {
    poses = parsePoses(text, $("he-pose-form").value, Number($("he-pose-unit").value));
  } catch (err) {
    if (!(err instanceof PoseTextError)) throw err;
    showHandEyeError("Robot poses", err.message, "line " + err.line + " · nothing was sent");
    return;
  }
  if (poses.length !== n) {
    showHandEyeError("Robot poses", poses.length + (poses.length === 1 ? " pose is" : " poses are") + " pasted for "
      + n + " photos: give one pose per photo, in the photos' order.", "nothing was sent");
    return;
  }
  const camera = handEyeCamera();
  if (camera.id === "") {
    showHandEyeError("Camera", "Give the site file's camera id, or its intrinsics.");
    return;
  }
  const setup = $("he-eye-to-hand").checked ? "eye_to_hand" : "eye_in_hand";
  const body = { setup, camera, flange_poses: poses };
  const size = numberOrNull("he-size-mm");
  if (size !== null) body.marker = { size_mm: size };
  const data = new FormData();
  data.append("request", new Blob([JSON.stringify(body)], { type: "application/json" }));
  const files = handEye.files.slice();
  for (const file of files) data.append("image", file, file.name);
  $("he-send").disabled = true;
  $("he-status").textContent = "Calibrating from " + n + " photos…";
  const started = performance.now();
  try {
    const response = await apiFetch(HAND_EYE_PATH, { method: "POST", body: data });
    if (response.ok) {
      showHandEye(await response.json(), files);
      $("he-status").textContent = "Done in " + ((performance.now() - started) / 1000).toFixed(1) + " s.";
    } else {
      $("he-status").textContent = "Refused.";
      await showHandEyeProblem(response, poseLines(text));
    }
  } catch (err) {
    $("he-status").textContent = "";
    showHandEyeError("The server could not be reached", String(err));
  } finally {
    $("he-send").disabled = false;
  }
}

// ---- the answer --------------------------------------------------------------------------

function numberRow(dl, field, label, value, digits, unit) {
  dl.append(el("dt", {}, label));
  const dd = el("dd", { "data-field": field }, fixed(value, digits) + (unit ? " " + unit : ""));
  if (value !== null && value !== undefined) dd.dataset.value = String(value);
  dl.append(dd);
}

/** Z-Y-X Euler angles (a, b, c) of a unit quaternion, degrees: R = Rz(a)·Ry(b)·Rx(c), as
 * the robot poses are given. */
function eulerZyxDeg([w, x, y, z]) {
  const r20 = 2 * (x * z - w * y);
  const a = Math.atan2(2 * (x * y + w * z), 1 - 2 * (y * y + z * z));
  const b = Math.asin(Math.max(-1, Math.min(1, -r20)));
  const c = Math.atan2(2 * (y * z + w * x), 1 - 2 * (x * x + y * y));
  return [a, b, c].map((v) => v * DEG_PER_RAD);
}

/** A parented pose's numbers, under `prefix` (`camera_pose`, `target_pose`). */
function poseList(dl, prefix, pose) {
  dl.replaceChildren();
  dl.append(el("dt", {}, "given in"), el("dd", { "data-field": prefix + ".parent" }, pose.parent + " frame"));
  ["x", "y", "z"].forEach((axis, i) => numberRow(dl, prefix + ".translation_mm." + axis, axis, pose.translation_mm[i], 2, "mm"));
  ["w", "x", "y", "z"].forEach((axis, i) => numberRow(dl, prefix + ".quaternion_wxyz." + axis, "q" + axis, pose.quaternion_wxyz[i], 6, ""));
  const euler = eulerZyxDeg(pose.quaternion_wxyz);
  ["a (about z)", "b (about y)", "c (about x)"].forEach((label, i) => numberRow(dl, prefix + ".euler_zyx_deg." + "abc"[i], label, euler[i], 3, "°"));
}

function handEyeViews(answer, files) {
  const body = $("he-views").tBodies[0];
  body.replaceChildren();
  const outliers = new Set((answer.warning_details || []).filter((w) => w.code === "outlier_view").flatMap((w) => w.views));
  for (const view of answer.views) {
    const tr = el("tr", { "data-view-index": String(view.index), "data-used": String(view.used) });
    const why = view.payload === null ? "no code read" : outliers.has(view.index) ? "left out as an outlier" : "not used";
    const file = files[view.index];
    tr.append(
      el("td", {}, String(view.index + 1)),
      el("td", { class: "file" }, file ? file.name : ""),
      el("td", { "data-field": "used", class: view.used ? "" : "flag-yes" }, view.used ? "yes" : "no: " + why),
      el("td", { class: "num", "data-field": "points" }, String(view.points)),
      el("td", { class: "num", "data-field": "rms_px" }, fixed(view.rms_px, 3)),
      el("td", { class: "num", "data-field": "rotation_residual_deg" }, fixed(view.rotation_residual_deg, 3)),
      el("td", { class: "num", "data-field": "translation_residual_mm" }, fixed(view.translation_residual_mm, 2)),
    );
    body.append(tr);
  }
}

function showHandEye(answer, files) {
  $("he-error").hidden = true;
  const used = answer.views.filter((v) => v.used).length;
  const inHand = answer.setup === "eye_in_hand";
  $("he-summary").textContent = (inHand ? "Eye-in-hand: the camera on the flange. " : "Eye-to-hand: the camera still, the code on the flange. ")
    + used + " of " + answer.views.length + " photos used; reprojection RMS " + fixed(answer.reprojection_rms_px, 3) + " px.";
  $("he-summary").dataset.used = String(used);
  $("he-camera-heading").textContent = inHand ? "The camera on the flange (T_flange←camera)" : "The camera in the robot frame (T_robot←camera)";
  $("he-target-heading").textContent = inHand ? "The code in the robot frame (T_robot←marker)" : "The code on the flange (T_flange←marker)";
  const cameraDl = $("he-camera-pose");
  poseList(cameraDl, "camera_pose", answer.camera_pose);
  ["x", "y", "z"].forEach((axis, i) => numberRow(cameraDl, "std.rotation_deg." + axis, "σ rotation about the camera's " + axis, answer.std.rotation_deg[i], 4, "°"));
  ["x", "y", "z"].forEach((axis, i) => numberRow(cameraDl, "std.translation_mm." + axis, "σ along the camera's " + axis, answer.std.translation_mm[i], 3, "mm"));
  numberRow(cameraDl, "reprojection_rms_px", "reprojection RMS", answer.reprojection_rms_px, 3, "px");
  poseList($("he-target-pose"), "target_pose", answer.target_pose);
  const details = answer.warning_details || [];
  $("he-warnings").replaceChildren(...details.map((w) => {
    const photos = w.views.length > 0 ? " Photos: " + w.views.map((k) => k + 1).join(", ") + "." : "";
    return el("li", { "data-code": w.code }, (HAND_EYE_WARNING_TEXT[w.code] || w.code) + " (" + w.detail + ")" + photos);
  }));
  if (details.length === 0) $("he-warnings").append(el("li", { class: "ok" }, "No warnings: the photos and poses constrain the mount."));
  $("he-site-mount").textContent = answer.site_mount;
  handEyeViews(answer, files);
  $("he-json").textContent = JSON.stringify(answer, null, 2);
  $("he-results").hidden = false;
  $("he-heading").focus();
}

async function copyMount() {
  try {
    await navigator.clipboard.writeText($("he-site-mount").textContent);
    $("he-status").textContent = "The mount is copied.";
  } catch (_) {
    $("he-status").textContent = "Select the mount and copy it by hand (the clipboard is not available here).";
  }
}

function handEyeCameraModeChanged() {
  const named = $("he-camera-mode-id").checked;
  $("he-named-camera").hidden = !named;
  $("he-intrinsics").hidden = named;
}

document.addEventListener("DOMContentLoaded", () => {
  if (location.hash === "#hand-eye") selectTab("tab-hand-eye", false);
  $("he-setup").addEventListener("submit", sendHandEye);
  $("he-photos").addEventListener("change", () => chooseHandEyeFiles($("he-photos").files));
  for (const id of ["he-poses", "he-pose-form", "he-pose-unit"]) $(id).addEventListener("input", checkPoses);
  $("he-camera-mode-intrinsics").addEventListener("change", handEyeCameraModeChanged);
  $("he-camera-mode-id").addEventListener("change", handEyeCameraModeChanged);
  $("he-copy-mount").addEventListener("click", copyMount);
  document.body.dataset.handEyeReady = "true";
});
