"""Unit tests for compare.metrics against hand-computed values."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

from compare import metrics as m


def const(h: int, w: int, v: float | tuple[float, float, float]) -> np.ndarray:
    out = np.empty((h, w, 3))
    out[...] = v
    return out


def test_constant_offset_values() -> None:
    # r = 1, x = 1.5 everywhere: d = 0.5
    r = const(16, 16, 1.0)
    x = const(16, 16, 1.5)
    got = m.compare_images(x, r)
    assert got["mse"] == pytest.approx(0.25)
    assert got["rmse"] == pytest.approx(0.5)
    assert got["relmse"] == pytest.approx(0.25 / 1.01)
    assert got["relmse_trimmed"] == pytest.approx(0.25 / 1.01)  # < 1000 pixels: no trim
    assert got["mape"] == pytest.approx(0.5 / 1.01)
    assert got["smape"] == pytest.approx(0.5 / 2.51)
    # both tonemapped images are constant (1.0 after clipping): SSIM = 1
    assert got["one_minus_ssim"] == pytest.approx(0.0, abs=1e-12)
    assert 0.0 < got["flip"] <= 1.0


def test_per_channel_values() -> None:
    # one pixel row, channels differ: r = (0, 1, 2), x = (1, 1, 0)
    r = const(4, 4, (0.0, 1.0, 2.0))
    x = const(4, 4, (1.0, 1.0, 0.0))
    got = m.compare_images(x, r)
    assert got["mse"] == pytest.approx((1 + 0 + 4) / 3)
    assert got["relmse"] == pytest.approx((1 / 0.01 + 0 + 4 / 4.01) / 3)
    assert got["mape"] == pytest.approx((1 / 0.01 + 0 + 2 / 2.01) / 3)
    assert got["smape"] == pytest.approx((1 / 1.01 + 0 + 2 / 2.01) / 3)


def test_identical_images_zero_error() -> None:
    rng = np.random.default_rng(1)
    r = rng.random((16, 20, 3)) * 3
    got = m.compare_images(r, r.copy())
    for k in m.METRICS:
        assert got[k] == pytest.approx(0.0, abs=1e-7), k


def test_ssim_constant_images_closed_form() -> None:
    # constant images a, b (in display space): SSIM = (2ab + C1) / (a^2 + b^2 + C1), C1 = 0.01^2
    r = const(16, 16, 0.2)
    x = const(16, 16, 0.05)
    a = float(m.tonemap_srgb(np.array(0.05)))
    b = float(m.tonemap_srgb(np.array(0.2)))
    c1 = 0.01**2
    expected = 1 - (2 * a * b + c1) / (a * a + b * b + c1)
    assert m.compare_images(x, r)["one_minus_ssim"] == pytest.approx(expected, rel=1e-9)


def test_trimmed_relmse_drops_top_pixels() -> None:
    # 2000 pixels -> floor(0.001 * 2000) = 2 pixels trimmed
    r = const(40, 50, 1.0)
    x = r.copy()
    x[0, 0] = 101.0  # two fireflies
    x[5, 7] = 51.0
    x[10, 10] = 2.0  # one moderate error, kept
    got = m.compare_images(x, r)
    assert got["relmse"] == pytest.approx((100**2 + 50**2 + 1) / 1.01 / 2000)
    assert got["relmse_trimmed"] == pytest.approx(1 / 1.01 / 1998)


def test_trimmed_mean_helper() -> None:
    v = np.arange(3000, dtype=float)  # trims 3 largest: 2997, 2998, 2999
    assert m.trimmed_mean(v) == pytest.approx(np.arange(2997).mean())
    assert m.trimmed_mean(np.array([1.0, 5.0])) == pytest.approx(3.0)


def test_flip_identical_zero_and_grows_with_noise() -> None:
    rng = np.random.default_rng(2)
    r = rng.random((32, 32, 3)) + 0.2
    small = r * (1 + 0.05 * rng.standard_normal(r.shape))
    big = r * (1 + 0.5 * rng.standard_normal(r.shape))
    big = np.maximum(big, 0)
    f0 = m.compare_images(r, r)["flip"]
    f1 = m.compare_images(small, r)["flip"]
    f2 = m.compare_images(big, r)["flip"]
    assert f0 == pytest.approx(0.0, abs=1e-7)
    assert 0 < f1 < f2 <= 1


def test_flip_black_reference_does_not_exit() -> None:
    # flip-evaluator would sys.exit on an all-black reference (empty exposure range)
    got = m.compare_images(const(8, 8, 1.0), const(8, 8, 0.0))
    assert 0 < got["flip"] <= 1
    assert m.compare_images(const(8, 8, 0.0), const(8, 8, 0.0))["flip"] == 0.0


def test_flip_of_a_dim_reference_is_that_of_the_same_images_brighter() -> None:
    """flip-evaluator exits the process when the reference's peak luminance is below float
    epsilon (its clamped median then lies above the peak). Scaled up first, a dim pair gets
    the FLIP of the same pair at ordinary brightness. In a child process: a regression
    would end the process that runs it."""
    code = (
        "import json, numpy as np\n"
        "from compare import metrics as m\n"
        "rng = np.random.default_rng(3)\n"
        "r = rng.uniform(0.1, 1.0, (24, 24, 3))\n"
        "x = r * (1 + 0.3 * rng.standard_normal(r.shape))\n"
        "out = [m.compare_images(x * k, r * k)['flip'] for k in (1.0, 1e-8, 5e-7, 1e-30)]\n"
        "print(json.dumps(out))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    bright, *dim = json.loads(r.stdout)
    assert 0 < bright < 1 and dim == pytest.approx([bright] * 3, rel=1e-4)
    assert not r.stderr, r.stderr


def test_flip_of_a_bright_image_against_a_denormal_reference_says_nothing() -> None:
    """Scaled up to a peak of 1, a test image 1e40 times a denormal reference overflowed
    float32 with a warning on stderr; held to float32's range, its FLIP is the error of
    such a pair, near 1."""
    rng = np.random.default_rng(0)
    ref = rng.uniform(size=(16, 16, 3)) * 1e-40
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = m.compare_images(rng.uniform(size=(16, 16, 3)), ref)["flip"]
    assert 0.9 < got <= 1


def test_negative_values_accepted() -> None:
    r = const(8, 8, 0.5)
    x = r.copy()
    x[0, 0] = -0.5
    got = m.compare_images(x, r)
    assert got["mse"] == pytest.approx(1.0 / 64)
    assert math.isfinite(got["flip"])


def test_grey_and_float32_inputs() -> None:
    r = np.ones((8, 8), dtype=np.float32)
    x = np.full((8, 8, 1), 2.0, dtype=np.float32)
    assert m.compare_images(x, r)["mse"] == pytest.approx(1.0)


def test_shape_mismatch_raises() -> None:
    mismatch = "shape mismatch.*test image is 5x4.*reference image is 4x4"
    with pytest.raises(ValueError, match=mismatch):
        m.compare_images(np.zeros((4, 5, 3)), np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match=r"expected an \(H, W, 3\) image"):
        m.compare_images(np.zeros((4, 4, 2)), np.zeros((4, 4, 2)))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_raises(bad: float) -> None:
    r = const(4, 4, 1.0)
    x = r.copy()
    x[2, 3, 1] = bad
    with pytest.raises(ValueError, match=r"test image has 1 pixel.*non-finite.*x=3, y=2"):
        m.compare_images(x, r)
    with pytest.raises(ValueError, match="reference image has 1 pixel"):
        m.compare_images(r, x)


def test_tiny_image_ssim_nan_but_others_fine() -> None:
    got = m.compare_images(const(10, 10, 1.0), const(10, 10, 2.0))  # below the 11x11 window
    assert math.isnan(got["one_minus_ssim"])
    assert got["mse"] == pytest.approx(1.0)


def test_ssim_is_wang_et_al() -> None:
    """Gaussian window (sigma 1.5) and population covariances, checked against a direct
    evaluation of Wang et al.'s formula at the centre pixel of a 11x11 image pair."""
    rng = np.random.default_rng(3)
    a, b = rng.uniform(0.2, 0.8, (2, 11, 11))
    g = np.exp(-0.5 * ((np.arange(11) - 5) / 1.5) ** 2)
    w = np.outer(g, g) / np.outer(g, g).sum()
    mu_a, mu_b = (w * a).sum(), (w * b).sum()
    var_a, var_b = (w * (a - mu_a) ** 2).sum(), (w * (b - mu_b) ** 2).sum()
    cov = (w * (a - mu_a) * (b - mu_b)).sum()
    c1, c2 = 0.01**2, 0.03**2
    expected = ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / (
        (mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2)
    )
    # On an 11x11 image only the centre pixel has a full window (scikit-image crops the rest).
    lin = lambda v: np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)  # noqa: E731
    x = np.repeat(lin(a)[:, :, None], 3, axis=2)
    r = np.repeat(lin(b)[:, :, None], 3, axis=2)
    assert 1 - m.compare_images(x, r)["one_minus_ssim"] == pytest.approx(expected, rel=1e-6)


