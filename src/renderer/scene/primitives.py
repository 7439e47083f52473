"""Triangle generators for the built-in shapes, in object space.

Every triangle's geometric normal is normalise(cross(v1 - v0, v2 - v0)) and points to the
stated side: +z for the rectangle, outwards for the cube and the sphere. Vertices are float64
(V, 3), faces int32 (F, 3).
"""

from __future__ import annotations

import numpy as np

Mesh = tuple[np.ndarray, np.ndarray]


def rectangle() -> Mesh:
    """[-1, 1]^2 in the z = 0 plane, normal +z (Mitsuba's ``rectangle``)."""
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)
    return v, f


def cube() -> Mesh:
    """[-1, 1]^3 with outward normals; 8 shared corners, 12 triangles."""
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
    # corner index = 4*(x>0) + 2*(y>0) + (z>0); each quad listed counter-clockwise seen from outside
    quads = [
        (0, 1, 3, 2),  # -x
        (4, 6, 7, 5),  # +x
        (0, 4, 5, 1),  # -y
        (2, 3, 7, 6),  # +y
        (0, 2, 6, 4),  # -z
        (1, 5, 7, 3),  # +z
    ]
    f = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(f, dtype=np.int32)


def icosphere(subdivisions: int) -> Mesh:
    """Unit sphere: an icosahedron split ``subdivisions`` times (20 * 4^n triangles)."""
    p = (1 + 5**0.5) / 2
    verts = [
        [-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0],
        [0, -1, p], [0, 1, p], [0, -1, -p], [0, 1, -p],
        [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1],
    ]  # fmt: skip
    faces = [
        (0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
        (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
        (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
        (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1),
    ]  # fmt: skip
    v = [np.array(x, dtype=np.float64) / np.linalg.norm(x) for x in verts]
    midpoint: dict[tuple[int, int], int] = {}  # edge -> index of its (projected) midpoint

    def mid(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in midpoint:
            m = v[a] + v[b]
            v.append(m / np.linalg.norm(m))
            midpoint[key] = len(v) - 1
        return midpoint[key]

    for _ in range(subdivisions):
        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(v), np.array(faces, dtype=np.int32)


def face_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Unnormalised geometric normals cross(v1 - v0, v2 - v0), length = 2 * triangle area."""
    return np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])


def area(v: np.ndarray, f: np.ndarray) -> float:
    return float(0.5 * np.linalg.norm(face_normals(v, f), axis=1).sum())
