"""Volume sources baked to one voxel grid, and the transmittance estimators over it.

Sources: Perlin noise (zero on the lattice, deterministic per seed, bounded), fBm octaves,
the step function, OpenVDB files (round trip through pyopenvdb: values, active bounding box,
declared bbox, index-to-world placement), and the shipped smoke scene's placement as the core
sees it. Estimators: delta (track length), ratio and residual ratio tracking are unbiased
against the exact optical depth (numpy reference of test_media); residual ratio tracking needs
fewer lookups than ratio tracking and none in constant cells; ray marching is biased but
converges as its step shrinks; per-cell minorant <= density <= majorant everywhere.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy import stats as sps

import stats
from conftest import SCENES
from renderer import _core
from renderer.scene import load_scene
from renderer.volumes import (
    fbm,
    perlin_density,
    perlin_noise,
    read_vdb,
    step_density,
    voxel_centres,
    write_vdb,
)
from test_media import GridRef, affine, smooth_density

UNBIASED = ["delta", "ratio", "residual"]
RAYS = {
    "diagonal": ((-0.3, -0.2, -0.1), (1.0, 0.8, 0.9)),
    "inside-out": ((0.45, 0.5, 0.55), (0.2, -1.0, 0.3)),
}
MARCH_STEPS = (0.5, 0.1, 0.01)
# z-tests per estimator and ray, residual against ratio (lookups, variance), ray marching per
# step and ray, the scene-keyed lookup counts (two).
N_TESTS = len(UNBIASED) * len(RAYS) + 2 + len(MARCH_STEPS) * len(RAYS) + 2
LEVEL = stats.sidak(stats.ALPHA, N_TESTS)


# --------------------------------------------------------------------------- procedural


def test_perlin_zero_on_lattice_and_bounded():
    lattice = np.random.default_rng(0).integers(-50, 50, (1000, 3)).astype(np.float64)
    assert np.all(perlin_noise(lattice, seed=3) == 0)
    x = np.random.default_rng(1).random((200_000, 3)) * 20 - 10
    n = perlin_noise(x, seed=3)
    assert np.abs(n).max() <= 1.05 and 0.15 < n.std() < 0.4
    np.testing.assert_array_equal(n, perlin_noise(x, seed=3))
    assert not np.array_equal(n, perlin_noise(x, seed=4))


def test_perlin_is_continuous():
    x = np.random.default_rng(2).random((10_000, 3)) * 8
    eps = 1e-6
    diff = np.abs(perlin_noise(x + eps, 1) - perlin_noise(x, 1))
    assert diff.max() < 1e-4


def test_fbm_octaves_add_detail_with_gain():
    x = np.random.default_rng(3).random((50_000, 3))
    one = fbm(x, octaves=1, frequency=4, seed=5)
    two = fbm(x, octaves=2, frequency=4, lacunarity=2, gain=0.5, seed=5)
    second = perlin_noise(x * 8, 5 + 7919)
    np.testing.assert_allclose(two - one, 0.5 * second, atol=1e-12)


def test_perlin_density_is_offset_noise_clipped():
    d = perlin_density((8, 6, 4), octaves=3, frequency=2, offset=0.1, seed=2)
    ref = np.maximum(0.1 + fbm(voxel_centres((8, 6, 4)), 3, 2, 2.0, 0.5, 2), 0)
    assert d.shape == (8, 6, 4) and d.dtype == np.float32
    np.testing.assert_allclose(d, ref, rtol=1e-6)


def test_perlin_density_bakes_in_slabs_alike(monkeypatch):
    """Large grids are baked a slab at a time: the result does not depend on the slab size."""
    import renderer.volumes as volumes

    whole = perlin_density((9, 5, 3), octaves=2, seed=4)
    monkeypatch.setattr(volumes, "_BAKE_POINTS", 2 * 5 * 3)  # slabs of 2 (and a last of 1)
    np.testing.assert_array_equal(volumes.perlin_density((9, 5, 3), octaves=2, seed=4), whole)


def test_step_density():
    d = step_density((4, 3, 2), axis=0, position=0.5, values=(0.25, 3.0))
    assert np.all(d[:2] == 0.25) and np.all(d[2:] == 3.0)
    d = step_density((2, 2, 10), axis=2, position=0.31, values=(1.0, 0.0))
    assert np.all(d[..., :3] == 1) and np.all(d[..., 3:] == 0)


# --------------------------------------------------------------------------- OpenVDB


def test_vdb_round_trip_and_placement(tmp_path):
    rng = np.random.default_rng(4)
    dense = np.zeros((20, 12, 9), np.float32)
    dense[3:15, 2:10, 1:8] = rng.random((12, 8, 7)).astype(np.float32) + 0.1
    origin, voxel = np.array([-0.4, 1.0, 2.5]), 0.05
    file = tmp_path / "g.vdb"
    write_vdb(file, dense, voxel, tuple(origin))
    # Active bounding box: exactly the non-zero block, placed where it was.
    a, to_world = read_vdb(file, "density")
    np.testing.assert_array_equal(a, dense[3:15, 2:10, 1:8])
    centre = lambda m, ijk, res: m[:3, :3] @ ((np.array(ijk) + 0.5) / res) + m[:3, 3]  # noqa: E731
    np.testing.assert_allclose(
        centre(to_world, (0, 0, 0), a.shape), origin + voxel * np.array([3, 2, 1])
    )
    # A declared bbox: the whole array, zeros included.
    b, to_world_b = read_vdb(file, "density", ((0, 0, 0), (19, 11, 8)))
    np.testing.assert_array_equal(b, dense)
    np.testing.assert_allclose(
        centre(to_world_b, (19, 11, 8), b.shape), origin + voxel * np.array([19, 11, 8])
    )
    with pytest.raises(Exception, match="no grid named"):
        read_vdb(file, "temperature")


def test_smoke_scene_places_the_vdb_grid():
    """The core's density at the world centre of voxel (i, j, k) equals the file's voxel."""
    scene = load_scene("smoke", ["film.width=8", "film.height=8"])
    m = scene.media["smoke"]
    a, _ = read_vdb(m.source, "density", ((0, 0, 0), (79, 79, 79)))
    from renderer.engine import build_native_scene

    native = build_native_scene(scene)
    idx = np.argwhere(a > 0.2)[::97]
    world = 0.025 * idx + np.array([-1, -0.05, -1]) + 0.0125  # make_plume.py's placement
    got = native.core.density(0, np.ascontiguousarray(world))
    np.testing.assert_allclose(got, a[tuple(idx.T)], rtol=1e-5)


# --------------------------------------------------------------------------- estimators


@pytest.fixture(scope="module")
def grid():
    return GridRef(
        smooth_density((12, 10, 14), seed=8), affine((2.0, 1.0, 1.5), 20, (1, 1, 0)), 3.0
    )


def world(grid, name):
    o, d = RAYS[name]
    m = grid.to_world
    dw = m[:3, :3] @ np.asarray(d, float)
    return m[:3, :3] @ np.asarray(o, float) + m[:3, 3], dw / np.linalg.norm(dw)


def estimate(grid, estimator, o, d, n=20_000, step=0.0, seed=10):
    _core.configure_medium(grid.scene, grid.id, _core.Estimator[estimator], step)
    t, lookups = _core.transmittance_samples(
        grid.scene, grid.id, tuple(o), tuple(d), np.inf, seed, n
    )
    _core.configure_medium(grid.scene, grid.id, _core.Estimator.ratio, 0.0)
    return t, lookups


@pytest.mark.parametrize("estimator", UNBIASED)
@pytest.mark.parametrize("ray", RAYS)
def test_unbiased_estimators_match_exact_transmittance(grid, estimator, ray):
    o, d = world(grid, ray)
    exact = float(np.exp(-grid.optical_depth(o, d, np.inf)[0]))
    t, _ = estimate(grid, estimator, o, d)
    assert np.all((t >= 0) & (t <= 1)), estimator
    mean, se = stats.mean_and_se(t)
    assert stats.z_p_value(mean, exact, max(se, 1e-12)) >= LEVEL, (estimator, mean, se, exact)


def test_residual_needs_fewer_lookups_and_less_variance_than_ratio():
    """With a density floor (as in fog), the per-cell control takes most of the extinction."""
    grid = GridRef(smooth_density((12, 10, 14), seed=8) + 1.0, affine((2.0, 1.0, 1.5)), 1.0)
    o, d = world(grid, "diagonal")
    # Lookups are counted per call: 20 calls of 1000 rays each, independent seeds per
    # estimator. One-sided Welch tests on the per-call means of the lookups and on the
    # per-call variances of the estimates (means of 1000 terms: near normal, whereas the
    # estimates themselves are far from normal, which rules out an F-test).
    lookups, variances = {}, {}
    for est, offset in (("ratio", 0), ("residual", 1)):
        calls = [estimate(grid, est, o, d, n=1000, seed=2 * b + offset) for b in range(20)]
        lookups[est] = [k for _, k in calls]
        variances[est] = [t.var(ddof=1) for t, _ in calls]
    for what in (lookups, variances):
        welch = sps.ttest_ind(what["residual"], what["ratio"], equal_var=False, alternative="less")
        assert welch.pvalue < LEVEL, what


def test_residual_is_exact_and_free_in_constant_cells():
    # T = 0.2466, below the roulette threshold (0.25): no roulette where nothing is looked up
    g = GridRef(np.full((8, 8, 8), 0.7, np.float32), affine(), 2.0)
    _core.configure_medium(g.scene, g.id, _core.Estimator.residual, 0.0)
    t, lookups = _core.transmittance_samples(
        g.scene, g.id, (0.5, 0.5, -1), (0, 0, 1), np.inf, 1, 100
    )
    assert lookups == 0
    np.testing.assert_allclose(t, np.exp(-0.7 * 2.0), rtol=1e-6)


def test_bounds_enclose_the_interpolated_density(grid):
    hi, lo = _core.grid_bounds(grid.scene, grid.id)
    q = np.random.default_rng(9).random((100_000, 3))
    p = q @ grid.to_world[:3, :3].T + grid.to_world[:3, 3]
    dens = grid.density_at(p)
    mz, my, mx = hi.shape
    cell = np.minimum((q * [mx, my, mz]).astype(int), [mx - 1, my - 1, mz - 1])
    assert np.all(dens <= hi[cell[:, 2], cell[:, 1], cell[:, 0]])
    assert np.all(dens >= lo[cell[:, 2], cell[:, 1], cell[:, 0]])
    assert np.all(lo <= hi)


@pytest.mark.parametrize("ray", RAYS)
def test_ray_marching_estimates_the_optical_depth_without_bias(grid, ray):
    """Marching with one random offset per ray estimates the optical depth without bias (only
    exp(-tau_hat) is biased, by Jensen's inequality), so tau_hat = -log T per sample must match
    the exact optical depth by a t-test at every step length, and its spread must shrink
    with the step. A wrong step length or a dropped segment biases tau_hat (measured spread:
    1e-3 to 1e-5 of tau, so a 1 % error is tens of standard errors)."""
    o, d = world(grid, ray)
    tau = float(grid.optical_depth(o, d, np.inf)[0])
    spreads = []
    for step in MARCH_STEPS:
        t, _ = estimate(grid, "raymarch", o, d, n=4000, step=step)
        tau_hat = -np.log(t)
        se = tau_hat.std(ddof=1) / np.sqrt(len(t))
        p = stats.t_p_value(tau_hat.mean(), tau, se, len(t) - 1)
        assert p >= LEVEL, (step, tau_hat.mean(), se, tau)
        spreads.append(se)
    assert spreads[0] > spreads[1] > spreads[2], spreads


def test_scene_estimator_setting_reaches_the_core():
    lookups, samples = {}, {}
    for est in ("ratio", "residual", "delta"):
        scene = load_scene("fog-step", ["film.width=4", "film.height=4",
                                        f"integrator.estimator={est}"])  # fmt: skip
        from renderer.engine import build_native_scene

        native = build_native_scene(scene)
        samples[est], lookups[est] = _core.transmittance_samples(
            native.core, 0, (-0.9, 0.1, 0.2), (1, 0, 0), 1.8, 3, 2000
        )
    # delta tracking estimates transmittance by 0 or 1, the ratio estimators by fractions
    assert set(np.unique(samples["delta"])) == {0.0, 1.0}
    assert not np.isin(samples["ratio"], [0.0, 1.0]).all()
    # The step is constant on each side except for its one-voxel ramp, which touches the two
    # majorant cells (4 voxels = 0.2475 wide) around it: residual tracking looks densities up
    # only there, at rate (2.0 - 0.1) per unit length (Poisson counts).
    expected = 2000 * 2 * 0.2475 * 1.9
    assert stats.z_p_value(lookups["residual"], expected, np.sqrt(expected)) >= LEVEL, lookups
    # Ratio tracking looks up densities everywhere: significantly more (Poisson counts).
    more = lookups["ratio"] - lookups["residual"]
    assert sps.norm.sf(more / np.sqrt(lookups["ratio"] + lookups["residual"])) < LEVEL, lookups


# --------------------------------------------------------------------------- scene keys


@pytest.mark.parametrize(
    "override,message",
    [
        ("integrator.estimator=woodcock", "integrator.estimator: expected one of: delta"),
        ("integrator.march_step=-1", "integrator.march_step"),
        ("media.fog.density={type: perlin}", "resolution: missing required key"),
        (
            "media.fog.density={type: perlin, resolution: 4, lacunarity: 1.0e300}",
            "density.lacunarity: expected a number >= 0 and <= 16",
        ),
        ("media.fog.density={type: perlin, resolution: 4, gain: 1.0e300}", "density.gain"),
        ("media.fog.density={type: cloud, resolution: 4}", "density.type: expected one of"),
        ("media.fog.density={type: step, resolution: 4, values: [1]}", "expected [below, above]"),
        ("media.fog.density={type: vdb, file: nothing.vdb}", "density file not found"),
        ("media.fog.phase={type: tabulated}", "give either values"),
        ("media.fog.phase={type: tabulated, values: [0, 0]}", "not all 0"),
        ("media.fog.phase={type: mie, effective_radius: 0}", "effective_radius"),
    ],
)
def test_scene_errors_name_the_key(override, message):
    from renderer.errors import PgiError

    with pytest.raises(PgiError, match=re.escape(message)):
        load_scene("fog-step", [override])


def test_vdb_grid_name_must_be_unique(tmp_path):
    """Two grids of one name: OpenVDB would read the first without a word; refused instead."""
    import pyopenvdb as vdb

    from renderer.errors import PgiError

    grids = []
    for value in (1.0, 2.0):
        g = vdb.FloatGrid()
        g.copyFromArray(np.full((2, 2, 2), value, np.float32))
        g.name = "density"
        grids.append(g)
    file = tmp_path / "twice.vdb"
    vdb.write(str(file), grids=grids)
    with pytest.raises(PgiError, match=f"{re.escape(str(file))}: 2 grids are named 'density'"):
        read_vdb(file, "density")
    grids[1].name = "other"  # unique again: read
    vdb.write(str(file), grids=grids)
    assert read_vdb(file, "density")[0].max() == 1.0


def test_vdb_grid_name_is_checked(tmp_path):
    from renderer.errors import PgiError

    scene = SCENES / "smoke" / "scene.yaml"
    with pytest.raises(PgiError, match="no grid named 'smoke'"):
        load_scene(scene, ["media.smoke.density.grid=smoke"])