def test_maps() -> None:
    r = const(3, 4, 1.0)
    x = r.copy()
    x[1, 2] = (2.0, 1.0, 1.0)
    rm = m.relmse_map(x, r)
    assert rm.shape == (3, 4)
    assert rm[1, 2] == pytest.approx(1 / 1.01 / 3)
    assert rm.sum() == pytest.approx(rm[1, 2])
    assert m.abs_error_map(x, r)[1, 2] == pytest.approx(1 / 3)
    fm, mean = m.flip_map(x, r)
    assert fm.shape == (3, 4) and mean == pytest.approx(fm.mean(), rel=1e-5)


def test_reference_error_factor() -> None:
    # halves differ by +-d around truth t: A = t + d, B = t - d -> R = t exactly,
    # (A-B)^2 = 4 d^2; estimate of ref MSE = 4 d^2 / 4 = d^2 (the error of one half is d^2;
    # in expectation the average's error is half of one half's error).
    t = const(4, 4, 1.0)
    d = 0.1
    got = m.reference_error(t + d, t - d)
    assert got["halves_mse"] == pytest.approx(4 * d * d)
    assert got["ref_mse"] == pytest.approx(d * d)
    assert got["halves_relmse"] == pytest.approx(4 * d * d / 1.01)
    assert got["ref_relmse"] == pytest.approx(d * d / 1.01)


