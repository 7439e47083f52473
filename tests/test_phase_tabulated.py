"""Rayleigh and tabulated phase functions, and the Lorenz-Mie tables fed to them.

- Sampling: chi-square tests of sampled directions against the evaluated density (spherical
  histograms about the forward direction), plus a fine 1-D test in cos(theta) at the CDF's
  quantiles for the forward-peaked Mie table.
- Evaluation integrates to 1 over the sphere; the pdf returned by sampling equals eval.
- Mitsuba ``tabphase`` convention: values at cos(theta) regularly spaced on [-1, 1], +1 the
  forward direction, piecewise-linear, auto-normalised (checked against a numpy reference).
- Mie (Bohren & Huffman series): the optical theorem (Q_ext = Q_sca for a real index), the
  Rayleigh limit for x << 1, S1 = S2 forward and S1 = -S2 backward, Bohren & Huffman's own
  worked example, and a cloud-like <cos>. Each sampling test has a control that must fail.
- Droplet sizes: the quadrature's effective radius and variance (Hansen & Travis's
  definitions) are the ones asked for, and a size exponent off by one fails that check.
"""

from __future__ import annotations

import numpy as np
import pytest

import stats
from renderer import _core
from renderer.volumes import (
    mie_amplitudes,
    mie_droplet_radii,
    mie_phase_table,
    tabulated_mean_cosine,
)

RAYLEIGH = _core.PhaseType.rayleigh
WO = (0.3, -0.5, 0.81)
TABLES = {
    "ramp": np.linspace(0.0, 1.0, 5),  # zero at the back: f0 = 0 case of the inversion
    "flat-with-gap": np.array([1.0, 1.0, 0.0, 0.0, 2.0, 0.5]),  # zero-mass intervals
    "random": np.random.default_rng(5).random(33) * 3,
    "mie-2um": np.array(mie_phase_table(2.0, resolution=1024)),
}
N_TESTS = 1 + len(TABLES) + 1 + 1  # the sampling tests (controls must fail)
LEVEL = stats.sidak(stats.ALPHA, N_TESTS)


def table_pdf(values: np.ndarray, wo):
    """numpy reference of the tabphase density per steradian."""
    mu_nodes = np.linspace(-1, 1, len(values))
    h = mu_nodes[1] - mu_nodes[0]
    integral = h * (values.sum() - 0.5 * (values[0] + values[-1]))
    fwd = -np.asarray(wo, np.float64) / np.linalg.norm(wo)

    def pdf(d: np.ndarray) -> np.ndarray:
        mu = np.clip(d @ fwd, -1, 1)
        return np.interp(mu, mu_nodes, values) / (2 * np.pi * integral)

    return pdf


def rayleigh_pdf(wo):
    fwd = -np.asarray(wo, np.float64) / np.linalg.norm(wo)
    return lambda d: 3 / (16 * np.pi) * (1 + (d @ fwd) ** 2)


def mu_chi2(mu: np.ndarray, density, bins: int = 200) -> stats.Chi2Result:
    """Chi-square of cos theta samples against an unnormalised density of cos theta, in bins
    of equal width (its CDF by the trapezoid rule on a fine grid)."""
    fine = np.linspace(-1, 1, 200_001)
    f = density(fine)
    cdf = np.concatenate([[0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(fine))])
    edges = np.linspace(-1, 1, bins + 1)
    edges[-1] = 1 + 1e-12
    return stats.chi2_1d(mu, edges, lambda x: np.interp(x, fine, cdf / cdf[-1]))


def domain():
    return stats.SphericalDomain(axis=tuple(-np.asarray(WO)), res_z=64, res_phi=16)


def test_rayleigh_sampling_chi2():
    def sample(n):
        wi, _ = _core.sample_phase(RAYLEIGH, 0.0, WO, np.random.default_rng(1).random((n, 2)))
        return wi

    result, _, _ = stats.SphericalChi2(sample, rayleigh_pdf(WO), domain(), 300_000).run()
    assert result.passed(LEVEL), result
    # The control, in cos theta where the density varies: 1 + 0.8 mu^2 is rejected.
    mu = sample(300_000) @ (-np.asarray(WO) / np.linalg.norm(WO))
    assert mu_chi2(mu, lambda m: 1 + m**2).passed(LEVEL)
    assert not mu_chi2(mu, lambda m: 1 + 0.8 * m**2).passed(LEVEL)


def test_rayleigh_eval_and_pdf():
    u = np.random.default_rng(2).random((1000, 2))
    wi, pdf = _core.sample_phase(RAYLEIGH, 0.0, WO, u)
    np.testing.assert_allclose(pdf, rayleigh_pdf(WO)(wi), rtol=1e-10)
    np.testing.assert_allclose(_core.eval_phase(RAYLEIGH, 0.0, WO, wi), pdf, rtol=1e-12)
    assert abs(domain().integrate(rayleigh_pdf(WO))[:-1].sum() - 1) < 1e-6


