"""vrl and vbl (cpp/ray_lights.h, cpp/vrl.h, methods/vrl.py, methods/vbl.py): ray lights.

- The density on a ray light about a camera line (Novak et al. 2012, sec. 4.1) follows the
  density it reports (chi-square; expected counts by integrating the density), integrates to
  one, is proportional to 1 / the distance to the camera line, and the test rejects a uniform
  density; skew, nearly parallel, parallel (uniform) and intersecting lines.
- The phase-aware equi-angular density (an option) follows the density it reports (chi-square)
  and differs from the plain one.
- The beam's mean of 1 / d^2 over its disc (vbl) equals a numerical quadrature over the disc,
  in and off the disc's plane, and tends to 1 / d^2 as r -> 0.
- For one ray light and one camera segment (or one surface point), the estimator's mean equals
  a quadrature of the double (single) integral, with the tolerance from the samples' variance:
  skew, nearly parallel, parallel, nearly intersecting, short segments, and beams; crossing
  lines give finite values; the same with phase-aware sampling.
- vrl and vbl agree with pt and Mitsuba on cbox-fog, with pt on scenes with density grids (and a
  Mie phase function), glass, a directional light and on juice (image mean and 4x4 blocks,
  tolerances from the measured variance).
- vbl's radius follows its schedule and vbl tends to vrl as r -> 0. (Same image for any thread
  count and chunking, and every shipped scene rendering finite: tests/test_vpl.py, for every
  method of the gathering kernel.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

import stats
from conftest import load_small
from parity import mitsuba, ours, same_image
from renderer import _core
from renderer.methods import get_method
from renderer.methods.pt import PathTracing
from renderer.methods.vbl import VirtualBeamLights
from renderer.methods.vrl import VirtualRayLights

SIGMA_T, ALBEDO, G = 1.0, 0.8, 0.5
REFLECTANCE = 0.5
FLOOR = 0


def unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def probe_scene():
    """A diffuse floor (y = 0, normal +y) and one grey homogeneous medium with HG g = 0.5."""
    s = _core.Scene()
    verts = np.array(
        [[(-1, 0, -1), (-1, 0, 1), (1, 0, 1)], [(-1, 0, -1), (1, 0, 1), (1, 0, -1)]], np.float64
    )
    s.add_material(_core.MaterialType.diffuse, (REFLECTANCE,) * 3, 1.5)
    none = np.full(2, -1, np.int32)
    s.set_triangles(verts, np.zeros(2, np.int32), none, none, none, np.zeros(2, np.uint8))
    s.add_homogeneous_medium((SIGMA_T,) * 3, (ALBEDO,) * 3, _core.PhaseType.hg, G)
    s.finalize()
    return s


def hg(cos_theta):
    """Henyey-Greenstein for the angle between the directions of travel."""
    return (1 - G * G) / (4 * math.pi * (1 + G * G - 2 * G * cos_theta) ** 1.5)


# --------------------------------------------------------------------------- the density

# ray light (origin, direction, length), camera line (origin, direction)
C, X = (0.0, 0.5, 0.0), (1.0, 0.0, 0.0)  # a camera line along x
LINE_CASES = {
    "skew": ((0.5, 0.8, -1.0), (0.2, 0.1, 1.0), 1.5, C, X),
    "closest-point-outside": ((0.5, 0.8, 0.4), (0.0, 0.3, 1.0), 2.0, C, X),
    "nearly-parallel": ((0.3, 0.7, 0.0), (1.0, 0.0, 2e-3), 1.0, C, X),
    "nearly-intersecting": ((0.8, 0.501, -0.5), (0.0, 0.0, 1.0), 1.0, C, X),
    "intersecting": ((0.8, 0.5, -0.5), (0.0, 0.6, 0.8), 1.0, (0.0, 0.875, 0.0), X),
}
MIN_H = 1e-9
N_TESTS = len(LINE_CASES) + 3  # and the phase-aware cases below
LEVEL = stats.sidak(stats.ALPHA, N_TESTS)
SAMPLES = 200_000


def _distance_to_line(points, c, wc):
    off = points - np.asarray(c)
    along = off @ np.asarray(wc)
    return np.linalg.norm(off - np.outer(along, wc), axis=1)


def _bin_masses(pdf, edges: np.ndarray) -> np.ndarray:
    """The density integrated over each bin, adaptively (it peaks sharply where lines meet)."""
    return np.array(
        [
            integrate.quad(lambda x: float(pdf(np.array([x]))[0]), a, b, epsabs=1e-13, limit=200)[0]
            for a, b in zip(edges[:-1], edges[1:], strict=True)
        ]
    )


@pytest.mark.parametrize("case", LINE_CASES)
def test_line_to_line_density_chi2(case):
    o, wl, length, c, wc = LINE_CASES[case]
    wl, wc = unit(wl), unit(wc)
    rng = np.random.default_rng(21 + list(LINE_CASES).index(case))
    v, pdf, uniform = _core.line_to_line_samples(
        o, wl, length, c, wc, MIN_H, 0.0, rng.random(SAMPLES)
    )
    assert not uniform
    assert np.all((v >= 0) & (v <= length)) and np.all(np.isfinite(pdf))

    def density(x):
        return _core.line_to_line_pdfs(o, wl, length, c, wc, MIN_H, 0.0, np.ascontiguousarray(x))

    np.testing.assert_allclose(pdf, density(v), rtol=1e-12)
    # Proportional to 1 / the distance to the camera line (not at a crossing: h is floored).
    if case != "intersecting":
        t = np.linspace(0, length, 7)
        dist = _distance_to_line(np.asarray(o) + np.outer(t, wl), c, wc)
        product = density(t) * dist
        np.testing.assert_allclose(product, product[0], rtol=1e-9)
    pilot, _, _ = _core.line_to_line_samples(o, wl, length, c, wc, MIN_H, 0.0, rng.random(20_000))
    edges = np.unique(np.quantile(pilot, np.linspace(0, 1, 41)))
    edges[0], edges[-1] = 0.0, length
    masses = _bin_masses(density, edges)
    assert masses.sum() == pytest.approx(1.0, abs=1e-6)
    observed = np.histogram(v, edges)[0]
    result = stats.chi2_test(observed, masses * SAMPLES)
    assert result.passed(LEVEL), result
    uniform_v = length * rng.random(SAMPLES)
    if case not in ("nearly-parallel",):  # there the density is nearly uniform by design
        assert not stats.chi2_test(np.histogram(uniform_v, edges)[0], masses * SAMPLES).passed(
            LEVEL
        )


def test_parallel_lines_draw_uniformly_and_the_softened_density_integrates_to_one():
    o, c, wc = (0.2, 0.7, 0.1), (0.0, 0.5, 0.0), (1.0, 0.0, 0.0)
    for wl in ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), unit((1.0, 0.0, 5e-5))):
        v, pdf, uniform = _core.line_to_line_samples(
            o, wl, 2.0, c, wc, MIN_H, 0.0, np.linspace(0, 1, 5)
        )
        assert uniform
        np.testing.assert_allclose(v, np.linspace(0, 2, 5))
        np.testing.assert_allclose(pdf, 0.5)
    # vbl softens h by r: still a density, finite where the lines cross.
    o, wl, length, c, wc = LINE_CASES["intersecting"]

    def pdf(x):
        return _core.line_to_line_pdfs(o, unit(wl), length, c, unit(wc), MIN_H, 0.05, np.array([x]))

    mass = integrate.quad(lambda x: pdf(x)[0], 0, length, points=[0.5], limit=200)[0]
    assert mass == pytest.approx(1.0, abs=1e-8)


# (origin, direction, t0, t1, centre, centre_out, g_line, g_centre)
PHASE_CASES = {
    "forward": ((0, 0, 0), (1, 0, 0), 0.0, 4.0, (1.5, 0.6, 0), (1, 0, 0), 0.9, 0.9),
    "backward-and-forward": (
        (0, 0, 0),
        (1, 0, 0),
        0.0,
        3.0,
        (1.0, 0.3, 0.2),
        (-1, 0, 0),
        -0.7,
        0.8,
    ),
    "infinite": ((0, 0, 0), (0, 0, 1), 0.5, np.inf, (0.2, 0.1, 1.0), (0, 1, 0), 0.95, 0.3),
}


@pytest.mark.parametrize("case", PHASE_CASES)
def test_phase_aware_equiangular_density_chi2(case):
    """The phase-aware point follows the density it reports, which integrates to one; the
    plain equi-angular density is rejected (the test has power)."""
    o, d, t0, t1, c, out, g_line, g_centre = PHASE_CASES[case]
    rng = np.random.default_rng(5 + list(PHASE_CASES).index(case))
    args = (o, d, t0, t1, c, out, g_line, g_centre)
    t, pdf, _ = _core.phase_aware_samples(*args, rng.random(SAMPLES), np.zeros(1))
    assert np.all((t >= t0) & (t <= t1))

    def density(x):
        return _core.phase_aware_samples(*args, np.zeros(0), np.ascontiguousarray(x))[2]

    np.testing.assert_allclose(pdf, density(t), rtol=1e-10)
    pilot = _core.phase_aware_samples(*args, rng.random(20_000), np.zeros(1))[0]
    edges = np.unique(np.quantile(pilot, np.linspace(0, 1, 41)))
    edges[0] = t0
    if np.isfinite(t1):
        edges[-1] = t1
    masses = _bin_masses(density, edges)
    tail = (
        integrate.quad(lambda x: density(np.array([x]))[0], edges[-1], np.inf)[0]
        if np.isinf(t1)
        else 0.0
    )
    assert masses.sum() + tail == pytest.approx(1.0, abs=1e-6)
    inside = t < edges[-1]
    observed = np.append(np.histogram(t[inside], edges)[0], np.count_nonzero(~inside))
    expected = np.append(masses, tail) * SAMPLES
    assert stats.chi2_test(observed, expected).passed(LEVEL)
    plain, _ = _core.equiangular_samples(o, d, t0, t1, c, rng.random(SAMPLES))
    observed = np.append(
        np.histogram(plain[plain < edges[-1]], edges)[0], np.count_nonzero(plain >= edges[-1])
    )
    assert not stats.chi2_test(observed, expected).passed(LEVEL)


# --------------------------------------------------------------------------- the beam's disc


def _disc_mean(z, rho, r):
    """(1 / (pi r^2)) int over the disc of 1 / |x - y'|^2, x at (rho, 0, z), by quadrature."""

    def over_angle(s):
        return integrate.quad(
            lambda phi: s / (z * z + rho * rho + s * s - 2 * rho * s * math.cos(phi)),
            0,
            2 * math.pi,
            limit=200,
        )[0]  # noqa: E501

    points = [rho] if 0 < rho < r else None
    return integrate.quad(over_angle, 0, r, points=points, limit=200)[0] / (math.pi * r * r)


