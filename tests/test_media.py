"""Tests of the media estimators (the native probes ``Scene.transmittance``, ``free_flight`` and
``density`` of renderer._core) against closed forms and numpy references.

- Homogeneous: closed-form transmittance; exponential free-flight distances; with RGB
  extinction (spectral MIS over a hero channel) the weighted estimators are unbiased per channel.
- Grid: trilinear density with voxel centres at (i + 0.5) / res and clamped edges, also under
  an affine placement; ratio tracking against exp(-optical depth) integrated exactly in numpy;
  delta-tracking collision distances against 1 - exp(-cumulative optical depth); empty grids,
  a single dense voxel and optical thicknesses from 1e-4 to 1e3.

Tolerances come from standard errors measured on the samples (batch means of independent
seeds, or per-sample variances), with the level corrected for the number of tests (Sidak).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import stats
from renderer import _core

ISOTROPIC = _core.PhaseType.isotropic
INF = float("inf")

# --------------------------------------------------------------------------- numpy references


def affine(scale=(1, 1, 1), angle_deg=0.0, axis=(0, 0, 1), translate=(0, 0, 0)) -> np.ndarray:
    """4x4 to_world: scale, then rotate about ``axis``, then translate."""
    a = np.asarray(axis, np.float64)
    a /= np.linalg.norm(a)
    th = math.radians(angle_deg)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    rot = np.eye(3) + math.sin(th) * k + (1 - math.cos(th)) * (k @ k)
    m = np.eye(4)
    m[:3, :3] = rot @ np.diag(np.asarray(scale, np.float64))
    m[:3, 3] = translate
    return m


class GridRef:
    """A density grid as the core receives it, with numpy reference computations."""

    def __init__(self, density_zyx: np.ndarray, to_world: np.ndarray, sigma: float,
                 albedo=(0.9, 0.9, 0.9), majorant_cell: int = 4):  # fmt: skip
        self.density = np.ascontiguousarray(density_zyx, np.float32)
        self.to_world = np.asarray(to_world, np.float64)
        self.w2l = np.linalg.inv(self.to_world)[:3]
        self.sigma = float(sigma)
        self.scene = _core.Scene()
        self.id = self.scene.add_grid_medium(
            self.density, np.ascontiguousarray(self.w2l), self.sigma, tuple(albedo),
            ISOTROPIC, 0.0, majorant_cell,
        )  # fmt: skip

    def local(self, p: np.ndarray) -> np.ndarray:
        return p @ self.w2l[:, :3].T + self.w2l[:, 3]

    def density_at(self, p_world: np.ndarray) -> np.ndarray:
        """Trilinear interpolation, voxel centres at (i + 0.5) / res, clamped, 0 outside."""
        q = self.local(np.atleast_2d(p_world))
        nz, ny, nx = self.density.shape
        res = np.array([nx, ny, nz])
        f = q * res - 0.5
        i0 = np.floor(f).astype(np.int64)
        t = f - i0
        vals = self.density.astype(np.float64)
        out = np.zeros(len(q))
        for dx in (0, 1):
            for dy in (0, 1):
                for dz in (0, 1):
                    ix = np.clip(i0[:, 0] + dx, 0, nx - 1)
                    iy = np.clip(i0[:, 1] + dy, 0, ny - 1)
                    iz = np.clip(i0[:, 2] + dz, 0, nz - 1)
                    w = (
                        (t[:, 0] if dx else 1 - t[:, 0])
                        * (t[:, 1] if dy else 1 - t[:, 1])
                        * (t[:, 2] if dz else 1 - t[:, 2])
                    )
                    out += w * vals[iz, iy, ix]
        inside = np.all((q >= 0) & (q <= 1), axis=1)
        return np.where(inside, out, 0.0)

    def breakpoints(self, o, d, tmax: float) -> np.ndarray:
        """Distances along the ray where the interpolated density stops being one cubic
        polynomial: the cube's faces and the planes through voxel centres."""
        ol, dl = self.local(o[None])[0], self.w2l[:, :3] @ d
        nz, ny, nx = self.density.shape
        t0, t1 = 0.0, tmax
        ts = []
        for a, n in enumerate((nx, ny, nz)):
            if dl[a] == 0:
                if not 0 <= ol[a] <= 1:
                    return np.array([])
                continue
            ta, tb = sorted(((0 - ol[a]) / dl[a], (1 - ol[a]) / dl[a]))
            t0, t1 = max(t0, ta), min(t1, tb)
            ts.append(((np.arange(n) + 0.5) / n - ol[a]) / dl[a])
        if not t0 < t1:
            return np.array([])
        ts = np.concatenate(ts + [np.array([t0, t1])])
        return np.unique(ts[(ts >= t0) & (ts <= t1)])

    def optical_depth(self, o, d, tmax: float, t: np.ndarray | None = None) -> np.ndarray:
        """sigma * integral of the density along o + s d, s in [0, min(t, tmax)], exact (Gauss-
        Legendre with 4 nodes is exact for the cubic between breakpoints). ``t`` defaults to
        [tmax]."""
        o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
        d = d / np.linalg.norm(d)
        t = np.atleast_1d(np.asarray([tmax] if t is None else t, np.float64))
        bp = self.breakpoints(o, d, tmax)
        if len(bp) < 2:
            return np.zeros(len(t))
        x, w = np.polynomial.legendre.leggauss(4)

        def segment(a: np.ndarray, b: np.ndarray) -> np.ndarray:
            s = 0.5 * (a + b)[:, None] + 0.5 * (b - a)[:, None] * x  # (S, 4)
            dens = self.density_at(o + s.reshape(-1, 1) * d).reshape(s.shape)
            return 0.5 * (b - a) * (dens * w).sum(axis=1)

        cum = np.concatenate([[0.0], np.cumsum(segment(bp[:-1], bp[1:]))])
        tc = np.clip(np.minimum(t, tmax), bp[0], bp[-1])
        k = np.clip(np.searchsorted(bp, tc, side="right") - 1, 0, len(bp) - 2)
        return self.sigma * (cum[k] + segment(bp[k], tc))

    def transmittance_batches(self, o, d, tmax, n: int, batches: int, seed: int):
        """Ratio-tracking means of ``batches`` independent runs of n paths each: the overall
        mean, its standard error (from the spread of the batch means) and density lookups."""
        means, lookups = [], 0
        for b in range(batches):
            m, lk = self.scene.transmittance(self.id, tuple(o), tuple(d), tmax, seed + b, n)
            means.append(m[0])
            lookups += lk
            assert m[0] == m[1] == m[2]  # gray extinction
        mean, se = stats.mean_and_se(np.array(means))
        return float(mean), float(se), lookups


