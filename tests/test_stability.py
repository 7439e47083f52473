"""Numerical stability on hard cases; each test asserts something that can fail.

- Optical thickness 1e-4 .. 1e3 along a ray through a lumpy grid and a grid with a single dense
  voxel, for delta, ratio and residual ratio tracking: estimates finite and in [0, 1]; unbiased
  against the exact optical depth wherever exp(-tau) is measurable, with samples sized so the
  tests have power (a 25 % error in the rarer outcome, except at tau = 10); Markov's inequality
  beyond; optical depth 1 where the ray enters and leaves the dense grids (tau >= 10); delta-
  tracked free flights: collision counts (binomial) and distances (Kolmogorov-Smirnov) at every
  thickness. Ray marching: in range, its optical depth unbiased; its free flights exactly
  exponential in a constant grid, and passing x as often as its transmittance to x says
  elsewhere. An all-zero grid is vacuum.
- Henyey-Greenstein g = +-0.99: sampling pdf equals eval (no weight != 1 from a mismatch, hence
  no firefly from one; the chi-square tests are in test_sampling.py), and renders agree with
  Mitsuba pixel block by block. |g| within 1e-10 and 2^-52 of 1: values and samples finite,
  and a render counts no non-finite sample.
- Scale invariance: a scene scaled by 1e-3 and 1e3 (extinction scaled inversely, point light
  intensities by s^2) renders the same image within noise (3x3 blocks and the image mean; a
  10 % error fails).
- Rays on boundaries: starting exactly on a grid face, grazing along a face, along an edge;
  a camera exactly on a fog's null boundary (face, grazing, corner) sees what a camera just
  outside it sees.
- Degenerate (zero-area) triangles are dropped, counted, and change nothing.
- White furnaces with a heterogeneous medium conserve energy, in every pixel, with each
  unbiased estimator.
- Every method renders every shipped scene briefly with no NaN/Inf and zero rejected samples.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import yaml
from scipy import stats as sps

import parity
import stats
from conftest import SCENES, load_small
from parity import Estimate, mitsuba, ours
from renderer import _core
from renderer.engine import build_native_scene
from renderer.errors import PgiError
from renderer.methods import get_method
from renderer.methods.pt import PathTracing
from renderer.scene import load_scene
from renderer.scene.model import Phase, PointLight, Shape
from test_furnace import FILM, GRID, L, furnace_yaml, grid_density
from test_media import GridRef, affine, smooth_density

ESTIMATORS = dict(_core.Estimator.__members__)  # delta, ratio, residual, raymarch
TRACKERS = ["delta", "ratio", "residual"]  # the unbiased transmittance estimators
THICKNESS = [1e-4, 1e-2, 1.0, 10.0, 1e2, 1e3]
GRIDS = ["lumpy", "single-voxel"]
# Across the whole ray: where exp(-tau) is measurable it is tested for bias; beyond (e^-100
# and less) the sum of the estimates is bounded by Markov's inequality.
OPAQUE = [tau for tau in THICKNESS if tau > 10]
# Optical depth 1 at the entry and at the exit of the ray through the denser grids: the
# numerics of huge extinction (tiny steps, long runs of null collisions) where T is measurable.
DENSE = [tau for tau in THICKNESS if tau >= 10]
SEGMENTS = ["entry", "exit"]
FURNACE_ESTIMATORS = ["delta", "residual"]
MARCHED = [tau for tau in THICKNESS if tau <= 10]  # thicker: exp(-tau_hat) underflows to 0
# Rays on the faces of a grid's unit cube scaled by 2: (origin, direction).
BOUNDARY_RAYS = [
    ((0.0, 0.7, 0.9), (1.0, 0.2, -0.3)),  # starts on the x = 0 face, going in
    ((0.3, 0.0, 0.5), (0.6, 0.0, 0.8)),  # grazes along the y = 0 face
    ((0.0, 2.0, 0.4), (0.0, 0.0, 1.0)),  # runs along the x = 0, y = 2 edge
    ((2.0, 1.0, 1.0), (1.0, 0.0, 0.0)),  # starts on the x = 2 face, going out
]
# Cameras on fog-step's fog boundary: (origin, target, direction pointing outside).
CAMERAS_ON_BOUNDARY = [
    ((0.99, 0.0, 0.9), (0.99, 0.0, -1.0), (1, 0, 0)),  # in the x = 0.99 face, looking along it
    ((0.0, 0.2, 0.99), (0.0, 0.0, -1.0), (0, 0, 1)),  # on the z = 0.99 face, looking in
    ((0.99, 0.99, 0.99), (-1.0, -1.0, -1.0), (1, 1, 1)),  # on the boundary's corner
]
SCALED_SCENES, SCALES = ["fog-step", "smoke"], [1e-3, 1e3]
MARCH_QUANTILES = [0.25, 0.5, 0.75]  # of the collision distance, for marched free flights
N_TESTS = (
    len(THICKNESS) * len(GRIDS) * len(TRACKERS)  # transmittance across the ray
    + len(DENSE) * len(SEGMENTS) * len(GRIDS) * len(TRACKERS)  # dense segments
    + len(THICKNESS) * len(GRIDS) * 2  # free flights: collision count and distances
    + len(MARCHED)
    + 2
    + len(MARCH_QUANTILES)  # marched free flights: constant grid, against marched T
    + len(BOUNDARY_RAYS) * len(TRACKERS)
    + 2 * 4  # HG g = +-0.99 against Mitsuba: blocks and image mean, chi-square and |z|
    + len(SCALED_SCENES) * len(SCALES) * 4  # blocks and image mean, chi-square and |z|
    + 3 * 4  # translated dense cube, pt, lt and pm: blocks and image mean
    + len(CAMERAS_ON_BOUNDARY) * 4  # blocks and image mean, chi-square and |z|
    + 2 * 3  # Rayleigh and Mie furnaces
)
LEVEL = stats.sidak(stats.ALPHA, N_TESTS)
# The grid furnace with each estimator is a family of its own, as in test_furnace.py: a t-test
# per 2x2-pixel block and channel, and one on the image mean per channel. Counted in the
# module's family, its 486 per-pixel tests had lowered every other test's level fourfold.
FURNACE_BLOCK = 2
FURNACE_BLOCK_LEVEL = stats.sidak(
    stats.ALPHA,
    len(FURNACE_ESTIMATORS) * 3 * (FILM[0] // FURNACE_BLOCK) * (FILM[1] // FURNACE_BLOCK),
)
FURNACE_MEAN_LEVEL = stats.sidak(stats.ALPHA, len(FURNACE_ESTIMATORS) * 3)
RAY = ((-0.2, -0.1, -0.3), (1.0, 0.9, 1.1))  # unit-cube frame
# The smallest relative error in a probability p that a two-sided test at LEVEL detects with
# power 0.9 from n samples is about (z_{1 - LEVEL/2} + z_{0.9}) / sqrt(n p).
DETECT, POWER = 0.25, 0.9
Z_DETECT = float(sps.norm.isf(LEVEL / 2) + sps.norm.isf(1 - POWER))


def sample_cap(tau: float) -> int:
    """Samples per test are capped by their cost: 6e6 in the thin grids, 1e6 from tau = 1 on
    (a flight through the single dense voxel at tau = 10 costs ~2 us)."""
    return 6_000_000 if tau < 1 else 1_000_000


def samples_to_detect(p_rare: float, cap: int) -> int:
    """Samples for a test at LEVEL to see a DETECT relative error in the probability p_rare of
    the rarer outcome (or, for a continuous estimator, in a mean carried by a fraction p_rare
    of the samples) with power POWER; at least 20 000, at most cap (then the power is less)."""
    return int(min(cap, max(20_000, math.ceil((Z_DETECT / DETECT) ** 2 / p_rare))))


def make_grid(kind: str, tau: float) -> tuple[GridRef, np.ndarray, np.ndarray]:
    """A grid whose optical depth along RAY is tau, with the world ray."""
    if kind == "lumpy":
        density = smooth_density((8, 8, 8), seed=7)
    else:
        density = np.zeros((9, 9, 9), np.float32)
        density[4, 4, 4] = 1.0  # the ray passes through its centre's neighbourhood
    to_world = affine((1.5, 2.0, 1.0), 25.0, (0, 1, 1), (0.3, -0.2, 0.1))
    o_l, d_l = (np.asarray(v, float) for v in RAY)
    if kind == "single-voxel":
        d_l = np.array([0.5, 0.5, 0.5]) - o_l  # straight through the dense voxel's centre
    o = to_world[:3, :3] @ o_l + to_world[:3, 3]
    d = to_world[:3, :3] @ d_l
    d /= np.linalg.norm(d)
    unit = GridRef(density, to_world, 1.0)
    sigma = tau / unit.optical_depth(o, d, np.inf)[0]
    return GridRef(density, to_world, sigma), o, d


def depth_point(grid: GridRef, o, d, depth: float) -> float:
    """The distance along the ray where its optical depth reaches `depth` (bisection)."""
    lo, hi = 0.0, float(grid.breakpoints(o, d, np.inf)[-1])
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if grid.optical_depth(o, d, np.inf, mid)[0] < depth else (lo, mid)
    return 0.5 * (lo + hi)


def transmittance(grid: GridRef, estimator: str, o, d, n: int, seed: int, step: float = 0.0,
                  tmax: float = np.inf):  # fmt: skip
    _core.configure_medium(grid.scene, grid.id, ESTIMATORS[estimator], step)
    return _core.transmittance_samples(grid.scene, grid.id, tuple(o), tuple(d), tmax, seed, n)


def check_transmittance(grid: GridRef, estimator: str, o, d, tmax: float, n: int, seed: int,
                        exact: float) -> None:  # fmt: skip
    """n estimates (drawn in chunks) are finite, in [0, 1], and unbiased for `exact`: delta
    tracking's 0/1 estimates by the exact binomial test, the others by a z-test on the mean."""
    total = squares = 0.0
    for first in range(0, n, 2_000_000):
        t, _ = transmittance(grid, estimator, o, d, min(n - first, 2_000_000), seed + first,
                             tmax=tmax)  # fmt: skip
        assert np.all(np.isfinite(t)) and np.all((t >= 0) & (t <= 1)), estimator
        if estimator == "delta":
            assert np.all((t == 0) | (t == 1))
        total, squares = total + t.sum(), squares + (t * t).sum()
    mean = total / n
    if estimator == "delta":  # the count of ones is exactly binomial
        assert stats.binomial_p_value(round(total), n, exact) >= LEVEL, (mean, exact, n)
    else:
        se = math.sqrt(max(squares / n - mean * mean, 0.0) / (n - 1))
        assert stats.z_p_value(mean, exact, se) >= LEVEL, (mean, se, exact, n)