@pytest.mark.parametrize(
    "z, rho, r",
    [(0.3, 0.0, 0.1), (0.05, 0.02, 0.1), (0.02, 0.3, 0.1), (0.0, 0.3, 0.1), (1e-3, 0.5, 0.2),
     (0.4, 0.35, 0.3)],
)  # fmt: skip
def test_beam_geometry_factor_is_the_disc_mean(z, rho, r):
    d2 = z * z + rho * rho
    factor = _core.beam_geometry_factor(z, rho * rho, r)
    assert factor / (d2 + r * r) == pytest.approx(_disc_mean(z, rho, r), rel=1e-6)


def test_beam_geometry_factor_tends_to_the_inverse_square():
    for r in (1e-3, 1e-5, 1e-9, 0.0):
        assert _core.beam_geometry_factor(0.3, 0.16, r) == pytest.approx(1.0, rel=2e-5)


# --------------------------------------------------------------------------- one pair

# camera segment (origin, direction, length), ray light (origin, direction, length)
PAIR_CASES = {
    "skew": (C, X, 2.0, (0.5, 0.8, -1.0), (0.2, 0.1, 1.0), 1.5),
    "nearly-parallel": (C, X, 1.5, (0.3, 0.7, 0.0), (1.0, 0.0, 2e-3), 1.0),
    "parallel": (C, X, 1.5, (0.3, 0.7, 0.0), (-1.0, 0.0, 0.0), 0.8),
    "nearly-intersecting": (C, X, 1.5, (0.8, 0.52, -0.5), (0.0, 0.0, 1.0), 1.0),
    "short-segments": (C, X, 0.05, (0.0, 0.6, -0.02), (0.3, 0.0, 1.0), 0.05),
}
PAIR_SAMPLES = 400_000


