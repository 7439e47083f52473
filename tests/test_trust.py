"""The reference trust check (compare/trust.py): each finding fires on the failure it is for and
none fires on sound references, on synthetic images whose noise is known."""

from __future__ import annotations

import re

import numpy as np
import pytest

from compare.trust import Estimate, check_reference, normal_score

H = W = 32


def truth(rng: np.random.Generator) -> np.ndarray:
    """A smooth image with a dark corner (1 % of the mean) and a bright spot."""
    y, x = np.mgrid[0:H, 0:W] / H
    base = 0.2 + 0.8 * np.exp(-((x - 0.6) ** 2 + (y - 0.4) ** 2) * 8)
    base[: H // 4, : W // 4] = 0.01
    return base[..., None] * np.array([1.0, 0.8, 0.6])


def noisy_iterations(image: np.ndarray, k: int, relative: float, rng) -> np.ndarray:
    """K independent images, each pixel with relative noise `relative` (skewed, as renders)."""
    gamma = rng.gamma(1 / relative**2, relative**2, size=(k, *image.shape[:2], 1))
    return image[None] * gamma


def reference_halves(image: np.ndarray, passes: int, relative: float, rng):
    halves = []
    for _ in range(2):
        its = noisy_iterations(image, passes, relative, rng)
        e = Estimate.from_iterations(its)
        halves.append(Estimate.from_passes(e.mean, e.variance, passes))
    mean = 0.5 * (halves[0].mean + halves[1].mean)
    var = 0.25 * (halves[0].variance + halves[1].variance)
    return Estimate.from_passes(mean, var, 2 * passes - 1), tuple(halves)


def test_sound_references_pass(seed_count=200):
    """200 sound references (8 passes a half, 5 % noise a pixel) against checks of 16
    iterations (30 % noise a pixel): no finding fires."""
    rng = np.random.default_rng(1)
    image = truth(rng)
    for _ in range(seed_count):
        ref, halves = reference_halves(image, 8, 0.05, rng)
        check = Estimate.from_iterations(noisy_iterations(image, 16, 0.3, rng))
        verdict = check_reference(ref, check, halves)
        assert verdict.trustworthy, verdict.findings


def test_a_black_reference_is_caught():
    rng = np.random.default_rng(2)
    image = truth(rng)
    ref, halves = reference_halves(image * 0, 8, 0.05, rng)
    check = Estimate.from_iterations(noisy_iterations(image, 16, 0.3, rng))
    verdict = check_reference(ref, check, halves)
    assert not verdict.trustworthy
    assert "100 % of the pixels where pt sees light are exactly 0" in verdict.line("Mitsuba")


def test_a_quarter_of_dead_pixels_is_caught_with_a_right_mean_elsewhere():
    """Mitsuba at sigma_t 10 in the dense-media issue: 25 % of its pixels exactly 0."""
    rng = np.random.default_rng(3)
    image = truth(rng)
    ref, halves = reference_halves(image, 8, 0.05, rng)
    dead = rng.random((H, W)) < 0.25
    ref = Estimate.from_passes(np.where(dead[..., None], 0, ref.mean), ref.variance, 15)
    check = Estimate.from_iterations(noisy_iterations(image, 16, 0.3, rng))
    verdict = check_reference(ref, check)
    assert any("pixels where pt sees light" in f for f in verdict.findings), verdict.findings


@pytest.mark.parametrize("bias", [-0.16, 0.05])
def test_a_biased_mean_is_caught(bias):
    """The cloud's Mitsuba reference was 16 % dark; a 5 % bias is caught too at this noise."""
    rng = np.random.default_rng(4)
    image = truth(rng)
    ref, halves = reference_halves(image * (1 + bias), 8, 0.05, rng)
    check = Estimate.from_iterations(noisy_iterations(image, 16, 0.3, rng))
    verdict = check_reference(ref, check, halves)
    assert not verdict.trustworthy
    found = re.search(r"image mean is ([0-9.]+) % (below|above) pt's", verdict.findings[0])
    assert found, verdict.findings
    assert float(found[1]) == pytest.approx(abs(bias) * 100, abs=1.0)
    assert found[2] == ("below" if bias < 0 else "above")


def test_a_small_bias_within_the_checks_noise_is_not_flagged():
    """1 % is far inside a 16-iteration check's interval at 30 % per-pixel noise: the check
    says nothing it cannot resolve."""
    rng = np.random.default_rng(5)
    image = truth(rng)
    ref, halves = reference_halves(image * 0.99, 8, 0.05, rng)
    check = Estimate.from_iterations(noisy_iterations(image, 16, 3.0, rng))
    assert check_reference(ref, check, halves).trustworthy


def test_one_channel_off_is_caught():
    """volpathmis's blue channel was 2.8 % low in a chromatic fog; a precise check sees it."""
    rng = np.random.default_rng(6)
    image = truth(rng)
    ref, halves = reference_halves(image * np.array([1, 1, 0.97]), 16, 0.01, rng)
    check = Estimate.from_iterations(noisy_iterations(image, 64, 0.02, rng))
    verdict = check_reference(ref, check, halves)
    assert not verdict.trustworthy
    assert "b channel's image mean is 3.0 % below" in verdict.findings[0]


def test_halves_that_disagree_are_caught():
    """Heavy tails: one half met a rare path (a block 3x too bright) that its own spread did
    not show; the mean of both still lies inside a noisy check's interval."""
    rng = np.random.default_rng(7)
    image = truth(rng)
    _, (a, b) = reference_halves(image, 8, 0.05, rng)
    spiked = a.mean.copy()
    spiked[8:16, 8:16] *= 3
    a = Estimate.from_passes(spiked, a.variance, 8)
    ref = Estimate.from_passes(0.5 * (a.mean + b.mean), 0.25 * (a.variance + b.variance), 15)
    check = Estimate.from_iterations(noisy_iterations(image, 4, 3.0, rng))
    verdict = check_reference(ref, check, (a, b))
    assert [f for f in verdict.findings if "halves disagree" in f], verdict.findings


def test_normal_score_maps_students_tail():
    assert normal_score(2.0, 0) == 2.0
    # P(t_3 > 3) = 0.0288 = P(N > 1.898)
    assert normal_score(3.0, 3) == pytest.approx(1.898, abs=1e-3)
    assert normal_score(-3.0, 3) == pytest.approx(-1.898, abs=1e-3)