@pytest.mark.parametrize("name", TABLES)
def test_tabulated_sampling_chi2(name):
    values = TABLES[name]

    def sample(n):
        wi, _ = _core.sample_phase_table(values, WO, np.random.default_rng(3).random((n, 2)))
        return wi

    result, _, _ = stats.SphericalChi2(sample, table_pdf(values, WO), domain(), 300_000).run()
    assert result.passed(LEVEL), f"{name}: {result}"


def test_tabulated_chi2_rejects_a_slightly_wrong_table():
    """The control, in cos theta: samples of the random table pass against their own density
    and fail against the same table with its largest node 10 % higher, and against its piecewise-
    constant version (each interval at the mean of its nodes: a sampler ignoring the slope)."""
    values = TABLES["random"]
    u = np.random.default_rng(3).random((300_000, 2))
    wi, _ = _core.sample_phase_table(values, WO, u)
    mu = wi @ (-np.asarray(WO) / np.linalg.norm(WO))
    nodes = np.linspace(-1, 1, len(values))
    assert mu_chi2(mu, lambda m: np.interp(m, nodes, values)).passed(LEVEL)
    bumped = values.copy()
    bumped[np.argmax(values)] *= 1.1
    assert not mu_chi2(mu, lambda m: np.interp(m, nodes, bumped)).passed(LEVEL)
    means = 0.5 * (values[1:] + values[:-1])

    def constant(m):
        return means[np.clip(np.searchsorted(nodes, m) - 1, 0, len(means) - 1)]

    assert not mu_chi2(mu, constant).passed(LEVEL)


def test_tabulated_eval_of_a_nan_direction_stays_in_the_table():
    """A NaN cosine once went through std::clamp to an out-of-bounds read."""
    got = _core.eval_phase_table(TABLES["ramp"], WO, np.array([[np.nan, 0.0, 0.0]]))
    assert got.shape == (1,)


@pytest.mark.parametrize("name", TABLES)
def test_tabulated_eval_matches_reference_and_integrates_to_one(name):
    values = TABLES[name]
    rng = np.random.default_rng(4)
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ours = _core.eval_phase_table(values, WO, d)
    np.testing.assert_allclose(ours, table_pdf(values, WO)(d), rtol=1e-9, atol=1e-12)
    # Exact integral of the piecewise-linear density: 2 pi * trapezoid over mu.
    mu = np.linspace(-1, 1, len(values))
    f = _core.eval_phase_table(values, (0, 0, -1), np.stack([0 * mu, np.sqrt(1 - mu**2), mu], 1))
    assert abs(2 * np.pi * np.trapz(f, mu) - 1) < 1e-12
    # Sampling returns pdf == eval, and the scale of the values does not matter.
    wi, pdf = _core.sample_phase_table(values * 7.5, WO, rng.random((2000, 2)))
    np.testing.assert_allclose(pdf, _core.eval_phase_table(values, WO, wi), rtol=1e-10)


def test_tabulated_forward_is_plus_one():
    """A table rising to cos = +1 scatters forward: <cos(wi, -wo)> > 0, as tabphase."""
    values = TABLES["ramp"]
    wi, _ = _core.sample_phase_table(values, WO, np.random.default_rng(6).random((100_000, 2)))
    mean, se = stats.mean_and_se(wi @ -np.asarray(WO) / np.linalg.norm(WO))
    assert stats.z_p_value(mean, tabulated_mean_cosine(values), se) >= LEVEL
    assert mean > 0.3


def test_mie_cos_theta_quantile_bins():
    """Fine 1-D test in cos(theta) at the table's CDF quantiles: resolves the forward peak."""
    values = TABLES["mie-2um"]
    n = 400_000
    wi, _ = _core.sample_phase_table(values, WO, np.random.default_rng(7).random((n, 2)))
    mu = np.clip(wi @ (-np.asarray(WO) / np.linalg.norm(WO)), -1, 1)
    nodes = np.linspace(-1, 1, len(values))
    fine = np.linspace(-1, 1, 400_001)
    dens = np.interp(fine, nodes, values)
    cdf = np.concatenate([[0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(fine))])
    cdf /= cdf[-1]
    edges = np.interp(np.linspace(0, 1, 201), cdf, fine)
    edges[-1] = 1 + 1e-12
    result = stats.chi2_1d(mu, edges, lambda x: np.interp(x, fine, cdf))
    assert result.passed(LEVEL), result