def _integrand(u, v, camera, light, radius):
    """The ray light's transport to the camera segment at (u, v), vectorised over u."""
    c, wc, _, o, wl, _ = camera + light
    c, wc, o, wl = map(np.asarray, (c, unit(wc), o, unit(wl)))
    x = c + np.outer(u, wc)
    y = o + v * wl
    d = y - x
    d2 = (d * d).sum(axis=1)
    dist = np.sqrt(d2)
    w = d / dist[:, None]
    sigma_s = SIGMA_T * ALBEDO
    # travel: along wl into y, then -w to x, then -wc to the camera
    phases = hg((-w) @ wl) * hg((w * wc).sum(axis=1))
    if radius > 0:
        z = d @ wl
        geometry = np.array(
            [
                _core.beam_geometry_factor(zi, max(0.0, q - zi * zi), radius)
                for zi, q in zip(z, d2, strict=True)
            ]
        )
        geometry /= d2 + radius * radius
    else:
        geometry = 1 / d2
    return np.exp(-SIGMA_T * (u + dist)) * sigma_s**2 * phases * geometry


def _pair_quadrature(camera, light, radius=0.0):
    """The double integral: u by graded composite Gauss-Legendre about the point of the camera
    line nearest y(v), v adaptively."""
    c, wc, s, o, wl, length = camera + light
    wc, wl = unit(wc), unit(wl)
    nodes, weights = np.polynomial.legendre.leggauss(12)

    def inner(v):
        y = np.asarray(o) + v * wl
        u_near = float((y - np.asarray(c)) @ wc)
        h = np.linalg.norm(y - np.asarray(c) - u_near * wc) + radius + 1e-12
        cuts = u_near + h * np.sinh(np.linspace(-12, 12, 161))
        cuts = np.unique(np.clip(np.concatenate([[0.0, s], cuts]), 0, s))
        lo, hi = cuts[:-1, None], cuts[1:, None]
        u = (0.5 * (lo + hi) + 0.5 * (hi - lo) * nodes).ravel()
        return float(
            (_integrand(u, v, camera, light, radius).reshape(-1, 12) * weights).sum(axis=1)
            @ (0.5 * (hi - lo)).ravel()
        )  # noqa: E501

    o_ = np.asarray(o) - np.asarray(c)
    n = np.cross(wc, wl)
    if np.linalg.norm(n) > 1e-9:
        v_near = -(o_ @ wl - (o_ @ wc) * (wc @ wl)) / (n @ n)
        points = [v_near] if 0 < v_near < length else None
    else:
        points = None
    return integrate.quad(inner, 0, length, points=points, limit=400, epsrel=1e-7)[0]


