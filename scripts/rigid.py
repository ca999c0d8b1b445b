#!/usr/bin/env python3
"""Rigid transforms as the ground truth of qrpose-sim writes them, shared by
scripts/handeye_study.py and scripts/pick_anchor.py: a 4 x 4 matrix of
`{translation_mm, quaternion_wxyz}` and the angle between two rotations. Not meant to be run
by itself."""

import math

import numpy as np


def rigid(spec):
    """4 x 4 matrix of {translation_mm, quaternion_wxyz} (the quaternion normalised)."""
    w, x, y, z = spec["quaternion_wxyz"]
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    r = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = spec["translation_mm"]
    return m


def angle_deg(r_a, r_b):
    """The angle of the rotation between r_a and r_b, degrees."""
    m = r_a.T @ r_b
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(m) - 1) / 2))))