def check_whole_ray(grid: GridRef, estimator: str, o, d, tau: float, truth: float,
                    exact: float | None = None) -> None:  # fmt: skip
    """check_transmittance over the whole ray, with samples sized by the exact transmittance
    (`exact`, default `truth`) to catch a 25 % error in its rarer outcome."""
    exact = truth if exact is None else exact
    n = samples_to_detect(min(exact, 1 - exact), sample_cap(tau))
    check_transmittance(grid, estimator, o, d, np.inf, n, 1000 * THICKNESS.index(tau), truth)


# --------------------------------------------------------------------------- optical thickness


@pytest.mark.parametrize("kind", GRIDS)
@pytest.mark.parametrize("tau", THICKNESS)
@pytest.mark.parametrize("estimator", TRACKERS)
def test_transmittance_across_the_medium(estimator, tau, kind):
    """Whole rays of optical depth 1e-4 .. 1e3. Where exp(-tau) is measurable, enough samples
    that a 25 % error in the rarer outcome's probability (a collision in the thinnest grids,
    passing through the thickest measurable ones) is caught with power 0.9 (at tau = 10 the
    cost caps the samples at 1e6: errors of about a factor 2 are caught there). Beyond, the
    truth is exp(-100) or less and Markov's inequality bounds the sum of the estimates."""
    grid, o, d = make_grid(kind, tau)
    depth = grid.optical_depth(o, d, np.inf)[0]
    if tau in OPAQUE:
        n = 2000
        t, _ = transmittance(grid, estimator, o, d, n, seed=17)
        assert np.all(np.isfinite(t)) and np.all((t >= 0) & (t <= 1))
        # P(sum >= n E[T] / LEVEL) <= LEVEL for any non-negative estimator of mean E[T]; in
        # logs, since E[T] = exp(-1000) underflows.
        log_bound = math.log(n / LEVEL) - depth
        assert t.sum() == 0 or math.log(t.sum()) <= log_bound, (t.sum(), log_bound)
        return
    check_whole_ray(grid, estimator, o, d, tau, math.exp(-depth))


