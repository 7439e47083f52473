"""Progressive radius schedules (cpp/radius_schedule.h; Knaus & Zwicker 2011)."""

from __future__ import annotations

import numpy as np
import pytest

from renderer import _core


@pytest.mark.parametrize("alpha", [0.3, 2 / 3, 0.9])
@pytest.mark.parametrize("dimension", [1, 2, 3])
def test_radii_follow_knaus_zwicker(alpha, dimension):
    r = _core.radius_schedule(0.1, alpha, dimension, 1000)
    i = np.arange(1, 1001)
    assert np.allclose(r, 0.1 * i ** ((alpha - 1) / dimension), rtol=1e-12)
    assert r[0] == pytest.approx(0.1)
    assert np.all(np.diff(r) < 0)
    # The kernel's area (d = 2) or volume (d = 3) shrinks as i^(alpha - 1).
    assert r[99] ** dimension / r[0] ** dimension == pytest.approx(100 ** (alpha - 1), rel=1e-9)


def test_alpha_one_keeps_the_radius():
    assert np.all(_core.radius_schedule(0.25, 1.0, 2, 50) == 0.25)


@pytest.mark.parametrize(
    "args",
    [(0.0, 0.5, 2), (-1.0, 0.5, 2), (0.1, 0.0, 2), (0.1, 1.5, 2), (0.1, 0.5, 0), (0.1, 0.5, 4)],
)
def test_invalid_schedules_are_rejected(args):
    with pytest.raises(ValueError):
        _core.radius_schedule(*args, 3)


@pytest.mark.parametrize("dimension", [1, 2, 3])
def test_expected_mse_slope(dimension):
    """MSE ~ n^-min(alpha, 4 (1 - alpha) / d); best at alpha = 4 / (d + 4)."""
    best = 4 / (dimension + 4)
    assert _core.radius_schedule_mse_slope(best, dimension) == pytest.approx(-best)
    for alpha in (0.2, 0.5, 0.8, 0.95):
        slope = _core.radius_schedule_mse_slope(alpha, dimension)
        assert slope == pytest.approx(-min(alpha, 4 * (1 - alpha) / dimension))
        assert slope >= -best - 1e-12


@pytest.mark.parametrize("dimension", [1, 2, 3])
def test_expected_mse_slope_with_a_bias_of_order_r(dimension):
    """At edges the bias is of order r: MSE ~ n^-min(alpha, 2 (1 - alpha) / d), best at
    alpha = 2 / (d + 2), and never faster than with a bias of order r^2."""
    best = 2 / (dimension + 2)
    assert _core.radius_schedule_mse_slope(best, dimension, 1) == pytest.approx(-best)
    for alpha in (0.2, 0.5, 0.8, 0.95):
        slope = _core.radius_schedule_mse_slope(alpha, dimension, 1)
        assert slope == pytest.approx(-min(alpha, 2 * (1 - alpha) / dimension))
        assert slope >= _core.radius_schedule_mse_slope(alpha, dimension) - 1e-12
    with pytest.raises(ValueError):
        _core.radius_schedule_mse_slope(0.5, dimension, 3)
