"""Statistical tests of BSDF, phase-function and emission-warp sampling (the native probes of
renderer._core).

Each sampler is checked against the density it reports with a chi-square test over the sphere
(tests/stats.py); the densities themselves are checked against independent closed forms and
for normalisation. The warps light emission uses (a spot's cone, a directional light's disk)
are checked the same way. Delta BSDFs are checked exactly (mirror and Snell directions, Fresnel
probabilities). Every random number comes from a fixed seed, so results are reproducible.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import stats
from renderer import _core

DIFFUSE, MIRROR, DIELECTRIC, NULL = (
    _core.MaterialType[k] for k in ("diffuse", "mirror", "dielectric", "null")
)
ISOTROPIC, HG = _core.PhaseType.isotropic, _core.PhaseType.hg
REFLECTANCE = (0.8, 0.5, 0.2)


def unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def rotate_towards(normal, cos_theta: float, tangent_hint=(0.3, 0.9, -0.2)) -> np.ndarray:
    """A unit vector at angle acos(cos_theta) from ``normal``."""
    n = unit(normal)
    t = np.asarray(tangent_hint, np.float64)
    t = unit(t - n * (t @ n))
    return unit(cos_theta * n + math.sqrt(max(0.0, 1 - cos_theta**2)) * t)


# --------------------------------------------------------------------------- cases

NORMALS = [(0, 0, 1), (0, 0, -1), (1, 0, 0), tuple(unit((0.4, -0.7, 0.2)))]
DIFFUSE_COS_WO = [1.0, 0.6, 0.01]
HG_G = [-0.99, -0.9, 0.0, 0.5, 0.9, 0.99]
DIELECTRIC_CASES = [  # (ior, cos of wo to the normal: > 0 outside, < 0 inside)
    (1.5, 1.0), (1.5, 0.7), (1.5, 0.2), (1.5, 0.02),
    (1.5, -1.0), (1.5, -0.9), (1.5, -0.5),  # -0.5 is beyond the critical angle: TIR
    (1 / 1.33, 0.6), (1 / 1.33, 0.3),  # an interface whose interior is less dense
]  # fmt: skip
WO_PHASE = tuple(unit((0.3, -0.5, 0.8)))
CONE_CASES = [  # (axis, cos of the cutoff angle): a half space down to a narrow spot
    ((0, 0, 1), 0.0), (tuple(unit((0.4, -0.7, 0.2))), 0.5), ((0, -1, 0), 0.8),
    (tuple(unit((-0.3, 0.1, -0.9))), 0.95), ((1, 0, 0), -0.5),
]  # fmt: skip

# Statistical hypothesis tests in this file, for the Sidak correction of the level each uses.
N_TESTS = (
    len(NORMALS) * len(DIFFUSE_COS_WO)  # diffuse chi-square
    + len(DIELECTRIC_CASES)  # Fresnel binomial
    + (len(HG_G) + 1)  # phase chi-square (HG and isotropic)
    + len(HG_G)  # HG cos(theta) chi-square
    + (len(HG_G) + 1)  # mean cosine t-tests
    + 1  # hemisphere-domain chi-square
    + 2 * len(CONE_CASES)  # cone chi-square over the sphere and of cos(theta)
    + 1  # disk chi-square
)
LEVEL = stats.sidak(stats.ALPHA, N_TESTS)


def bsdf_pdf(type_: int, normal, wo):
    def pdf(d: np.ndarray) -> np.ndarray:
        return _core.eval_bsdf(type_, REFLECTANCE, 1.5, tuple(normal), tuple(wo), d)[1]

    return pdf


def phase_pdf(type_: int, g: float, wo):
    def pdf(d: np.ndarray) -> np.ndarray:
        return _core.eval_phase(type_, g, tuple(wo), d)

    return pdf


def hg_reference(cos_theta: np.ndarray, g: float) -> np.ndarray:
    """Henyey-Greenstein (1941) per steradian; cos_theta between wi and the propagation
    direction -wo, so g > 0 peaks forward."""
    denom = 1 + g * g - 2 * g * cos_theta
    return (1 - g * g) / (4 * math.pi * denom**1.5)


def hg_cos_cdf(mu: np.ndarray, g: float) -> np.ndarray:
    """CDF of cos(theta) under Henyey-Greenstein (closed form of the integral above)."""
    if abs(g) < 1e-12:
        return 0.5 * (mu + 1)
    return (1 - g * g) / (2 * g) * (1 / np.sqrt(1 + g * g - 2 * g * mu) - 1 / (1 + g))


def fresnel_reference(cos_i: float, eta_i: float, eta_t: float) -> tuple[float, float]:
    """Unpolarised Fresnel reflectance and cos(theta_t) (Born & Wolf), from Snell's law."""
    sin_t = eta_i / eta_t * math.sqrt(max(0.0, 1 - cos_i**2))
    if sin_t >= 1:
        return 1.0, 0.0
    cos_t = math.sqrt(1 - sin_t**2)
    r_s = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t)
    r_p = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t)
    return 0.5 * (r_s**2 + r_p**2), cos_t