def test_reference_error_statistics() -> None:
    # Monte-Carlo check of the 1/4 factor: two independent halves with noise sigma each
    rng = np.random.default_rng(3)
    t = const(200, 200, 1.0)
    s = 0.05
    a = t + s * rng.standard_normal(t.shape)
    b = t + s * rng.standard_normal(t.shape)
    est = m.reference_error(a, b)["ref_mse"]
    true = float(((0.5 * (a + b) - t) ** 2).mean())
    # Each is a mean of N squared normals: relative standard deviation sqrt(2 / N) (0.4 %),
    # and the difference of two independent ones sqrt(2) times that; 5 of them as the bound.
    rel_sd = np.sqrt(2 / a.size)
    assert est == pytest.approx(true, rel=5 * np.sqrt(2) * rel_sd)
    assert est == pytest.approx(s * s / 2, rel=5 * rel_sd)


def test_reference_ok_is_the_factor_or_more() -> None:
    assert m.reference_ok(1.0, 0.1) and not m.reference_ok(0.99, 0.1)
    assert m.reference_ok(0.5, 0.1, factor=5) and not m.reference_ok(0.5, 0.1, factor=6)


# --- the reference's own error removed ----------------------------------------------------------


def _truth(rng: np.random.Generator, h: int = 48, w: int = 64) -> np.ndarray:
    """A coloured image with dark (below relMSE's eps) and bright parts."""
    level = np.exp(rng.uniform(np.log(0.03), np.log(3.0), (h, w, 1)))
    return level * np.array([1.0, 0.7, 0.4])


