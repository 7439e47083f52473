"""The photon kd-tree (cpp/photon_map.h) against brute force on random inputs.

Both queries must return exactly the brute-force sets: points within r of a
centre (surface density estimation) and points within r of a ray segment whose
projection lies on it (the beam radiance estimate's photon discs).
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer import _core


def _brute_sphere(points, c, r):
    d2 = ((points - c) ** 2).sum(axis=1)
    return np.flatnonzero(d2 < r * r)


def _brute_ray(points, o, d, tmax, r):
    v = points - o
    t = v @ d
    q = (v * v).sum(axis=1) - t * t
    return np.flatnonzero((t >= 0) & (t <= tmax) & (q < r * r))


def _clouds(rng):
    yield "uniform", rng.uniform(-1, 1, size=(5000, 3))
    yield (
        "clustered",
        np.concatenate(
            [rng.normal(c, 0.05, size=(700, 3)) for c in rng.uniform(-1, 1, size=(6, 3))]
        ),
    )
    # Many exact duplicates and points on a plane (surface photons on a wall).
    plane = rng.uniform(-1, 1, size=(3000, 3))
    plane[:, 1] = -1.0
    yield "plane+duplicates", np.concatenate([plane, np.repeat(plane[:50], 20, axis=0)])
    yield "tiny", rng.uniform(-1, 1, size=(3, 3))


@pytest.mark.parametrize("seed", [0, 1])
def test_sphere_queries_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    for name, pts in _clouds(rng):
        tree = _core.PointTree(np.ascontiguousarray(pts))
        assert tree.size == len(pts)
        for _ in range(60):
            c = rng.uniform(-1.2, 1.2, 3)
            if rng.random() < 0.3:
                c = pts[rng.integers(len(pts))]  # centred on a point
            r = float(rng.choice([1e-3, 0.05, 0.2, 0.7, 3.0]))
            got = np.sort(tree.query_sphere(tuple(c), r))
            want = _brute_sphere(pts, c, r)
            assert np.array_equal(got, want), (name, c, r)


@pytest.mark.parametrize("seed", [0, 1])
def test_ray_queries_match_brute_force(seed):
    rng = np.random.default_rng(seed + 10)
    for name, pts in _clouds(rng):
        tree = _core.PointTree(np.ascontiguousarray(pts))
        for _ in range(60):
            o = rng.uniform(-1.5, 1.5, 3)
            d = rng.normal(size=3)
            if rng.random() < 0.3:  # axis-aligned rays exercise the zero-slope slab case
                d = np.zeros(3)
                d[rng.integers(3)] = rng.choice([-1.0, 1.0])
            d /= np.linalg.norm(d)
            tmax = float(rng.choice([0.1, 1.0, 5.0, 1e30]))
            r = float(rng.choice([1e-3, 0.05, 0.2, 0.6]))
            got = np.sort(tree.query_ray(tuple(o), tuple(d), tmax, r))
            want = _brute_ray(pts, o, d, tmax, r)
            assert np.array_equal(got, want), (name, o, d, tmax, r)


def test_empty_tree_finds_nothing():
    tree = _core.PointTree(np.zeros((0, 3)))
    assert tree.size == 0
    assert len(tree.query_sphere((0, 0, 0), 1.0)) == 0
    assert len(tree.query_ray((0, 0, 0), (1, 0, 0), 1.0, 1.0)) == 0


def test_large_cloud_spot_check():
    """A photon-map sized cloud (200k points): the tree stays exact at depth."""
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1, 1, size=(200_000, 3))
    tree = _core.PointTree(pts)
    for _ in range(20):
        c = rng.uniform(-1, 1, 3)
        assert np.array_equal(
            np.sort(tree.query_sphere(tuple(c), 0.05)), _brute_sphere(pts, c, 0.05)
        )
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        got = np.sort(tree.query_ray(tuple(c), tuple(d), 1.0, 0.02))
        assert np.array_equal(got, _brute_ray(pts, c, d, 1.0, 0.02))
