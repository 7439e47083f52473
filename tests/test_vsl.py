"""vsl (cpp/vsl.h, methods/vsl.py): virtual spherical lights.

- The transfer K(x, y) = 1 / (pi r^2) * integral over the cone of F_x F_y: in the far field it
  is the point light's F_x F_y / d^2 (exactly where F_x F_y is constant across the cone:
  isotropic phase functions at both ends; to O(r / d) otherwise), inside the sphere it is
  4 F / r^2 exactly for a constant F, and its MIS estimate is unbiased for the cone integral
  (against quadrature, on surfaces, in media, for an area light, near and far).
- Rendered with a vanishing radius, vsl is vpl unclamped, to the last digits; with a fixed
  radius its image is biased, the more so the larger the radius, and with the shrinking radius
  of its schedule it agrees with pt.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import stats
from conftest import load_small
from parity import agreement, mitsuba, ours, same_image
from renderer import _core
from renderer.errors import PgiError
from renderer.methods.pt import PathTracing
from renderer.methods.vpl import VirtualPointLights
from renderer.methods.vsl import VirtualSphericalLights

DIFFUSE = _core.MaterialType.diffuse
KIND = _core.VirtualLightKind
REFLECTANCE = (0.5, 0.6, 0.7)
FLOOR, WALL = 0, 2  # a triangle of each quad


def probe_scene(g: float):
    """A floor (y = 0, normal +y) and a wall (x = -1, normal +x), diffuse, and one medium with
    an HG phase function (isotropic for g = 0)."""
    s = _core.Scene()
    floor = [[(-1, 0, -1), (-1, 0, 1), (1, 0, 1)], [(-1, 0, -1), (1, 0, 1), (1, 0, -1)]]
    wall = [[(-1, 0, -1), (-1, 1, -1), (-1, 1, 1)], [(-1, 0, -1), (-1, 1, 1), (-1, 0, 1)]]
    verts = np.array(floor + wall, dtype=np.float64)
    s.add_material(DIFFUSE, REFLECTANCE, 1.5)
    n = len(verts)
    none = np.full(n, -1, np.int32)
    s.set_triangles(verts, np.zeros(n, np.int32), none, none, none, np.zeros(n, np.uint8))
    phase = _core.PhaseType.hg if g else _core.PhaseType.isotropic
    s.add_homogeneous_medium((1.0, 1.0, 1.0), (0.8, 0.8, 0.8), phase, g)
    s.finalize()
    return s


def unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


# A gather point (position, wo, triangle, medium) and a light (kind, position, axis, triangle,
# medium, light), as the probes take them.
X_MEDIUM = ((0.1, 0.5, 0.0), tuple(unit((0.2, 1, 0.5))), -1, 0)
X_FLOOR = ((0.1, 0.0, 0.2), tuple(unit((0.3, 1, 0.4))), FLOOR, -1)
Y_MEDIUM = (KIND.medium, (0.3, 0.6, -0.1), tuple(unit((0.5, 0.2, -1))), -1, 0, -1)
Y_FLOOR = (KIND.surface, (-0.3, 0.0, 0.1), tuple(unit((0.2, 1, -0.3))), FLOOR, -1, -1)
Y_WALL_LIGHT = (KIND.area_light, (-1.0, 0.3, 0.2), (1.0, 0.0, 0.0), WALL, -1, -1)


def vsl(scene, x, y, radius, n=1, seed=0) -> np.ndarray:
    return _core.spherical_light_transfers(scene, *x, *y, radius, n, seed)


def vpl(scene, x, y) -> np.ndarray:
    return np.array(_core.point_light_transfer(scene, *x, *y, 0.0))


def _moved(light, position):
    return (light[0], position, *light[2:])


# (axis, 1 - cos of the half-angle): every direction, a hemisphere, a wide cone, and the narrow
# cones of far spheres, down to where sin(theta) from sqrt(1 - cos^2) would keep 3 digits
NARROW_CONES = [
    ((0, 0, 1), 2.0), (tuple(unit((0.4, -0.7, 0.2))), 1.0), ((0, -1, 0), 0.3),
    (tuple(unit((-0.3, 0.1, -0.9))), 1e-3), ((1, 0, 0), 1e-7), (tuple(unit((1, 2, 3))), 1e-10),
]  # fmt: skip
CONE_LEVEL = stats.sidak(stats.ALPHA, len(NARROW_CONES))


def cone_coordinates(d: np.ndarray, axis) -> tuple[np.ndarray, np.ndarray]:
    """1 - cos(theta) to the axis (as |d - axis|^2 / 2, which keeps its digits near the axis)
    and the azimuth about it."""
    basis = stats.frame(np.asarray(axis, np.float64))
    a = 0.5 * ((d - basis[2]) ** 2).sum(axis=1)
    phi = np.mod(np.arctan2(d @ basis[1], d @ basis[0]), 2 * math.pi)
    return a, phi


def cone_histogram(d: np.ndarray, axis, one_minus_cos: float, bins: int = 20) -> np.ndarray:
    """Counts over bins of equal solid angle of the cone: equal steps of 1 - cos(theta) times
    equal steps of azimuth; directions outside the cone in one last bin."""
    a, phi = cone_coordinates(d, axis)
    q = a / one_minus_cos
    inside = q < 1 + 1e-9
    edges = [np.linspace(0, 1 + 1e-9, bins + 1), np.linspace(0, 2 * math.pi, bins + 1)]
    h, _, _ = np.histogram2d(q[inside], phi[inside], bins=edges)
    return np.append(h.ravel(), np.count_nonzero(~inside))


@pytest.mark.parametrize("axis, one_minus_cos", NARROW_CONES)
def test_cone_sampling_chi2(axis, one_minus_cos):
    """vsl's cone strategy is uniform in solid angle within the cone (chi-square over bins of
    equal solid angle, which (1 - cos, azimuth) gives for any width), unit and inside it, also
    in the narrowest cone; the test rejects directions drawn with u1^2 (a control)."""
    n, bins = 200_000, 20
    u = np.random.default_rng(int(-math.log10(one_minus_cos) * 10) + 40).random((n, 2))
    d = _core.sample_uniform_narrow_cone(axis, one_minus_cos, u)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1, rtol=1e-13)
    expected = np.append(np.full(bins * bins, n / bins**2), 0.0)
    result = stats.chi2_test(cone_histogram(d, axis, one_minus_cos, bins), expected)
    assert result.passed(CONE_LEVEL), result
    u[:, 0] **= 2
    control = cone_histogram(_core.sample_uniform_narrow_cone(axis, one_minus_cos, u), axis,
                             one_minus_cos, bins)  # fmt: skip
    assert not stats.chi2_test(control, expected).passed(CONE_LEVEL)


def test_far_field_is_the_point_light():
    """A sphere 1e-6 of the distance across: with isotropic phase functions at both ends (F
    constant over the cone) every estimate is the point light's transfer to rounding; with
    HG lobes and a diffuse surface, to O(r / d)."""
    iso = probe_scene(0.0)
    d = np.linalg.norm(np.subtract(Y_MEDIUM[1], X_MEDIUM[0]))
    np.testing.assert_allclose(
        vsl(iso, X_MEDIUM, Y_MEDIUM, 1e-6 * d, n=50),
        np.tile(vpl(iso, X_MEDIUM, Y_MEDIUM), (50, 1)),
        rtol=1e-12,
    )
    hg = probe_scene(0.7)
    for x, y in (
        (X_MEDIUM, Y_MEDIUM),
        (X_FLOOR, Y_MEDIUM),
        (X_MEDIUM, Y_FLOOR),
        (X_FLOOR, Y_WALL_LIGHT),
    ):
        d = np.linalg.norm(np.subtract(y[1], x[0]))
        point = vpl(hg, x, y)
        assert point.min() > 0
        np.testing.assert_allclose(
            vsl(hg, x, y, 1e-6 * d, n=50), np.tile(point, (50, 1)), rtol=2e-5
        )


def test_inside_the_sphere_a_constant_lobe_gives_four_over_r_squared():
    """With isotropic phase functions at both ends and d <= r / 2 the cone is every direction
    and every strategy's direction lies in it: each estimate is exactly 4 F / r^2, vpl's clamp
    at r / 2."""
    iso = probe_scene(0.0)
    f = (1 / (4 * math.pi)) ** 2
    near = _moved(Y_MEDIUM, (0.15, 0.55, 0.0))  # 0.07 from x
    np.testing.assert_allclose(vsl(iso, X_MEDIUM, near, 0.2, n=20), 4 * f / 0.04, rtol=1e-12)


def cone_integral(scene_g: float, x, y, radius: float, nodes: int = 160) -> np.ndarray:
    """1 / (pi r^2) * integral over the cone of F_x(w) F_y(-w), by Gauss-Legendre in
    (cos theta, phi) about the direction to y, F from the core's own BSDF and phase probes."""
    xp, wo, x_tri, _ = x
    kind, yp, axis, y_tri, _, _ = y
    to_y = np.subtract(yp, xp)
    d2 = float(to_y @ to_y)
    omega = 4 * math.pi if 4 * d2 <= radius**2 else math.pi * radius**2 / d2
    gx, gw = np.polynomial.legendre.leggauss(nodes)
    z = 1 - 0.5 * (gx + 1) * omega / (2 * math.pi)  # cos theta over [1 - omc, 1]
    phi = math.pi * (gx + 1)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    ww = np.outer(gw * omega / (4 * math.pi), gw * math.pi)  # dz dphi, both halved
    r = np.sqrt(np.clip(1 - zz**2, 0, None))
    local = np.stack([r * np.cos(pp), r * np.sin(pp), zz], axis=-1).reshape(-1, 3)
    n = unit(to_y)
    helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    s = unit(np.cross(helper, n))
    w = local @ np.stack([s, np.cross(n, s), n])
    w = np.ascontiguousarray(w)
    hg = _core.PhaseType.hg if scene_g else _core.PhaseType.isotropic
    normals = {FLOOR: (0, 1, 0), WALL: (1, 0, 0)}
    if x_tri >= 0:
        fx = _core.eval_bsdf(DIFFUSE, REFLECTANCE, 1.5, normals[x_tri], wo, w)[0]
    else:
        fx = np.repeat(_core.eval_phase(hg, scene_g, wo, w)[:, None], 3, axis=1)
    if kind == KIND.medium:
        fy = np.repeat(
            _core.eval_phase(hg, scene_g, axis, np.ascontiguousarray(-w))[:, None], 3, axis=1
        )
    elif kind == KIND.surface:
        fy = _core.eval_bsdf(
            DIFFUSE, REFLECTANCE, 1.5, normals[y_tri], axis, np.ascontiguousarray(-w)
        )[0]
    else:
        fy = np.repeat(np.clip(-w @ np.asarray(axis), 0, None)[:, None], 3, axis=1)
    f = (np.asarray(fx) * np.asarray(fy)).reshape(nodes, nodes, 3)
    return (f * ww[..., None]).sum(axis=(0, 1)) / (math.pi * radius**2)


