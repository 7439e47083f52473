"""Furnace tests of the whole path tracer: scenes whose exact image is known.

A closed box whose six walls face inwards and emit radiance ``L (1 - rho)`` with diffuse
reflectance ``rho`` is filled with a non-absorbing medium (albedo 1) and the camera sits inside
it. Radiance is then L everywhere and in every direction: the box is in equilibrium (emission
plus reflection of L gives L at the walls, and a conservative medium neither adds nor removes
radiance along L-constant fields). So every pixel of an unbiased renderer converges to L,
whatever the medium's density, phase function, heterogeneity or the walls' reflectance.

Each iteration of ``PathTracing`` is an independent estimate; the per-pixel standard error
comes from the spread of the per-iteration images. Means of 2x2-pixel blocks are tested
(Student t, Sidak-corrected over all blocks, channels and cases: a family of its own; single
pixels, at 64 samples an iteration, were skewed enough for a false alarm at that level in one
of 18 case-seeds), and the image mean over all pixels is tested the same
way in a second family (its cases and channels), which resolves biases far below the per-pixel
noise. Each family has a false-alarm rate of stats.ALPHA. Power, asserted below: every case's
image mean rejects a 1 % loss in all channels, and a 5 % loss in any one channel alone (its
noisiest channel has a relative standard error near 0.7 %). The block tests catch only
gross local errors (about 20 % in the noisiest blocks). Rendering
uses max_depth -1 (unbounded, Russian roulette only).
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import stats
from parity import Estimate
from renderer.methods.pt import PathTracing
from renderer.scene import load_scene

L = np.array([1.0, 0.6, 0.3])  # radiance of the furnace, per channel
FILM = (10, 8)
# 64 iterations of 64 spp: enough samples per iteration that per-iteration pixel values are
# close to normal, so the Student t-test on their spread is valid, and enough iterations for
# the power asserted below (at 32 x 32, a 5-10 % loss confined to one case passed).
ITERATIONS = 64
SPP_PER_ITERATION = 64

# Walls of [-1, 1]^3 as the unit rectangle (z = 0, normal +z) rotated by exact matrices so that
# each normal faces into the box (and shared edges have bit-identical vertices).
_WALLS = {
    "floor": ([[1, 0, 0], [0, 0, 1], [0, -1, 0]], [0, -1, 0]),  # normal +y
    "ceiling": ([[1, 0, 0], [0, 0, -1], [0, 1, 0]], [0, 1, 0]),  # normal -y
    "back": ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0, 0, -1]),  # normal +z
    "front": ([[1, 0, 0], [0, -1, 0], [0, 0, -1]], [0, 0, 1]),  # normal -z
    "left": ([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], [-1, 0, 0]),  # normal +x
    "right": ([[0, 0, -1], [0, 1, 0], [1, 0, 0]], [1, 0, 0]),  # normal -x
}


def wall_matrix(rot, offset) -> list[list[float]]:
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = offset
    return m.tolist()


def furnace_yaml(medium: dict, rho: tuple[float, float, float], inner: bool = False) -> dict:
    """The box filled with ``medium``, or (``inner``) empty with the medium inside a smaller
    cube [-0.6, 0.6]^3 with a null (index-matched) boundary. Either way the camera sits in the
    medium and looks out through it at the walls."""
    emission = (L * (1 - np.asarray(rho))).tolist()
    fill = None if inner else "fill"
    shapes = [
        {"name": name, "type": "rectangle", "material": "wall", "emission": emission,
         "exterior": fill, "transform": [{"matrix": wall_matrix(rot, off)}]}
        for name, (rot, off) in _WALLS.items()
    ]  # fmt: skip
    if inner:
        shapes.append({"name": "boundary", "type": "cube", "material": "boundary",
                       "interior": "fill", "transform": [{"scale": 0.6}]})  # fmt: skip
    return {
        "name": "furnace",
        "description": "closed emitting box filled with a conservative medium: the image is L",
        "camera": {
            "origin": [0.1, -0.2, 0.3],
            "target": [1.0, 0.5, -1.0],
            "up": [0, 1, 0],
            "fov": 100,
            "medium": "fill",  # the camera origin is inside the inner cube too
        },
        "film": {"width": FILM[0], "height": FILM[1]},
        "integrator": {"max_depth": -1, "rr_depth": 5},
        "materials": {
            "wall": {"type": "diffuse", "reflectance": list(rho)},
            "boundary": {"type": "null"},
        },
        "media": {"fill": medium},
        "shapes": shapes,
    }


def grid_density() -> np.ndarray:
    """A lumpy [x, y, z] density: thin gas with dense blobs (peak / mean about 6)."""
    n = 16
    x, y, z = np.meshgrid(*([(np.arange(n) + 0.5) / n] * 3), indexing="ij")
    d = np.full((n, n, n), 0.1)
    for c, r, a in [((0.3, 0.4, 0.5), 0.15, 6.0), ((0.7, 0.6, 0.3), 0.1, 10.0),
                    ((0.5, 0.8, 0.8), 0.2, 3.0)]:  # fmt: skip
        d += a * np.exp(-((x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2) / (2 * r * r))
    return d.astype(np.float32)


HOMOGENEOUS = {"type": "homogeneous", "sigma_t": [0.5, 1.0, 2.0], "albedo": 1.0,
               "phase": {"type": "hg", "g": 0.6}}  # fmt: skip
GRID = {"type": "grid", "density": "density.npy", "sigma_t": 1.5, "albedo": 1.0,
        "phase": {"type": "hg", "g": -0.3},
        "transform": [{"scale": 2.0}, {"translate": [-1, -1, -1]}]}  # fmt: skip
# Dense and chromatic: before pt drew its hero channel once per path (medium.h, SpectralMis),
# the densest channel here was heavy-tailed (one iteration's image mean at 3.7 L, pixels at
# 150-210 L, a relative standard error of 4.4 % against 0.2 % for red) and this case failed
# its block and one-channel power tests; now blue's error is 0.5 % and its largest pixel 11 L.
DENSE = {"type": "homogeneous", "sigma_t": [4.0, 6.0, 8.0], "albedo": 1.0,
         "phase": {"type": "isotropic"}}  # fmt: skip
INNER_GRID = dict(GRID, transform=[{"scale": 1.2}, {"translate": [-0.6, -0.6, -0.6]}])
CASES = {  # name: (medium, wall reflectance, medium inside a null-bounded inner cube)
    "homogeneous-black-walls": (HOMOGENEOUS, (0.0, 0.0, 0.0), False),
    "homogeneous-reflective-walls": (HOMOGENEOUS, (0.5, 0.8, 0.2), False),
    "grid-black-walls": (GRID, (0.0, 0.0, 0.0), False),
    "grid-reflective-walls": (GRID, (0.7, 0.3, 0.5), False),
    "null-bounded-dense-medium": (DENSE, (0.4, 0.4, 0.4), True),
    "null-bounded-grid": (INNER_GRID, (0.0, 0.0, 0.0), True),
}
# Two families: a t-test per case, 2x2-pixel block and channel; and one per case on the image
# mean per channel.
BLOCK = 2
BLOCK_LEVEL = stats.sidak(stats.ALPHA, len(CASES) * 3 * (FILM[0] // BLOCK) * (FILM[1] // BLOCK))
MEAN_LEVEL = stats.sidak(stats.ALPHA, len(CASES) * 3)


def render_iterations(folder, medium: dict, rho, inner: bool) -> tuple[np.ndarray, dict]:
    """(ITERATIONS, H, W, 3) independent per-iteration images and the method's stats."""
    np.save(folder / "density.npy", grid_density())
    path = folder / "scene.yaml"
    path.write_text(yaml.safe_dump(furnace_yaml(medium, rho, inner)))
    scene = load_scene(path)
    method = PathTracing(scene, seed=5, threads=2, params={"spp_per_wave": SPP_PER_ITERATION})
    images, previous = [], np.zeros((FILM[1], FILM[0], 3))
    for i in range(ITERATIONS):
        method.run_iteration(i)
        current = method.image()
        # The image is the average of the iterations so far (equal spp each): difference it.
        images.append((i + 1) * current - i * previous)
        previous = current
    return np.array(images), method.stats()


