"""Every method that can render it against the closed form of a slab of fog (tests/slab.py).

A slab 1 unit thick and 1000 wide under a directional light, single scattering only: the image
is known exactly, so each method is judged against it by its own variance alone, at 32 x 32:
the image mean, the quadrants and 8 x 8 pixel blocks (parity.multiscale_agreement with
BLOCK 8: a 4 x 4 grid of blocks).

- pt, bdpt and Mitsuba's volpath, unbiased, on the slab itself (bdpt's light subpaths start on
  a disc as wide as the scene and seldom reach the camera's view: its next-event and
  path-traced strategies carry the image, their MIS weights are what is checked); lt,
  unbiased, on a slab 4 units wide (same image): from 1000 units of slab it sees a vertex of
  the camera's view every few light paths in a million (measured: 225 % +- 160 % of the
  closed form after 40 iterations).
- pm and ppb at one wide radius each, kept fixed: the kernels lie parallel to the slab's faces
  wherever the usual one would reach across them (cpp/boundary_kernels.h), so no photon or beam
  is missed and the estimate is exact at any radius; the same radii with the usual kernels
  lost a third of the light and more (pm at the old default radius of 14: 0.64 of the image
  mean, 0.51 in the corners).
- pm, sppm and ppb at their defaults, whose radii the pilot derives from the photons (pm 14 and
  sppm 28, at the scene's cap, the old rule's radii; ppb 71, at its cap of a tenth of the
  medium's extent; methods/radii.py), after the iterations
  each ran in 6 s here (bench/bench_slab.py; 2 threads on a loaded 2-core machine): within
  the issue's 2 % of the closed form, beyond the noise of those iterations. The old defaults
  (radii from the scene's bounding box, with the usual kernels) gave pm 0.64 and sppm 0.68,
  and fail.

Power: each check fails with 2 % less light overall and with 5 % less in any one quadrant
(asserted where the method's noise allows it: pt, bdpt, lt and the fixed-radius runs); the defaults'
test, whose iterations are those of 6 s, resolves what its printed standard error says (ppb's
is about 6 %: its beams near the camera's view are few, a handful an iteration).
"""

from __future__ import annotations

import numpy as np
import pytest

import parity
from parity import Estimate, iteration_images, mitsuba, multiscale_agreement, ours
from renderer.methods import get_method
from slab import IMAGE_MEAN, closed_form, slab_scene

# The iterations each method ran in 6 s at its defaults (bench/bench_slab.py), and the relative
# bias the issue allows at its defaults.
SIX_SECONDS = {"pm": 160, "sppm": 160, "ppb": 700}
ALLOWANCE = 0.02
# (width, film) of each slab: the issue's; lt's; the wide kernels' (8 x 8, blocks of 2 pixels)
SLABS = {"issue": (1000.0, 32), "lt": (4.0, 32), "wide-kernels": (50.0, 8)}


@pytest.fixture(scope="module")
def slabs(tmp_path_factory):
    """(scene, closed form as an Estimate of zero variance) of each slab."""
    out = {}
    for name, (width, res) in SLABS.items():
        scene = slab_scene(tmp_path_factory.mktemp(name), width, res)
        exact = closed_form(scene)
        out[name] = scene, Estimate(np.stack([exact, exact]))
    return out


def test_the_closed_form_is_the_issues(slabs):
    _, exact = slabs["issue"]
    assert exact.mean.mean() == pytest.approx(IMAGE_MEAN, abs=5e-7)
    _, narrow = slabs["lt"]
    assert np.allclose(narrow.mean, exact.mean, rtol=1e-12)


