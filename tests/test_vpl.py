"""vpl (cpp/vpl.h, cpp/virtual_lights.h, methods/vpl.py): virtual point lights in media.

- Equi-angular sampling (cpp/equiangular.h) follows the density it reports (chi-square, with
  expected counts from integrating that density over each bin), and so does the truncated
  exponential it is mixed with; the test rejects a wrong density.
- Unclamped, vpl is unbiased for every path (its coverage, cpp/virtual_lights.h GatherWalk): it
  agrees with pt and with Mitsuba on cbox and cbox-fog (image mean and 4x4 blocks, tolerances
  from the measured variance), at several max depths, and with pt on scenes that exercise a
  directional light with the camera in fog, point lights in a density grid, and glass (camera
  paths that go on past their gather points).
- Clamping only ever removes light: with the same random numbers a clamped image is nowhere
  brighter than the unclamped one, a larger clamp nowhere brighter than a smaller, and the
  loss is far beyond the noise for a wide clamp; the progressive bound relaxes on schedule.
- The image does not depend on the thread count or on the chunking of shadow rays.
"""

from __future__ import annotations

import numpy as np
import pytest

import stats
from conftest import SCENES, load_small
from parity import assert_block_check_has_power, mitsuba, ours, same_image
from renderer import _core
from renderer.errors import PgiError
from renderer.methods import get_method
from renderer.methods.pt import PathTracing
from renderer.methods.vpl import VirtualPointLights

# --------------------------------------------------------------------------- sampling

EQUIANGULAR_CASES = {  # origin, direction, t0, t1, centre
    "centre-beside-the-segment": ((0, 0, 0), (1, 0, 0), 0.0, 5.0, (2, 1, 0)),
    "close-to-the-line": ((0, 0, 0), (0, 0, 1), 0.0, 3.0, (0.02, -0.01, 1.3)),
    "behind-the-start": ((0, 0, 0), (1, 0, 0), 0.0, 3.0, (-1, 0.5, 0.2)),
    "infinite-segment": ((1, 2, 3), (0.3, -0.2, 0.9), 0.5, np.inf, (1.5, 1.5, 4)),
}
EXPONENTIAL_CASES = [(1.0, 2.0), (5.0, np.inf), (0.3, 0.5)]  # sigma, t1
N_TESTS = len(EQUIANGULAR_CASES) + len(EXPONENTIAL_CASES)
LEVEL = stats.sidak(stats.ALPHA, N_TESTS)
SAMPLES = 200_000


def _bin_masses(pdf, edges: np.ndarray) -> np.ndarray:
    """The density integrated over each bin by 8-point Gauss-Legendre on 16 pieces of it."""
    x, w = np.polynomial.legendre.leggauss(8)
    masses = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        cuts = np.linspace(a, b, 17)
        lo, hi = cuts[:-1, None], cuts[1:, None]
        points = (0.5 * (lo + hi) + 0.5 * (hi - lo) * x).ravel()
        masses.append(
            float((pdf(points).reshape(16, 8) * w).sum(axis=1) @ (0.5 * (hi - lo)).ravel())
        )
    return np.array(masses)


def _edges(samples: np.ndarray, bins: int = 60) -> np.ndarray:
    """Bins of about equal counts (quantiles of the samples, from a separate draw)."""
    return np.unique(np.quantile(samples, np.linspace(0, 1, bins + 1)))


@pytest.mark.parametrize("case", EQUIANGULAR_CASES)
def test_equiangular_sampling_chi2(case):
    o, d, t0, t1, c = EQUIANGULAR_CASES[case]
    rng = np.random.default_rng(11 + list(EQUIANGULAR_CASES).index(case))
    t, pdf = _core.equiangular_samples(o, d, t0, t1, c, rng.random(SAMPLES))
    assert np.all((t >= t0) & (t <= t1))

    def density(x):
        return _core.equiangular_pdfs(o, d, t0, t1, c, np.ascontiguousarray(x))[0]

    np.testing.assert_allclose(pdf, density(t), rtol=1e-12)
    pilot, _ = _core.equiangular_samples(o, d, t0, t1, c, rng.random(20_000))
    edges = _edges(pilot)
    edges[0], edges[-1] = t0, (t1 if np.isfinite(t1) else edges[-1])
    masses = _bin_masses(density, edges)
    inside = (t >= edges[0]) & (t < edges[-1])
    observed = np.append(np.histogram(t[inside], edges)[0], np.count_nonzero(~inside))
    expected = np.append(masses, max(0.0, 1 - masses.sum())) * SAMPLES
    result = stats.chi2_test(observed, expected)
    assert result.passed(LEVEL), result
    # The density integrates to one (an infinite segment: its tail in closed form).
    assert masses.sum() == pytest.approx(1.0, abs=2e-3 if np.isinf(t1) else 1e-9)
    # ...and the test has power: uniform points on the segment are rejected.
    if np.isfinite(t1):
        uniform = t0 + (t1 - t0) * rng.random(SAMPLES)
        observed = np.append(np.histogram(uniform, edges)[0], 0)
        assert not stats.chi2_test(observed, expected).passed(LEVEL)