@pytest.mark.parametrize("x", [0.3, 3.0, 25.0, 120.0])
def test_mie_optical_theorem(x):
    """A non-absorbing sphere scatters all it extinguishes: Q_ext = 4/x^2 Re S(0) equals
    Q_sca = 2/x^2 * integral (|S1|^2 + |S2|^2)/2 dmu."""
    mu = np.cos(np.linspace(0, np.pi, 20001))[::-1]
    s1, s2 = mie_amplitudes(x, complex(1.333, 0), mu)
    q_ext = 4 / x**2 * s1[-1].real
    q_sca = 2 / x**2 * np.trapz(0.5 * (np.abs(s1) ** 2 + np.abs(s2) ** 2), mu)
    assert abs(q_ext - q_sca) < 2e-3 * q_ext, (q_ext, q_sca)
    np.testing.assert_allclose(s1[-1], s2[-1], rtol=1e-10)  # forward
    np.testing.assert_allclose(s1[0], -s2[0], rtol=1e-8, atol=1e-12)  # backward


def test_mie_matches_bohren_and_huffmans_example():
    """The worked example of Bohren & Huffman's BHMIE (1983, appendix A): a sphere of radius
    0.525 um and refractive index 1.55 at 0.6328 um prints Q_sca = Q_ext = 3.10543 and
    Q_back = 2.92534. A size parameter off by 3.5e-5 (x = 5.213 instead of 5.21282) already
    moves Q_ext to 3.10500, so radius, wavelength and index conventions all show here."""
    x = 2 * np.pi * 0.525 / 0.6328
    mu = np.cos(np.linspace(0, np.pi, 40001))[::-1]
    s1, s2 = mie_amplitudes(x, complex(1.55, 0), mu)
    q_ext = 4 / x**2 * s1[-1].real
    q_sca = 2 / x**2 * np.trapz(0.5 * (np.abs(s1) ** 2 + np.abs(s2) ** 2), mu)
    q_back = 4 / x**2 * np.abs(s1[0]) ** 2
    np.testing.assert_allclose([q_ext, q_sca, q_back], [3.10543, 3.10543, 2.92534], atol=6e-6)


def test_mie_rayleigh_limit():
    mu = np.linspace(-1, 1, 101)
    s1, s2 = mie_amplitudes(0.01, complex(1.333, 0), mu)
    p = 0.5 * (np.abs(s1) ** 2 + np.abs(s2) ** 2)
    np.testing.assert_allclose(p / p[50], 1 + mu**2, rtol=1e-3)


def test_mie_water_droplets_are_forward_scattering():
    """Fog/cloud droplets of a few micrometres have <cos theta> of about 0.8-0.9."""
    g = tabulated_mean_cosine(mie_phase_table(2.0))
    assert 0.75 < g < 0.92, g
    assert abs(tabulated_mean_cosine(mie_phase_table(0.02, resolution=256))) < 0.05  # Rayleigh


def effective_radius_and_variance(r: np.ndarray, weights: np.ndarray) -> tuple[float, float]:
    """Hansen & Travis (1974, eqs. 2.53-2.54): the cross-section-weighted mean radius and the
    cross-section-weighted variance of r divided by its square."""
    area = weights * r**2
    a = float((area * r).sum() / area.sum())
    return a, float((area * (r - a) ** 2).sum() / (a**2 * area.sum()))


# Truncating the distribution to [0.05 a, a (1 + 8 sqrt(v))] moves the moments by at most
# 0.2 % (radius) and 0.4 % (variance), at the loader's largest variance 0.5; below 0.3 by under
# 1e-4. An exponent off by one moves the effective radius by a v, 1 % at the smallest v 0.01.
RADIUS_RTOL, VARIANCE_RTOL = 5e-3, 1e-2


@pytest.mark.parametrize("a, v", [(2.0, 0.01), (2.0, 0.1), (10.0, 0.3), (0.5, 0.5)])
def test_droplet_sizes_have_the_effective_radius_and_variance_asked_for(a, v):
    effective_a, effective_v = effective_radius_and_variance(*mie_droplet_radii(a, v))
    assert effective_a == pytest.approx(a, rel=RADIUS_RTOL)
    assert effective_v == pytest.approx(v, rel=VARIANCE_RTOL)


@pytest.mark.parametrize("v", [0.01, 0.1, 0.5])
def test_control_a_size_exponent_off_by_one_is_caught(v):
    a = 2.0
    r, weights = mie_droplet_radii(a, v)
    effective_a, _ = effective_radius_and_variance(r, weights * r)  # r^((1 - 2v) / v)
    assert effective_a != pytest.approx(a, rel=RADIUS_RTOL)
