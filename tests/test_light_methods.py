"""Every light-side method on every shipped scene it can render, at its default parameters.

lt, pm, sppm and ppb against pt, whose agreement with Mitsuba covers every shipped scene
(test_parity: the box scenes; test_parity_media: fog-perlin, fog-step, smoke, juice;
test_caustic_scenes: crepuscular, volcaustic), on a 16 x 16 film: the image mean, the four
quadrants and the 4 x 4 pixel blocks must agree beyond each one's noise and beyond a bias
allowance (parity.multiscale_agreement: the largest |z| within its Bonferroni bound and the
chi-square at parity.ALPHA, per scale). The radii and light paths per iteration are the
defaults (the radii derived by the pilot, methods/radii.py); camera paths are 16 per pixel and
iteration (pm, sppm, ppb), which changes neither.

lt is unbiased: no allowance. It renders the scenes whose camera sees no glass (a pinhole
cannot be connected through a specular surface: cbox-glass, juice and volcaustic show their
glass black) and is not inside a medium (its variance is infinite there: crepuscular,
volcaustic).

pm, sppm and ppb are consistent: their kernels' bias is of order r where a kernel straddles an
edge, a corner or a boundary (docs/methods.md). Their allowance at each scale is c r, with r
the mean over the run's iterations of the method's widest kernel radius (pm: its fixed radius;
sppm and ppb: their schedules'), and c measured for each scene, method and scale (BIAS, by
bench/bench_light_bias.py: 128 iterations at seed 11 against pt at 64 x 2048 spp; c is the
largest |relative deviation| + 2 standard errors over the cells of that scale, over r): the
bound holds for the bias of these radii, whatever they are, and grows with them. A radius
picked small to hide the bias is what the old tests did; these run at the defaults.

Power: each check fails with 5 % of the light taken from any one quadrant, or moved from one
quadrant to the opposite one (a blur that keeps the image mean), beyond the allowance of the
quadrants (parity.assert_multiscale_check_has_power with the loss plus that allowance).
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_small
from parity import (
    Estimate,
    Scales,
    assert_multiscale_check_has_power,
    iteration_images,
    multiscale_agreement,
    ours,
)
from renderer.methods import get_method
from renderer.methods.pt import PathTracing

RES = 16
SCENES = [
    "cbox", "cbox-fog", "cbox-glass", "cbox-grid", "crepuscular",
    "fog-perlin", "fog-step", "juice", "smoke", "volcaustic",
]  # fmt: skip
LT_SCENES = ["cbox", "cbox-fog", "cbox-grid", "fog-perlin", "fog-step", "smoke"]
# iterations, and method parameters besides the defaults
RUNS = {
    "lt": (24, {}),
    "pm": (48, {"spp_per_iteration": 16}),
    "sppm": (48, {"spp_per_iteration": 16}),
    "ppb": (96, {"spp_per_iteration": 16}),
}
LOSS = 0.05
# c of the allowance c r for (mean, quadrants, blocks), per scene and method (module docstring)
BIAS: dict[str, dict[str, tuple[float, float, float]]] = {}

_references: dict[str, Estimate] = {}


def reference(name: str) -> Estimate:
    """pt's image of the scene: 16 images of 256 spp."""
    if name not in _references:
        _references[name] = ours(
            PathTracing, load_small(name, RES, RES), 16, seed=99, spp_per_wave=256
        )
    return _references[name]


def mean_radius(method, iterations: int) -> float:
    """The mean over the run's iterations of the widest of the method's kernel radii."""
    kernel = method.camera_paths.kernel
    media = list(method.native.medium_ids.values())
    if method.id == "ppb":
        radii = [
            [kernel.radius(i, m) for m in media] + [kernel.surface_radius(i)]
            for i in range(iterations)
        ]
    else:
        radii = [
            [kernel.volume_radius(i, m) for m in media] + [kernel.surface_radius(i)]
            for i in range(iterations)
        ]
    return float(np.mean(radii, axis=0).max())


def run(name: str, method_id: str) -> tuple[Estimate, Scales]:
    iterations, params = RUNS[method_id]
    method = get_method(method_id)(load_small(name, RES, RES), seed=3, threads=2, params=params)
    est = Estimate(iteration_images(method, iterations))
    if method_id == "lt":
        return est, Scales()
    r = mean_radius(method, iterations)
    c = BIAS[name][method_id]
    return est, Scales(*(ci * r for ci in c))


def check(name: str, method_id: str) -> None:
    est, allowance = run(name, method_id)
    ref = reference(name)
    agrees, detail = multiscale_agreement(est, ref, allowance)
    ratio = est.mean.mean() / ref.mean.mean()
    print(f"{name} {method_id}: mean {ratio - 1:+.2%}, allowance {allowance}; {detail}")
    assert agrees, f"{name} {method_id}: allowance {allowance}: {detail}"
    assert_multiscale_check_has_power(
        est, ref, f"{name} {method_id}", LOSS + allowance.quadrants, allowance
    )


# One class per method: pytest-xdist's loadscope runs each on a worker of its own.
class TestLt:
    @pytest.mark.parametrize("name", LT_SCENES)
    def test_agrees_with_pt(self, name):
        check(name, "lt")


class TestPm:
    @pytest.mark.parametrize("name", SCENES)
    def test_agrees_with_pt(self, name):
        check(name, "pm")


class TestSppm:
    @pytest.mark.parametrize("name", SCENES)
    def test_agrees_with_pt(self, name):
        check(name, "sppm")


class TestPpb:
    @pytest.mark.parametrize("name", SCENES)
    def test_agrees_with_pt(self, name):
        check(name, "ppb")