CASES = {  # x, y, radius: the sphere around x (d <= r / 2), about as wide as d, far
    "medium-medium-inside": (X_MEDIUM, _moved(Y_MEDIUM, (0.15, 0.55, 0.0)), 0.2),
    "surface-medium-wide": (X_FLOOR, _moved(Y_MEDIUM, (0.2, 0.25, 0.1)), 0.4),
    "medium-surface": (X_MEDIUM, Y_FLOOR, 0.5),
    "surface-area-light": (X_FLOOR, _moved(Y_WALL_LIGHT, (-1.0, 0.15, 0.25)), 0.6),
    "medium-medium-far": (X_MEDIUM, Y_MEDIUM, 0.1),
}


@pytest.mark.parametrize("case", CASES)
def test_mis_estimate_is_unbiased_for_the_cone_integral(case):
    x, y, radius = CASES[case]
    scene = probe_scene(0.6)
    samples = vsl(scene, x, y, radius, n=200_000, seed=3)
    exact = cone_integral(0.6, x, y, radius)
    mean, se = samples.mean(axis=0), samples.std(axis=0) / math.sqrt(len(samples))
    z = (mean - exact) / se
    print(case, mean, exact, z)
    assert exact.min() > 0 and np.all(np.abs(z) < 4.5), (mean, exact, z)


