"""The photon-beam BVH (cpp/beams.h) against brute force on random beams and rays.

For every (ray, beam) pair, brute force computes the closest approach of the two lines in
numpy and keeps the pairs whose distance is below the radius with both closest points on
their segments; the BVH must report exactly those pairs, each once, with the same parameters.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderer import _core

MIN_SINE = 1e-4  # kMinBeamSine: nearly parallel pairs are skipped


def random_beams(rng: np.random.Generator, n: int, long: bool):
    origins = rng.uniform(-1, 1, (n, 3))
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    lengths = rng.exponential(1.5 if long else 0.2, n)
    return origins, dirs, lengths


def brute_force(origins, dirs, lengths, ray_o, ray_d, ray_t, radius):
    """Set of (ray, beam) pairs and their (t_beam, t_ray, distance, sin)."""
    found = {}
    for i, (o, d, tmax) in enumerate(zip(ray_o, ray_d, ray_t, strict=True)):
        n = np.cross(dirs, d)
        sin2 = (n**2).sum(1)
        w = o - origins
        s = np.einsum("ij,ij->i", np.cross(w, d), n) / sin2
        t = np.einsum("ij,ij->i", np.cross(w, dirs), n) / sin2
        sin = np.sqrt(sin2)
        dist = np.abs(np.einsum("ij,ij->i", w, n)) / sin
        ok = (
            (sin >= MIN_SINE) & (dist < radius) & (t >= 0) & (t <= tmax) & (s >= 0) & (s <= lengths)
        )
        for j in np.flatnonzero(ok):
            found[(i, int(j))] = (s[j], t[j], dist[j], sin[j])
    return found


@pytest.mark.parametrize(
    "long,piece", [(False, 0.0), (True, 0.0), (True, 0.1), (True, 0.5)], ids=str
)
def test_queries_match_brute_force(long, piece):
    rng = np.random.default_rng(7 + int(long) + int(10 * piece))
    origins, dirs, lengths = random_beams(rng, 3000, long)
    radius = 0.03
    bvh = _core.BeamBvh(1 << 20)
    bvh.build(origins, dirs, lengths, radius, piece)
    assert bvh.beam_count == 3000 and bvh.truncated == 0
    if piece > 0:
        assert bvh.piece_count > 3000  # long beams were split
    nrays = 300
    ray_o = rng.uniform(-1.5, 1.5, (nrays, 3))
    ray_d = rng.normal(size=(nrays, 3))
    ray_d /= np.linalg.norm(ray_d, axis=1, keepdims=True)
    ray_t = rng.uniform(0.5, 3.0, nrays)
    ray_t[:20] = np.inf  # rays that escape
    ray, beam, tb, tr, dist, sin = bvh.query(ray_o, ray_d, ray_t)
    expected = brute_force(origins, dirs, lengths, ray_o, ray_d, ray_t, radius)
    got = list(zip(ray.tolist(), beam.tolist(), strict=True))
    assert len(got) == len(set(got)), "a pair was reported twice"
    # Pairs on the very edge of a test (float rounding) may differ; there are none in practice.
    assert set(got) == set(expected), (
        f"missing {len(set(expected) - set(got))}, extra {len(set(got) - set(expected))}"
    )
    assert len(expected) > 100  # the test exercises many pairs
    want = np.array([expected[p] for p in got])
    np.testing.assert_allclose(np.stack([tb, tr, dist, sin], 1), want, rtol=1e-9, atol=1e-9)


def test_k_nearest_beams_match_brute_force():
    """The pilot's beam query (methods/radii.py), on a tree of radius 0: the k-th smallest
    distance among the pairs brute force finds within a bound, or inf when fewer than k."""
    rng = np.random.default_rng(5)
    origins, dirs, lengths = random_beams(rng, 2000, True)
    bvh = _core.BeamBvh(1 << 20)
    bvh.build(origins, dirs, lengths, 0.0, 0.1)
    nrays = 200
    ray_o = rng.uniform(-1.5, 1.5, (nrays, 3))
    ray_d = rng.normal(size=(nrays, 3))
    ray_d /= np.linalg.norm(ray_d, axis=1, keepdims=True)
    ray_t = rng.uniform(0.5, 3.0, nrays)
    for k, bound in ((1, 0.05), (8, 0.2), (64, 0.2)):
        got = bvh.kth_nearest(ray_o, ray_d, ray_t, k, bound)
        pairs = brute_force(origins, dirs, lengths, ray_o, ray_d, ray_t, bound)
        for i in range(nrays):
            dist = sorted(v[2] for (r, _), v in pairs.items() if r == i)
            want = dist[k - 1] if len(dist) >= k else np.inf
            assert got[i] == pytest.approx(want, rel=1e-9), (i, k, bound)
        assert np.isfinite(got).sum() > 20  # the test exercises found and unfound alike


def test_memory_bound_truncates_and_counts():
    rng = np.random.default_rng(3)
    origins, dirs, lengths = random_beams(rng, 500, True)
    bvh = _core.BeamBvh(200)
    bvh.build(origins, dirs, lengths, 0.05, 0.05)
    assert bvh.beam_count == 200
    assert bvh.truncated == 300
    # Pieces stay within their bound (16 per beam on average) by growing longer.
    assert bvh.piece_count <= 16 * 200 + 200
    assert bvh.piece_length >= lengths[:200].sum() / 3200 - 1e-12
    # Kept beams are the first ones, in order: queries only ever report them.
    ray, beam, *_ = bvh.query(np.zeros((50, 3)), rng.normal(size=(50, 3)), np.full(50, 5.0))
    assert len(beam) == 0 or beam.max() < 200


def test_empty_and_degenerate_beams():
    bvh = _core.BeamBvh(100)
    bvh.build(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), 0.1, 0.0)
    ray, *_ = bvh.query(np.zeros((1, 3)), np.array([[1.0, 0, 0]]), np.array([1.0]))
    assert len(ray) == 0
    # Zero-length beams are not stored.
    bvh.build(np.zeros((2, 3)), np.array([[0, 1.0, 0], [0, 0, 1.0]]), np.array([0.0, 1.0]), 0.1, 0)
    assert bvh.beam_count == 1
