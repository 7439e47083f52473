"""Generate plume.vdb: a procedural smoke plume written with pyopenvdb (no real .vdb can be
downloaded here). Deterministic: the same voxels every run (OpenVDB stamps each file with a
random UUID, so the bytes differ).

A column rises from the floor, widening with height, its centre twisting around the vertical
axis; fractal Perlin noise advected upwards breaks it into wisps, and a dense core runs up its
middle. Voxels are 1/40 world units; voxel (0, 0, 0) is centred at (-1, -0.05, -1) + half a
voxel, so the 80^3 index box [0, 79]^3 fills x, z in [-1, 1], y in [-0.05, 1.95] (the scene
declares that box: the active voxels cover only the plume). Zero voxels stay inactive.

Run: python scenes/smoke/make_plume.py  (needs pyopenvdb and numpy < 2)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderer.volumes import fbm, write_vdb

RES = 80
VOXEL = 2.0 / RES
ORIGIN = np.array([-1.0, -0.05, -1.0])


def plume(res: int = RES) -> np.ndarray:
    idx = np.stack(np.meshgrid(*(np.arange(res),) * 3, indexing="ij"), axis=-1)
    p = ORIGIN + (idx + 0.5) * VOXEL  # world positions of voxel centres
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    h = np.clip(y / 1.7, 0.0, None)  # height along the plume, 0 at the floor
    # The centre line twists around the vertical axis as it rises.
    cx = 0.12 * h * np.cos(4.0 * h) + 0.05
    cz = 0.12 * h * np.sin(4.0 * h)
    radius = 0.15 + 0.3 * h
    rho = np.hypot(x - cx, z - cz) / radius
    envelope = np.exp(-2.5 * rho**2) * np.clip(1.15 - h, 0.0, 1.0)
    envelope *= np.clip(y / 0.08, 0.0, 1.0)  # rises from the floor
    # Wisps: noise sampled in a frame that rises with the smoke and twists with it.
    q = np.stack([x - cx, y * 0.7 - 0.3 * h**2, z - cz], axis=-1)
    noise = fbm(q, octaves=4, frequency=3.0, lacunarity=2.1, gain=0.55, seed=11)
    core = np.exp(-8.0 * rho**2) * np.clip(1.0 - 0.8 * h, 0.0, 1.0)
    density = envelope * np.clip(0.55 + 1.6 * noise, 0.0, None) + 1.2 * core * envelope
    density[density < 2e-3] = 0.0
    return (density / density.max()).astype(np.float32)


if __name__ == "__main__":
    out = Path(__file__).with_name("plume.vdb")
    d = plume()
    write_vdb(out, d, VOXEL, tuple(ORIGIN + 0.5 * VOXEL))
    print(
        f"{out}: {np.count_nonzero(d)} active voxels, mean {d.mean():.4f}, "
        f"{out.stat().st_size / 1e6:.2f} MB"
    )
