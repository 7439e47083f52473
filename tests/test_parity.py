"""Parity with Mitsuba 3: our pt and Mitsuba's volpath render the same scene file alike.

Tolerances come from measured variance only: each renderer gives K independent images, and
their means are compared with two-sample z-scores (see parity.py). The test fails with
probability about alpha = 1e-3 per check when both renderers are right.
"""

from __future__ import annotations

import pytest

from conftest import load_small
from parity import agreement, mitsuba, ours
from renderer.methods.pt import PathTracing

ALPHA = 1e-3
RES = 32
# (scene, our iterations x spp per iteration, Mitsuba passes x spp per pass)
CASES = [
    ("cbox", 48, 32, 48, 32),
    ("cbox-fog", 48, 32, 48, 32),
    ("cbox-grid", 48, 32, 48, 32),
    ("cbox-glass", 48, 32, 48, 32),
]


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def estimates(request):
    name, iters, spp, passes, mspp = request.param
    scene = load_small(name, RES, RES)
    return name, ours(PathTracing, scene, iters, spp_per_wave=spp), mitsuba(scene, passes, mspp)


def test_mean_radiance_matches_mitsuba(estimates):
    name, a, b = estimates
    result = agreement(a.image_mean(), b.image_mean(), ALPHA)
    assert result.max_abs_z < result.z_limit, f"{name}: {result}"


def test_blocks_match_mitsuba(estimates):
    name, a, b = estimates
    result = agreement(a.blocks(4), b.blocks(4), ALPHA)
    assert result.p_value > ALPHA, f"{name}: {result}"
    assert result.max_abs_z < result.z_limit, f"{name}: {result}"


def test_pixels_match_mitsuba(estimates):
    name, a, b = estimates
    result = agreement(a, b, ALPHA)
    assert result.max_abs_z < result.z_limit, f"{name}: {result}"