def test_equiangular_weight_cancels_the_inverse_square():
    """1 / (p(t) |x(t) - c|^2) is the same for every t: (theta_1 - theta_0) / h."""
    o, d, t0, t1, c = EQUIANGULAR_CASES["centre-beside-the-segment"]
    t = np.linspace(t0, t1, 9)
    pdf, weight = _core.equiangular_pdfs(o, d, t0, t1, c, t)
    x = np.asarray(o) + np.outer(t, d)
    np.testing.assert_allclose(1 / (pdf * ((x - c) ** 2).sum(axis=1)), weight, rtol=1e-12)
    assert weight == pytest.approx((np.arctan(3.0) + np.arctan(2.0)) / 1.0, rel=1e-12)


@pytest.mark.parametrize("sigma, t1", EXPONENTIAL_CASES)
def test_truncated_exponential_sampling_chi2(sigma, t1):
    rng = np.random.default_rng(int(sigma * 100))
    t, pdf = _core.truncated_exponential_samples(sigma, t1, rng.random(SAMPLES))
    mass = 1 - np.exp(-sigma * t1)
    np.testing.assert_allclose(pdf, sigma * np.exp(-sigma * t) / mass, rtol=1e-12)
    edges = np.linspace(0, min(t1, 8 / sigma), 41)
    result = stats.chi2_1d(t, edges, lambda x: (1 - np.exp(-sigma * x)) / mass)
    assert result.passed(LEVEL), result


# --------------------------------------------------------------------------- images

RES = 12


def _vpl(scene, iterations: int, seed: int = 1, **params):
    return ours(VirtualPointLights, scene, iterations, seed=seed, **params)


@pytest.mark.parametrize("name", ["cbox", "cbox-fog"])
def test_unclamped_vpl_agrees_with_pt_and_mitsuba(name):
    """Image mean and 4x4 blocks against pt and against Mitsuba's volpath; a 3 % darker block
    is caught."""
    scene = load_small(name, RES, RES)
    vpl = _vpl(scene, 32, clamp="none", light_paths=128, spp_per_iteration=2)
    pt = ours(PathTracing, scene, 16, seed=2, spp_per_wave=64)
    ok, why = same_image(vpl, pt, alpha=1e-3, block=4)
    assert ok, f"{name} against pt: {why}"
    ref = mitsuba(scene, 16, 256)
    ok, why = same_image(vpl, ref, alpha=1e-3, block=4)
    assert ok, f"{name} against Mitsuba: {why}"
    assert_block_check_has_power(vpl, ref, f"vpl {name}", size=4)


@pytest.mark.parametrize("max_depth", [2, 3])
def test_depths_follow_mitsuba(max_depth):
    """max_depth 2 (direct light and single scattering) and 3 on cbox-fog: a light of depth k
    joined to a gather point after s camera-side events is a path of k + s events."""
    scene = load_small("cbox-fog", RES, RES, (f"integrator.max_depth={max_depth}",))
    vpl = _vpl(scene, 48, clamp="none", light_paths=64, spp_per_iteration=2)
    ok, why = same_image(vpl, mitsuba(scene, 16, 256), alpha=1e-3, block=4)
    assert ok, f"max_depth {max_depth}: {why}"


# (scene, parameters): what these scenes add to cbox and cbox-fog
VARIANTS = {
    # a directional light through null windows, the camera inside the fog
    "crepuscular": ("crepuscular", {}),
    # point lights inside a density grid: exact lights, ratio-tracked camera segments
    "smoke": ("smoke", {}),
    # glass: camera paths go on past their gather points (caustics, light through glass)
    "cbox-glass": ("cbox-glass", {}),
    # camera segments' points drawn half the time by the free-flight density (one-sample MIS)
    "free-flight-mis": ("cbox-fog", {"free_flight_fraction": 0.5}),
}


@pytest.mark.parametrize("variant", VARIANTS)
def test_unclamped_vpl_agrees_with_pt_on_more_scenes(variant):
    name, params = VARIANTS[variant]
    scene = load_small(name, RES, RES)
    vpl = _vpl(scene, 24, clamp="none", light_paths=64, spp_per_iteration=2, **params)
    pt = ours(PathTracing, scene, 16, seed=2, spp_per_wave=64)
    ok, why = same_image(vpl, pt, alpha=1e-3, block=4)
    assert ok, f"{variant}: {why}"


def test_clamping_darkens_never_brightens_and_more_for_a_wider_clamp():
    """Same seed, same random numbers: clamp none >= 0.02 >= 0.1 >= 0.4 (relative) pixel by
    pixel, exactly; the image mean falls at each step, and the widest clamp's loss against pt
    lies far beyond the noise."""
    scene = load_small("cbox-fog", RES, RES)
    images = []
    for clamp in (None, 0.02, 0.1, 0.4):
        params = (
            {"clamp": "none"}
            if clamp is None
            else {"clamp": "fixed", "clamp_distance_relative": clamp}
        )
        method = VirtualPointLights(scene, seed=4, threads=2, params={"light_paths": 64, **params})
        for i in range(6):
            method.run_iteration(i)
        images.append(method.image())
    for brighter, darker in zip(images, images[1:], strict=False):
        assert np.all(darker <= brighter)
        assert darker.mean() < brighter.mean()
    pt = ours(PathTracing, scene, 8, seed=2, spp_per_wave=64).image_mean()
    pt_mean, pt_se = pt.mean.mean(), pt.stderr.mean()
    loss = [(pt_mean - image.mean()) / pt_mean for image in images]
    print("relative loss against pt:", np.round(loss, 4), "pt's relative stderr", pt_se / pt_mean)
    assert loss[-1] > 10 * pt_se / pt_mean


