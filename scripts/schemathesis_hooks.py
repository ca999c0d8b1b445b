"""Schemathesis hooks for scripts/schemathesis.sh: image bodies that are images, and, in the
positive run only, generated requests mapped into what the server accepts where no schema can
say it.

Image bodies. No schema can say "the bytes of a JPEG", so schemathesis would send random
bytes to the image endpoints and every one would be refused (422 `undecodable_image`). Here
the image media types (the raw bodies and the multipart `image` part) draw from photos that
`qrpose render` made (the paths in QRPOSE_ST_IMAGES, colon-separated). In the negative run one
time in eight they are arbitrary bytes instead, so that refusals are still exercised; in the
positive run they are always photos (rule: bytes that are not a JPEG or PNG are
`undecodable_image`).

The positive run (QRPOSE_ST_MODE=positive) checks `positive_data_acceptance`: every request
valid by the document must be answered 2xx. The document is as strict as the server except
for the residue that no schema can state (docs/service.md,
Fuzzing). Each mapping below takes a generated request into the valid subset for one rule of
that residue, and nothing else; the negative run (QRPOSE_ST_MODE=negative) maps nothing and
sends what it generates. A mapped request must still be valid by the document: the hooks
check it against the operation's schema and raise when it is not (and schemathesis
re-validates what a hook changed: a request that the mapping made invalid would count as
negative data, and its 200 would fail `negative_data_rejection`).

1. Magnitudes beyond double precision (`non_finite_number`, `numerically_degenerate`,
   `invalid_prior` for a quaternion of norm under 1e-9): a pixel pitch of 5e-324 µm makes
   the focal length in pixels infinite, a quaternion of 1e-200 cannot be normalised, corners
   1e-9 px apart at 1e6 px coincide once rounded. Every number of a pose request (JSON body,
   `request` part, query) is brought within MIN_MAGNITUDE <= |x| <= MAX_MAGNITUDE, sign kept,
   zero kept. Distortion coefficients are brought within |k| <= MAX_DISTORTION instead
   (rule: a corner that cannot be undistorted with the coefficients is
   `undistortion_failed`; mild coefficients near the image centre always can be).
2. The corners of `POST /v1/pose/corners` (rule: the quadrilateral is convex, clockwise on
   screen, its corners distinct, and no three within 1e-6 of a line: `non_convex_corners`,
   `mirrored_corners`, `duplicate_corners`, `collinear_corners`; and a pose exists, else
   `no_solution`). They are replaced by the image of a square of the request's marker size
   (the site's 50 mm when the request gives none) at a pose in front of the request's
   camera: 4 to 20 sizes away, within 0.15 of the distance off axis, tilted up to 50°, any
   roll; through the request's lens (`camera.distortion`, OpenCV's models as the server
   reads them: the server undistorts them back to the square's exact image), then in
   pixels through the camera's intrinsics (the site camera's for `camera.id`: the site's
   cameras here have no distortion), in image-plane mm through `focal_length_mm`, in the
   request's `corner_order`. The pose is
   drawn from a generator seeded with the generated corners, so different generated
   requests give different quadrilaterals. Only corners generated as the document says
   (four distinct pairs of two numbers) are replaced: others are sent as generated, so that
   a document looser than the server would show. The camera's pixel aspect fy/fx is
   brought within [1/2, 2] (at 1e9 a square's image is a line: collinear).
3. A camera id the loaded site does not know (`unknown_camera`): any generated `camera.id`
   or `camera_id` becomes a camera of the site (QRPOSE_ST_SITE, the YAML file the server
   loaded).
4. The raw image body's camera across query parameters and its marker size without a site
   (OpenAPI cannot make parameters required for one media type only: `incomplete_camera`,
   `missing_field`): the query's camera is completed into the one form its parameters
   start (a site camera by `camera_id`; the sensor form when it has `focal_length_mm` or
   `pixel_size_um` and no `fx_px`/`fy_px`; else the pixel form), missing values taken from
   the rendered photos' camera (1000 px, 639.5, 359.5; 4 mm over 4 µm), the parameters of
   the other forms dropped; without a site a missing `marker_size_mm` is 50. The lens
   model's coefficients likewise: a coefficient the query's `distortion_model` does not have
   is dropped (the JSON form says it with `const: 0`, flat parameters cannot).
5. The paper's iteration (Eq. 12) settles only on axis and square on: off axis or tilted the
   true depths repel it (docs/paper-reproduction.md, "Why the printed method falls short"),
   and a gain above 1 overshoots; it then drifts until the solved corners are collinear
   (`no_solution`). With `method = paper` the square of rule 2 is drawn on the axis, square
   on (any roll), and a `gain` above 1 becomes 1 (the paper's own value). Square on means
   once undistorted: rule 2 draws the square through the lens, as a camera would, because
   corners taken as ideal and undistorted by the server would be a tilted square's, which
   repels the iteration even for coefficients of 0.01. Not converging
   within `max_iterations` is an answer (`converged: false`), not a refusal.
6. `points = finders` needs `method = reprojection` (`points_need_reprojection`). The JSON
   forms say it (the document's `not`), flat query parameters cannot, nor can the merge of a
   multipart body's query parameters under its `request` part (the part winning, field by
   field for the solver): when the request the server reads breaks it, the query's `points`
   and `method` are dropped, which leaves the part's own (valid) choice.
7. The photos of `POST /v1/calibrate` (rule: the photos show one printed code, decoded in
   at least three of them, from one camera at one resolution: `no_code_found`,
   `too_few_views`, `mixed_image_sizes`; and each photo costs a detection, so that many
   exceed the request timeout, 503 `timeout`, which `not_a_server_error` counts as a
   failure). The `image` parts become views of one code that `qrpose render` made from
   different angles at one size (the paths in QRPOSE_ST_VIEWS, colon-separated), cycled,
   MAX_CALIBRATION_PHOTOS of them at most; the `request` part gets rule 1.
8. A robot pose's quaternion must be a unit one (within 1e-3, `invalid_robot_pose`): every
   `quaternion_wxyz` of a `flange_pose` is normalised (a zero one becomes the identity).
   The photos of `POST /v1/calibrate/hand-eye` (rules: one flange pose per photo,
   `flange_poses_mismatch`; at least four photos with the code read, `too_few_views`; motions
   about two axes, `degenerate_motion`) become the views of rule 7, all four, and the
   request the session they are: the render's camera and code size, and each view's flange
   pose from its true pose with a fixed mount and target (so the views agree).
"""
import hashlib
import json
import math
import os
import random