@pytest.mark.parametrize("tau", [1e-2, 1.0])
@pytest.mark.parametrize("estimator", TRACKERS)
def test_transmittance_tests_catch_a_25_percent_error(estimator, tau):
    """The power the sample sizes above are chosen for: told a truth 25 % off in its rarer
    outcome (a collision at tau = 0.01, passing through at tau = 1), the same test fails."""
    grid, o, d = make_grid("lumpy", tau)
    depth = grid.optical_depth(o, d, np.inf)[0]
    wrong = math.exp(-1.25 * depth) if depth < math.log(2) else 1.25 * math.exp(-depth)
    with pytest.raises(AssertionError):
        check_whole_ray(grid, estimator, o, d, tau, wrong, exact=math.exp(-depth))


@pytest.mark.parametrize("kind", GRIDS)
@pytest.mark.parametrize("segment", SEGMENTS)
@pytest.mark.parametrize("tau", DENSE)
@pytest.mark.parametrize("estimator", TRACKERS)
def test_transmittance_through_dense_segments(estimator, tau, segment, kind):
    """Optical depth 1 where the ray enters and where it leaves a grid of optical depth
    10 .. 1000 along it: extinction up to 1e3 times the thin grids', T = exp(-1) measurable."""
    grid, o, d = make_grid(kind, tau)
    start = 0.0 if segment == "entry" else depth_point(grid, o, d, tau - 1.0)
    end = depth_point(grid, o, d, 1.0) if segment == "entry" else grid.breakpoints(o, d, np.inf)[-1]
    depth = grid.optical_depth(o, d, np.inf, [start, end])
    o = o + start * d
    check_transmittance(grid, estimator, o, d, end - start, 5000, 31, math.exp(depth[0] - depth[1]))


@pytest.mark.parametrize("kind", GRIDS)
@pytest.mark.parametrize("tau", THICKNESS)
def test_free_flights_across_the_medium(tau, kind):
    """Delta-tracked free flights through the same grids: the number that collide is binomial
    with the exact collision probability (samples sized as for transmittance, fewer where a
    flight costs thousands of lookups), and the collision distances follow the exact CDF
    (Kolmogorov-Smirnov on up to 50 000 of them)."""
    grid, o, d = make_grid(kind, tau)
    p_hit = -math.expm1(-grid.optical_depth(o, d, np.inf)[0])
    if tau in OPAQUE:  # every flight collides (one costs up to thousands of lookups here)
        n = 5000
    else:
        n = samples_to_detect(min(p_hit, 1 - p_hit), sample_cap(tau))
    tf, w = grid.scene.free_flight(grid.id, tuple(o), tuple(d), np.inf, 3, n)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    hit = np.isfinite(tf)
    assert stats.binomial_p_value(int(hit.sum()), n, p_hit) >= LEVEL, (hit.mean(), p_hit)

    def cdf(x: np.ndarray) -> np.ndarray:  # given a collision
        return -np.expm1(-grid.optical_depth(o, d, np.inf, x)) / p_hit

    assert np.all(tf[hit] >= 0)
    assert stats.ks_test(tf[hit][:50_000], cdf) >= LEVEL, (tau, kind, hit.sum())


