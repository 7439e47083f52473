"""Statistical goodness-of-fit helpers for the sampling and media tests.

In the spirit of Mitsuba 3's ``chi2`` test library (and pbrt's): a sampler is compared with the
density it claims to follow by Pearson's chi-square test on a histogram.

- Directions are binned in (cos theta, phi) about an axis, so every bin of a sphere (or
  hemisphere) has the same solid angle ``d(cos theta) * d(phi)``.
- Expected counts come from integrating the density over each bin numerically, by adaptive
  Gauss-Legendre cubature (bins are split until the estimate is stable), so narrow peaks such as
  Henyey-Greenstein with g = 0.99 are integrated accurately.
- Bins with an expected count below 5 are pooled together (Mitsuba's rule); a sample in a bin
  of zero expected mass is an immediate failure.
- The significance level is corrected for the number of tests run (Sidak), so a suite of many
  tests keeps an overall false-rejection rate of ``alpha``.

Everything here is plain numpy/scipy so it can be reused by any test.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

# Overall false-rejection rate of one test file (before the Sidak correction).
ALPHA = 1e-3
# Mitsuba's threshold for pooling low-expectation bins.
MIN_EXPECTED = 5.0


def sidak(alpha: float, n_tests: int) -> float:
    """Per-test level so that ``n_tests`` independent tests reject with total rate ``alpha``."""
    return 1.0 - (1.0 - alpha) ** (1.0 / max(1, n_tests))


def frame(axis: np.ndarray) -> np.ndarray:
    """Orthonormal basis (rows s, t, n) with n = axis normalised."""
    n = np.asarray(axis, np.float64)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    s = np.cross(helper, n)
    s /= np.linalg.norm(s)
    return np.stack([s, np.cross(n, s), n])


# --------------------------------------------------------------------------- spherical domain


@dataclass(frozen=True)
class SphericalDomain:
    """Directions binned in (z = cos theta, phi) about ``axis``; z in [z_min, 1]."""

    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    res_z: int = 40
    res_phi: int = 80
    hemisphere: bool = False

    @property
    def z_min(self) -> float:
        return 0.0 if self.hemisphere else -1.0

    @property
    def basis(self) -> np.ndarray:
        return frame(np.asarray(self.axis))

    @property
    def z_edges(self) -> np.ndarray:
        return np.linspace(self.z_min, 1.0, self.res_z + 1)

    @property
    def phi_edges(self) -> np.ndarray:
        return np.linspace(0.0, 2 * np.pi, self.res_phi + 1)

    def to_world(self, z: np.ndarray, phi: np.ndarray) -> np.ndarray:
        r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
        local = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
        return local @ self.basis

    def to_zphi(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        local = np.asarray(d, np.float64) @ self.basis.T
        local /= np.linalg.norm(local, axis=-1, keepdims=True)
        phi = np.mod(np.arctan2(local[:, 1], local[:, 0]), 2 * np.pi)
        return np.clip(local[:, 2], -1.0, 1.0), phi

    def histogram(self, d: np.ndarray) -> np.ndarray:
        """Counts per (z, phi) bin. Directions outside the domain (below a hemisphere's
        horizon) are counted in an extra last bin whose expected count is 0."""
        z, phi = self.to_zphi(d)
        inside = z >= self.z_min
        h, _, _ = np.histogram2d(z[inside], phi[inside], bins=[self.z_edges, self.phi_edges])
        return np.append(h.ravel(), np.count_nonzero(~inside))

    def integrate(
        self,
        pdf: Callable[[np.ndarray], np.ndarray],
        rel_tol: float = 1e-6,
        abs_tol: float = 1e-10,
        max_level: int = 30,
    ) -> np.ndarray:
        """Integral of ``pdf`` (a function of (N, 3) world directions) over every bin, by
        adaptive 4x4 Gauss-Legendre cubature in (z, phi) (solid angle = dz dphi).

        Each rectangle is also integrated as two halves split in z and as two halves split in
        phi; it is accepted when both agree with the whole within ``max(abs_tol, rel_tol *
        value)`` (absolute probability mass), otherwise it is split along the axis that
        disagrees more (so a peak at the pole is refined in z only). The returned array has
        one entry per histogram bin plus the outside bin (always 0). Discontinuities of the
        density should lie on bin edges (e.g. a BSDF's horizon: use its normal as the axis).
        """
        ze, pe = self.z_edges, self.phi_edges
        zz0, pp0 = np.meshgrid(ze[:-1], pe[:-1], indexing="ij")
        zz1, pp1 = np.meshgrid(ze[1:], pe[1:], indexing="ij")
        rect = np.stack([zz0.ravel(), zz1.ravel(), pp0.ravel(), pp1.ravel()], axis=1)
        owner = np.arange(len(rect))
        total = np.zeros(len(rect) + 1)
        whole = _gauss_2d(pdf, self, rect)
        for level in range(max_level + 1):
            halves_z = _halves(rect, axis=0)
            halves_p = _halves(rect, axis=1)
            both = _gauss_2d(pdf, self, np.concatenate([halves_z, halves_p])).reshape(2, -1, 2)
            sum_z, sum_p = both.sum(axis=2)
            err_z, err_p = np.abs(sum_z - whole), np.abs(sum_p - whole)
            tol = np.maximum(abs_tol, rel_tol * np.abs(sum_z))
            done = (np.maximum(err_z, err_p) <= tol) | (level == max_level)
            np.add.at(total, owner[done], sum_z[done])
            split_z = ~done & (err_z >= err_p)
            split_p = ~done & ~split_z
            rect = np.concatenate(
                [halves_z.reshape(-1, 2, 4)[split_z], halves_p.reshape(-1, 2, 4)[split_p]]
            ).reshape(-1, 4)
            whole = np.concatenate([both[0][split_z], both[1][split_p]]).ravel()
            owner = np.repeat(np.concatenate([owner[split_z], owner[split_p]]), 2)
            if not len(rect):
                break
        return total


_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


def _area(rect: np.ndarray) -> np.ndarray:
    return (rect[:, 1] - rect[:, 0]) * (rect[:, 3] - rect[:, 2])


def _halves(rect: np.ndarray, axis: int) -> np.ndarray:
    """Each rectangle (z0, z1, p0, p1) cut in two along z (axis 0) or phi (axis 1); the two
    halves of a parent are consecutive rows."""
    lo, hi = rect[:, 2 * axis], rect[:, 2 * axis + 1]
    mid = 0.5 * (lo + hi)
    a, b = rect.copy(), rect.copy()
    a[:, 2 * axis + 1] = mid
    b[:, 2 * axis] = mid
    return np.stack([a, b], axis=1).reshape(-1, 4)


def _gauss_2d(pdf, domain: SphericalDomain, rect: np.ndarray) -> np.ndarray:
    if not len(rect):
        return np.zeros(0)
    z0, z1, p0, p1 = (rect[:, i : i + 1] for i in range(4))
    zs = 0.5 * (z0 + z1) + 0.5 * (z1 - z0) * _GL_X  # (R, 4)
    ps = 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * _GL_X
    z = np.repeat(zs, 4, axis=1)  # (R, 16): z index slow, phi fast
    phi = np.tile(ps, (1, 4))
    w = np.outer(_GL_W, _GL_W).ravel()
    d = np.ascontiguousarray(domain.to_world(z.ravel(), phi.ravel()))
    values = np.asarray(pdf(d), np.float64).reshape(z.shape)
    return (values * w).sum(axis=1) * 0.25 * _area(rect)


# --------------------------------------------------------------------------- chi-square


@dataclass(frozen=True)
class Chi2Result:
    statistic: float
    dof: int
    p_value: float
    reason: str  # why the test failed outright, "" otherwise

    def passed(self, level: float) -> bool:
        return not self.reason and self.p_value >= level

    def __str__(self) -> str:
        extra = f" ({self.reason})" if self.reason else ""
        return f"chi2 = {self.statistic:.4g}, dof = {self.dof}, p = {self.p_value:.4g}{extra}"


def chi2_test(observed: np.ndarray, expected: np.ndarray) -> Chi2Result:
    """Pearson's chi-square test of counts against expected counts.

    As Mitsuba's ``ChiSquareTest``: bins are visited by increasing expected count and those
    below ``MIN_EXPECTED`` are pooled into one bin (added to the test only if the pool reaches
    the threshold, otherwise merged into the next bin); observations in a bin of zero expected
    count fail at once. The degrees of freedom are the number of bins used minus one (the
    total is fixed by the sample count).
    """
    obs = np.asarray(observed, np.float64).ravel()
    exp = np.asarray(expected, np.float64).ravel()
    bad = (exp <= 0) & (obs > 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        return Chi2Result(np.inf, 0, 0.0, f"{int(obs[bad].sum())} samples in bins of zero "
                          f"expected count (first: bin {i}, {int(obs[i])} samples)")  # fmt: skip
    order = np.argsort(exp, kind="stable")
    stat, used = 0.0, 0
    pool_o = pool_e = 0.0
    for i in order:
        if exp[i] <= 0:
            continue
        if exp[i] < MIN_EXPECTED or (0 < pool_e < MIN_EXPECTED):
            pool_o += obs[i]
            pool_e += exp[i]
            continue
        stat += (obs[i] - exp[i]) ** 2 / exp[i]
        used += 1
    if pool_e > 0:
        stat += (pool_o - pool_e) ** 2 / pool_e
        used += 1
    dof = used - 1
    if dof < 1:
        return Chi2Result(stat, dof, 0.0, "fewer than two usable bins")
    return Chi2Result(stat, dof, float(sps.chi2.sf(stat, dof)), "")


@dataclass
class SphericalChi2:
    """A chi-square test of sampled directions against a density on the sphere.

    ``sample(n) -> (N, 3)`` returns directions (rows of invalid samples may be dropped by the
    caller beforehand: the density must then integrate to the valid fraction), ``pdf(d)`` the
    density per steradian of (N, 3) directions.
    """

    sample: Callable[[int], np.ndarray]
    pdf: Callable[[np.ndarray], np.ndarray]
    domain: SphericalDomain
    n: int = 500_000

    def run(self) -> tuple[Chi2Result, np.ndarray, np.ndarray]:
        d = np.asarray(self.sample(self.n), np.float64)
        observed = self.domain.histogram(d)
        mass = self.domain.integrate(self.pdf)
        expected = mass * self.n
        return chi2_test(observed, expected), observed, expected


# --------------------------------------------------------------------------- 1D helpers


def chi2_1d(samples: np.ndarray, edges: np.ndarray, cdf: Callable[[np.ndarray], np.ndarray],
            total_mass: float = 1.0) -> Chi2Result:  # fmt: skip
    """Chi-square test of scalar samples against a distribution given by its CDF.

    ``edges`` partition the support; samples outside [edges[0], edges[-1]) fall in one extra
    bin whose expected probability is ``total_mass`` minus the mass inside (e.g. the
    probability of no collision for free-flight distances, whose samples are +inf).
    """
    x = np.asarray(samples, np.float64)
    edges = np.asarray(edges, np.float64)
    inside = (x >= edges[0]) & (x < edges[-1])
    counts, _ = np.histogram(x[inside], bins=edges)
    c = np.asarray(cdf(edges), np.float64)
    p = np.diff(c)
    outside = max(0.0, total_mass - (c[-1] - c[0]))
    observed = np.append(counts, np.count_nonzero(~inside))
    expected = np.append(p, outside) * len(x)
    return chi2_test(observed, expected)


def ks_test(samples: np.ndarray, cdf: Callable[[np.ndarray], np.ndarray]) -> float:
    """p-value of the one-sample Kolmogorov-Smirnov test against a continuous CDF."""
    return float(sps.kstest(np.asarray(samples, np.float64), cdf).pvalue)


def binomial_p_value(successes: int, trials: int, p: float) -> float:
    """Two-sided exact binomial test p-value."""
    return float(sps.binomtest(int(successes), int(trials), float(p)).pvalue)


def z_p_value(estimate: np.ndarray, expected: np.ndarray, std_error: np.ndarray) -> np.ndarray:
    """Two-sided normal p-values of estimates with known standard errors.

    A zero standard error requires an exact match (p = 1 if equal, 0 otherwise)."""
    est, exp, se = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in
                                         (estimate, expected, std_error)))  # fmt: skip
    diff = np.abs(est - exp)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = 2.0 * sps.norm.sf(diff / se)
    return np.where(se > 0, p, np.where(diff == 0, 1.0, 0.0))


def t_p_value(estimate: np.ndarray, expected: np.ndarray, std_error: np.ndarray,
              dof: int) -> np.ndarray:  # fmt: skip
    """Two-sided Student-t p-values (standard errors estimated with ``dof`` degrees)."""
    est, exp, se = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in
                                         (estimate, expected, std_error)))  # fmt: skip
    diff = np.abs(est - exp)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = 2.0 * sps.t.sf(diff / se, dof)
    return np.where(se > 0, p, np.where(diff == 0, 1.0, 0.0))


def mean_and_se(x: np.ndarray, axis: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Sample mean and its standard error along ``axis`` (independent samples)."""
    x = np.asarray(x, np.float64)
    n = x.shape[axis]
    return x.mean(axis=axis), x.std(axis=axis, ddof=1) / np.sqrt(n)


@dataclass(frozen=True)
class SlopeFit:
    """Log-log slope of the mean of several independent error curves, with its jackknife
    standard error over the curves (leave one run out) and Student's t on n - 1 degrees."""

    slope: float
    stderr: float
    runs: int

    def interval(self, alpha: float) -> tuple[float, float]:
        half = float(sps.t.isf(alpha / 2, self.runs - 1)) * self.stderr
        return self.slope - half, self.slope + half

    def consistent_with(self, lo: float, hi: float, alpha: float) -> bool:
        """Whether the two-sided ``1 - alpha`` interval meets the range [lo, hi]."""
        low, high = self.interval(alpha)
        return high >= lo and low <= hi

    def __str__(self) -> str:
        return f"slope {self.slope:.3f} +- {self.stderr:.3f} (jackknife over {self.runs} runs)"


def loglog_slope(curves: np.ndarray, budgets) -> SlopeFit:
    """Fit log(mean error) against log(budget); ``curves`` is runs x budgets, each run
    independent (its own seed). Errors at or below zero (a subtracted noise floor that the
    estimate undershot) are clipped to a tiny positive value."""
    curves = np.asarray(curves, np.float64)
    n = len(curves)
    if n < 3:
        raise ValueError("a jackknife standard error needs at least 3 runs")
    x = np.log(np.asarray(budgets, np.float64))

    def fit(c: np.ndarray) -> float:
        return float(np.polyfit(x, np.log(np.maximum(c.mean(axis=0), 1e-30)), 1)[0])

    leave_one_out = np.array([fit(np.delete(curves, i, axis=0)) for i in range(n)])
    stderr = float(np.sqrt((n - 1) / n * ((leave_one_out - leave_one_out.mean()) ** 2).sum()))
    return SlopeFit(fit(curves), stderr, n)
