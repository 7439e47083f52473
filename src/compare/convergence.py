"""Convergence analysis: log-log slope of error vs time, and time needed to reach an error.

For an unbiased estimator MSE ~ t^-1 (slope -1 on a log-log plot); a consistent progressive
estimator with a d-dimensional kernel reaches at best t^(-4/(d+4)) (Knaus & Zwicker 2011).
The fitted slope is reported next to each curve. A noisy reference adds its own error to every
measurement (E[measured] = true error + reference error for MSE; approximately for relMSE), which
flattens the curves of fast methods; ``fit_slope_of_corrected`` fits the errors with it removed
(compare.metrics.corrected_errors), ``fit_slope_above_floor`` the excess over a known floor.
``bounded`` keeps a time-to-error estimate within what the measurements support.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .metrics import COVERAGE


@dataclass(frozen=True)
class SlopeFit:
    slope: float  # d log(error) / d log(time)
    intercept: float  # log10(error) at t = 1 s
    r2: float
    n: int

    def predict(self, t: float) -> float:
        return 10.0 ** (self.intercept + self.slope * math.log10(t))


def fit_slope(times: Sequence[float], errors: Sequence[float]) -> SlopeFit:
    """Least-squares line through (log10 t, log10 error); non-positive points are ignored."""
    t = np.asarray(times, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    ok = (t > 0) & (e > 0) & np.isfinite(t) & np.isfinite(e)
    x, y = np.log10(t[ok]), np.log10(e[ok])
    n = int(ok.sum())
    if n < 2 or np.ptp(x) == 0:
        return SlopeFit(math.nan, math.nan, math.nan, n)
    slope, intercept = np.polyfit(x, y, 1)
    resid = y - (slope * x + intercept)
    ss_tot = float(((y - y.mean()) ** 2).sum())
    r2 = 1.0 - float((resid**2).sum()) / ss_tot if ss_tot > 0 else 1.0
    return SlopeFit(float(slope), float(intercept), r2, n)


# Points whose error is within this factor of the floor are dropped from the excess fit: their
# excess is mostly the noise of the floor's own estimate.
FLOOR_MARGIN = 2.0
# The excess fit needs points at three budgets or more, spanning at least this factor in
# time: the points left may otherwise all come from one budget (two seeds at 1 s give a
# "slope" of pure seed noise).
MIN_FIT_POINTS = 3
MIN_FIT_SPAN = 4.0


def enough_budgets(budgets: Sequence[float] | np.ndarray) -> bool:
    """Whether points from these budgets can show a slope: three budgets or more, spanning
    at least MIN_FIT_SPAN (two points always lie on a line, whatever their noise)."""
    b = np.unique(np.asarray(budgets, dtype=np.float64))
    return b.size >= MIN_FIT_POINTS and b.max(initial=0) >= MIN_FIT_SPAN * b.min(initial=math.inf)


def fit_slope_over_budgets(
    times: Sequence[float], errors: Sequence[float], budgets: Sequence[float]
) -> SlopeFit:
    """fit_slope, NaN (with n = points) unless the points come from enough_budgets."""
    if not enough_budgets(budgets):
        return SlopeFit(math.nan, math.nan, math.nan, len(times))
    return fit_slope(times, errors)


def fit_slope_above_floor(
    times: Sequence[float],
    errors: Sequence[float],
    floor: float,
    margin: float = FLOOR_MARGIN,
    budgets: Sequence[float] | None = None,
) -> SlopeFit:
    """Slope of (error - floor) vs time, ``floor`` being an additive error that does not fall
    with render time (the reference's own error). Uses the points with error >= margin x floor;
    NaN (with n = points kept) when the floor is unknown or the points kept come from fewer
    than MIN_FIT_POINTS budgets or span less than MIN_FIT_SPAN in budget. ``budgets`` (one per
    point; default: the times) tells points of one budget apart."""
    e = np.asarray(errors, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64)
    b = t if budgets is None else np.asarray(budgets, dtype=np.float64)
    if not (math.isfinite(floor) and floor >= 0):
        return SlopeFit(math.nan, math.nan, math.nan, 0)
    keep = (e >= margin * floor) & (t > 0) & np.isfinite(e)
    # The span is the budgets': a first snapshot a little off its budget (1.003 s) must not
    # drop budgets of exactly 1-4 s.
    if not enough_budgets(b[keep]):
        return SlopeFit(math.nan, math.nan, math.nan, int(keep.sum()))
    return fit_slope(t[keep], e[keep] - floor)


# Corrected errors are fitted only where they are at least this many times their uncertainty
# (their interval of COVERAGE uncertainties within a factor of about 1.5 of them): the
# logarithm of an error the reference cannot resolve is noise.
MIN_SIGNAL = 2.0 * COVERAGE


def fit_slope_of_corrected(
    times: Sequence[float],
    corrected: Sequence[float],
    uncertainty: Sequence[float],
    budgets: Sequence[float] | None = None,
) -> SlopeFit:
    """Slope of the corrected errors vs time, over the points with corrected >= MIN_SIGNAL x
    their uncertainty; NaN (with n = points kept) unless those come from enough_budgets."""
    t = np.asarray(times, dtype=np.float64)
    c = np.asarray(corrected, dtype=np.float64)
    u = np.asarray(uncertainty, dtype=np.float64)
    b = t if budgets is None else np.asarray(budgets, dtype=np.float64)
    keep = (c > 0) & np.isfinite(c) & (c >= MIN_SIGNAL * np.nan_to_num(u, nan=np.inf)) & (t > 0)
    if not enough_budgets(b[keep]):
        return SlopeFit(math.nan, math.nan, math.nan, int(keep.sum()))
    return fit_slope(t[keep], c[keep])


def time_to_error(
    times: Sequence[float],
    errors: Sequence[float],
    target: float,
    extrapolate: bool = True,
    budgets: Sequence[float] | None = None,
) -> tuple[float, bool]:
    """Time at which a (mean) error curve first reaches ``target``.

    Measured: if the first point is above the target, linear interpolation in log-log space
    between the last point above it and the first point at or below it. Otherwise, when
    ``extrapolate`` and the fitted slope is negative, the fitted slope is followed from the
    nearest measured point: back from the first point when the curve starts at or below the
    target (the time is then at most the first time), on from the last point when it never
    gets there (at least the last time). A slope is fitted only to points of enough_budgets
    (``budgets``, each point's, default ``times``): through two points any noise is a slope.
    Returns ``(time, extrapolated)``; ``(nan, True)`` when no estimate is possible.
    """
    t = np.asarray(times, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    b = t if budgets is None else np.asarray(budgets, dtype=np.float64)
    order = np.argsort(t)
    t, e, b = t[order], e[order], b[order]
    ok = (t > 0) & (e > 0) & np.isfinite(e)
    t, e, b = t[ok], e[ok], b[ok]
    if t.size == 0 or not target > 0:
        return math.nan, True
    lt, le, lg = np.log10(t), np.log10(e), math.log10(target)
    if e[0] == target:
        return float(t[0]), False
    if e[0] > target:
        reached = np.flatnonzero(e <= target)
        if reached.size:  # the first crossing from above
            i = int(reached[0])
            f = (le[i - 1] - lg) / (le[i - 1] - le[i])
            return float(10 ** (lt[i - 1] + f * (lt[i] - lt[i - 1]))), False
    if not extrapolate or not enough_budgets(b):
        return math.nan, True
    fit = fit_slope(t, e)
    if not fit.slope < 0:
        return math.nan, True
    end = 0 if e[0] < target else -1  # the measured point nearest to the target
    exponent = lt[end] + (lg - le[end]) / fit.slope
    exponent = min(exponent, lt[0]) if end == 0 else max(exponent, lt[-1])
    if not abs(exponent) < 300:  # a nearly flat fit: out of float range either way
        return (math.inf if exponent > 0 else 0.0), True
    return float(10**exponent), True


# Extrapolated times further than this factor outside a method's measured times are replaced
# by what the measurements do show: reached by its first budget, or not by its last.
EXTRAPOLATION_LIMIT = 4.0


def bounded(
    estimate: tuple[float, bool], times: np.ndarray, errors: np.ndarray, target: float
) -> tuple[float, bool, str]:
    """(seconds, extrapolated, bound) from a time_to_error estimate of the curve (times,
    errors): an extrapolation far outside the measured times, or none at all, becomes what
    the measurements show: "<=" the first time (its error was already at or below the target
    there) or ">=" the last (never reached)."""
    t, extrap = estimate
    ok = np.isfinite(times) & np.isfinite(errors) & (times > 0)
    if not extrap or not ok.any():
        return t, extrap, ""
    times, errors = times[ok], errors[ok]
    first, last = float(times.min()), float(times.max())
    if errors[np.argmin(times)] <= target:  # reached by the first measurement
        if math.isfinite(t) and t >= first / EXTRAPOLATION_LIMIT:
            return t, True, ""
        return first, False, "<="
    if math.isfinite(t) and t <= last * EXTRAPOLATION_LIMIT:
        return t, True, ""
    return last, False, ">="