@pytest.mark.parametrize("tau", THICKNESS)
def test_ray_marching_stays_in_range_and_unbiased_in_optical_depth(tau):
    """Biased in transmittance, but in [0, 1]; its optical depth tau_hat = -log T per sample
    (one random offset per ray) is unbiased at any thickness where T does not underflow:
    t-test against the exact optical depth."""
    grid, o, d = make_grid("lumpy", tau)
    exact_tau = grid.optical_depth(o, d, np.inf)[0]
    voxel = np.linalg.norm(grid.to_world[:3, :3], axis=0).min() / 8
    t, _ = transmittance(grid, "raymarch", o, d, 500, seed=5, step=voxel / 10)
    assert np.all(np.isfinite(t)) and np.all((t >= 0) & (t <= 1))
    if tau in MARCHED:
        tau_hat = -np.log(t)
        mean, se = stats.mean_and_se(tau_hat)
        assert stats.t_p_value(mean, exact_tau, se, len(t) - 1) >= LEVEL, (mean, se, exact_tau)


def marched_free_flights(grid: GridRef, o, d, step: float, n: int, seed: int) -> np.ndarray:
    _core.configure_medium(grid.scene, grid.id, ESTIMATORS["raymarch"], step)
    t, w = grid.scene.free_flight(grid.id, tuple(o), tuple(d), np.inf, seed, n)
    hit = np.isfinite(t)
    assert np.all(t[hit] >= 0) and np.all(np.isfinite(w)) and np.all(w >= 0)
    return t


def test_marched_free_flights_exact_in_a_constant_grid():
    """In a constant grid every step's extinction is exact, so marched free flights are
    exactly exponential: collision count (binomial) and distances (Kolmogorov-Smirnov)."""
    grid = GridRef(np.ones((6, 6, 6), np.float32), affine((2.0, 1.5, 1.0), 20.0, (1, 0, 1)), 0.8)
    o, d = np.array([-0.5, 0.2, 0.1]), np.array([1.0, 0.35, 0.2]) / np.linalg.norm([1, 0.35, 0.2])
    n = 100_000
    t = marched_free_flights(grid, o, d, 0.13, n, seed=4)
    hit = np.isfinite(t)
    p_hit = -math.expm1(-grid.optical_depth(o, d, np.inf)[0])
    assert 0.2 < p_hit < 0.9
    assert stats.binomial_p_value(int(hit.sum()), n, p_hit) >= LEVEL, (hit.mean(), p_hit)

    def cdf(x: np.ndarray) -> np.ndarray:
        return -np.expm1(-grid.optical_depth(o, d, np.inf, x)) / p_hit

    assert stats.ks_test(t[hit], cdf) >= LEVEL


@pytest.mark.parametrize("quantile", MARCH_QUANTILES)
def test_marched_free_flights_agree_with_marched_transmittance(quantile):
    """Ray marching's flights and its transmittance share one scheme (one step offset per ray),
    biased alike: P(a flight passes x) = E[marched T(0, x)] at any step, here a coarse one
    (half a voxel) in the lumpy grid at optical depth 2, at the exact collision CDF's quantiles."""
    grid, o, d = make_grid("lumpy", 2.0)
    voxel = np.linalg.norm(grid.to_world[:3, :3], axis=0).min() / 8
    p_hit = -math.expm1(-2.0)
    x = depth_point(grid, o, d, -math.log1p(-quantile * p_hit))
    n = 200_000
    passed = np.mean(marched_free_flights(grid, o, d, voxel / 2, n, seed=6) > x)
    t, _ = transmittance(grid, "raymarch", o, d, n, seed=7, step=voxel / 2, tmax=x)
    se = math.sqrt(passed * (1 - passed) / n + t.var(ddof=1) / n)
    assert stats.z_p_value(passed, float(t.mean()), se) >= LEVEL, (quantile, passed, t.mean())


def test_all_zero_grid_is_vacuum():
    grid = GridRef(np.zeros((6, 5, 4), np.float32), affine((2, 2, 2)), 5.0)
    for estimator in ESTIMATORS:
        t, lookups = transmittance(grid, estimator, (-1, 0.5, 0.7), (1, 0.2, 0.1), 100, 1)
        assert np.all(t == 1) and lookups == 0, estimator
    tf, w = grid.scene.free_flight(grid.id, (-1, 0.5, 0.7), (1, 0.2, 0.1), np.inf, 1, 100)
    assert np.all(np.isinf(tf)) and np.all(w == 1)


# --------------------------------------------------------------------------- boundaries


@pytest.mark.parametrize("estimator", TRACKERS)
def test_rays_on_grid_boundaries(estimator):
    """Starting exactly on a face going in, grazing along a face (inside the closed cube, the
    clamped edge voxels apply) and along an edge: finite and matching the exact reference."""
    grid = GridRef(smooth_density((8, 8, 8), seed=3), affine((2.0, 2.0, 2.0)), 1.5)
    for o, d in BOUNDARY_RAYS:
        d = np.asarray(d) / np.linalg.norm(d)
        exact = math.exp(-grid.optical_depth(np.asarray(o, float), d, np.inf)[0])
        t, _ = transmittance(grid, estimator, o, d, 20_000, seed=9)
        assert np.all(np.isfinite(t)) and np.all((t >= 0) & (t <= 1))
        mean, se = stats.mean_and_se(t)
        assert stats.z_p_value(mean, exact, max(float(se), 1e-15)) >= LEVEL, (o, d, mean, exact)


