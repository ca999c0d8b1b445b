"""Schemathesis hooks for scripts/schemathesis.sh: image bodies that are images.

No schema can say "the bytes of a JPEG", so schemathesis would send random bytes to the image
endpoints and every one would be refused (422 `undecodable_image`), leaving the success path
of those endpoints unfuzzed. Here the image media types draw from photos that `qrpose render`
made (the paths in QRPOSE_ST_IMAGES, colon-separated) and, one time in eight, from arbitrary
bytes, so that refusals are still exercised.
"""
import os

import schemathesis
from hypothesis import strategies as st

_photos = [open(p, "rb").read() for p in os.environ.get("QRPOSE_ST_IMAGES", "").split(":") if p]


def _image_bytes():
    """A rendered photo seven times in eight, else a few arbitrary bytes."""
    noise = st.binary(min_size=1, max_size=64)
    if not _photos:
        return noise
    return st.integers(0, 7).flatmap(lambda k: noise if k == 0 else st.sampled_from(_photos))


for media_type in ("image/jpeg", "image/png", "image/jpeg, image/png"):
    schemathesis.openapi.media_type(media_type, _image_bytes())