def _check_mean(samples: np.ndarray, expected: float, label: str):
    mean, stderr = samples.mean(), samples.std() / math.sqrt(len(samples))
    z = (mean - expected) / stderr
    print(f"{label}: estimate {mean:.6g} +- {stderr:.2g}, quadrature {expected:.6g}, z {z:.2f}")
    assert np.all(np.isfinite(samples))
    assert abs(z) < 4.5, f"{label}: z = {z:.2f}"


@pytest.mark.parametrize("phase_aware", [False, True])
@pytest.mark.parametrize("radius", [0.0, 0.05])
@pytest.mark.parametrize("case", PAIR_CASES)
def test_segment_estimator_mean_is_the_double_integral(case, radius, phase_aware):
    camera, light = PAIR_CASES[case][:3], PAIR_CASES[case][3:]
    scene = probe_scene()
    values = _core.ray_light_segment_estimates(
        scene, *camera, 0, *light, 0, radius, phase_aware, PAIR_SAMPLES, 7
    )
    np.testing.assert_array_equal(values[:, 0], values[:, 2])  # grey
    label = f"{case} r={radius} phase-aware {phase_aware}"
    _check_mean(values[:, 0], _pair_quadrature(camera, light, radius), label)


def test_crossing_lines_give_finite_values():
    """Lines that cross, and a ray light on the camera line itself: finite values; rays on one
    line bring nothing (every y is on the camera line: measure zero), beams do."""
    camera = ((0.0, 0.5, 0.0), (1.0, 0.0, 0.0), 1.5)
    crossing, collinear = (
        ((0.8, 0.5, -0.5), (0.0, 0.0, 1.0), 1.0),
        ((0.3, 0.5, 0.0), (1.0, 0.0, 0.0), 0.5),
    )
    for light in (crossing, collinear):
        for radius in (0.0, 0.05):
            for phase_aware in (False, True):
                values = _core.ray_light_segment_estimates(
                    probe_scene(), *camera, 0, *light, 0, radius, phase_aware, 20_000, 3
                )
                assert np.all(np.isfinite(values))
                assert values.max() > 0 or (light is collinear and radius == 0)