@pytest.mark.parametrize(
    "method, slab, iterations, params, power",
    [
        ("pt", "issue", 16, {"spp_per_wave": 128}, True),
        ("bdpt", "issue", 16, {"spp_per_iteration": 32}, True),
        ("lt", "lt", 96, {}, True),
        # wide fixed radii, 40 and 200 times the slab's thickness: the loss the usual kernels
        # would show at them (pm at width 50 with a tenth of this radius: 0.968)
        ("pm", "wide-kernels", 48, {"volume_radius_world": 10.0}, True),
        ("ppb", "wide-kernels", 200, {"beam_radius_world": 10.0, "beam_alpha": 1.0}, False),
    ],
    ids=["pt", "bdpt", "lt-4-wide", "pm-radius-10", "ppb-radius-10"],
)
def test_unbiased_estimates_match_the_closed_form(slabs, method, slab, iterations, params, power):
    """The image mean, quadrants and blocks (8 x 8 pixels; 2 x 2 on the 8 x 8 film) agree with
    the closed form beyond each one's noise. Kernels wider than the film make every cell share
    the same photons and beams: those checks take the Bonferroni bound alone (no chi-square).
    Power: 2 % less light overall and 5 % less in any one quadrant fail (where the method's
    noise resolves it: not ppb's, whose quadrant standard error here is about 2 %)."""
    scene, exact = slabs[slab]
    est = ours(get_method(method), scene, iterations, seed=3, **params)
    block = 2 if slab == "wide-kernels" else 8
    chi2 = method in ("pt", "bdpt", "lt")
    agrees, detail = multiscale_agreement(est, exact, block=block, chi2=chi2)
    ratio = est.mean.mean() / exact.mean.mean()
    print(f"{method}: {ratio:.4f} of the closed form; {detail}")
    assert agrees, f"{method}: {ratio:.4f} of the closed form: {detail}"
    if power:
        darker = Estimate(est.samples * 0.98)
        assert not multiscale_agreement(darker, exact, block=block, chi2=chi2)[0], "2 % passed"
        parity.assert_multiscale_check_has_power(est, exact, method, block=block, chi2=chi2)


def test_mitsuba_matches_the_closed_form(slabs):
    """Mitsuba's volpath on the exported slab (the `mitsuba` method's renderer, and the
    reference the other scenes are judged by), as the unbiased methods above, with the same
    power: a 2 % loss overall and 5 % in any one quadrant fail."""
    scene, exact = slabs["issue"]
    est = mitsuba(scene, 16, 128, seed=3000)
    agrees, detail = multiscale_agreement(est, exact, block=8)
    ratio = est.mean.mean() / exact.mean.mean()
    print(f"mitsuba: {ratio:.4f} of the closed form; {detail}")
    assert agrees, f"mitsuba: {ratio:.4f} of the closed form: {detail}"
    assert not multiscale_agreement(Estimate(est.samples * 0.98), exact, block=8)[0]
    parity.assert_multiscale_check_has_power(est, exact, "mitsuba", block=8)


@pytest.mark.parametrize("method", ["pm", "sppm", "ppb"])
def test_defaults_are_within_two_percent_after_six_seconds(slabs, method):
    """The image mean within ALLOWANCE of the closed form beyond its noise (Welch t at
    parity.ALPHA over the iterations), with the radii the pilot derives."""
    scene, exact = slabs["issue"]
    renderer = get_method(method)(scene, seed=5, threads=2, params={})
    est = Estimate(iteration_images(renderer, SIX_SECONDS[method]))
    mean, exact_mean = est.image_mean(), exact.image_mean()
    ratio = float(mean.mean.mean() / IMAGE_MEAN)
    se = float(mean.stderr.mean() / IMAGE_MEAN)
    result = parity.agreement_beyond(mean, exact_mean, ALLOWANCE)
    print(f"{method}: {ratio:.4f} +- {se:.4f} of the closed form: {result}")
    assert result.passes, f"{method}: {ratio:.4f} +- {se:.4f} of the closed form: {result}"
    radii = renderer.stats()["radii"]
    print({k: (round(v["world"], 3), v["rule"]) for k, v in radii.items()})
    # derived by the pilot from the slab's photons (whichever bound it lies at)
    assert "nearest over" in radii["fog"]["rule"]
