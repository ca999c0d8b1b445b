"""Poses through a client that openapi-python-client generated (tests/generated_clients.rs).

    python pose.py PARENT PACKAGE BASE_URL PHOTO SITE CORNERS_JSON

PARENT holds the generated package PACKAGE; the server at BASE_URL serves the document it
was generated from. With SITE = 1 the camera is the site's `front` and the marker size the
site's; else the photo's camera (1000 px, principal point at the centre) and 50 mm. Sends
CORNERS_JSON (four [u, v] pairs) to POST /v1/pose/corners and PHOTO (a JPEG) to
POST /v1/pose/image as multipart, each with the generated models, and prints
{"corners": pose, "image": answer} as JSON; exits non-zero with the answer on any status but
200. Only the generated package is used: no request is written by hand.
"""
import importlib
import json
import sys

parent, package, base_url, photo, site, corners_json = sys.argv[1:7]
sys.path.insert(0, parent)


def module(name):
    return importlib.import_module(f"{package}.{name}")


models = module("models")
types = module("types")
client = module("client").Client(base_url=base_url, raise_on_unexpected_status=True, timeout=60)
corners_api = module("api.pose.pose_from_corners")
image_api = module("api.pose.pose_from_image")

if site == "1":
    camera = models.CameraSiteId(id="front")
    sized = {}
else:
    camera = models.CameraPixels(fx_px=1000.0, fy_px=1000.0, cx_px=639.5, cy_px=359.5)
    sized = {"marker": models.MarkerDto(size_mm=50.0)}


def answer(response):
    if response.status_code != 200:
        sys.exit(f"HTTP {response.status_code}: {response.content.decode(errors='replace')}")
    return response.parsed.to_dict()


corners = models.PixelCornersRequest(corners_px=json.loads(corners_json), camera=camera, **sized)
pose = answer(corners_api.sync_detailed(client=client, body=corners))

with open(photo, "rb") as f:
    image = types.File(payload=f, file_name="photo.jpg", mime_type="image/jpeg")
    form = models.PoseFromImageFilesBody(image=image, request=models.ImageRequest(camera=camera, **sized))
    found = answer(image_api.sync_detailed(client=client, body=form))

print(json.dumps({"corners": pose, "image": found}))
