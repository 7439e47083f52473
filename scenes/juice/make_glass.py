"""Generate juice.ply: the closed body of liquid in a glass, a tessellated cylinder (unit radius,
y from 0 to 1, 64 segments) with outward normals (counter-clockwise faces seen from outside).
The scene scales and places it. Deterministic; run: python scenes/juice/make_glass.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

SEGMENTS = 64


def cylinder(segments: int = SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    phi = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.cos(phi), np.zeros(segments), -np.sin(phi)], axis=1)
    bottom, top = ring.copy(), ring + [0, 1, 0]
    verts = np.concatenate([bottom, top, [[0, 0, 0], [0, 1, 0]]])
    c_bottom, c_top = 2 * segments, 2 * segments + 1
    faces = []
    for i in range(segments):
        j = (i + 1) % segments
        # phi turns clockwise seen from +y (ring = (cos, 0, -sin)), so these windings face out.
        faces += [(i, segments + j, segments + i), (i, j, segments + j)]  # side
        faces += [(c_top, segments + i, segments + j)]  # top cap, normal +y
        faces += [(c_bottom, j, i)]  # bottom cap, normal -y
    return verts, np.array(faces, np.int64)


def write_ply(path: Path, verts: np.ndarray, faces: np.ndarray) -> None:
    lines = ["ply", "format ascii 1.0", f"element vertex {len(verts)}",
             "property float x", "property float y", "property float z",
             f"element face {len(faces)}", "property list uchar int vertex_indices",
             "end_header"]  # fmt: skip
    lines += [f"{x:.7g} {y:.7g} {z:.7g}" for x, y, z in verts]
    lines += [f"3 {a} {b} {c}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    v, f = cylinder()
    # Check: every face normal points away from the axis (sides) or along +-y (caps).
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    centre = v[f].mean(axis=1) - [0, 0.5, 0]
    assert np.all(np.einsum("ij,ij->i", n, centre) > 0)
    write_ply(Path(__file__).with_name("juice.ply"), v, f)
