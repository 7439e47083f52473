"""Parity with Mitsuba 3 on the media scenes, for each unbiased transmittance estimator.

smoke (OpenVDB plume), fog-perlin (Perlin fog, Mie tabphase), fog-step (step function) and
juice (medium inside a dielectric mesh) rendered by our pt with integrator.estimator = delta,
ratio and residual must agree with Mitsuba's volpath within measured noise (two-sample z-scores
of 4x4-block means and of the image mean, Bonferroni/chi-square as tests/parity.py). The biased
ray-marching estimator is not asserted here; bench/bench_media.py measures its bias. juice has
a homogeneous medium only (closed forms), so one estimator covers it.
"""

from __future__ import annotations

import pytest

from conftest import load_small
from parity import agreement, mitsuba, ours
from renderer.methods.pt import PathTracing

ALPHA = 1e-3
RES = 16
# Independent images x spp each, for both renderers. The per-image spp must be high enough for
# the per-image means to be near normal (the z-scores estimate the variance from 32 images):
# juice's caustic paths through the liquid are heavy-tailed and need more.
IMAGES = 32
SPP = {"smoke": 32, "fog-perlin": 32, "fog-step": 32, "juice": 64}
CASES = [
    (scene, est)
    for scene in ("smoke", "fog-perlin", "fog-step")
    for est in ("delta", "ratio", "residual")
] + [("juice", "ratio")]

_mitsuba_cache: dict = {}


@pytest.fixture(scope="module", params=CASES, ids=[f"{s}-{e}" for s, e in CASES])
def estimates(request):
    name, estimator = request.param
    scene = load_small(name, RES, RES, (f"integrator.estimator={estimator}",))
    if name not in _mitsuba_cache:
        _mitsuba_cache[name] = mitsuba(scene, IMAGES, SPP[name])
    mine = ours(PathTracing, scene, IMAGES, spp_per_wave=SPP[name])
    return f"{name}/{estimator}", mine, _mitsuba_cache[name]


def test_mean_radiance_matches_mitsuba(estimates):
    name, a, b = estimates
    result = agreement(a.image_mean(), b.image_mean(), ALPHA)
    assert result.max_abs_z < result.z_limit, f"{name}: {result}"


def test_blocks_match_mitsuba(estimates):
    name, a, b = estimates
    result = agreement(a.blocks(4), b.blocks(4), ALPHA)
    assert result.p_value > ALPHA, f"{name}: {result}"
    assert result.max_abs_z < result.z_limit, f"{name}: {result}"