# --------------------------------------------------------------------------- HG g = +-0.99


@pytest.mark.parametrize("g", [-0.99, 0.99])
def test_extreme_hg_pdf_equals_eval(g):
    """Sampling returns pdf == eval exactly, so the sample weight is exactly 1 (no firefly
    from a pdf mismatch), even in the narrow peak."""
    u = np.random.default_rng(1).random((200_000, 2))
    wo = (0.2, 0.3, -0.93)
    wi, pdf = _core.sample_phase(_core.PhaseType.hg, g, wo, u)
    np.testing.assert_allclose(_core.eval_phase(_core.PhaseType.hg, g, wo, wi), pdf, rtol=1e-9)
    assert np.all(np.isfinite(pdf)) and pdf.max() < 1.1 * (1 + abs(g)) / (
        4 * np.pi * (1 - abs(g)) ** 2
    )


# |g| where 1 + g^2 - 2 g mu cancels. Both round to 1 in float32, so the loader refuses them
# (Mitsuba could not load them); the core must still stay finite there.
NEAR_ONE = [1 - 1e-10, 1 - 2**-52]


@pytest.mark.parametrize("g", [s * g for g in NEAR_ONE for s in (1, -1)])
def test_hg_within_rounding_of_one_stays_finite(g):
    """In the peak of HG with |g| this close to 1, 1 + g^2 - 2 g cos(theta) rounds to 0 unless
    written as a sum of non-negative terms: the pdf was infinite and the MIS weights NaN."""
    wo = np.array([0.0, 0.0, -1.0])
    ahead = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])  # -wo and wo: one is the peak
    values = _core.eval_phase(_core.PhaseType.hg, g, tuple(wo), ahead)
    peak = (1 + abs(g)) / (4 * np.pi * (1 - abs(g)) ** 2)
    assert np.all(np.isfinite(values)) and values.max() == pytest.approx(peak, rel=1e-6)
    assert values.min() > 0
    wi, pdf = _core.sample_phase(
        _core.PhaseType.hg, g, tuple(wo), np.random.default_rng(2).random((20_000, 2))
    )
    assert np.all(np.isfinite(pdf)) and np.all(pdf > 0) and np.all(np.isfinite(wi))
    # Nearly every sample lies in the peak, on the side the sign of g says.
    assert np.mean(np.sign(g) * (wi @ -wo) > 1 - 1e-6) > 0.999


def test_hg_within_rounding_of_one_renders_finite():
    """pt through fog whose phase function is this peaked counts no non-finite sample (the
    phase function set past the loader, which refuses such g)."""
    with pytest.raises(PgiError, match="in float32"):
        load_small("fog-step", 8, 8, (f"media.fog.phase={{type: hg, g: {NEAR_ONE[0]!r}}}",))
    scene = load_small("fog-step", 8, 8)
    fog = scene.media["fog"]
    peaked = dataclasses.replace(fog, phase=Phase("hg", g=NEAR_ONE[0]))
    scene = dataclasses.replace(scene, media={**scene.media, "fog": peaked})
    method = PathTracing(scene, seed=3, threads=2, params={"spp_per_wave": 64})
    method.run_iteration(0)
    assert method.stats()["nonfinite"] == 0
    assert np.all(np.isfinite(method.image()))


@pytest.mark.parametrize("g", [-0.99, 0.99])
def test_extreme_hg_renders_match_mitsuba(g):
    """3x3-pixel blocks and the image mean agree with Mitsuba (chi-square and largest |z| at
    LEVEL), and the check has power: our images scaled by 0.95 fail it (by the image mean,
    measured, p ~ 1e-11; 0.97 failed too). A firefly from a pdf mismatch cannot occur: the
    renderer's phase sampling returns pdf == eval exactly (test above), so every sampled
    weight is exactly 1."""
    scene = load_small("fog-step", 12, 12, (f"media.fog.phase={{type: hg, g: {g}}}",))
    a = ours(PathTracing, scene, 64, spp_per_wave=192)
    b = mitsuba(scene, 32, 384)
    agrees, why = parity.same_image(a, b, LEVEL)
    assert agrees, why
    agrees, why = parity.same_image(Estimate(a.samples * 0.95), b, LEVEL)
    assert not agrees, f"a 5 % loss passed: {why}"


# --------------------------------------------------------------------------- scale invariance


def scaled(scene, s: float):
    """The scene with every length multiplied by s and extinction divided by s."""
    shapes = [dataclasses.replace(sh, vertices=sh.vertices * s) for sh in scene.shapes]
    media = {}
    for name, m in scene.media.items():
        to_world = None
        if m.to_world is not None:
            to_world = np.diag([s, s, s, 1.0]) @ m.to_world
        media[name] = dataclasses.replace(m, scale=m.scale / s, to_world=to_world)
    lights = [
        dataclasses.replace(
            li, position=li.position * s, intensity=tuple(np.multiply(li.intensity, s * s))
        )
        if isinstance(li, PointLight)
        else li
        for li in scene.lights
    ]
    camera = dataclasses.replace(
        scene.camera, origin=scene.camera.origin * s, target=scene.camera.target * s
    )
    return dataclasses.replace(scene, shapes=shapes, media=media, lights=lights, camera=camera)


