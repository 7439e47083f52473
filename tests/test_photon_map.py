"""The photon kd-tree (cpp/photon_map.h) against brute force on random inputs.

Both queries must return exactly the brute-force sets: points within r of a
centre (surface density estimation) and points within r of a ray segment whose
projection lies on it (the beam radiance estimate's photon discs). Surface density
estimation on top of the tree (which photons belong to a surface) is checked photon by
photon.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_small
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


def test_surface_photons_count_only_on_the_surface_they_lie_on():
    """Surface density estimation (reflected_photon_power, shared by pm, sppm and ppb) sums a
    photon at x only when it lies within the radius on a surface facing the same way and
    arrived from that surface's front: near cbox's floor-to-back-wall corner the floor's
    photons are not the wall's. The image tests cannot see a leak there: with the facing
    rule removed, ppb's 4x4 blocks of cbox-fog still agreed with pt (p = 0.26)."""
    from renderer.engine import build_native_scene

    scene = load_small("cbox", 8, 8)
    native = build_native_scene(scene)
    tris = native.triangles
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    names = native.per_triangle(scene, [s.name for s in scene.shapes])
    wall, floor = np.flatnonzero(names == "back"), np.flatnonzero(names == "floor")
    assert len(wall) == 2 and len(floor) == 2
    assert np.allclose(normals[wall], [0, 0, 1]) and np.allclose(normals[floor], [0, 1, 0])
    white = np.array(scene.materials["white"].reflectance)

    r = 0.02
    x = np.array([0.0, -1 + 0.4 * r, -1.0])  # on the back wall, 0.4 r above the floor
    # the wall triangle that holds x, and the other one (coplanar)
    bary = [np.linalg.lstsq((tris[t, 1:] - tris[t, 0]).T, x - tris[t, 0], rcond=None)[0]
            for t in wall]  # fmt: skip
    here = next(i for i, b in enumerate(bary) if b.min() >= 0 and b.sum() <= 1)
    on, other = wall[here], wall[1 - here]
    front = np.array([0.3, 0.4, 0.866])  # arrives from the wall's front, and the floor's
    cases = {  # name: (position, triangle, wi, counts)
        "on the wall": (x + [0.3 * r, 0.2 * r, 0], on, front, True),
        # the rule asks the photon's triangle which way it faces, not which triangle it is
        "of the wall's other triangle": (x + [-0.5 * r, 0.1 * r, 0], other, front, True),
        "on the floor": (x + [0.1 * r, -0.4 * r, 0.3 * r], floor[0], front, False),
        "from behind the wall": (x + [0.1 * r, 0.1 * r, 0], on, -front, False),
        "beyond the radius": (x + [1.01 * r, 0, 0], on, front, False),
    }
    power = np.array([[1.0, 2.0, 4.0]]) * np.arange(1, len(cases) + 1)[:, None]
    pos = np.array([c[0] for c in cases.values()])
    tri = np.array([c[1] for c in cases.values()], dtype=np.int32)
    wi = np.array([c[2] for c in cases.values()])
    counts = np.array([c[3] for c in cases.values()])

    def gathered(keep, wo=(0.0, 0.0, 1.0)):
        return np.array(native.core.surface_photon_power(
            int(on), x, wo, r, pos[keep], tri[keep], wi[keep], power[keep]))  # fmt: skip

    expected = power[counts].sum(axis=0) * white / np.pi
    assert np.allclose(gathered(np.ones(len(cases), bool)), expected, rtol=1e-12)
    for i, name in enumerate(cases):  # one at a time: each alone counts or not
        alone = np.arange(len(cases)) == i
        got = gathered(alone)
        want = power[i] * white / np.pi if counts[i] else np.zeros(3)
        assert np.allclose(got, want, rtol=1e-12, atol=0), (name, got, want)
    # seen from behind the one-sided wall: nothing
    assert np.all(gathered(np.ones(len(cases), bool), wo=(0.0, 0.0, -1.0)) == 0)


@pytest.mark.parametrize("seed", [0, 1])
def test_k_nearest_distances_match_brute_force(seed):
    """The pilot's queries (methods/radii.py): the distance to the k-th nearest point around a
    point, and around a segment (distance to the segment), or inf when fewer than k lie within
    the bound."""
    rng = np.random.default_rng(seed)
    for name, pts in _clouds(rng):
        tree = _core.PointTree(np.ascontiguousarray(pts))
        for _ in range(40):
            k = int(rng.choice([1, 4, 32]))
            bound = float(rng.choice([0.05, 0.5, 5.0]))
            c = rng.uniform(-1.2, 1.2, 3)
            want = np.sort(np.linalg.norm(pts - c, axis=1))
            want = want[k - 1] if len(want) >= k and want[k - 1] < bound else np.inf
            assert tree.kth_nearest_to_point(tuple(c), k, bound) == pytest.approx(want), name
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            tmax = float(rng.uniform(0, 2))
            t = np.clip((pts - c) @ d, 0, tmax)
            dist = np.sort(np.linalg.norm(pts - c - t[:, None] * d, axis=1))
            want = dist[k - 1] if len(dist) >= k and dist[k - 1] < bound else np.inf
            got = tree.kth_nearest_to_segment(tuple(c), tuple(d), tmax, k, bound)
            assert got == pytest.approx(want), (name, k, bound)
