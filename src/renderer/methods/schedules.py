"""Expected convergence of the progressive radius schedules (cpp/radius_schedule.h)."""

from __future__ import annotations

from .. import _core


def expected_mse_slopes(kernels: list[tuple[float, int]]) -> dict[str, float]:
    """Sidecar fields for a consistent method whose kernels each have (alpha, dimension): the
    log-log slope its MSE should reach, where the radiance is smooth (bias of order r^2) and
    where kernels straddle edges (bias of order r). The slowest kernel sets each rate; an
    empty list (nothing blurred) gives the unbiased -1."""
    slopes = {}
    for key, order in (("expected_mse_slope", 2), ("expected_mse_slope_at_edges", 1)):
        rates = [_core.radius_schedule_mse_slope(a, d, order) for a, d in kernels]
        slopes[key] = max(rates, default=-1.0) + 0.0  # + 0.0: no "-0.0" in the sidecar
    return slopes