RES = 12


def test_a_vanishing_radius_is_vpl_unclamped():
    """The same seed, a sphere of 1e-9 scene radii (fixed): vsl's image is vpl's to 1e-6."""
    scene = load_small("cbox-fog", 8, 8)
    images = []
    for cls, params in (
        (VirtualSphericalLights, {"sphere_radius_relative": 1e-9, "sphere_alpha": 1.0}),
        (VirtualPointLights, {"clamp": "none"}),
    ):
        method = cls(scene, seed=6, threads=2, params={"light_paths": 32, **params})
        for i in range(2):
            method.run_iteration(i)
        images.append(method.image())
    assert images[0].max() > 0
    np.testing.assert_allclose(images[0], images[1], rtol=1e-6, atol=0)


def test_a_wider_fixed_radius_is_darker():
    """cbox-fog: with a fixed radius the image is darker than with a vanishing one (the same
    random numbers: paired per iteration), the more so the larger the radius (the shrinking
    radius's agreement with pt and Mitsuba: below)."""
    scene = load_small("cbox-fog", RES, RES)

    def per_iteration_means(radius: float) -> np.ndarray:
        fixed = ours(VirtualSphericalLights, scene, 8, seed=1, light_paths=64,
                     sphere_radius_relative=radius, sphere_alpha=1.0)  # fmt: skip
        return fixed.samples.mean(axis=(1, 2, 3))

    means = {radius: per_iteration_means(radius) for radius in (1e-9, 0.15, 0.5)}

    def loss(wider: float, narrower: float) -> tuple[float, float]:
        d = (means[narrower] - means[wider]) / means[1e-9].mean()
        return d.mean(), d.std(ddof=1) / math.sqrt(len(d))

    losses = {pair: loss(*pair) for pair in ((0.15, 1e-9), (0.5, 0.15))}
    print("relative loss (and its standard error), wider radius against narrower:", losses)
    assert all(mean > 5 * se for mean, se in losses.values())


