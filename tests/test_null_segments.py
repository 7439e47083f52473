"""Transmittance over medium segments split by null surfaces, for every method, against
the closed form.

A camera ray crosses a constant, purely absorbing density grid [-1, 1]^3 (optical depth 2
along the axis) that an index-matched null plane cuts in two, then meets an emitting wall:
a pixel is the mean of Le exp(-length in the cube) over its rays, about Le exp(-2) (the
image mean is 2 % below it: off-axis rays cross more of the cube, corner rays leave through
its sides; `expected_image_mean` integrates it). Each segment's transmittance is estimated
separately (ratio tracking over an exact majorant, so each estimate is 0 or 1); the product
is unbiased only if the two segments use independent random numbers. pm once keyed them by
specular depth, which null crossings do not change: both halves drew the same numbers and
the pixels came out about exp(1) = 2.7x too bright.

Power: the standard error of the image mean is 0.8-1.1 % of it over 32 iterations, so with
the t limit (about 4.1) a bias of 5-7 % fails; 7 % less or more light fails for every method
(asserted; with half the camera samples ppb's 7 % more passed).

The second test cuts cbox-fog's scattering fog by three null planes with fog on both sides:
nothing the paths do may change at such a crossing (depth, MIS state, which medium, the
photon and beam estimates on either side), so the image must stay the same.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import stats
from conftest import SCENES, load_small
from parity import Estimate, ours, same_image
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


def expected_image_mean(samples: int = 1000) -> float:
    """Le exp(-L) averaged over the film (midpoint rule, samples^2 rays; ~1e-7 accurate):
    L is the length of the camera ray inside [-1, 1]^3, from slab clipping."""
    camera = SCENE["camera"]
    tan_half = np.tan(np.radians(camera["fov"] / 2))  # square film: the same on both axes
    s = ((np.arange(samples) + 0.5) / samples * 2 - 1) * tan_half
    sx, sy = np.meshgrid(s, s)
    d = np.stack([sx, sy, np.ones_like(sx)], axis=-1)  # the camera looks along +z
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    origin = np.asarray(camera["origin"], float)
    t_in, t_out = np.zeros(sx.shape), np.full(sx.shape, np.inf)
    for a in range(3):
        with np.errstate(divide="ignore"):
            ta, tb = (-1 - origin[a]) / d[..., a], (1 - origin[a]) / d[..., a]
        t_in = np.maximum(t_in, np.minimum(ta, tb))
        t_out = np.minimum(t_out, np.maximum(ta, tb))
    emitted = SCENE["shapes"][0]["emission"]
    return float(emitted * np.exp(-np.clip(t_out - t_in, 0, None)).mean())


ITERATIONS = 32
# Enough samples per iteration for a tight mean on 16 pixels in well under a second each.
PARAMS = {
    "pt": {"spp_per_wave": 128},
    "lt": {"light_paths": 1 << 14},
    "pm": {"light_paths": 256, "spp_per_iteration": 128},
    "sppm": {"light_paths": 256, "spp_per_iteration": 128},
    "ppb": {"light_paths": 256, "spp_per_iteration": 256},
}


@pytest.mark.parametrize("method", list(PARAMS))
def test_segments_split_by_a_null_plane_multiply_their_transmittances(tmp_path, method):
    np.save(tmp_path / "ones.npy", np.ones((2, 2, 2), np.float32))
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(SCENE))
    scene = load_scene(tmp_path / "scene.yaml")
    est = ours(get_method(method), scene, ITERATIONS, seed=3, **PARAMS[method]).image_mean()
    mean, err = float(est.mean.mean()), float(est.stderr.mean())
    expected = expected_image_mean()
    print(f"{method}: {mean:.4f} +- {err:.4f}, expected {expected:.4f}")
    assert err > 0  # the estimate is random, so the check below can fail
    # Student t over the iterations; 1e-3 false alarms over the five methods
    level = stats.sidak(1e-3, len(PARAMS))
    p = float(stats.t_p_value(mean, expected, err, dof=ITERATIONS - 1))
    assert p >= level, (mean, err, p)
    for scale in (0.93, 1.07):  # the check has power: a 7 % bias fails it (module docstring)
        p = float(stats.t_p_value(mean * scale, expected, err * scale, dof=ITERATIONS - 1))
        assert p < level, f"{method}: images x {scale} passed (p = {p:.2g})"


# Three planes through the fog, fog on both sides, their edges inside the fog box.
CUTS = [
    {"name": f"cut-{axis}", "type": "rectangle", "material": "boundary", "interior": "fog",
     "exterior": "fog", "transform": [{"scale": 0.97}, *turn, {"translate": at}]}
    for axis, turn, at in [
        ("x", [{"rotate": {"axis": [0, 1, 0], "angle": 90}}], [0.3, 0, 0]),
        ("y", [{"rotate": {"axis": [1, 0, 0], "angle": 90}}], [0, 0.5, 0]),
        ("z", [], [0, 0, -0.2]),
    ]
]  # fmt: skip
# 12x12; iterations for a 3-5 % difference to fail (measured: factors 0.95 fail them all).
CUT_PARAMS = {
    "pt": ({"spp_per_wave": 16}, 512),
    "lt": ({"light_paths": 1 << 14}, 32),
    "pm": ({"light_paths": 1 << 14, "spp_per_iteration": 8}, 64),
    "sppm": ({"light_paths": 1 << 14, "spp_per_iteration": 8}, 64),
    "ppb": ({"light_paths": 1 << 12, "spp_per_iteration": 8}, 128),
}
CUT_LEVEL = stats.sidak(stats.ALPHA, len(CUT_PARAMS) * 4)  # blocks and mean, chi-square and |z|


@pytest.fixture(scope="module")
def cut_fog(tmp_path_factory):
    doc = yaml.safe_load((SCENES / "cbox-fog" / "scene.yaml").read_text())
    doc["include"] = str(SCENES / "cbox" / "box.yaml")
    doc["shapes"] = doc["shapes"] + CUTS
    path = tmp_path_factory.mktemp("cut-fog") / "scene.yaml"
    path.write_text(yaml.safe_dump(doc))
    return load_scene(path, ["film.width=12", "film.height=12"])


@pytest.mark.parametrize("method", list(CUT_PARAMS))
def test_null_cuts_inside_a_scattering_medium_change_nothing(cut_fog, method):
    """cbox-fog with and without the cuts (independent seeds): 3x3-pixel blocks and the image
    mean agree. A null crossing taken for a specular bounce (pt's MIS then counts the light
    found after it twice) makes pt's image 28 % brighter and fails; the cut image times 0.95
    fails for every method."""
    params, iterations = CUT_PARAMS[method]
    method_cls = get_method(method)
    whole = ours(method_cls, load_small("cbox-fog", 12, 12), iterations, seed=1, **params)
    cut = ours(method_cls, cut_fog, iterations, seed=2, **params)
    same, why = same_image(whole, cut, CUT_LEVEL)
    assert same, (method, why)
    weaker = Estimate(cut.samples * 0.95)
    assert not same_image(whole, weaker, CUT_LEVEL)[0], "the check has no power here"