@pytest.fixture(scope="module", params=SCALED_SCENES)
def scaled_renders(request) -> tuple[str, Estimate, dict[float, Estimate]]:
    name = request.param
    scene = load_small(name, 12, 12)
    base = ours(PathTracing, scene, 16, seed=1, spp_per_wave=128)
    others = {s: ours(PathTracing, scaled(scene, s), 16, seed=2, spp_per_wave=128) for s in SCALES}
    return name, base, others


def same_image(a: Estimate, b: Estimate) -> tuple[bool, str]:
    """3x3-pixel blocks and the image mean agree (chi-square and largest |z|, at LEVEL)."""
    return parity.same_image(a, b, LEVEL)


def test_scale_invariance(scaled_renders):
    name, base, others = scaled_renders
    for s, other in others.items():
        agree, why = same_image(base, other)
        assert agree, (name, s, why)


def test_scale_invariance_can_fail(scaled_renders):
    """The check has power: the scaled scenes' images times 0.9 fail it (measured at these
    sizes at scale 1e3: smoke fails from 3 % on, fog-step, noisier, from 10 %)."""
    name, base, others = scaled_renders
    for s, other in others.items():
        agree, why = same_image(base, Estimate(other.samples * 0.9))
        assert not agree, (name, s, why)


# --------------------------------------------------------------------------- translation invariance


# A cube of dense fog (mean free path 5e-4, a ten-thousandth of the box) in the Cornell box,
# seen face-on. Surface offsets grow with the distance from the origin: shifted by SHIFT they
# are 13x those at the origin (optical depth 0.1 -> 1.3 across one).
DENSE_BLOB = {
    "name": "dense-blob",
    "include": str(SCENES / "cbox" / "box.yaml"),
    "integrator": {"max_depth": 12, "rr_depth": 5},
    "media": {"dense": {"type": "homogeneous", "sigma_t": 2000, "albedo": 0.9}},
    "materials": {"boundary": {"type": "null"}},
    "shapes": [
        {"name": "blob", "type": "cube", "material": "boundary", "interior": "dense",
         "transform": [{"scale": 0.6}, {"rotate": {"axis": [0, 1, 0], "angle": 20}},
                       {"translate": [0, -0.2, 0.2]}]},
    ],
}  # fmt: skip
SHIFT = 20.0
TRANSLATED = {
    "pt": {"spp_per_wave": 16},
    "lt": {"light_paths": 1 << 14},
    "pm": {"light_paths": 1 << 14, "spp_per_iteration": 8},
}
ITERATIONS = {"pt": 512, "lt": 32, "pm": 128}


def translated(scene, shift: float):
    """The scene's shapes and camera moved by (shift, shift, shift) (DENSE_BLOB's only light
    is an area light, one of its shapes)."""
    move = np.full(3, shift)
    shapes = [dataclasses.replace(sh, vertices=sh.vertices + move) for sh in scene.shapes]
    camera = dataclasses.replace(
        scene.camera, origin=scene.camera.origin + move, target=scene.camera.target + move
    )
    return dataclasses.replace(scene, shapes=shapes, camera=camera)


@pytest.fixture(scope="module", params=list(TRANSLATED))
def translated_renders(request, tmp_path_factory) -> tuple[str, Estimate, Estimate]:
    path = tmp_path_factory.mktemp("dense-blob") / "scene.yaml"
    path.write_text(yaml.safe_dump(DENSE_BLOB))
    scene = load_scene(path, ["film.width=12", "film.height=12"])
    method_cls = get_method(request.param)
    params = TRANSLATED[request.param]
    base = ours(method_cls, scene, ITERATIONS[request.param], seed=1, **params)
    moved = ours(method_cls, translated(scene, SHIFT), ITERATIONS[request.param], seed=2, **params)
    return request.param, base, moved


def test_translation_invariance_in_a_dense_medium(translated_renders):
    """Rays leave surfaces an offset off them; the medium in that offset is counted (RayStart
    in the renderer). Skipping it made the cube's centre 8 % (pt) and 13 % (lt) darker when
    moved by SHIFT (and 1 % darker at the origin); without it each method here fails."""
    method, base, moved = translated_renders
    agree, why = same_image(base, moved)
    assert agree, (method, why)


def test_translation_invariance_can_fail(translated_renders):
    """The check has power: the moved scene's image times 0.95 fails it (the offsets it guards
    made the moved cube 8-13 % darker). At 0.97 a change of random stream alone took pm's
    p-value to the limit; here pm's block chi-square gives p 5.6e-9 at 0.97, 1.8e-27 at 0.95."""
    method, base, moved = translated_renders
    agree, why = same_image(base, Estimate(moved.samples * 0.95))
    assert not agree, (method, why)


# --------------------------------------------------------------------------- degenerate triangles


def test_degenerate_triangles_are_dropped_and_harmless():
    scene = load_small("fog-step", 8, 8)
    v = np.array([[0.1, 0.2, 0.3], [0.5, 0.2, 0.3], [0.3, 0.2, 0.3], [0.2, 0.4, 0.1]])
    faces = np.array([[0, 1, 2], [0, 0, 3], [3, 3, 3]], np.int32)  # collinear, repeated, point
    junk = Shape("junk", v, faces, material="white")
    bad = dataclasses.replace(scene, shapes=[*scene.shapes, junk])
    assert build_native_scene(bad).dropped_triangles == 3
    a = PathTracing(scene, seed=4, threads=2, params={"spp_per_wave": 8})
    b = PathTracing(bad, seed=4, threads=2, params={"spp_per_wave": 8})
    for m in (a, b):
        m.run_iteration(0)
    assert b.stats()["dropped_degenerate_triangles"] == 3
    np.testing.assert_array_equal(a.image(), b.image())