@pytest.mark.parametrize("phase_aware", [False, True])
@pytest.mark.parametrize("radius", [0.0, 0.05])
def test_point_estimator_mean_is_the_integral(radius, phase_aware):
    """A ray light above a point of the floor: int Tr W sigma_s f_y f_x G dv."""
    x, wo = np.array([0.1, 0.0, 0.2]), unit((0.3, 1, 0.4))
    o, wl, length = np.array([-0.4, 0.3, 0.1]), unit((1.0, 0.05, 0.1)), 1.2
    values = _core.ray_light_point_estimates(
        probe_scene(), x, wo, FLOOR, -1, o, wl, length, 0, radius, phase_aware, PAIR_SAMPLES, 5
    )

    def integrand(v):
        y = o + v * wl
        d = y - x
        d2 = d @ d
        w = d / math.sqrt(d2)
        z = d @ wl
        geometry = _core.beam_geometry_factor(z, d2 - z * z, radius) / (d2 + radius * radius)
        cos_x = max(0.0, w[1])
        return (
            math.exp(-SIGMA_T * math.sqrt(d2))
            * SIGMA_T
            * ALBEDO
            * hg((-w) @ wl)
            * REFLECTANCE
            / math.pi
            * cos_x
            * geometry
        )  # noqa: E501

    t_near = float((x - o) @ wl)
    expected = integrate.quad(integrand, 0, length, points=[t_near], limit=200, epsrel=1e-9)[0]
    _check_mean(values[:, 0], expected, f"point r={radius} phase-aware {phase_aware}")


# --------------------------------------------------------------------------- images

RES = 12


@pytest.mark.parametrize("cls", [VirtualRayLights, VirtualBeamLights])
def test_agrees_with_pt_and_mitsuba_on_cbox_fog(cls):
    """Unclamped (the point lights at surfaces), vrl and vbl with a small radius are unbiased or
    nearly: image mean and 4x4 blocks against pt and Mitsuba's volpath."""
    scene = load_small("cbox-fog", RES, RES)
    params = {"clamp": "none", "light_paths": 64, "spp_per_iteration": 2}
    if cls is VirtualBeamLights:
        params["beam_radius_relative"] = 0.01
    ours_ = ours(cls, scene, 24, **params)
    pt = ours(PathTracing, scene, 16, seed=2, spp_per_wave=64)
    ok, why = same_image(ours_, pt, alpha=1e-3, block=4)
    assert ok, f"against pt: {why}"
    ok, why = same_image(ours_, mitsuba(scene, 16, 256), alpha=1e-3, block=4)
    assert ok, f"against Mitsuba: {why}"


# (scene, method, parameters): what these scenes and options add to cbox-fog
VARIANTS = {
    # a density grid lit by point lights: ray lights cut to the grid's box
    "smoke": ("smoke", VirtualRayLights, {}),
    # glass: camera paths go on past their gather points
    "cbox-glass": ("cbox-glass", VirtualRayLights, {}),
    # a directional light, the camera inside fog
    "crepuscular": ("crepuscular", VirtualRayLights, {}),
    # the paper's scene: a glass of a dense, scattering liquid
    "juice": ("juice", VirtualRayLights, {}),
    # a grid with a tabulated (Mie) phase function: beams with phase-aware sampling
    "fog-perlin": (
        "fog-perlin",
        VirtualBeamLights,
        {"beam_radius_relative": 0.01, "phase_sampling": True},
    ),
}


@pytest.mark.parametrize("variant", VARIANTS)
def test_agrees_with_pt_on_more_scenes(variant):
    name, cls, params = VARIANTS[variant]
    scene = load_small(name, RES, RES)
    estimate = ours(cls, scene, 16, clamp="none", light_paths=64, spp_per_iteration=2, **params)
    pt = ours(PathTracing, scene, 16, seed=2, spp_per_wave=64)
    ok, why = same_image(estimate, pt, alpha=1e-3, block=4)
    assert ok, f"{variant}: {why}"


def test_beam_radius_follows_its_schedule_and_vbl_tends_to_vrl():
    scene = load_small("cbox-fog", 6, 6)
    m = VirtualBeamLights(
        scene, seed=0, threads=1, params={"beam_radius_relative": 0.1, "beam_alpha": 0.5}
    )
    r1 = 0.1 * m.native.core.scene_radius
    for i in (0, 1, 7, 99):
        assert m.gather.kernel.beam_radius(i) == pytest.approx(r1 * (i + 1) ** -0.5, rel=1e-12)
    images = {}
    for method, params in (("vrl", {}), ("vbl", {"beam_radius_relative": 1e-9})):
        m = get_method(method)(scene, seed=3, threads=2, params={"light_paths": 16, **params})
        for i in range(2):
            m.run_iteration(i)
        images[method] = m.image()
    np.testing.assert_allclose(images["vbl"], images["vrl"], rtol=1e-6, atol=1e-12)