def _noisy(rng: np.random.Generator, truth: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """truth plus zero-mean noise of standard deviation ``sd`` per value, the channels of a
    pixel moving together as a renderer's do (the same paths carry every channel)."""
    return truth + sd * rng.standard_normal(truth.shape[:2] + (1,))


def test_corrected_error_is_the_measured_less_the_references_own() -> None:
    rng = np.random.default_rng(4)
    t = _truth(rng)
    a, b, x = (_noisy(rng, t, s * t) for s in (0.05, 0.05, 0.1))
    got = m.corrected_errors(x, a, b)
    measured = m.compare_images(x, 0.5 * (a + b))
    own = m.reference_error(a, b)
    assert got["mse_corrected"] == pytest.approx(measured["mse"] - own["ref_mse"], rel=1e-12)
    assert got["relmse_corrected"] == pytest.approx(
        measured["relmse"] - own["ref_relmse"], rel=1e-12
    )
    assert got["rmse_corrected"] == pytest.approx(got["mse_corrected"] ** 0.5)
    assert 0 < got["relmse_u_shared"] < got["relmse_u"]
    # an image closer to the truth than the reference can tell may come out below zero
    assert m.corrected_errors(t, a, b)["mse_corrected"] == pytest.approx(
        -own["ref_mse"] + float(((t - 0.5 * (a + b)) ** 2).mean()), rel=1e-9
    )


@pytest.mark.parametrize("bias", [1.0, 0.97], ids=["unbiased", "biased"])
@pytest.mark.parametrize("known_variances", [True, False], ids=["passes", "halves-only"])
@pytest.mark.parametrize("reference_noise", [0.02, 0.2], ids=["fine", "coarse"])
def test_corrected_error_equals_the_true_error_within_its_uncertainty(
    bias: float, known_variances: bool, reference_noise: float
) -> None:
    """A known truth, one method image (noise 5 % per value, unbiased or 3 % dark) and 300
    draws of two reference halves of different noise (``reference_noise`` and 1.5x it per
    value, their variances given or estimated from the halves alone; "coarse": the
    reference's own error is 27x the method's). Over the draws the corrected error is the
    true one on average, it misses it by about its stated uncertainty (a little less: the
    uncertainty is an upper bound) and by two uncertainties at most in 90 % of the draws;
    the error as measured is off by several. relMSE keeps the reference in its denominator,
    which is corrected to first order only: it is checked at the fine reference, within 3 %
    of itself besides."""
    rng = np.random.default_rng(11)
    t = _truth(rng)
    x = _noisy(rng, bias * t, 0.05 * t)
    sd_a, sd_b = reference_noise * t, 1.5 * reference_noise * t

    def measured(r: np.ndarray) -> dict[str, float]:
        return {"mse": float(((x - r) ** 2).mean()), "relmse": float(m.relmse_map(x, r).mean())}

    true = measured(t)
    metrics = ("mse", "relmse") if reference_noise < 0.1 else ("mse",)
    off = {k: [] for k in metrics}  # corrected - true
    u = {k: [] for k in metrics}
    raw = {k: [] for k in metrics}  # measured - true
    for _ in range(300):
        a, b = _noisy(rng, t, sd_a), _noisy(rng, t, sd_b)
        variances = (sd_a**2, sd_b**2) if known_variances else (None, None)
        got = m.corrected_errors(x, a, b, *variances)
        against_reference = measured(0.5 * (a + b))
        for k in metrics:
            off[k].append(got[f"{k}_corrected"] - true[k])
            u[k].append(got[f"{k}_u"])
            raw[k].append(against_reference[k] - true[k])
    for k in metrics:
        miss, stated = np.asarray(off[k]), np.asarray(u[k])
        first_order = 0.03 * true[k] if k == "relmse" else 0.0
        # 300 draws: the mean miss has a standard error of 0.06 of the uncertainty
        assert abs(miss.mean()) < 0.25 * stated.mean() + first_order, (k, miss.mean())
        assert 0.6 < miss.std() / stated.mean() < 1.2, (k, miss.std() / stated.mean())
        assert np.mean(np.abs(miss) <= m.COVERAGE * stated) >= 0.9, k
        assert np.mean(raw[k]) > 3 * stated.mean(), k  # the measured error is far off


def test_a_corrected_error_is_determined_within_a_fraction_of_itself() -> None:
    assert m.determined(1.0, 0.1, 0.2) and not m.determined(1.0, 0.11, 0.2)
    assert not m.determined(-1.0, 0.0, 0.2) and not m.determined(0.0, 0.0, 0.2)
    assert m.determined(1.0, 0.0, 0.2)
