"""Transmittance over medium segments split by null surfaces, for every method, against
the closed form.

A camera ray crosses a constant, purely absorbing density grid [-1, 1]^3 (optical depth 2)
that an index-matched null plane cuts in two, then meets an emitting wall: every pixel is
Le exp(-2). Each segment's transmittance is estimated separately (ratio tracking over an
exact majorant, so each estimate is 0 or 1); the product is unbiased only if the two
segments use independent random numbers. pm once keyed them by specular depth, which null
crossings do not change: both halves drew the same numbers and the pixels came out
Le exp(-1) = 2.7x too bright.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import stats
from parity import ours
from renderer.methods import get_method
from renderer.scene import load_scene

WALL_FACING_CAMERA = [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 2], [0, 0, 0, 1]]
SCENE = {
    "camera": {"origin": [0, 0, -4], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 20},
    "film": {"width": 4, "height": 4},
    "materials": {"wall": {"type": "diffuse", "reflectance": 0.5}, "boundary": {"type": "null"}},
    "media": {"absorber": {"type": "grid", "density": "ones.npy", "sigma_t": 1.0, "albedo": 0.0,
                           "transform": [{"scale": 2}, {"translate": [-1, -1, -1]}]}},
    "shapes": [
        {"type": "rectangle", "material": "wall", "emission": 1.0,
         "transform": [{"scale": 3}, {"matrix": WALL_FACING_CAMERA}]},
        {"type": "cube", "material": "boundary", "interior": "absorber"},
        {"type": "rectangle", "material": "boundary", "interior": "absorber",
         "exterior": "absorber"},  # the cut, at z = 0
    ],
}  # fmt: skip

# Enough samples per iteration for a tight mean on 16 pixels in a second or two.
PARAMS = {
    "pt": {"spp_per_wave": 64},
    "lt": {"light_paths": 1 << 14},
    "pm": {"photons": 256, "spp_per_iteration": 64},
    "sppm": {"photons": 256, "spp_per_iteration": 64},
    "ppb": {"light_paths": 256, "spp_per_iteration": 64},
}


@pytest.mark.parametrize("method", list(PARAMS))
def test_segments_split_by_a_null_plane_multiply_their_transmittances(tmp_path, method):
    np.save(tmp_path / "ones.npy", np.ones((2, 2, 2), np.float32))
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(SCENE))
    scene = load_scene(tmp_path / "scene.yaml")
    est = ours(get_method(method), scene, 8, seed=3, **PARAMS[method]).image_mean()
    mean, err = float(est.mean.mean()), float(est.stderr.mean())
    expected = np.exp(-2.0)
    print(f"{method}: {mean:.4f} +- {err:.4f}, expected {expected:.4f}")
    assert err > 0  # the estimate is random, so the check below can fail
    # Student t on 8 iterations; 1e-3 false alarms over the five methods
    p = float(stats.t_p_value(mean, expected, err, dof=7))
    assert p >= stats.sidak(1e-3, len(PARAMS)), (mean, err, p)