def smooth_density(shape_zyx, seed: int) -> np.ndarray:
    """A positive, lumpy density (sum of Gaussian blobs) with peak/mean about 5."""
    rng = np.random.default_rng(seed)
    nz, ny, nx = shape_zyx
    z, y, x = np.meshgrid(*(((np.arange(n) + 0.5) / n) for n in (nz, ny, nx)), indexing="ij")
    out = np.full(shape_zyx, 0.05)
    for _ in range(6):
        c = rng.random(3)
        r = 0.08 + 0.15 * rng.random()
        out += rng.random() * 2 * np.exp(-((x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2)
                                         / (2 * r * r))  # fmt: skip
    return out.astype(np.float32)


def homogeneous(sigma_t, albedo=(1.0, 1.0, 1.0)):
    scene = _core.Scene()
    return scene, scene.add_homogeneous_medium(
        tuple(map(float, sigma_t)), tuple(albedo), ISOTROPIC, 0.0
    )


# --------------------------------------------------------------------------- cases

GRID_TRANSFORMS = {
    "unit": affine(),
    "scaled-rotated-translated": affine((2.0, 0.5, 3.0), 30.0, (1, 2, 0.5), (-1.0, 0.3, 2.0)),
    "mirrored": affine((-1.5, 1.0, 0.8), -50.0, (0, 1, 0), (0.5, 0.0, -0.2)),
}
# (origin, direction, tmax) in the unit-cube frame of the grid; mapped to world by to_world.
LOCAL_RAYS = {
    "diagonal-through": ((-0.2, -0.1, -0.3), (1.0, 0.9, 1.1), INF),
    "starts-inside": ((0.4, 0.6, 0.5), (-0.3, 0.2, 1.0), INF),
    "ends-inside": ((0.5, -0.5, 0.5), (0.1, 1.0, 0.05), 1.1),  # tmax in local units, scaled
    "axis-aligned": ((0.37, 0.61, -1.0), (0.0, 0.0, 1.0), INF),
}
FREE_FLIGHT_RAYS = ["diagonal-through", "ends-inside"]
THICKNESS = [1e-4, 1e-2, 1.0, 10.0, 1e2, 1e3]

# Hypothesis tests in this file, for the Sidak correction: homogeneous gray free flight
# (binomial + chi2 + KS), RGB free flight (3 channels x (1 pass + 8 bins)), ratio tracking and
# delta tracking (binomial + KS) per transform and ray, majorant-cell variants, dense voxel.
RGB_BINS = 8
N_TESTS = (
    3
    + 3 * (1 + RGB_BINS)
    + len(GRID_TRANSFORMS) * len(LOCAL_RAYS)
    + 2 * len(GRID_TRANSFORMS) * len(FREE_FLIGHT_RAYS)
    + 3
    + 1
)
LEVEL = stats.sidak(stats.ALPHA, N_TESTS)


def world_ray(grid: GridRef, name: str):
    o_l, d_l, tmax_l = LOCAL_RAYS[name]
    m = grid.to_world
    o = m[:3, :3] @ np.asarray(o_l, np.float64) + m[:3, 3]
    d_w = m[:3, :3] @ np.asarray(d_l, np.float64)
    scale = np.linalg.norm(d_w) / np.linalg.norm(d_l)  # world length per local length
    return o, d_w / np.linalg.norm(d_w), tmax_l * scale if math.isfinite(tmax_l) else INF


# --------------------------------------------------------------------------- homogeneous


@pytest.mark.parametrize("tmax", [0.0, 0.3, 1.0, 7.5])
def test_homogeneous_transmittance_closed_form(tmax):
    sigma = np.array([0.5, 1.0, 2.0])
    scene, m = homogeneous(sigma)
    tr, lookups = scene.transmittance(m, (0.1, 0.2, 0.3), (1.0, 2.0, -1.0), tmax, 1, 4)
    np.testing.assert_allclose(tr, np.exp(-sigma * tmax), rtol=1e-14)
    assert lookups == 0


def test_homogeneous_transmittance_infinite_ray():
    """An unbounded ray: T = 0 where sigma_t > 0 and T = 1 in a channel with sigma_t = 0."""
    scene, m = homogeneous((0.0, 1.0, 2.0))
    tr, _ = scene.transmittance(m, (0, 0, 0), (0, 0, 1), INF, 1, 1)
    np.testing.assert_array_equal(tr, [1.0, 0.0, 0.0])


def test_homogeneous_free_flight_infinite_ray_is_finite():
    """An unbounded ray in a medium with a zero extinction channel: a path that does not
    collide (hero channel 0) must get a finite weight, exp(-sigma tmax) / mean(...) -> (3,0,0)."""
    scene, m = homogeneous((0.0, 1.0, 2.0))
    t, w = scene.free_flight(m, (0, 0, 0), (0, 0, 1), INF, 1, 3000)
    assert np.isinf(t).any()
    bad = ~np.all(np.isfinite(w), axis=1)
    assert not bad.any(), f"{bad.sum()} of {len(w)} weights are not finite, e.g. {w[bad][0]}"
    np.testing.assert_allclose(w[np.isinf(t)], np.broadcast_to([3.0, 0, 0], w[np.isinf(t)].shape))


def test_homogeneous_free_flight_gray_is_exponential():
    sigma, tmax, n = 1.3, 2.0, 200_000
    scene, m = homogeneous((sigma,) * 3, albedo=(0.7, 0.7, 0.7))
    t, w = scene.free_flight(m, (0, 0, 0), (0.0, 1.0, 0.0), tmax, 42, n)
    hit = np.isfinite(t)
    assert np.all((t[hit] >= 0) & (t[hit] < tmax))
    p_hit = -math.expm1(-sigma * tmax)
    assert stats.binomial_p_value(hit.sum(), n, p_hit) >= LEVEL
    edges = np.linspace(0, tmax, 41)
    result = stats.chi2_1d(t, edges, lambda x: -np.expm1(-sigma * x))
    assert result.passed(LEVEL), result
    # Given a collision, t follows the exponential truncated to [0, tmax).
    p = stats.ks_test(t[hit], lambda x: -np.expm1(-sigma * np.clip(x, 0, tmax)) / p_hit)
    assert p >= LEVEL
    # Gray extinction: weights are exactly the albedo on collision, 1 on passing.
    np.testing.assert_allclose(w[hit], 0.7, rtol=1e-12)
    np.testing.assert_allclose(w[~hit], 1.0, rtol=1e-12)


def test_homogeneous_free_flight_rgb_unbiased():
    """Spectral MIS over the hero channel: per channel, E[w 1{pass}] = exp(-sigma tmax) and
    E[w 1{collision in [a, b)}] = albedo (exp(-sigma a) - exp(-sigma b))."""
    sigma = np.array([0.2, 1.0, 3.0])
    albedo = np.array([0.9, 0.5, 0.7])
    tmax, n = 1.5, 400_000
    scene, m = homogeneous(sigma, albedo)
    t, w = scene.free_flight(m, (1, 2, 3), (0.3, -0.4, 0.5), tmax, 7, n)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    passed = ~np.isfinite(t)
    mean, se = stats.mean_and_se(w * passed[:, None])
    p = stats.z_p_value(mean, np.exp(-sigma * tmax), se)
    assert np.all(p >= LEVEL), (mean, np.exp(-sigma * tmax), se)
    edges = np.linspace(0, tmax, RGB_BINS + 1)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        inside = (t >= a) & (t < b)
        mean, se = stats.mean_and_se(w * inside[:, None])
        expected = albedo * (np.exp(-sigma * a) - np.exp(-sigma * b))
        p = stats.z_p_value(mean, expected, se)
        assert np.all(p >= LEVEL), (a, b, mean, expected, se)


# --------------------------------------------------------------------------- grid: density


@pytest.mark.parametrize("name", list(GRID_TRANSFORMS))
def test_grid_density_matches_trilinear_reference(name):
    density = np.random.default_rng(1).random((5, 6, 7)).astype(np.float32)  # nz, ny, nx differ
    grid = GridRef(density, GRID_TRANSFORMS[name], 1.0)
    rng = np.random.default_rng(2)
    q = rng.uniform(-0.1, 1.1, size=(20_000, 3))  # includes points outside the cube
    q[:200] = rng.uniform(0, 0.04, size=(200, 3))  # near a corner: the clamped edge region
    q[200:400, 0] = 1.0 - 1e-9  # on a face
    p = q @ grid.to_world[:3, :3].T + grid.to_world[:3, 3]
    got = grid.scene.density(grid.id, np.ascontiguousarray(p))
    np.testing.assert_allclose(got, grid.density_at(p), rtol=1e-10, atol=1e-12)
    outside = np.any((q < 0) | (q > 1), axis=1)
    assert np.all(got[outside] == 0) and np.any(got[~outside] > 0)


def test_grid_density_at_a_nan_point_is_zero():
    """NaN is outside the grid: once it passed the bounds check and read far out of bounds."""
    grid = GridRef(np.ones((2, 2, 2), np.float32), GRID_TRANSFORMS["unit"], 1.0)
    p = np.array([[np.nan, 0.5, 0.5], [0.5, np.nan, 0.5], [0.5, 0.5, np.nan], [0.5, 0.5, 0.5]])
    got = grid.scene.density(grid.id, p)
    assert list(got[:3]) == [0, 0, 0] and got[3] > 0


def test_grid_density_at_voxel_centres_equals_voxels():
    """Voxel (i, j, k) = density_zyx[k, j, i] sits at ((i, j, k) + 0.5) / res."""
    density = np.random.default_rng(3).random((3, 4, 5)).astype(np.float32)
    grid = GridRef(density, GRID_TRANSFORMS["scaled-rotated-translated"], 1.0)
    k, j, i = np.meshgrid(*(np.arange(n) for n in density.shape), indexing="ij")
    q = (np.stack([i, j, k], axis=-1).reshape(-1, 3) + 0.5) / np.array([5, 4, 3])
    p = q @ grid.to_world[:3, :3].T + grid.to_world[:3, 3]
    got = grid.scene.density(grid.id, np.ascontiguousarray(p))
    np.testing.assert_allclose(got, density.ravel(), rtol=1e-6)


def test_numpy_optical_depth_reference():
    """The reference integral itself: a linear ramp along x (exactly representable)."""
    n = 8
    ramp = np.broadcast_to((np.arange(n) + 0.5) / n, (n, n, n)).astype(np.float32)
    grid = GridRef(ramp, affine(), 2.0)
    # Along x at y = z = 0.5: density = x inside [0.5/n, 1 - 0.5/n], clamped flat outside.
    tau = grid.optical_depth((0.0, 0.5, 0.5), (1.0, 0.0, 0.0), INF)[0]
    lo, hi = 0.5 / n, 1 - 0.5 / n
    exact = 2.0 * (lo * lo + (hi * hi - lo * lo) / 2 + hi * (1 - hi))
    assert tau == pytest.approx(exact, rel=1e-12)


# --------------------------------------------------------------------------- grid: tracking


@pytest.mark.parametrize("ray", list(LOCAL_RAYS))
@pytest.mark.parametrize("name", list(GRID_TRANSFORMS))
def test_ratio_tracking_matches_exact_transmittance(name, ray):
    grid = GridRef(smooth_density((12, 10, 14), seed=4), GRID_TRANSFORMS[name], 1.0)
    o, d, tmax = world_ray(grid, ray)
    # Scale extinction so the optical depth along the ray is 1.5 (T = 0.22).
    grid = GridRef(grid.density, grid.to_world, 1.5 / grid.optical_depth(o, d, tmax)[0])
    exact = math.exp(-grid.optical_depth(o, d, tmax)[0])
    mean, se, lookups = grid.transmittance_batches(o, d, tmax, 4000, 16, seed=100)
    assert lookups > 0 and 0 < mean < 1
    assert stats.t_p_value(mean, exact, se, 15) >= LEVEL, (mean, exact, se)


@pytest.mark.parametrize("ray", FREE_FLIGHT_RAYS)
@pytest.mark.parametrize("name", list(GRID_TRANSFORMS))
def test_delta_tracking_collision_cdf(name, ray):
    grid = GridRef(smooth_density((12, 10, 14), seed=5), GRID_TRANSFORMS[name], 1.0)
    o, d, tmax = world_ray(grid, ray)
    grid = GridRef(grid.density, grid.to_world, 1.2 / grid.optical_depth(o, d, tmax)[0],
                   albedo=(0.8, 0.6, 0.4))  # fmt: skip
    n = 100_000
    t, w = grid.scene.free_flight(grid.id, tuple(o), tuple(d), tmax, 9, n)
    hit = np.isfinite(t)
    p_hit = -math.expm1(-grid.optical_depth(o, d, tmax)[0])
    assert stats.binomial_p_value(hit.sum(), n, p_hit) >= LEVEL, (hit.mean(), p_hit)

    def cdf(x: np.ndarray) -> np.ndarray:  # given a collision
        return -np.expm1(-grid.optical_depth(o, d, tmax, x)) / p_hit

    assert stats.ks_test(t[hit], cdf) >= LEVEL
    np.testing.assert_array_equal(w[hit], np.broadcast_to([0.8, 0.6, 0.4], w[hit].shape))
    np.testing.assert_array_equal(w[~hit], 1.0)
    # Collisions only happen where there is medium.
    assert np.all(grid.density_at(o + t[hit, None] * d) > 0)


@pytest.mark.parametrize("cell", [1, 3, 64])
def test_ratio_tracking_unbiased_for_any_majorant_cell(cell):
    """Majorant cells of 1 voxel, 3 voxels (not dividing the resolution) or one global cell."""
    density = smooth_density((12, 10, 14), seed=6)
    grid = GridRef(density, affine((1.5, 1.5, 1.5)), 1.0, majorant_cell=cell)
    o, d, tmax = world_ray(grid, "diagonal-through")
    grid = GridRef(density, grid.to_world, 1.0 / grid.optical_depth(o, d, tmax)[0],
                   majorant_cell=cell)  # fmt: skip
    exact = math.exp(-grid.optical_depth(o, d, tmax)[0])
    mean, se, _ = grid.transmittance_batches(o, d, tmax, 4000, 16, seed=200)
    assert stats.t_p_value(mean, exact, se, 15) >= LEVEL, (mean, exact, se)


def test_empty_grid_is_vacuum():
    grid = GridRef(np.zeros((4, 5, 6), np.float32), affine((2, 2, 2), 10, (0, 1, 0)), 5.0)
    o, d, tmax = world_ray(grid, "diagonal-through")
    tr, lookups = grid.scene.transmittance(grid.id, tuple(o), tuple(d), tmax, 1, 1000)
    assert tr == [1.0, 1.0, 1.0] and lookups == 0
    t, w = grid.scene.free_flight(grid.id, tuple(o), tuple(d), tmax, 1, 1000)
    assert np.all(np.isinf(t)) and np.all(w == 1.0)


def test_single_dense_voxel():
    n = 16
    density = np.zeros((n, n, n), np.float32)
    density[2, 3, 2] = 400.0  # z, y, x: voxel (2, 3, 2), centre (2.5, 3.5, 2.5) / 16
    grid = GridRef(density, affine(), 0.12)
    centre = np.array([2.5, 3.5, 2.5]) / n
    # Through the voxel centre along x: tau = 0.12 * 400 * (1 / 16) (the tent integrates to
    # one voxel width).
    o, d = np.array([-0.5, centre[1], centre[2]]), np.array([1.0, 0, 0])
    tau = grid.optical_depth(o, d, INF)[0]
    assert tau == pytest.approx(0.12 * 400 / n, rel=1e-6)
    mean, se, _ = grid.transmittance_batches(o, d, INF, 4000, 16, seed=300)
    assert stats.t_p_value(mean, math.exp(-tau), se, 15) >= LEVEL, (mean, math.exp(-tau), se)
    t, _ = grid.scene.free_flight(grid.id, tuple(o), tuple(d), INF, 3, 20_000)
    hit = t[np.isfinite(t)]
    assert len(hit) and np.all(np.abs(o[0] + hit - centre[0]) < 1 / n)  # within the tent
    # A ray through majorant cells far from the voxel: exact T = 1 and no density lookups
    # (empty space is skipped by the majorant grid; a global majorant would not).
    o2 = np.array([-0.5, 0.8, 0.8])
    tr, lookups = grid.scene.transmittance(grid.id, tuple(o2), tuple(d), INF, 4, 1000)
    assert tr == [1.0, 1.0, 1.0] and lookups == 0
    t2, _ = grid.scene.free_flight(grid.id, tuple(o2), tuple(d), INF, 4, 1000)
    assert np.all(np.isinf(t2))


@pytest.mark.parametrize("tau", THICKNESS)
def test_optical_thickness_range(tau):
    """Homogeneous media from nearly transparent to opaque: closed-form transmittance exact per
    channel, free flights finite and inside the segment. (Grids over the same range of
    thickness, with statistical tests, are in test_stability.py.)"""
    scene, m = homogeneous((tau, tau / 2, tau * 2), albedo=(0.5, 0.5, 0.5))
    tr, _ = scene.transmittance(m, (0, 0, 0), (0, 0, 1), 1.0, 1, 1)
    np.testing.assert_allclose(tr, np.exp(-np.array([tau, tau / 2, tau * 2])), rtol=1e-12)
    t, w = scene.free_flight(m, (0, 0, 0), (0, 0, 1), 1.0, 1, 10_000)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    assert np.all((t[np.isfinite(t)] >= 0) & (t[np.isfinite(t)] < 1))
