"""Russian roulette (cpp/wavefront.h, survive_roulette; docs/scene-format.md): the default rule
takes survival from the throughput, uncapped, so that paths through white, dense media (clouds:
hundreds of events each) keep bounded weights; Mitsuba's rule, capped at 0.95, stays available
as integrator.rr=mitsuba."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_small
from parity import agreement, ours
from renderer.errors import PgiError
from renderer.methods import get_method

# cbox-fog made white and dense (the dense-media issue's case): an optical depth of about 100
# across the box, albedo 0.999, unlimited depth. Paths take hundreds of events to leave.
DENSE = (
    "media.fog.sigma_t=50",
    "media.fog.albedo=0.999",
    "integrator.max_depth=-1",
)


@pytest.fixture(scope="module")
def dense_pt():
    scene = load_small("cbox-fog", 12, 12, DENSE)
    return ours(get_method("pt"), scene, 24, seed=1, spp_per_wave=64)


def test_white_dense_fog_pt_and_lt_agree(dense_pt):
    """pt and lt, two estimators that share nothing but the scene and the roulette rule, agree
    on the image mean of the dense, white fog (its value is about 9e-3 per pixel: under
    Mitsuba's rule both were 10-100x darker, with a spread of 4-14x between seeds)."""
    scene = load_small("cbox-fog", 12, 12, DENSE)
    lt = ours(get_method("lt"), scene, 12, seed=2, light_paths=1 << 14)
    result = agreement(dense_pt.image_mean(), lt.image_mean())
    means = dense_pt.image_mean().mean.mean(), lt.image_mean().mean.mean()
    print(f"pt {means[0]:.3e}, lt {means[1]:.3e}: {result}")
    assert result.passes, result
    assert 5e-3 < dense_pt.image_mean().mean.mean() < 2e-2


def test_mitsubas_rule_is_far_too_dark_there(dense_pt):
    """The control: the same pt, samples and seed with Mitsuba's roulette lose most of the
    light (its survivors' weights of 0.95^-n are too rare to show at this budget)."""
    scene = load_small("cbox-fog", 12, 12, (*DENSE, "integrator.rr=mitsuba"))
    capped = ours(get_method("pt"), scene, 24, seed=1, spp_per_wave=64)
    assert capped.image_mean().mean.mean() < 0.5 * dense_pt.image_mean().mean.mean()


def test_both_rules_render_the_same_image_where_paths_are_short():
    """Both rules are unbiased: on cbox-glass (where refraction's eta^2 lets the throughput
    rule keep paths that Mitsuba's would roulette) the image means agree."""
    a = ours(get_method("pt"), load_small("cbox-glass", 12, 12), 16, seed=3, spp_per_wave=16)
    scene = load_small("cbox-glass", 12, 12, ("integrator.rr=mitsuba",))
    b = ours(get_method("pt"), scene, 16, seed=4, spp_per_wave=16)
    result = agreement(a.image_mean(), b.image_mean())
    assert result.passes, result


def test_the_rule_is_checked_by_the_loader():
    with pytest.raises(PgiError, match=r"integrator\.rr: .*'throughput', 'mitsuba'|integrator"):
        load_small("cbox", 4, 4, ("integrator.rr=capped",))
    assert load_small("cbox", 4, 4).integrator.rr == "throughput"
    assert np.isfinite(load_small("cbox", 4, 4, ("integrator.rr=mitsuba",)).integrator.rr_depth)