@pytest.fixture(scope="module")
def furnace(tmp_path_factory):
    """Renders of each case, made once per module."""
    cache: dict[str, tuple[np.ndarray, dict]] = {}

    def get(case: str) -> tuple[np.ndarray, dict]:
        if case not in cache:
            cache[case] = render_iterations(tmp_path_factory.mktemp(case), *CASES[case])
        return cache[case]

    return get


def image_mean_p_values(images: np.ndarray) -> np.ndarray:
    """Per channel: the p-value of the image mean against L (Student t over iterations)."""
    image_mean, image_se = stats.mean_and_se(images.mean(axis=(1, 2)))
    return stats.t_p_value(image_mean, L, image_se, len(images) - 1)


@pytest.mark.parametrize("case", list(CASES))
def test_furnace(furnace, case):
    images, info = furnace(case)
    assert info["nonfinite"] == 0
    assert np.all(np.isfinite(images)) and np.all(images >= 0)
    n = len(images)
    blocks = Estimate(images).blocks(BLOCK).samples
    mean, se = stats.mean_and_se(blocks)
    assert np.all(se > 0)
    p = stats.t_p_value(mean, L, se, n - 1)
    worst = np.unravel_index(np.argmin(p), p.shape)
    assert p.min() >= BLOCK_LEVEL, (
        f"block (y, x, c) = {worst}: {mean[worst]:.5f} +- {se[worst]:.5f}, expected "
        f"{L[worst[2]]}, p = {p.min():.3g} < {BLOCK_LEVEL:.3g}"
    )
    # The image mean per channel: independent pixels, so its standard error is small.
    p = image_mean_p_values(images)
    assert np.all(p >= MEAN_LEVEL), (p, MEAN_LEVEL)


@pytest.mark.parametrize("case", list(CASES))
def test_each_case_detects_small_losses(furnace, case):
    """The image-mean test has power in every case on its own: the renders scaled by 0.99 (a
    1 % energy loss) are rejected, and so are renders with one channel alone scaled by 0.95."""
    images, _ = furnace(case)
    p = image_mean_p_values(images * 0.99)
    assert p.min() < MEAN_LEVEL, f"{case}: a 1 % loss passed (p = {p})"
    for channel in range(3):
        scale = np.ones(3)
        scale[channel] = 0.95
        p = image_mean_p_values(images * scale)
        assert p[channel] < MEAN_LEVEL, f"{case}: a 5 % loss in channel {channel} passed ({p})"