def test_progressive_clamp_relaxes_on_schedule():
    """d_i = d_1 i^(alpha - 1) in world units (d_1 relative to the scene's radius), fixed: d_1,
    none: 0; the sidecar says which are consistent."""
    scene = load_small("cbox", 4, 4)
    for clamp in ("none", "fixed", "progressive"):
        params = {"clamp": clamp, "light_paths": 4}
        if clamp != "none":
            params["clamp_distance_relative"] = 0.05
        if clamp == "progressive":
            params["clamp_alpha"] = 0.5
        method = VirtualPointLights(scene, seed=0, threads=1, params=params)
        d1 = 0.05 * method.native.core.scene_radius
        for i in (0, 1, 7, 99):
            expected = {"none": 0.0, "fixed": d1, "progressive": d1 * (i + 1) ** -0.5}[clamp]
            assert method.gather.kernel.clamp_distance(i) == pytest.approx(expected, rel=1e-12)
        assert method.method_stats()["consistent"] == (clamp != "fixed")


# the methods of the gathering kernel (cpp/vpl.h; vrl and vbl: tests/test_vrl.py)
GATHERING = ["vpl", "vsl", "vrl", "vbl"]


@pytest.mark.parametrize("method_id", ["vpl", "vrl", "vbl"])
@pytest.mark.parametrize("name", ["cbox-fog", "cbox-glass", "smoke"])
def test_same_image_for_any_thread_count_and_chunking(name, method_id):
    scene = load_small(name, 8, 8)
    images = []
    for threads, chunk in ((1, 1 << 15), (2, 1 << 15), (2, 777)):
        method = get_method(method_id)(scene, seed=5, threads=threads, params={"light_paths": 16})
        method.gather.kernel.set_chunk_pairs(chunk)
        for i in range(2):
            method.run_iteration(i)
        images.append(method.image())
    assert np.array_equal(images[0], images[1]) and np.array_equal(images[0], images[2])
    assert images[0].max() > 0


SHIPPED = sorted(p.parent.name for p in SCENES.glob("*/scene.yaml"))


@pytest.mark.parametrize("method", GATHERING)
def test_every_shipped_scene_renders(method):
    assert len(SHIPPED) >= 11
    for name in SHIPPED:
        params = {"light_paths": 8, "spp_per_iteration": 8}
        m = get_method(method)(load_small(name, 6, 6), seed=1, threads=2, params=params)
        m.run_iteration(0)
        image = m.image()
        assert np.all(np.isfinite(image)) and image.min() >= 0 and image.max() > 0, name
        s = m.stats()
        assert s["nonfinite"] == 0 and s["virtual_lights"] > 0, (name, s)
        assert s["continuations"] == (name in ("cbox-glass", "juice", "volcaustic")), name


@pytest.mark.parametrize(
    "params, message",
    [
        ({"clamp": "soft"}, "clamp must be none or fixed or progressive, got .soft."),
        (
            {"clamp": "none", "clamp_distance_relative": 0.1},
            "clamp_distance_relative has no effect",
        ),
        ({"clamp": "fixed", "clamp_alpha": 0.5}, "clamp_alpha has no effect with clamp=fixed"),
        ({"clamp_alpha": 1.0}, "clamp_alpha must be a number > 0 and < 1"),
        (
            {"clamp_distance_relative": 3},
            "clamp_distance_relative must be a number >= 1e-09 and <= 2",
        ),
        ({"free_flight_fraction": 1.0}, "free_flight_fraction must be a number >= 0 and < 1"),
        ({"light_paths": 0}, "light_paths must be an integer >= 1"),
        (
            {"clamp_distance_world": 0.1, "clamp_distance_relative": 0.1},
            "give clamp_distance_world",
        ),
    ],
)
def test_bad_parameters_are_one_line_errors(params, message):
    with pytest.raises(PgiError, match=f"^method vpl: {message}"):
        VirtualPointLights(load_small("cbox", 4, 4), seed=0, threads=1, params=params)


def test_a_light_on_the_camera_ray_has_no_equiangular_density():
    """A centre on the ray's line (h = 0) has no equi-angular density: refused by the probe, and
    skipped by the kernel (a set of measure zero) instead of turned into infinities."""
    with pytest.raises(ValueError, match="on the ray's line"):
        _core.equiangular_samples((0, 0, 0), (1, 0, 0), 0.0, 1.0, (0.5, 0, 0), np.array([0.5]))