import schemathesis
import yaml
from hypothesis import strategies as st

_photos = [open(p, "rb").read() for p in os.environ.get("QRPOSE_ST_IMAGES", "").split(":") if p]
_views = [open(p, "rb").read() for p in os.environ.get("QRPOSE_ST_VIEWS", "").split(":") if p]
_positive = os.environ.get("QRPOSE_ST_MODE") == "positive"
_site_file = os.environ.get("QRPOSE_ST_SITE", "")
_site = yaml.safe_load(open(_site_file)) if _site_file else None

MIN_MAGNITUDE = 1e-2
MAX_MAGNITUDE = 1e4
MAX_DISTORTION = 1e-2
_DISTORTION = {"k1", "k2", "k3", "k4", "k5", "k6", "p1", "p2"}
# The coefficients each lens model has (docs/calibration.md).
_MODEL_COEFFICIENTS = {
    "plumb_bob": {"k1", "k2", "p1", "p2", "k3"},
    "rational_polynomial": _DISTORTION,
    "equidistant": {"k1", "k2", "k3", "k4"},
}
_CORNERS = "/v1/pose/corners"
_IMAGE_ROUTES = ("/v1/pose/image", "/v1/pose/image/annotated")
_CALIBRATE = "/v1/calibrate"
_HAND_EYE = "/v1/calibrate/hand-eye"
# The views of rule 7 as scripts/schemathesis.sh renders them: 320 × 240, f 1000 px, a 50 mm
# code whose centre is 250 mm ahead, R = Rx(alpha)·Ry(beta), in QRPOSE_ST_VIEWS's order.
_VIEW_ANGLES_DEG = [(0.0, 0.0), (25.0, 0.0), (0.0, 25.0), (-20.0, 15.0)]
_VIEW_CAMERA = {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 159.5, "cy_px": 119.5}
_VIEW_CODE_MM = 50.0
_VIEW_DEPTH_MM = 250.0
MAX_CALIBRATION_PHOTOS = 4
_PIXEL_FORM = ("fx_px", "fy_px", "cx_px", "cy_px")
_SENSOR_FORM = ("focal_length_mm", "pixel_size_um", "cx_px", "cy_px")
_PHOTO_CAMERA = {"fx_px": 1000.0, "fy_px": 1000.0, "cx_px": 639.5, "cy_px": 359.5,
                 "focal_length_mm": 4.0, "pixel_size_um": 4.0}