def test_both_renderers_get_the_same_triangles():
    """Degenerate triangles are dropped for Mitsuba too; a small triangle near the origin of a
    very large scene is not degenerate (its own coordinates set the bound, not the scene's size:
    float32 resolves it there) and both renderers keep it."""
    from renderer.scene.mitsuba_export import load_mitsuba_scene

    scene = load_small("fog-step", 8, 8)
    v = np.array([[0.1, 0.2, 0.3], [0.5, 0.2, 0.3], [0.3, 0.2, 0.3], [0.2, 0.4, 0.1]])
    junk = Shape("junk", v, np.array([[0, 1, 2], [0, 0, 3]], np.int32), material="white")
    s = 1e6  # a floor 2e6 wide
    floor = Shape(
        "floor",
        np.array([[-s, -1, -s], [s, -1, -s], [s, -1, s], [-s, -1, s]]),
        np.array([[0, 1, 2], [0, 2, 3]], np.int32),
        material="white",
    )
    tiny = Shape(
        "tiny",
        np.array([[0, 0, 0.5], [0.02, 0, 0.5], [0, 0.02, 0.5]]),
        np.array([[0, 1, 2]], np.int32),
        material="white",
    )
    bad = dataclasses.replace(scene, shapes=[*scene.shapes, junk, floor, tiny])
    native = build_native_scene(bad)
    assert native.dropped_triangles == 2
    ours_count = len(native.triangles)
    theirs = sum(shape.face_count() for shape in load_mitsuba_scene(bad).shapes())
    assert theirs == ours_count == sum(len(sh.faces) for sh in bad.shapes) - 2


# --------------------------------------------------------------------------- energy


@pytest.mark.parametrize("estimator", FURNACE_ESTIMATORS)
def test_heterogeneous_furnace_with_each_estimator(tmp_path, estimator):
    """test_furnace.py's grid furnace (reflective walls) with shadow-ray transmittance by
    another estimator: every 2x2-pixel block and the image mean converge to L, and a 2 %
    loss (the renders scaled by 0.98) fails the image-mean test."""
    np.save(tmp_path / "density.npy", grid_density())
    doc = furnace_yaml(GRID, (0.7, 0.3, 0.5))
    doc["integrator"]["estimator"] = estimator
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(doc))
    scene = load_scene(tmp_path / "scene.yaml")
    est = ours(PathTracing, scene, 64, seed=6, spp_per_wave=64)
    images = est.samples
    assert images.shape[1:3] == (FILM[1], FILM[0])
    mean, se = stats.mean_and_se(est.blocks(FURNACE_BLOCK).samples)
    p = stats.t_p_value(mean, L, se, len(images) - 1)
    worst = np.unravel_index(np.argmin(p), p.shape)
    assert p.min() >= FURNACE_BLOCK_LEVEL, (estimator, worst, mean[worst], se[worst])

    def image_mean_p(samples: np.ndarray) -> np.ndarray:
        image_mean, image_se = stats.mean_and_se(samples.mean(axis=(1, 2)))
        return stats.t_p_value(image_mean, L, image_se, len(samples) - 1)

    assert np.all(image_mean_p(images) >= FURNACE_MEAN_LEVEL), (estimator, image_mean_p(images))
    assert image_mean_p(images * 0.98).min() < FURNACE_MEAN_LEVEL, "a 2 % loss passed"


@pytest.mark.parametrize("phase", [{"type": "rayleigh"}, {"type": "mie", "resolution": 512}])
def test_furnace_with_rayleigh_and_mie_phase(tmp_path, phase):
    """Sampled phase weights are exactly 1 in the renderer too: a conservative furnace with
    these phase functions still converges to L."""
    medium = {"type": "homogeneous", "sigma_t": [0.5, 1.0, 2.0], "albedo": 1.0, "phase": phase}
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(furnace_yaml(medium, (0.5, 0.8, 0.2))))
    est = ours(PathTracing, load_scene(tmp_path / "scene.yaml"), 24, seed=7, spp_per_wave=32)
    image_mean, image_se = stats.mean_and_se(est.samples.mean(axis=(1, 2)))
    p = stats.t_p_value(image_mean, L, image_se, len(est.samples) - 1)
    assert np.all(p >= LEVEL), (phase, image_mean, image_se)
    # The control: a 4 % loss in any one channel fails (3 % passed in the blue one).
    for channel in range(3):
        lost = image_mean.copy()
        lost[channel] *= 0.96
        p = stats.t_p_value(lost, L, image_se, len(est.samples) - 1)
        assert p[channel] < LEVEL, (phase, channel, image_mean, image_se)


# --------------------------------------------------------------------------- grazing cameras