# --------------------------------------------------------------------------- diffuse


@pytest.mark.parametrize("normal", NORMALS)
@pytest.mark.parametrize("cos_wo", DIFFUSE_COS_WO)
def test_diffuse_sampling_chi2(normal, cos_wo):
    wo = rotate_towards(normal, cos_wo)
    rng = np.random.default_rng(1000 + NORMALS.index(normal) * 10 + DIFFUSE_COS_WO.index(cos_wo))

    def sample(n: int) -> np.ndarray:
        wi, _, _, valid, delta = _core.sample_bsdf(
            DIFFUSE, REFLECTANCE, 1.5, normal, tuple(wo), rng.random((n, 3))
        )
        assert valid.all() and not delta.any()
        return wi

    # Full sphere about the normal: a sample below the horizon lands in a zero-mass bin.
    domain = stats.SphericalDomain(axis=normal, res_z=20, res_phi=40)
    result, _, _ = stats.SphericalChi2(sample, bsdf_pdf(DIFFUSE, normal, wo), domain, 200_000).run()
    assert result.passed(LEVEL), result


@pytest.mark.parametrize("normal", NORMALS)
def test_diffuse_eval_matches_lambert(normal):
    n = unit(normal)
    wo = rotate_towards(n, 0.5)
    rng = np.random.default_rng(7)
    wi = rng.normal(size=(2000, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    f_cos, pdf = _core.eval_bsdf(DIFFUSE, REFLECTANCE, 1.5, normal, tuple(wo), wi)
    cos = np.clip(wi @ n, 0, None)
    np.testing.assert_allclose(pdf, cos / math.pi, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(f_cos, np.outer(cos / math.pi, REFLECTANCE), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("normal", NORMALS)
def test_diffuse_sample_pdf_and_weight_match_eval(normal):
    wo = rotate_towards(normal, 0.3)
    u = np.random.default_rng(11).random((5000, 3))
    wi, weight, pdf, valid, _ = _core.sample_bsdf(DIFFUSE, REFLECTANCE, 1.5, normal, tuple(wo), u)
    assert valid.all()
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1, rtol=1e-12)
    f_cos, pdf_eval = _core.eval_bsdf(DIFFUSE, REFLECTANCE, 1.5, normal, tuple(wo), wi)
    np.testing.assert_allclose(pdf, pdf_eval, rtol=1e-10)
    np.testing.assert_allclose(weight, f_cos / pdf_eval[:, None], rtol=1e-10)


def test_diffuse_from_below_is_absorbed():
    normal = (0.0, 0.0, 1.0)
    wo = (0.2, 0.1, -0.9)
    u = np.random.default_rng(3).random((1000, 3))
    _, _, _, valid, _ = _core.sample_bsdf(DIFFUSE, REFLECTANCE, 1.5, normal, wo, u)
    assert not valid.any()
    f_cos, pdf = _core.eval_bsdf(DIFFUSE, REFLECTANCE, 1.5, normal, wo, np.array([[0.0, 0, 1]]))
    assert np.all(f_cos == 0) and np.all(pdf == 0)


# --------------------------------------------------------------------------- delta BSDFs


@pytest.mark.parametrize("normal", NORMALS)
def test_mirror_reflection_is_exact(normal):
    n = unit(normal)
    rng = np.random.default_rng(5)
    for cos_wo in (1.0, 0.5, 0.05):
        wo = rotate_towards(n, cos_wo)
        wi, weight, _, valid, delta = _core.sample_bsdf(
            MIRROR, REFLECTANCE, 1.5, normal, tuple(wo), rng.random((100, 3))
        )
        assert valid.all() and delta.all()
        np.testing.assert_allclose(wi, np.broadcast_to(2 * (wo @ n) * n - wo, wi.shape), atol=1e-14)
        np.testing.assert_array_equal(weight, 1.0)
        f_cos, pdf = _core.eval_bsdf(MIRROR, REFLECTANCE, 1.5, normal, tuple(wo), wi)
        assert np.all(f_cos == 0) and np.all(pdf == 0)  # a delta lobe has no density
    below = tuple(-rotate_towards(n, 0.5))
    valid = _core.sample_bsdf(MIRROR, REFLECTANCE, 1.5, normal, below, rng.random((10, 3)))[3]
    assert not valid.any()


def test_null_passes_straight_through():
    wo = unit((0.3, -0.2, 0.9))
    for normal in NORMALS:
        wi, weight, _, valid, delta = _core.sample_bsdf(
            NULL, REFLECTANCE, 1.5, normal, tuple(wo), np.random.default_rng(2).random((10, 3))
        )
        assert valid.all() and delta.all()
        np.testing.assert_allclose(wi, np.broadcast_to(-wo, wi.shape), atol=1e-15)
        np.testing.assert_array_equal(weight, 1.0)


@pytest.mark.parametrize("ior,cos_wo", DIELECTRIC_CASES)
def test_dielectric_fresnel_and_snell(ior, cos_wo):
    normal = unit((0.2, 0.5, -0.8))
    outside = cos_wo > 0
    wo = rotate_towards(normal, cos_wo)
    eta_i, eta_t = (1.0, ior) if outside else (ior, 1.0)
    cos_i = abs(cos_wo)
    F, cos_t = fresnel_reference(cos_i, eta_i, eta_t)
    n_samples = 100_000
    u = np.random.default_rng(int(1e4 * ior * (1 + cos_wo))).random((n_samples, 3))
    wi, weight, pdf, valid, delta = _core.sample_bsdf(
        DIELECTRIC, REFLECTANCE, ior, tuple(normal), tuple(wo), u
    )
    assert valid.all() and delta.all()
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1, rtol=1e-12)
    side = np.sign(wi @ normal) == np.sign(cos_wo)
    refl, refr = side, ~side

    # Event probabilities: the reported pdf is the Fresnel term, reflection happens with
    # probability F (exact binomial test), and it is decided by u3 < F.
    np.testing.assert_allclose(pdf[refl], F, rtol=1e-12)
    np.testing.assert_allclose(pdf[refr], 1 - F, rtol=1e-12)
    assert stats.binomial_p_value(refl.sum(), n_samples, F) >= LEVEL, (refl.sum(), F)
    if refl.any() and refr.any():
        assert u[refl, 2].max() < F <= u[refr, 2].min()

    # Reflection: the exact mirror direction, weight 1.
    nf = normal if outside else -normal
    mirror = 2 * (wo @ nf) * nf - wo
    np.testing.assert_allclose(wi[refl], np.broadcast_to(mirror, wi[refl].shape), atol=1e-14)
    np.testing.assert_array_equal(weight[refl], 1.0)

    # Refraction: Snell's law, in the plane of incidence, on the other side; radiance scaled by
    # (eta_i / eta_t)^2.
    if F < 1:
        assert refr.any()
        t = wi[refr]
        np.testing.assert_allclose(np.abs(t @ normal), cos_t, rtol=1e-12, atol=1e-14)
        sin_i = np.linalg.norm(np.cross(wo, normal))
        sin_t = np.linalg.norm(np.cross(t, normal), axis=1)
        np.testing.assert_allclose(eta_t * sin_t, eta_i * sin_i, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(np.cross(wo, normal) @ t.T, 0, atol=1e-14)  # coplanar
        if sin_i > 1e-9:  # tangential parts point opposite ways (wo points away from surface)
            tan_wo = wo - (wo @ normal) * normal
            tan_t = t - (t @ normal)[:, None] * normal
            assert np.all(tan_t @ tan_wo < 0)
        np.testing.assert_allclose(weight[refr], (eta_i / eta_t) ** 2, rtol=1e-12)
    else:
        assert not refr.any()


def test_fresnel_reference_values():
    # Normal incidence on glass: ((n - 1) / (n + 1))^2 = 0.04; Brewster's angle: r_p = 0.
    assert fresnel_reference(1.0, 1.0, 1.5)[0] == pytest.approx(0.04, rel=1e-12)
    brewster = math.atan(1.5)
    r, _ = fresnel_reference(math.cos(brewster), 1.0, 1.5)
    cos_t = math.cos(math.asin(math.sin(brewster) / 1.5))
    r_s = (math.cos(brewster) - 1.5 * cos_t) / (math.cos(brewster) + 1.5 * cos_t)
    assert r == pytest.approx(0.5 * r_s**2, rel=1e-12)


# --------------------------------------------------------------------------- phase functions

PHASES = [(HG, g) for g in HG_G] + [(ISOTROPIC, 0.0)]


def sample_phase_dirs(type_: int, g: float, wo, seed: int):
    def sample(n: int) -> np.ndarray:
        rng = np.random.default_rng(seed)
        wi, _ = _core.sample_phase(type_, g, tuple(wo), rng.random((n, 2)))
        return wi

    return sample


@pytest.mark.parametrize("type_,g", PHASES)
def test_phase_sampling_chi2(type_, g):
    domain = stats.SphericalDomain(axis=tuple(-np.asarray(WO_PHASE)), res_z=40, res_phi=40)
    sample = sample_phase_dirs(type_, g, WO_PHASE, seed=2000 + PHASES.index((type_, g)))
    test = stats.SphericalChi2(sample, phase_pdf(type_, g, WO_PHASE), domain, 400_000)
    result, _, _ = test.run()
    assert result.passed(LEVEL), result


@pytest.mark.parametrize("g", HG_G)
def test_hg_cos_theta_equiprobable_bins(g):
    """cos(theta) to the forward direction against the closed-form HG CDF, binned at its
    quantiles: fine resolution inside the narrow peaks of |g| = 0.99 that the spherical
    histogram lumps into one ring."""
    n = 400_000
    rng = np.random.default_rng(3000 + HG_G.index(g))
    wi, _ = _core.sample_phase(HG, g, WO_PHASE, rng.random((n, 2)))
    mu = wi @ -np.asarray(WO_PHASE)
    grid = np.linspace(-1, 1, 200_001)
    cdf = hg_cos_cdf(grid, g)
    edges = np.interp(np.linspace(0, 1, 201), cdf, grid)  # 200 bins of equal probability
    edges[0], edges[-1] = -1.0, 1.0 + 1e-12
    result = stats.chi2_1d(mu, edges, lambda x: hg_cos_cdf(np.minimum(x, 1.0), g))
    assert result.passed(LEVEL), result


@pytest.mark.parametrize("type_,g", PHASES)
def test_phase_mean_cosine_is_g(type_, g):
    """E[cos(wi, -wo)] = g fixes the sign convention (g > 0 forward)."""
    n = 200_000
    rng = np.random.default_rng(4000 + PHASES.index((type_, g)))
    wi, _ = _core.sample_phase(type_, g, WO_PHASE, rng.random((n, 2)))
    mean, se = stats.mean_and_se(wi @ -np.asarray(WO_PHASE))
    assert stats.t_p_value(mean, g, se, n - 1) >= LEVEL, (mean, se, g)


@pytest.mark.parametrize("type_,g", PHASES)
def test_phase_pdf_matches_eval_and_closed_form(type_, g):
    rng = np.random.default_rng(5)
    wi, pdf = _core.sample_phase(type_, g, WO_PHASE, rng.random((5000, 2)))
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1, rtol=1e-12)
    np.testing.assert_allclose(pdf, _core.eval_phase(type_, g, WO_PHASE, wi), rtol=1e-9)
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    expected = hg_reference(d @ -np.asarray(WO_PHASE), g)
    np.testing.assert_allclose(_core.eval_phase(type_, g, WO_PHASE, d), expected, rtol=1e-12)
    assert np.all(pdf > 0) and np.all(np.isfinite(pdf))


@pytest.mark.parametrize("g", [0.5, 0.9])
def test_hg_forward_peak_direction(g):
    """g > 0: the density is largest at wi = -wo (straight on), smallest at wi = wo."""
    wo = np.asarray(WO_PHASE)
    fwd, back = _core.eval_phase(HG, g, WO_PHASE, np.stack([-wo, wo]))
    assert fwd == pytest.approx((1 + g) / (4 * math.pi * (1 - g) ** 2), rel=1e-12)
    assert back == pytest.approx((1 - g) / (4 * math.pi * (1 + g) ** 2), rel=1e-12)


# --------------------------------------------------------------------------- normalisation


@pytest.mark.parametrize("type_,g", PHASES)
def test_phase_pdf_integrates_to_one(type_, g):
    domain = stats.SphericalDomain(axis=tuple(-np.asarray(WO_PHASE)), res_z=8, res_phi=8)
    assert domain.integrate(phase_pdf(type_, g, WO_PHASE)).sum() == pytest.approx(1, abs=1e-7)


@pytest.mark.parametrize("cos_wo", DIFFUSE_COS_WO)
def test_diffuse_pdf_integrates_to_one(cos_wo):
    normal = NORMALS[3]
    wo = rotate_towards(normal, cos_wo)
    domain = stats.SphericalDomain(axis=normal, res_z=8, res_phi=8)
    assert domain.integrate(bsdf_pdf(DIFFUSE, normal, wo)).sum() == pytest.approx(1, abs=1e-7)


def test_integrator_exact_on_known_densities():
    """The cubature of tests/stats.py: uniform density gives each bin dz dphi / 4 pi."""
    domain = stats.SphericalDomain(axis=(0.1, 0.2, 0.9), res_z=6, res_phi=5)
    mass = domain.integrate(lambda d: np.full(len(d), 1 / (4 * math.pi)))
    np.testing.assert_allclose(mass[:-1], 1 / 30, rtol=1e-12)
    assert mass[-1] == 0


# --------------------------------------------------------------------------- the test can fail


@pytest.mark.parametrize("g_sample,g_eval", [(0.5, 0.45), (0.9, 0.88), (0.3, -0.3)])
def test_chi2_rejects_wrong_hg_density(g_sample, g_eval):
    """Samples drawn with one g, tested against the density of a nearby g: rejected."""
    domain = stats.SphericalDomain(axis=tuple(-np.asarray(WO_PHASE)), res_z=40, res_phi=40)
    sample = sample_phase_dirs(HG, g_sample, WO_PHASE, seed=6000)
    result, _, _ = stats.SphericalChi2(sample, phase_pdf(HG, g_eval, WO_PHASE), domain).run()
    assert not result.passed(LEVEL), result
    assert result.p_value < 1e-12


def test_chi2_rejects_uniform_hemisphere_for_diffuse():
    normal = (0.0, 0.0, 1.0)
    rng = np.random.default_rng(6001)

    def sample(n: int) -> np.ndarray:
        return _core.sample_bsdf(DIFFUSE, REFLECTANCE, 1.5, normal, normal, rng.random((n, 3)))[0]

    def uniform_hemisphere(d: np.ndarray) -> np.ndarray:
        return np.where(d[:, 2] > 0, 1 / (2 * math.pi), 0.0)

    domain = stats.SphericalDomain(axis=normal, res_z=20, res_phi=40)
    result, _, _ = stats.SphericalChi2(sample, uniform_hemisphere, domain, 200_000).run()
    assert not result.passed(LEVEL), result


def test_chi2_rejects_samples_outside_the_support():
    """A sample in a bin of zero expected mass fails at once (e.g. below a BSDF's horizon)."""
    observed = np.array([10.0, 20.0, 1.0])
    expected = np.array([15.0, 16.0, 0.0])
    result = stats.chi2_test(observed, expected)
    assert not result.passed(LEVEL) and "zero expected" in result.reason


def test_chi2_pools_small_bins():
    """Bins below 5 expected are pooled: 10 bins of 1 expected make one bin of 10."""
    observed = np.array([1.0] * 10 + [100.0, 100.0])
    expected = np.array([1.0] * 10 + [100.0, 100.0])
    result = stats.chi2_test(observed, expected)
    assert result.dof == 2 and result.statistic == 0 and result.p_value == 1


def test_hemisphere_domain():
    """A hemisphere domain: diffuse samples fit; a direction below the horizon is counted in
    the outside bin, whose expected count is 0, and fails the test."""
    normal = (0.0, 1.0, 0.0)
    domain = stats.SphericalDomain(axis=normal, res_z=10, res_phi=20, hemisphere=True)
    u = np.random.default_rng(6002).random((100_000, 3))
    wi = _core.sample_bsdf(DIFFUSE, REFLECTANCE, 1.5, normal, normal, u)[0]
    mass = domain.integrate(bsdf_pdf(DIFFUSE, normal, normal))
    assert mass.sum() == pytest.approx(1, abs=1e-9) and mass[-1] == 0
    assert stats.chi2_test(domain.histogram(wi), mass * len(wi)).passed(LEVEL)
    wi[0] = (0.0, -0.5, np.sqrt(0.75))
    result = stats.chi2_test(domain.histogram(wi), mass * len(wi))
    assert not result.passed(LEVEL) and "zero expected" in result.reason


# --------------------------------------------------------------------------- cone and disk
# The warps of sampling.h behind emission: a spot light's directions (uniform in solid angle in
# its cutoff cone) and a directional light's starting points (uniform on a disk).


def cone_pdf(axis, cos_cutoff: float):
    """Uniform per steradian inside the cone, 0 outside."""
    a = unit(axis)

    def pdf(d: np.ndarray) -> np.ndarray:
        return np.where(d @ a >= cos_cutoff, 1 / (2 * math.pi * (1 - cos_cutoff)), 0.0)

    return pdf


def cone_angle_uniform_pdf(axis, cos_cutoff: float):
    """A wrong density for the controls: uniform in the angle theta to the axis instead of in
    solid angle, 1 / (theta_max 2 pi sin(theta)) per steradian."""
    a, theta_max = unit(axis), math.acos(cos_cutoff)

    def pdf(d: np.ndarray) -> np.ndarray:
        z = np.clip(d @ a, -1.0, 1.0)
        sin = np.sqrt(np.maximum(1 - z * z, 1e-300))
        return np.where(z >= cos_cutoff, 1 / (theta_max * 2 * math.pi * sin), 0.0)

    return pdf


def sample_cone_dirs(axis, cos_cutoff: float, seed: int, exponent: float = 1.0):
    """The native cone warp, fed u1^exponent (1: the uniforms the renderer draws; otherwise a
    control's wrong input)."""

    def sample(n: int) -> np.ndarray:
        u = np.random.default_rng(seed).random((n, 2))
        u[:, 0] **= exponent
        d, pdf = _core.sample_uniform_cone(tuple(axis), cos_cutoff, u)
        np.testing.assert_allclose(pdf, 1 / (2 * math.pi * (1 - cos_cutoff)), rtol=1e-14)
        return d

    return sample


def uniform_cos_cdf(cos_cutoff: float):
    """CDF of cos(theta) for directions uniform in solid angle in the cone."""
    return lambda x: np.clip((x - cos_cutoff) / (1 - cos_cutoff), 0.0, 1.0)


def cone_cos_chi2(d: np.ndarray, axis, cos_cutoff: float, cdf) -> stats.Chi2Result:
    """cos(theta) to the axis in 100 equal bins over [cos_cutoff, 1] against `cdf`: finer than
    the sphere's rings, of which a narrow cone covers one."""
    edges = np.linspace(cos_cutoff, 1.0, 101)
    edges[-1] = 1 + 1e-12  # cos(theta) = 1 is inside
    return stats.chi2_1d(d @ unit(axis), edges, cdf)


def cone_domain(axis) -> stats.SphericalDomain:
    # z edges every 0.05: each case's cutoff lies on one, as the density's discontinuity should.
    return stats.SphericalDomain(axis=tuple(unit(axis)), res_z=40, res_phi=40)


@pytest.mark.parametrize("axis,cos_cutoff", CONE_CASES)
def test_uniform_cone_sampling_chi2(axis, cos_cutoff):
    sample = sample_cone_dirs(axis, cos_cutoff, seed=7000 + CONE_CASES.index((axis, cos_cutoff)))
    test = stats.SphericalChi2(sample, cone_pdf(axis, cos_cutoff), cone_domain(axis), 400_000)
    result, _, _ = test.run()
    assert result.passed(LEVEL), result
    d = sample(400_000)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1, rtol=1e-12)
    assert np.all(d @ unit(axis) >= cos_cutoff - 1e-12)
    result = cone_cos_chi2(d, axis, cos_cutoff, uniform_cos_cdf(cos_cutoff))
    assert result.passed(LEVEL), result


@pytest.mark.parametrize("axis,cos_cutoff", CONE_CASES)
def test_uniform_cone_pdf_integrates_to_one(axis, cos_cutoff):
    mass = cone_domain(axis).integrate(cone_pdf(axis, cos_cutoff))
    assert mass.sum() == pytest.approx(1, abs=1e-7)


def disk_histogram(points: np.ndarray, res_r2: int = 20, res_phi: int = 40) -> np.ndarray:
    """Counts in bins of equal area, (r^2, phi); points off the unit disk (r > 1, or z != 0)
    go to one last bin."""
    r2 = points[:, 0] ** 2 + points[:, 1] ** 2
    phi = np.mod(np.arctan2(points[:, 1], points[:, 0]), 2 * math.pi)
    inside = (r2 <= 1) & (points[:, 2] == 0)
    bins = [np.linspace(0, 1 + 1e-12, res_r2 + 1), np.linspace(0, 2 * math.pi, res_phi + 1)]
    h, _, _ = np.histogram2d(r2[inside], phi[inside], bins=bins)
    return np.append(h.ravel(), np.count_nonzero(~inside))


def disk_expected(n: int, mass_within, res_r2: int = 20, res_phi: int = 40) -> np.ndarray:
    """Expected counts of disk_histogram for a density invariant under rotation whose mass
    within radius r is mass_within(r)."""
    ring = np.diff(mass_within(np.sqrt(np.linspace(0, 1, res_r2 + 1))))
    return np.append(np.repeat(ring / res_phi, res_phi), 0.0) * n


def test_uniform_disk_sampling_chi2():
    n = 400_000
    points, pdf = _core.sample_uniform_disk(np.random.default_rng(7100).random((n, 2)))
    np.testing.assert_array_equal(pdf, 1 / math.pi)
    result = stats.chi2_test(disk_histogram(points), disk_expected(n, lambda r: r * r))
    assert result.passed(LEVEL), result


# --------------------------------------------------------------------------- cone and disk controls


@pytest.mark.parametrize("axis,cos_cutoff", [CONE_CASES[1], CONE_CASES[3]])
def test_chi2_rejects_cone_uniform_in_angle(axis, cos_cutoff):
    """Directions uniform in theta instead of in solid angle against the cone's density, and
    the cone's own samples against that wrong density: rejected."""
    n = 400_000
    theta_max = math.acos(cos_cutoff)
    rng = np.random.default_rng(7200)

    def angle_uniform(count: int) -> np.ndarray:
        theta, phi = theta_max * rng.random(count), 2 * math.pi * rng.random(count)
        sin = np.sin(theta)
        local = np.stack([sin * np.cos(phi), sin * np.sin(phi), np.cos(theta)], 1)
        return local @ stats.frame(unit(axis))

    def angle_uniform_cdf(x):
        return np.clip((theta_max - np.arccos(np.clip(x, -1.0, 1.0))) / theta_max, 0.0, 1.0)

    sample = sample_cone_dirs(axis, cos_cutoff, seed=7201)
    right = uniform_cos_cdf(cos_cutoff)
    assert not cone_cos_chi2(angle_uniform(n), axis, cos_cutoff, right).passed(LEVEL)
    assert not cone_cos_chi2(sample(n), axis, cos_cutoff, angle_uniform_cdf).passed(LEVEL)
    if cos_cutoff <= 0.9:  # a narrower cone lies in one ring of the sphere's bins
        domain, pdf = cone_domain(axis), cone_pdf(axis, cos_cutoff)
        result, _, _ = stats.SphericalChi2(angle_uniform, pdf, domain, n).run()
        assert not result.passed(LEVEL), result
        wrong = cone_angle_uniform_pdf(axis, cos_cutoff)
        result, _, _ = stats.SphericalChi2(sample, wrong, domain, n).run()
        assert not result.passed(LEVEL), result


@pytest.mark.parametrize("exponent", [0.97, 1.03])
def test_chi2_rejects_cone_with_a_wrong_exponent(exponent):
    """The cone warp fed u1^exponent, so that cos(theta) is no longer uniform: rejected."""
    axis, cos_cutoff = CONE_CASES[2]
    sample = sample_cone_dirs(axis, cos_cutoff, seed=7300, exponent=exponent)
    test = stats.SphericalChi2(sample, cone_pdf(axis, cos_cutoff), cone_domain(axis), 400_000)
    result, _, _ = test.run()
    assert not result.passed(LEVEL), result
    result = cone_cos_chi2(sample(400_000), axis, cos_cutoff, uniform_cos_cdf(cos_cutoff))
    assert not result.passed(LEVEL), result


def test_chi2_rejects_wrong_disk_densities():
    """Points uniform in r (crowded at the centre) or at r = u^0.52 against the uniform disk,
    the disk's own samples against the density uniform in r, and a point off the disk: all
    rejected."""
    n = 400_000
    rng = np.random.default_rng(7400)
    phi = 2 * math.pi * rng.random(n)

    def polar(r: np.ndarray) -> np.ndarray:
        return np.stack([r * np.cos(phi), r * np.sin(phi), np.zeros(n)], 1)

    uniform_area = disk_expected(n, lambda r: r * r)
    for r in (rng.random(n), rng.random(n) ** 0.52):
        result = stats.chi2_test(disk_histogram(polar(r)), uniform_area)
        assert not result.passed(LEVEL), result
    points, _ = _core.sample_uniform_disk(np.random.default_rng(7401).random((n, 2)))
    result = stats.chi2_test(disk_histogram(points), disk_expected(n, lambda r: r))
    assert not result.passed(LEVEL), result
    points[0] = (0.8, 0.7, 0.0)  # r > 1: in the bin of zero expected count
    result = stats.chi2_test(disk_histogram(points), uniform_area)
    assert not result.passed(LEVEL) and "zero expected" in result.reason