_SITE_MARKER_MM = 50.0
_NON_REPROJECTION = ("paper", "depth-newton")


def _image_bytes():
    """A rendered photo; in the negative run, one time in eight a few arbitrary bytes."""
    noise = st.binary(min_size=1, max_size=64)
    if not _photos:
        return noise
    if _positive:
        return st.sampled_from(_photos)
    return st.integers(0, 7).flatmap(lambda k: noise if k == 0 else st.sampled_from(_photos))


for media_type in ("image/jpeg", "image/png", "image/jpeg, image/png"):
    schemathesis.openapi.media_type(media_type, _image_bytes())


# Rule 1: magnitudes.

def _bounded(x, low, high):
    """`x` with its magnitude brought within [low, high], sign kept; zero and bools kept."""
    if isinstance(x, bool) or not isinstance(x, (int, float)) or x == 0:
        return x
    magnitude = min(max(abs(x), low), high)
    if isinstance(x, int):
        return int(math.copysign(max(round(magnitude), 1), x))
    return math.copysign(magnitude, x)


def _within_range(value, key=None):
    """`value` (a JSON value) with every number bounded by rule 1."""
    if isinstance(value, dict):
        return {k: _within_range(v, k) for k, v in value.items()}
    if isinstance(value, list):
        return [_within_range(v, key) for v in value]
    if key in _DISTORTION:
        return _bounded(value, 0.0, MAX_DISTORTION)
    return _bounded(value, MIN_MAGNITUDE, MAX_MAGNITUDE)


# Rule 3: site cameras.

def _site_cameras():
    return (_site or {}).get("cameras") or {}


def _known_camera_id(generated):
    """A camera of the loaded site, chosen by `generated`."""
    ids = sorted(_site_cameras())
    return ids[sum(str(generated).encode()) % len(ids)]


# Rule 2: corners as the image of a square in front of the camera.