@pytest.mark.parametrize("origin,target,outside", CAMERAS_ON_BOUNDARY)
def test_camera_on_medium_boundary(origin, target, outside):
    """A camera exactly on the fog's null boundary (in vacuum, as the scene says) sees what a
    camera 1e-4 outside sees: rays leaving the boundary must enter the fog, not skip it (fog
    seen as vacuum) nor cross it twice. 3x3-pixel blocks and the image mean (chi-square and
    largest |z|), and the check has power: the on-boundary images scaled by 0.9 fail it (a
    5 % loss failed for two of the three cameras, not for the first, in the fog's face and
    looking along it, at |z| 3.7)."""

    def render(position, seed):
        at = f"camera.origin={[float(x) for x in position]}"
        scene = load_small("fog-step", 10, 10, (at, f"camera.target={list(target)}"))
        return ours(PathTracing, scene, 48, seed=seed, spp_per_wave=64)  # finite, >= 0

    on = render(origin, 1)
    near = render(np.add(origin, 1e-4 * np.asarray(outside)), 2)
    assert on.samples.mean() > 0
    agrees, why = parity.same_image(on, near, LEVEL)
    assert agrees, why
    agrees, why = parity.same_image(Estimate(on.samples * 0.9), near, LEVEL)
    assert not agrees, f"a 10 % loss passed: {why}"


# --------------------------------------------------------------------------- shipped scenes


SHIPPED = sorted(p.parent.name for p in SCENES.glob("*/scene.yaml"))


# Each of our methods, a few thousand paths per iteration at 12x12.
SWEEP = {
    "pt": {"spp_per_wave": 16},
    "lt": {"light_paths": 1 << 14},
    "pm": {"light_paths": 1 << 14, "spp_per_iteration": 8},
    "sppm": {"light_paths": 1 << 14, "spp_per_iteration": 8},
    "ppb": {"light_paths": 1 << 12, "spp_per_iteration": 8},
}


@pytest.mark.parametrize("method_id", list(SWEEP))
@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scene_renders_finite(name, method_id):
    """Two iterations of every method on every shipped scene: no sample rejected as
    non-finite, the image finite, non-negative and not black."""
    scene = load_small(name, 12, 12)
    method = get_method(method_id)(scene, seed=0, threads=2, params=SWEEP[method_id])
    for i in range(2):
        method.run_iteration(i)
    image = method.image()
    assert np.all(np.isfinite(image)) and np.all(image >= 0)
    assert image.max() > 0
    assert method.stats()["nonfinite"] == 0


def test_film_drops_and_counts_nonfinite_samples():
    """Every method adds samples through the same film: NaN and +-Inf are counted and
    dropped, finite samples (negative ones included) are kept."""
    nan, inf = float("nan"), float("inf")
    samples = np.array(
        [[1, 2, 3], [nan, 0, 0], [0, inf, 1], [0, 0, -inf], [0.5, -0.5, 0], [nan, nan, nan]]
    )
    image, dropped = _core.film_add_samples(samples)
    assert dropped == 4
    np.testing.assert_array_equal(
        image.reshape(-1, 3),
        [[1, 2, 3], [0, 0, 0], [0, 0, 0], [0, 0, 0], [0.5, -0.5, 0], [0, 0, 0]],
    )


class _NanMethod:
    """A method whose image holds a NaN: what a film that let one through would give."""

    def __init__(self, scene, *, seed, threads, params, spp_budget=None) -> None:
        self.iterations = 0
        self.method_params = {}

    def run_iteration(self, iteration: int) -> None:
        self.iterations += 1

    def image(self) -> np.ndarray:
        image = np.ones((4, 4, 3))
        image[1, 2, 0] = np.nan
        return image

    def stats(self) -> dict:
        return {"iterations": self.iterations, "spp": self.iterations, "nonfinite": 0}


def test_nonfinite_pixels_never_reach_a_file(tmp_path, monkeypatch):
    """Behind the film, two more guards: the render refuses to write a non-finite image
    (snapshots included) and the EXR writer refuses one; neither leaves a file."""
    from renderer import progressive
    from renderer.imageio import write_exr

    with pytest.raises(ValueError, match="non-finite"):
        write_exr(tmp_path / "a.exr", np.full((2, 2, 3), np.inf))
    monkeypatch.setattr(progressive, "get_method", lambda _: _NanMethod)
    settings = progressive.RenderSettings(method="pt", seed=0, threads=1, snapshots=(1e-9,))
    with pytest.raises(RuntimeError, match="non-finite pixels"):
        progressive.render(load_small("cbox", 4, 4), settings, tmp_path / "b.exr", progress=False)
    assert list(tmp_path.iterdir()) == []


def test_estimate_helper_is_independent_per_iteration():
    """Guard for the tests above: ours() returns per-iteration images, not running means.
    Iteration k depends only on (seed, k), so a fresh method that runs iteration k alone
    must give exactly the k-th sample, and the samples must average to the final image."""
    scene = load_small("fog-step", 6, 6)
    est: Estimate = ours(PathTracing, scene, 4, spp_per_wave=4)
    for k in (1, 3):
        alone = PathTracing(scene, seed=1, threads=2, params={"spp_per_wave": 4})
        alone.run_iteration(k)
        np.testing.assert_allclose(est.samples[k], alone.image(), rtol=1e-12, atol=1e-15)
    method = PathTracing(scene, seed=1, threads=2, params={"spp_per_wave": 4})
    for k in range(4):
        method.run_iteration(k)
    np.testing.assert_allclose(est.samples.mean(axis=0), method.image(), rtol=1e-12, atol=1e-15)
