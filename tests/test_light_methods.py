"""Light-side methods on the shipped scenes, at their default parameters.

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
bench/bench_light_bias.py at seed 11; c is the largest |relative deviation| + 2 standard errors
over the cells of that scale, over r: on cbox, cbox-fog, cbox-glass and crepuscular 256 or 128
iterations against pt at 64 x 2048 spp, at the radii of the rule's first version, which their
media hardly changed since (cbox-fog 0.034 -> 0.035; cbox-glass pm 0.043 -> 0.037, ppb 0.014 ->
0.010); on the others 48 iterations against pt at 32 x 512 spp, whose noise the 2 standard
errors make part of c): the bound holds for the bias of these radii, whatever they are, and
grows with them. The scene's cap and the k of today's rule (methods/radii.py) changed the radii
again (e.g. crepuscular pm 0.20 -> 0.046 at the cap, cbox pm 0.026 -> 0.035, ppb's surface
photons about 1.4 times as wide); c was kept, the allowance following r: an O(r) bias. A radius
picked small to hide the bias is what the old tests did; these run at the defaults. Each cell's
colour is judged as a vector beyond the allowance (parity.agreement_beyond). cloud is not
checked here: a check that catches a 5 % loss in a quadrant needs each quadrant's standard
error near 1 %, and on the cloud (a dense, white, strongly forward-scattering medium) that
costs far more than the ~60 CPU seconds the suite can spare. Measured at this test's settings
(16 x 16, one thread, seed 3; the top quadrants, the cloud itself, are the noisiest): pt 1.8 %
after 16 x 256 spp in 11 s (1 % would take ~36 s; this test's usual 32 x 1024 spp ~90 s), lt
10 % after 24 iterations in 1.5 s (1 %: ~150 s), pm 8.8 % after 48 in 3.4 s (~260 s), sppm 9.7 %
after 48 in 3.2 s (~300 s), ppb 14-28 % after 96 in 3.0 s (heavy-tailed; ~2400 s). Within 60 s
(pt 20 s, 10 s each) they would resolve losses of about 23 % (lt), 29 % (pm), 31 % (sppm) and
none worth the name for ppb (over 80 %). docs/methods.md gives the cloud's measured bias.

Power: each check fails with LOSS (5 %) of the light taken from any one quadrant, or moved
from one quadrant to the opposite one (a blur that keeps the image mean), beyond the allowance
of the quadrants (parity.assert_multiscale_check_has_power with the loss plus that allowance);
where the iterations the suite can afford leave a quadrant's standard error above 1 %, the
loss that case resolves is stated instead (NOISY: 6-14 %; 26-28 % on volcaustic).
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

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
# Method parameters besides the defaults: camera paths only, which change no radius.
PARAMS = {"lt": {}, "pm": {"spp_per_iteration": 16}, "sppm": {"spp_per_iteration": 16},
          "ppb": {"spp_per_iteration": 16}}  # fmt: skip
# c of the allowance c r for (mean, quadrants, blocks), per scene and method (module docstring)
BIAS: dict[str, dict[str, tuple[float, float, float]]] = {
    "cbox": {"pm": (0.57, 1.37, 2.06), "sppm": (0.6, 1.44, 2.14), "ppb": (0.88, 1.91, 2.65)},
    "cbox-fog": {"pm": (0.26, 0.67, 1.56), "sppm": (0.26, 0.7, 1.61), "ppb": (0.51, 0.93, 2.24)},
    "cbox-glass": {"pm": (0.28, 0.98, 1.54), "sppm": (0.28, 0.95, 1.48), "ppb": (1.12, 1.69, 4.17)},
    "crepuscular": {"pm": (0.12, 0.2, 0.4), "sppm": (0.17, 0.27, 0.56), "ppb": (0.4, 0.51, 0.84)},
    "cbox-grid": {"pm": (0.58, 2.09, 3.02), "sppm": (0.45, 1.72, 2.48), "ppb": (2.11, 3.18, 4.65)},
    "fog-perlin": {"pm": (0.71, 2.25, 3.25), "sppm": (0.51, 1.75, 2.55), "ppb": (1.79, 3.01, 6.59)},
    "fog-step": {"pm": (0.7, 1.01, 2.14), "sppm": (0.6, 0.91, 1.81), "ppb": (1.26, 1.88, 3.84)},
    "juice": {"pm": (1.04, 2.94, 4.03), "sppm": (0.8, 2.35, 3.23), "ppb": (1.36, 2.15, 2.96)},
    "smoke": {"pm": (0.49, 0.72, 3.5), "sppm": (0.43, 0.66, 2.45), "ppb": (0.35, 0.72, 2.89)},
    "volcaustic": {"pm": (0.68, 1.36, 4.27), "sppm": (0.58, 1.13, 3.6), "ppb": (1.86, 4.62, 8.65)},
}  # fmt: skip
# Iterations of each run (pm, sppm, ppb): enough for a quadrant's standard error of about 1 %
# (with the reference's), where an iteration is cheap; 48 / 48 / 96 where it is not.
ITERATIONS = {
    "cbox": (192, 192, 768),
    "crepuscular": (384, 384, 384),
}
LT_ITERATIONS = 24
# The loss in one quadrant (or moved between two) that each check must catch beyond the
# quadrants' allowance: 5 %, or what that case's noise resolves (5.5 standard errors of a
# quadrant, from the runs that measured BIAS, rounded up to a percent; volcaustic's caustic
# through the glass sphere leaves a quadrant's standard error at 5 % after 48 iterations;
# smoke's pm and sppm, heavy-tailed, at 1.3 % in this test's run against 0.8 % in bench's: 5 %
# taken from its first quadrant gave |z| 3.5, 6 % is caught).
LOSS = 0.05
NOISY = {
    ("cbox", "pm"): 0.06, ("cbox", "sppm"): 0.06,
    ("cbox-fog", "pm"): 0.06, ("cbox-fog", "sppm"): 0.06,
    ("cbox-glass", "pm"): 0.08, ("cbox-glass", "sppm"): 0.08, ("cbox-glass", "ppb"): 0.06,
    ("crepuscular", "ppb"): 0.06,
    ("cbox-grid", "pm"): 0.10, ("cbox-grid", "ppb"): 0.12, ("cbox-grid", "sppm"): 0.10,
    ("fog-perlin", "pm"): 0.09, ("fog-perlin", "ppb"): 0.14, ("fog-perlin", "sppm"): 0.09,
    ("fog-step", "pm"): 0.12, ("fog-step", "ppb"): 0.11, ("fog-step", "sppm"): 0.12,
    ("juice", "pm"): 0.11, ("juice", "ppb"): 0.13, ("juice", "sppm"): 0.11,
    ("smoke", "pm"): 0.07, ("smoke", "sppm"): 0.07, ("smoke", "ppb"): 0.11,
    ("volcaustic", "pm"): 0.28, ("volcaustic", "ppb"): 0.26, ("volcaustic", "sppm"): 0.28,
}  # fmt: skip

_references: dict[str, Estimate] = {}


def reference(name: str, shared: Path | None = None) -> Estimate:
    """pt's image of the scene: 32 images of 1024 spp. With ``shared`` (a folder every test
    worker sees) one worker renders it and the others read it (~110 s of rendering for the ten
    scenes, which each worker of `-n 2` would otherwise repeat); the images are the same."""
    if name in _references:
        return _references[name]
    if shared is None:
        _references[name] = render_reference(name)
        return _references[name]
    shared.mkdir(parents=True, exist_ok=True)
    stored = shared / f"{name}.npy"
    with open(shared / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the other worker waits for this one's render
        if not stored.exists():
            np.save(shared / f"{name}.tmp.npy", render_reference(name).samples)
            (shared / f"{name}.tmp.npy").replace(stored)
        _references[name] = Estimate(np.load(stored))
    return _references[name]


def render_reference(name: str) -> Estimate:
    return ours(PathTracing, load_small(name, RES, RES), 32, seed=99, spp_per_wave=1024)


@pytest.fixture(scope="session")
def shared_references(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder all test workers share (xdist's workers' temporary folders have one parent)."""
    base = tmp_path_factory.getbasetemp()
    return (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "light-references"


def iterations(name: str, method_id: str) -> int:
    if method_id == "lt":
        return LT_ITERATIONS
    return ITERATIONS.get(name, (48, 48, 96))[["pm", "sppm", "ppb"].index(method_id)]


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
    n = iterations(name, method_id)
    params = PARAMS[method_id]
    method = get_method(method_id)(load_small(name, RES, RES), seed=3, threads=2, params=params)
    est = Estimate(iteration_images(method, n))
    if method_id == "lt":
        return est, Scales()
    r = mean_radius(method, n)
    c = BIAS[name][method_id]
    return est, Scales(*(ci * r for ci in c))


def check(name: str, method_id: str, shared: Path) -> None:
    est, allowance = run(name, method_id)
    ref = reference(name, shared)
    agrees, detail = multiscale_agreement(est, ref, allowance)
    ratio = est.mean.mean() / ref.mean.mean()
    print(f"{name} {method_id}: mean {ratio - 1:+.2%}, allowance {allowance}; {detail}")
    assert agrees, f"{name} {method_id}: allowance {allowance}: {detail}"
    loss = NOISY.get((name, method_id), LOSS)
    assert_multiscale_check_has_power(
        est, ref, f"{name} {method_id}", loss + allowance.quadrants, allowance
    )


# One class per method: pytest-xdist's loadscope runs each on a worker of its own.
class TestLt:
    @pytest.mark.parametrize("name", LT_SCENES)
    def test_agrees_with_pt(self, name, shared_references):
        check(name, "lt", shared_references)


class TestPm:
    @pytest.mark.parametrize("name", SCENES)
    def test_agrees_with_pt(self, name, shared_references):
        check(name, "pm", shared_references)


class TestSppm:
    @pytest.mark.parametrize("name", SCENES)
    def test_agrees_with_pt(self, name, shared_references):
        check(name, "sppm", shared_references)


class TestPpb:
    @pytest.mark.parametrize("name", SCENES)
    def test_agrees_with_pt(self, name, shared_references):
        check(name, "ppb", shared_references)