# (scene, vsl iterations, pt samples per pixel of each of its 16 images): the shipped media
# scenes, each with what it adds
MEDIA_SCENES = {
    "cbox-fog": (64, 128),  # homogeneous fog lit by an area light inside it
    "crepuscular": (256, 512),  # a directional light through null windows, the camera in fog
    "smoke": (192, 256),  # point lights inside a density grid (ratio-tracked camera segments)
}
# r_1 for the agreement checks: 0.03 of the scene's radius, shrinking on the default schedule.
# From the default 0.1 the spread's bias is still visible after 48 iterations (cbox-fog 2-5 %
# darker than pt over three seeds, where the image mean's standard error is about 1 %).
CHECK_RADIUS = 0.03
# Scenes whose blocks are too heavy-tailed at this budget for the chi-square over a block's
# correlated channels: smoke's point lights sit inside the grid, and a block's images swing by
# 5-15 % (one seed in five failed the chi-square with every |z| below 3, and vpl unclamped
# with the same light paths failed it alike). Its blocks and mean are held to the |z| bound.
HEAVY_TAILED = {"smoke"}


def _shrinking(scene, iterations: int, seed: int):
    return ours(VirtualSphericalLights, scene, iterations, seed=seed, light_paths=64,
                spp_per_iteration=2, sphere_radius_relative=CHECK_RADIUS)  # fmt: skip