def _rotation(rng, max_tilt_deg):
    """A rotation matrix: any roll about the optical axis, then a tilt of up to
    `max_tilt_deg`."""
    roll = rng.uniform(0, 2 * math.pi)
    tilt = math.radians(rng.uniform(0, max_tilt_deg))
    phi = rng.uniform(0, 2 * math.pi)
    ax, ay = math.cos(phi), math.sin(phi)
    c, s = math.cos(tilt), math.sin(tilt)
    # Rodrigues about the in-plane axis (ax, ay, 0).
    tilt_m = [[c + ax * ax * (1 - c), ax * ay * (1 - c), ay * s],
              [ax * ay * (1 - c), c + ay * ay * (1 - c), -ax * s],
              [-ay * s, ax * s, c]]
    cr, sr = math.cos(roll), math.sin(roll)
    roll_m = [[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]]
    return [[sum(tilt_m[i][k] * roll_m[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def _normalised_square(size_mm, rng, on_axis):
    """The four corners (top-left, top-right, bottom-right, bottom-left of the symbol) of a
    square of side `size_mm` at a random pose in front of the camera, as (x/z, y/z); with
    `on_axis`, centred on the optical axis and square on."""
    h = size_mm / 2
    r = _rotation(rng, 0 if on_axis else 50)
    z = size_mm * rng.uniform(4, 20)
    off = 0 if on_axis else 0.15
    t = (z * rng.uniform(-off, off), z * rng.uniform(-off, off), z)
    out = []
    for px, py in ((-h, -h), (h, -h), (h, h), (-h, h)):
        p = [r[i][0] * px + r[i][1] * py + t[i] for i in range(3)]
        out.append((p[0] / p[2], p[1] / p[2]))
    return out


def _distorted(x, y, distortion):
    """The normalised point (x, y) through the lens `distortion` (the request's JSON form;
    None for none): OpenCV's models, as crates/qrpose-core/src/geometry/distortion/."""
    if not distortion:
        return x, y
    k = {name: distortion.get(name) or 0.0 for name in _DISTORTION}
    r2 = x * x + y * y
    if distortion.get("model") == "equidistant":
        r = math.sqrt(r2)
        if r == 0:
            return x, y
        theta = math.atan(r)
        t2 = theta * theta
        theta_d = theta * (1 + t2 * (k["k1"] + t2 * (k["k2"] + t2 * (k["k3"] + t2 * k["k4"]))))
        return x * theta_d / r, y * theta_d / r
    # plumb_bob is the rational model with k4 = k5 = k6 = 0 (the document's `const: 0`).
    radial = (1 + r2 * (k["k1"] + r2 * (k["k2"] + r2 * k["k3"]))) / (
        1 + r2 * (k["k4"] + r2 * (k["k5"] + r2 * k["k6"])))
    p1, p2 = k["p1"], k["p2"]
    return (x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y)


def _camera_of(camera):
    """(fx, fy, cx, cy) of a pixel, sensor or site camera; (f, f, 0, 0) of the image plane."""
    if "id" in camera:
        intrinsics = _site_cameras()[camera["id"]]["intrinsics"]
        return intrinsics["fx_px"], intrinsics["fy_px"], intrinsics["cx_px"], intrinsics["cy_px"]
    if "fx_px" in camera:
        return camera["fx_px"], camera["fy_px"], camera["cx_px"], camera["cy_px"]
    if "cx_px" in camera:
        f_px = camera["focal_length_mm"] / (camera["pixel_size_um"] / 1000)
        return f_px, f_px, camera["cx_px"], camera["cy_px"]
    return camera["focal_length_mm"], camera["focal_length_mm"], 0.0, 0.0


def _map_corners_request(body):
    key = "corners_px" if "corners_px" in body else "corners_mm"
    # As generated: bounding magnitudes (rule 1) may make distinct corners coincide, and
    # the square replaces them anyway.
    generated = body[key]
    as_documented = len(generated) == 4 and all(len(c) == 2 for c in generated) and len(
        {tuple(c) for c in generated}) == 4
    body = _within_range(body)
    solver = body.get("solver") or {}
    paper = solver.get("method") == "paper"
    if paper and solver.get("gain", 1.0) > 1.0:
        solver["gain"] = 1.0
    camera = body["camera"]
    if "id" in camera:
        camera["id"] = _known_camera_id(camera["id"])
    if "fx_px" in camera:
        camera["fy_px"] = camera["fx_px"] * min(max(camera["fy_px"] / camera["fx_px"], 0.5), 2.0)
    if not as_documented:
        body[key] = generated
        return body
    seed = hashlib.sha256(json.dumps(generated).encode()).digest()
    rng = random.Random(seed)
    size_mm = (body.get("marker") or {}).get("size_mm", _SITE_MARKER_MM)
    fx, fy, cx, cy = _camera_of(camera)
    lens = camera.get("distortion")
    corners = [[cx + fx * xd, cy + fy * yd]
               for xd, yd in (_distorted(x, y, lens) for x, y in _normalised_square(size_mm, rng, paper))]
    if body.get("corner_order") == "paper":
        tl, tr, br, bl = corners
        corners = [br, tr, tl, bl]
    body[key] = corners
    return body


# Rules 4 and 5: the image routes' query.

def _complete_raw_camera(query):
    """The query's camera completed into the one form its parameters start (rule 4)."""
    if _site is not None and "camera_id" in query:
        query["camera_id"] = _known_camera_id(query["camera_id"])
        for name in _PIXEL_FORM + _SENSOR_FORM + tuple(_DISTORTION) + ("distortion_model",):
            query.pop(name, None)
        return
    query.pop("camera_id", None)
    sensor = ("focal_length_mm" in query or "pixel_size_um" in query) and not (
        "fx_px" in query or "fy_px" in query)
    form, other = (_SENSOR_FORM, _PIXEL_FORM) if sensor else (_PIXEL_FORM, _SENSOR_FORM)
    for name in other:
        if name not in form:
            query.pop(name, None)
    for name in form:
        query.setdefault(name, _PHOTO_CAMERA[name])
    if _site is None:
        query.setdefault("marker_size_mm", _SITE_MARKER_MM)


def _read_points_and_method(query, part):
    """`points` and the solver's `method` of the request the server reads: the part's over
    the query's (`src/api/image/merge.rs`)."""
    points = part["points"] if "points" in part else query.get("points")
    solver = part.get("solver") or {}
    method = solver["method"] if "method" in solver else query.get("method")
    return points, method


def _map_image_query(query, part):
    """Rules 1, 4 and 5 for the query of an image route; `part` is the multipart `request`
    part, None for a raw body."""
    query = _within_range(dict(query))
    # The lens model takes only its own coefficients (the JSON form's `const: 0`; flat
    # parameters cannot say it): the others are dropped.
    model = query.get("distortion_model", "plumb_bob")
    model = model if isinstance(model, str) else None
    for name in _DISTORTION - _MODEL_COEFFICIENTS.get(model, _DISTORTION):
        query.pop(name, None)
    if part is None:
        _complete_raw_camera(query)
    points, method = _read_points_and_method(query, part or {})
    if points == "finders" and method in _NON_REPROJECTION:
        query.pop("points", None)
        query.pop("method", None)
    return query


def _map_image_part(part):
    """Rules 1 and 3 for the multipart `request` part."""
    part = _within_range(part)
    camera = part.get("camera") or {}
    if "id" in camera:
        camera["id"] = _known_camera_id(camera["id"])
    return part


# Rule 8: robot poses.

def _unit_quaternions(value):
    """`value` with every `quaternion_wxyz` normalised (zero: the identity)."""
    if isinstance(value, dict):
        out = {k: _unit_quaternions(v) for k, v in value.items()}
        q = out.get("quaternion_wxyz")
        if isinstance(q, list) and len(q) == 4 and all(isinstance(c, (int, float)) for c in q):
            norm = math.sqrt(sum(c * c for c in q))
            out["quaternion_wxyz"] = [c / norm for c in q] if norm > 0 else [1.0, 0.0, 0.0, 0.0]
        return out
    if isinstance(value, list):
        return [_unit_quaternions(v) for v in value]
    return value


def _matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def _rot_x(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return [[1, 0, 0], [0, c, -s], [0, s, c]]


def _rot_y(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return [[c, 0, s], [0, 1, 0], [-s, 0, c]]


def _pose(r, t):
    return (r, t)


def _compose(a, b):
    (ra, ta), (rb, tb) = a, b
    return (_matmul(ra, rb), [sum(ra[i][k] * tb[k] for k in range(3)) + ta[i] for i in range(3)])


def _inverse(a):
    r, t = a
    rt = [[r[j][i] for j in range(3)] for i in range(3)]
    return (rt, [-sum(rt[i][k] * t[k] for k in range(3)) for i in range(3)])


def _wire(pose):
    """A pose as the wire's quaternion form (w ≥ 0)."""
    r, t = pose
    w = math.sqrt(max(0.0, 1.0 + r[0][0] + r[1][1] + r[2][2])) / 2.0
    if w > 1e-6:
        x, y, z = ((r[2][1] - r[1][2]) / (4 * w), (r[0][2] - r[2][0]) / (4 * w),
                   (r[1][0] - r[0][1]) / (4 * w))
    else:  # a half turn: never one of the views
        x, y, z = 1.0, 0.0, 0.0
    return {"translation_mm": t, "quaternion_wxyz": [w, x, y, z]}


def _hand_eye_poses(setup, count):
    """The flange poses of the first `count` views (cycled) for `setup`, with a fixed mount X
    and target Y: eye-in-hand F = Y·T_marker←camera·X⁻¹, eye-to-hand F = X·T_camera←marker·Y⁻¹."""
    mount = _pose(_matmul(_rot_x(10.0), _rot_y(-5.0)), [20.0, -30.0, 80.0])
    target = _pose(_rot_y(180.0), [600.0, 0.0, 0.0]) if setup == "eye_in_hand" else _pose(
        _rot_x(5.0), [0.0, 0.0, 120.0])
    poses = []
    for i in range(count):
        alpha, beta = _VIEW_ANGLES_DEG[i % len(_VIEW_ANGLES_DEG)]
        marker_in_camera = _pose(_matmul(_rot_x(alpha), _rot_y(beta)), [0.0, 0.0, _VIEW_DEPTH_MM])
        if setup == "eye_in_hand":
            flange = _compose(_compose(target, _inverse(marker_in_camera)), _inverse(mount))
        else:
            flange = _compose(_compose(mount, marker_in_camera), _inverse(target))
        poses.append(_wire(flange))
    return poses


def _map_hand_eye_form(operation, form):
    """Rules 1, 3 and 8 for the multipart form of `POST /v1/calibrate/hand-eye`."""
    request = _within_range(form["request"])
    request.pop("marker", None)
    request["marker"] = {"size_mm": _VIEW_CODE_MM}
    request["camera"] = dict(_VIEW_CAMERA)
    if _views:
        form["image"] = list(_views)
    count = len(form.get("image") or [])
    request["flange_poses"] = _hand_eye_poses(request.get("setup"), count)
    form["request"] = request
    photos = ["photo"] * count
    _assert_valid_body(operation, "multipart/form-data", {**form, "image": photos})


# Validity of what the mappings give.

def _validator(operation, media_type):
    from schemathesis.core.jsonschema import make_validator
    from schemathesis.core.parameters import ParameterLocation
    from schemathesis.specs.openapi.utils import read_from_wire
    from schemathesis.transport.serialization import contains_binary

    alternative = operation.get_body_for_media_type(media_type)
    return make_validator(alternative.validation_schema, operation.schema.adapter.jsonschema_validator_cls)


def _assert_valid_body(operation, media_type, body):
    validator = _validator(operation, media_type)
    errors = [e.message for e in validator.iter_errors(body)]
    if errors:
        raise AssertionError(f"a mapped {media_type} body is not valid by the document: {errors[:3]}; {body!r}")


def _is_image_route(context):
    return context.operation is not None and context.operation.path in _IMAGE_ROUTES


def _map_calibrate_form(operation, form):
    """Rules 1 and 7 for the multipart form of `POST /v1/calibrate`."""
    form["request"] = _within_range(form["request"])
    if isinstance(form.get("image"), list) and _views:
        count = min(len(form["image"]), MAX_CALIBRATION_PHOTOS)
        form["image"] = [_views[i % len(_views)] for i in range(count)]
    photos = ["photo"] * len(form.get("image") or [])
    _assert_valid_body(operation, "multipart/form-data", {**form, "image": photos})


@schemathesis.hook
def map_body(context, body):
    """The multipart `request` part and image (rules 1 and 3), the calibration's photos
    (rule 7); positive run only.

    Done here rather than in `map_case`: a multipart body holds bytes, which schemathesis
    cannot re-validate, so a body changed after generation would count as negative."""
    if not _positive or context.operation is None:
        return body
    form = getattr(body, "body", body)
    if not isinstance(form, dict) or not isinstance(form.get("request"), dict):
        return body
    if context.operation.path == _CALIBRATE:
        _map_calibrate_form(context.operation, form)
        return body
    if context.operation.path == _HAND_EYE:
        _map_hand_eye_form(context.operation, form)
        return body
    if not _is_image_route(context):
        return body
    form["request"] = _unit_quaternions(_map_image_part(form["request"]))
    if not isinstance(form.get("image"), (bytes, bytearray)) and _photos:
        form["image"] = _photos[0]
    _assert_valid_body(context.operation, "multipart/form-data", {**form, "image": "photo"})
    return body


@schemathesis.hook
def map_case(context, case):
    """The corners request (rules 1 to 3) and the image routes' query (rules 1, 4, 5), for
    positive cases of the positive run."""
    if not _positive or case.meta is None or not case.meta.generation.mode.is_positive:
        return case
    if case.operation.path == _CORNERS and isinstance(case.body, dict):
        case.body = _unit_quaternions(_map_corners_request(case.body))
        _assert_valid_body(case.operation, case.media_type, case.body)
    elif case.operation.path in _IMAGE_ROUTES:
        form = getattr(case.body, "get", lambda _key: None)
        part = form("request") if case.media_type == "multipart/form-data" else None
        if case.media_type == "multipart/form-data" and not isinstance(part, dict):
            return case
        case.query = _map_image_query(case.query or {}, part)
    return case


# One false report, in the negative run.

_JSON_TYPES = (dict, list, str, int, float, bool, type(None))

def _without_bytes(form):
    """A multipart body with each part of bytes (ours, or schemathesis's own `Binary`) written
    as a binary string, which is what the document says it is."""
    return {k: ("bytes" if isinstance(v, (bytes, bytearray)) or type(v) not in _JSON_TYPES else v)
            for k, v in form.items()}


@schemathesis.hook
def filter_failure(context, failure, case, response):
    """Keeps every failure but one false report of `negative_data_rejection`.

    Schemathesis labels a generated multipart body negative without validating it when a
    part is bytes (`filter_values` in schemathesis/specs/openapi/negative/__init__.py returns
    at `contains_binary`), and the `image` part, `format: binary`, always is. A mutation
    that changes nothing then yields a valid request labelled negative: dropping `format`
    from a number, which JSON Schema checks on strings only. The server answers it 200, as it
    should. Such a report is dropped only when the request as sent is valid by the document:
    its query against the operation's parameters (read as the server reads text), its body
    (each part of bytes standing for the binary string it is) against the multipart schema. Each one dropped is written to
    QRPOSE_ST_DROPPED, and schemathesis prints it as "dropped by `filter_failure`"."""
    from schemathesis.core.failures import AcceptedNegativeData
    from schemathesis.core.jsonschema import make_validator
    from schemathesis.core.parameters import ParameterLocation
    from schemathesis.specs.openapi.utils import read_from_wire
    from schemathesis.transport.serialization import contains_binary

    if not isinstance(failure, AcceptedNegativeData) or case.media_type != "multipart/form-data":
        return True
    if not isinstance(case.body, dict) or not contains_binary(case.body):
        return True
    operation = case.operation
    validator_cls = operation.schema.adapter.jsonschema_validator_cls
    body_valid = _validator(operation, case.media_type).is_valid(_without_bytes(case.body))
    query = make_validator(operation.query.validation_schema, validator_cls)
    # As the server reads it: `"false"` sent for a boolean is `false` (as schemathesis itself
    # reads parameters when it re-validates a case).
    query_valid = query.is_valid(case.query or {}) or query.is_valid(
        read_from_wire(operation, ParameterLocation.QUERY, case.query or {}))
    if not (body_valid and query_valid):
        return True
    dropped = os.environ.get("QRPOSE_ST_DROPPED")
    if dropped:
        with open(dropped, "a") as f:
            f.write(f"{case.operation.label} {case.id}: valid by the document, labelled negative\n")
    return False
