"""Generate cloud.vdb: a procedural cumulus written with pyopenvdb (no real cloud .vdb can be
downloaded here). Deterministic: the same voxels every run (OpenVDB stamps each file with a
random UUID, so the bytes differ).

A flat-bottomed heap of overlapping puffs (smooth balls of different sizes), its edge eaten
into by fractal Perlin noise; the density rises over a thin rim to a saturated interior. Voxels
are 2/64 world units; voxel (0, 0, 0) is centred at (-1, -1, -1) + half a voxel, so the 64^3
index box [0, 63]^3 fills [-1, 1]^3 (the scene declares that box; zero voxels stay inactive).
With the scene's sigma_t the optical depth along a line through the core is a few hundred.

Run: python scenes/cloud/make_cloud.py  (needs pyopenvdb and numpy < 2)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderer.volumes import fbm, write_vdb

RES = 64
VOXEL = 2.0 / RES
ORIGIN = np.array([-1.0, -1.0, -1.0])
# Puffs: centre (x, y, z) and radius, in world units.
PUFFS = [
    ((0.0, -0.15, 0.0), 0.55),
    ((-0.45, -0.3, 0.1), 0.4),
    ((0.45, -0.28, -0.05), 0.42),
    ((0.1, 0.25, 0.05), 0.42),
    ((-0.2, 0.1, -0.3), 0.35),
    ((0.3, 0.05, 0.35), 0.33),
    ((-0.3, 0.35, 0.25), 0.28),
]


def cloud(res: int = RES) -> np.ndarray:
    idx = np.stack(np.meshgrid(*(np.arange(res),) * 3, indexing="ij"), axis=-1)
    p = ORIGIN + (idx + 0.5) * VOXEL  # world positions of voxel centres
    # Signed distance-like field: how far inside the union of puffs, in units of their radii.
    inside = np.full(p.shape[:3], -np.inf)
    for centre, radius in PUFFS:
        d = 1.0 - np.linalg.norm(p - np.asarray(centre), axis=-1) / radius
        inside = np.maximum(inside, d)
    inside -= 0.35 * np.clip((-0.45 - p[..., 1]) / 0.1, 0.0, None)  # a flat base
    noise = fbm(p * np.array([1.0, 1.3, 1.0]), octaves=5, frequency=2.5, lacunarity=2.0,
                gain=0.5, seed=23)  # fmt: skip
    shaped = inside + 0.35 * noise
    # A rim about 0.15 of a radius deep, then saturated.
    density = np.clip(shaped / 0.15, 0.0, 1.0) ** 1.5
    density[density < 1e-3] = 0.0
    return density.astype(np.float32)


if __name__ == "__main__":
    out = Path(__file__).with_name("cloud.vdb")
    d = cloud()
    write_vdb(out, d, VOXEL, tuple(ORIGIN + 0.5 * VOXEL))
    print(
        f"{out}: {np.count_nonzero(d)} active voxels, mean {d.mean():.4f}, "
        f"{out.stat().st_size / 1e6:.2f} MB"
    )