@pytest.mark.parametrize("name", MEDIA_SCENES)
def test_shrinking_radius_agrees_with_pt(name):
    """With the radius shrinking on its schedule, vsl's image agrees with pt's at a modest
    budget: the image mean and 8x8 blocks of 16x16 pixels (chi-square and largest |z|), with
    tolerances from the measured variance of both. Measured false alarms: none in 5 seeds on
    cbox-fog and crepuscular."""
    iterations, spp = MEDIA_SCENES[name]
    scene = load_small(name, 16, 16)
    pt = ours(PathTracing, scene, 16, seed=2, spp_per_wave=spp)
    vsl = _shrinking(scene, iterations, seed=1)
    if name in HEAVY_TAILED:
        blocks = agreement(vsl.blocks(8), pt.blocks(8), alpha=1e-3)
        mean = agreement(vsl.image_mean(), pt.image_mean(), alpha=1e-3)
        assert blocks.z_ok and mean.z_ok, f"{name}: blocks {blocks}; mean {mean}"
    else:
        ok, why = same_image(vsl, pt, alpha=1e-3, block=8)
        assert ok, f"{name}: {why}"


def test_shrinking_radius_agrees_with_mitsuba():
    """cbox-fog against Mitsuba's volpath, as against pt above."""
    scene = load_small("cbox-fog", 16, 16)
    ok, why = same_image(
        _shrinking(scene, 64, seed=3), mitsuba(scene, 16, 256), alpha=1e-3, block=8
    )
    assert ok, why


def test_radius_shrinks_on_schedule_and_the_sidecar_says_so():
    scene = load_small("cbox", 4, 4)
    method = VirtualSphericalLights(
        scene, seed=0, threads=1, params={"sphere_radius_relative": 0.2, "light_paths": 2}
    )
    r1 = 0.2 * method.native.core.scene_radius
    for i in (0, 1, 10):
        assert method.gather.kernel.radius(i) == pytest.approx(
            r1 * (i + 1) ** (2 / 3 - 1), rel=1e-12
        )
    for i in range(3):
        method.run_iteration(i)
    s = method.stats()
    assert s["sphere_radius_world"] == pytest.approx(r1 * 3 ** (-1 / 3))
    assert s["consistent"] and s["expected_mse_slope"] == pytest.approx(-2 / 3)


def test_same_image_for_one_and_two_threads():
    scene = load_small("cbox-fog", 8, 8)
    images = []
    for threads in (1, 2):
        method = VirtualSphericalLights(scene, seed=5, threads=threads, params={"light_paths": 16})
        for i in range(2):
            method.run_iteration(i)
        images.append(method.image())
    assert np.array_equal(*images) and images[0].max() > 0


@pytest.mark.parametrize(
    "params, message",
    [
        ({"sphere_alpha": 0}, "sphere_alpha must be a number > 0 and <= 1"),
        (
            {"sphere_radius_relative": 3},
            "sphere_radius_relative must be a number >= 1e-09 and <= 2",
        ),
        ({"clamp": "fixed"}, "unknown parameter"),
    ],
)
def test_bad_parameters_are_one_line_errors(params, message):
    with pytest.raises(PgiError, match=f"^method vsl: {message}"):
        VirtualSphericalLights(load_small("cbox", 4, 4), seed=0, threads=1, params=params)


def test_estimates_are_finite_at_the_centre():
    """A gather point a hair from the light's centre: bounded by 4 F / r^2, never infinite."""
    scene = probe_scene(0.6)
    near = _moved(Y_MEDIUM, tuple(np.add(X_MEDIUM[0], (1e-12, 0, 0))))
    values = vsl(scene, X_MEDIUM, near, 0.1, n=100)
    hg_peak = (1 - 0.6**2) / (4 * math.pi * (1 - 0.6) ** 3)
    assert np.all(np.isfinite(values)) and values.max() <= 4 * hg_peak**2 / 0.01
