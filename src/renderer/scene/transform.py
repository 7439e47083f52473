"""Affine transforms for scene files: a list of ops composed in order into one 4x4 matrix.

Ops (each a one-key mapping), applied to points in the order listed, like Mitsuba's
``<transform>``:  ``{scale: s | [sx, sy, sz]}``, ``{rotate: {axis: [x, y, z], angle: deg}}``
(right-handed, degrees), ``{translate: [x, y, z]}``, ``{matrix: 4x4 rows}`` (acts on column
vectors, last row must be 0 0 0 1).
"""

from __future__ import annotations

import numpy as np


def scale(s: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[0, 0], m[1, 1], m[2, 2] = s
    return m


def translate(t: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = t
    return m


def rotate(axis: np.ndarray, angle_deg: float) -> np.ndarray:
    """Rotation by ``angle_deg`` about ``axis`` (right-hand rule), Rodrigues' formula."""
    x, y, z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    a = np.radians(angle_deg)
    c, s = np.cos(a), np.sin(a)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    m = np.eye(4)
    m[:3, :3] = c * np.eye(3) + s * k + (1 - c) * np.outer([x, y, z], [x, y, z])
    return m


def apply_points(m: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Transform (N, 3) points by the affine 4x4 matrix ``m``."""
    return p @ m[:3, :3].T + m[:3, 3]
