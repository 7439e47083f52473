"""Make density.npy for cbox-grid: a smoke plume (dense core, thin surroundings).

Deterministic (fixed seed). The array is float32, indexed [x, y, z] (y up), 32^3, with a
background of 0.03, a core of peak >= 10x the mean, and smoothed noise for structure.
Run: python scenes/cbox-grid/make_density.py
"""

from pathlib import Path

import numpy as np

RES = 32


def smooth_noise(rng: np.random.Generator, res: int, cutoff: float) -> np.ndarray:
    """White noise low-pass filtered in Fourier space, normalised to [-1, 1]."""
    k = np.fft.fftfreq(res)
    kk = np.sqrt(k[:, None, None] ** 2 + k[None, :, None] ** 2 + k[None, None, :] ** 2)
    n = np.fft.ifftn(np.fft.fftn(rng.standard_normal((res,) * 3)) * np.exp(-((kk / cutoff) ** 2)))
    n = n.real
    return n / np.abs(n).max()


def make() -> np.ndarray:
    rng = np.random.default_rng(20240607)
    c = (np.arange(RES) + 0.5) / RES  # voxel centres in the unit cube
    x, y, z = np.meshgrid(c, c, c, indexing="ij")
    # plume between the two boxes, its axis wobbling with height; radius 0.06 at the floor to
    # 0.2 at the top; a dense blob (the core) part-way up
    ax = 0.42 + 0.06 * np.sin(6.0 * y)
    az = 0.6 + 0.05 * np.cos(5.0 * y)
    radius = 0.06 + 0.14 * y
    plume = np.exp(-((x - ax) ** 2 + (z - az) ** 2) / radius**2) * np.clip(1.1 - y, 0, None)
    core = np.exp(-((x - 0.45) ** 2 + (y - 0.45) ** 2 + (z - 0.6) ** 2) / 0.01)
    d = 3.0 * plume + 5.0 * core
    d *= 1.0 + 0.6 * smooth_noise(rng, RES, 0.12)
    return np.clip(d, 0, None).astype(np.float32) + np.float32(0.03)


if __name__ == "__main__":
    density = make()
    out = Path(__file__).with_name("density.npy")
    np.save(out, density)
    print(
        f"{out}: shape {density.shape}, mean {density.mean():.3f}, max {density.max():.3f}, "
        f"peak/mean {density.max() / density.mean():.1f}"
    )
