"""Light sampling: next-event estimation (Scene::sample_light) and light-path emission
(sample_emission), each against the density it claims, by chi-square tests.

One scene holds every light type: an ellipsoid lamp (an icosphere scaled unevenly, so its
triangles differ in area by up to ~4x), a rectangular lamp, a point light, a spot and a
directional light. The probes take the uniform numbers the renderer would draw and return
what it samples:

- the light picked follows the selection pmf (by estimated power, as docs/methods.md says);
- an area light's points are uniform by area: per triangle in proportion to its area, and
  uniform inside each triangle (counts in k^2 congruent sub-triangles);
- the pdf a sample carries is the one MIS evaluates for the same hit (Scene::area_light_pdf)
  and the geometric one, pick d^2 / (A cos); a sample's value is radiance / pdf;
- emitted directions: cosine-weighted about an area light's normal, uniform on the sphere
  for a point light, uniform in a spot's cutoff cone; a directional light's paths start
  uniformly on a disk covering the scene, perpendicular to its direction;
- each path's starting power is the light's power over its pick probability.

The controls: each histogram test rejects a density that is slightly wrong.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import stats as sps

import stats
from renderer import _core
from renderer.engine import build_native_scene
from renderer.scene import load_scene

N = 400_000
# The goodness-of-fit checks that must pass, for the family's false-alarm rate: the pick
# (2: light, emission), points by triangle area and inside triangles (2 x 2), the area
# light's cosine lobe, the point light's sphere, the spot's cone (2: cos theta, azimuth), the
# directional disk (2: r^2, azimuth). The controls, which must fail, are not counted.
N_TESTS = 2 + 4 + 1 + 1 + 2 + 2
LEVEL = stats.sidak(stats.ALPHA, N_TESTS)
SPOT_CUTOFF, SPOT_BEAM = 30.0, 20.0

SCENE = {
    "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 40},
    "film": {"width": 4, "height": 4},
    "materials": {"white": {"type": "diffuse", "reflectance": 0.5}},
    "shapes": [
        {"type": "rectangle", "material": "white",
         "transform": [{"rotate": {"axis": [1, 0, 0], "angle": -90}}, {"scale": 2},
                       {"translate": [0, -1, 0]}]},
        {"type": "sphere", "subdivisions": 1, "material": "white", "emission": [1, 2, 3],
         "transform": [{"scale": [0.4, 0.1, 0.25]}, {"translate": [0.2, 0.5, 0]}]},
        {"type": "rectangle", "material": "white", "emission": [4, 4, 2],
         "transform": [{"scale": [0.3, 0.2, 1]}, {"rotate": {"axis": [0, 1, 0], "angle": 30}},
                       {"translate": [-0.5, 0.2, -0.6]}]},
    ],
    "lights": [
        {"type": "point", "position": [0.5, 0.8, 0.3], "intensity": [2, 1, 1]},
        {"type": "spot", "position": [-0.3, 0.9, 0.2], "target": [0, -1, 0], "intensity": 3,
         "cutoff_angle": SPOT_CUTOFF, "beam_width": SPOT_BEAM},
        {"type": "directional", "direction": [0.3, -1, -0.2], "irradiance": [0.5, 0.6, 0.7]},
    ],
}  # fmt: skip
ELLIPSOID, LAMP, POINT, SPOT, SUN = range(5)  # light indices: area lights first, in order


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lights")
    (folder / "scene.yaml").write_text(yaml.safe_dump(SCENE))
    return load_scene(folder / "scene.yaml")


@pytest.fixture(scope="module")
def native(scene):
    return build_native_scene(scene)


def rgb(value) -> np.ndarray:
    return np.asarray(value, np.float64)


def emitter_triangles(scene, native, shape_index: int) -> np.ndarray:
    """Indices, in the core's triangle list, of one shape's triangles."""
    owner = np.concatenate([np.full(len(s.faces), i) for i, s in enumerate(scene.shapes)])
    return np.flatnonzero(owner[native.kept] == shape_index)


def areas(native, tris: np.ndarray) -> np.ndarray:
    t = native.triangles[tris]
    return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)


def normals(native, tris: np.ndarray) -> np.ndarray:
    t = native.triangles[tris]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def barycentrics(native, tris: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(b0, b1, b2) of each point in its triangle (least squares in the triangle's plane)."""
    t = native.triangles[tris]
    e1, e2, d = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0], points - t[:, 0]
    g = np.stack([np.einsum("ni,ni->n", a, b) for a in (e1, e2) for b in (e1, e2)], 1)
    r = np.stack([np.einsum("ni,ni->n", e1, d), np.einsum("ni,ni->n", e2, d)], 1)
    det = g[:, 0] * g[:, 3] - g[:, 1] * g[:, 2]
    b1 = (g[:, 3] * r[:, 0] - g[:, 1] * r[:, 1]) / det
    b2 = (g[:, 0] * r[:, 1] - g[:, 2] * r[:, 0]) / det
    return np.stack([1 - b1 - b2, b1, b2], 1)


def sub_triangle_counts(b: np.ndarray, k: int) -> np.ndarray:
    """Counts of barycentric points in the k^2 congruent sub-triangles of the triangle."""
    cell = np.clip(np.floor(b * k).astype(int), 0, k - 1)
    i, j = cell[:, 1], cell[:, 2]
    upward = cell[:, 0] + i + j == k - 1  # the cell's corner triangle, else the one beside it
    index = np.where(upward, (i * k + j) * 2, (i * k + j) * 2 + 1)
    counts = np.bincount(index, minlength=2 * k * k).astype(float)
    valid = np.array([2 * (a * k + c) + s for a in range(k) for c in range(k) for s in (0, 1)
                      if a + c + s <= k - 1])  # fmt: skip
    assert len(valid) == k * k and counts.sum() == counts[valid].sum()
    return counts[valid]


def expected_pmf(scene, native) -> np.ndarray:
    """Selection by estimated power (docs/methods.md): pi A mean(Le) for area lights, 4 pi
    mean(I) for points, 2 pi (1 - cos of the mean of cutoff and beam) mean(I) for spots,
    pi R^2 mean(E) for directional lights (R: the scene's bounding radius)."""
    power = []
    for index in (1, 2):
        tris = emitter_triangles(scene, native, index)
        power.append(math.pi * areas(native, tris).sum() * np.mean(scene.shapes[index].emission))
    point, spot, sun = scene.lights
    power.append(4 * math.pi * np.mean(point.intensity))
    half = math.radians(0.5 * (spot.cutoff_angle + spot.beam_width))
    power.append(2 * math.pi * (1 - math.cos(half)) * np.mean(spot.intensity))
    power.append(math.pi * native.core.scene_radius**2 * np.mean(sun.irradiance))
    power = np.array(power)
    return power / power.sum()


FROM = (0.1, -0.5, 0.4)  # a shading point below both lamps


@pytest.fixture(scope="module")
def light_samples(native):
    u = np.random.default_rng(1).random((N, 4))
    names = ("point", "wi", "value", "pdf", "light", "triangle", "valid", "delta")
    return dict(zip(names, _core.sample_light(native.core, FROM, u), strict=True))


@pytest.fixture(scope="module")
def emission_samples(native):
    u = np.random.default_rng(2).random((N, 6))
    names = ("pos", "dir", "power", "vertex_power", "light", "triangle", "has_direction")
    return dict(zip(names, _core.sample_emission(native.core, u), strict=True))


def test_the_pmf_is_by_power(scene, native):
    pmf = _core.light_pmf(native.core)
    np.testing.assert_allclose(pmf, expected_pmf(scene, native), rtol=1e-12)


@pytest.mark.parametrize("which", ["light", "emission"])
def test_lights_are_picked_by_the_pmf(native, light_samples, emission_samples, which):
    picked = (light_samples if which == "light" else emission_samples)["light"]
    pmf = _core.light_pmf(native.core)
    counts = np.bincount(picked, minlength=len(pmf))
    result = stats.chi2_test(counts, N * pmf)
    assert result.passed(LEVEL), result
    # The control: uniform picking is rejected (the pmf differs from it).
    assert not stats.chi2_test(counts, np.full(len(pmf), N / len(pmf))).passed(LEVEL)


@pytest.mark.parametrize("which", ["light", "emission"])
def test_area_light_points_are_uniform_by_area(scene, native, light_samples, emission_samples,
                                               which):  # fmt: skip
    s = light_samples if which == "light" else emission_samples
    points = s["point" if which == "light" else "pos"]
    tris = emitter_triangles(scene, native, 1)
    area = areas(native, tris)
    assert area.max() > 3 * area.min()  # unequal triangles, or the test could not tell
    mine = s["light"] == ELLIPSOID
    assert np.isin(s["triangle"][mine], tris).all()
    counts = np.array([np.count_nonzero(s["triangle"][mine] == t) for t in tris])
    by_area = stats.chi2_test(counts, mine.sum() * area / area.sum())
    assert by_area.passed(LEVEL), by_area
    equal = stats.chi2_test(counts, np.full(len(tris), mine.sum() / len(tris)))
    assert not equal.passed(LEVEL), f"equal picking passed: {equal}"
    # Inside the triangles: uniform over 16 congruent sub-triangles of each (pooled).
    b = barycentrics(native, s["triangle"][mine], points[mine])
    assert np.all(b > -1e-9) and np.all(np.abs(b.sum(axis=1) - 1) < 1e-9)
    cells = sub_triangle_counts(b, 4)
    inside = stats.chi2_test(cells, np.full(len(cells), mine.sum() / len(cells)))
    assert inside.passed(LEVEL), inside
    # The control: the warp without its square root (b1 = 1 - u1, b2 = u1 u2) is rejected.
    u1, u2 = np.random.default_rng(3).random((2, int(mine.sum())))
    wrong = sub_triangle_counts(np.stack([u1 * (1 - u2), 1 - u1, u1 * u2], 1), 4)
    rejected = stats.chi2_test(wrong, np.full(len(cells), mine.sum() / len(cells)))
    assert not rejected.passed(LEVEL), rejected


def test_area_light_pdf_and_value(scene, native, light_samples):
    s = light_samples
    pmf = _core.light_pmf(native.core)
    for light, shape in ((ELLIPSOID, 1), (LAMP, 2)):
        valid = (s["light"] == light) & (s["valid"] == 1)
        assert valid.sum() > 1000
        tris = s["triangle"][valid]
        to = s["point"][valid] - np.asarray(FROM)
        d2 = np.einsum("ni,ni->n", to, to)
        cos_l = -np.einsum("ni,ni->n", to, normals(native, tris)) / np.sqrt(d2)
        assert np.all(cos_l > 0)
        area = areas(native, emitter_triangles(scene, native, shape)).sum()
        geometric = pmf[light] * d2 / (area * cos_l)
        np.testing.assert_allclose(s["pdf"][valid], geometric, rtol=1e-10)
        mis = _core.area_light_pdf(native.core, FROM, tris.astype(np.int32), s["point"][valid])
        np.testing.assert_allclose(mis, s["pdf"][valid], rtol=1e-12)
        np.testing.assert_allclose(s["wi"][valid], to / np.sqrt(d2)[:, None], rtol=1e-12)
        le = np.asarray(scene.shapes[shape].emission, float)
        np.testing.assert_allclose(s["value"][valid], le / s["pdf"][valid][:, None], rtol=1e-12)
        assert s["delta"][valid].sum() == 0
    # Points on the back of a one-sided lamp carry nothing.
    back = (s["light"] == ELLIPSOID) & (s["valid"] == 0)
    assert back.sum() > 1000 and np.all(s["value"][back] == 0)
    # Seen from the light's own point there is no direction: the pdf is 0, not 0/0, which
    # MIS would have turned into a lost sample.
    on_lamp = np.flatnonzero((s["light"] == LAMP) & (s["valid"] == 1))[0]
    point, tri = s["point"][on_lamp], s["triangle"][on_lamp : on_lamp + 1].astype(np.int32)
    assert _core.area_light_pdf(native.core, tuple(point), tri, point[None])[0] == 0


def test_power_heuristic_passes_a_nan_on():
    """MIS weights a^2 / (a^2 + b^2); no pdf at all weighs 0, but a NaN pdf must give a NaN
    weight, so that the film counts the sample as non-finite instead of losing it unseen; so
    must a negative one. Pdfs whose squares overflow or underflow (or an infinite one) still
    get their weight, not inf / inf or 0 / 0."""
    assert _core.power_heuristic(1.0, 1.0) == 0.5 and _core.power_heuristic(2.0, 0.0) == 1.0
    assert _core.power_heuristic(0.0, 0.0) == 0.0 and _core.power_heuristic(0.0, 1e-200) == 0
    for pdfs in ((1.0, math.nan), (math.nan, 1.0), (math.inf, math.inf), (-1.0, 1.0), (1, -1e-9)):
        assert math.isnan(_core.power_heuristic(*pdfs)), pdfs
    assert _core.power_heuristic(1e-170, 1e-170) == 0.5 and _core.power_heuristic(1e-200, 0) == 1
    assert _core.power_heuristic(2e-170, 1e-170) == pytest.approx(0.8, rel=1e-15)
    assert _core.power_heuristic(math.inf, 1.0) == 1.0 and _core.power_heuristic(1.0, math.inf) == 0
    assert _core.power_heuristic(1e200, 1e200) == 0.5
    assert _core.power_heuristic(2e160, 1e160) == pytest.approx(0.8, rel=1e-15)


def mitsuba_spot_falloff(cos_angle: np.ndarray) -> np.ndarray:
    """1 within the beam width, falling linearly in angle to 0 at the cutoff (Mitsuba's spot)."""
    angle = np.arccos(np.clip(cos_angle, -1, 1))
    cutoff, beam = math.radians(SPOT_CUTOFF), math.radians(SPOT_BEAM)
    return np.clip((cutoff - angle) / (cutoff - beam), 0, 1)


def test_delta_light_values(scene, native):
    """A point or spot light's value is I falloff / (d^2 pick), a directional light's E / pick,
    seen from points all around them (inside, across and outside the spot's cone)."""
    pmf = _core.light_pmf(native.core)
    point, spot, sun = scene.lights
    rng = np.random.default_rng(4)
    axis = (spot.target - spot.position) / np.linalg.norm(spot.target - spot.position)
    for light, u_pick in ((POINT, pmf[:POINT].sum()), (SPOT, pmf[:SPOT].sum()),
                          (SUN, pmf[:SUN].sum())):  # fmt: skip
        u = np.full((1, 4), 0.5)
        u[0, 0] = u_pick + 0.5 * pmf[light]
        for x in rng.uniform(-1, 1, (200, 3)):
            s = _core.sample_light(native.core, tuple(x), u)
            assert s[4][0] == light
            value = s[2][0]
            if light == SUN:
                assert s[6][0] == 1 and s[7][0] == 1
                np.testing.assert_allclose(value, rgb(sun.irradiance) / pmf[light], rtol=1e-12)
                np.testing.assert_allclose(s[1][0], -rgb(sun.direction), rtol=1e-12)
                continue
            lamp = point if light == POINT else spot
            to = lamp.position - x
            d2 = to @ to
            falloff = 1.0
            if light == SPOT:
                falloff = mitsuba_spot_falloff(-(to / math.sqrt(d2)) @ axis)
            if falloff == 0:
                assert s[6][0] == 0 and np.all(value == 0)
            else:
                assert s[6][0] == 1 and s[7][0] == 1 and s[3][0] == 0
                expected = rgb(lamp.intensity) * falloff / (d2 * pmf[light])
                np.testing.assert_allclose(value, expected, rtol=1e-9)


def emitted(emission_samples, light: int) -> dict:
    mine = (emission_samples["light"] == light) & (emission_samples["has_direction"] == 1)
    return {k: v[mine] for k, v in emission_samples.items()}


def test_area_light_emits_cosine_weighted(scene, native, emission_samples):
    e = emitted(emission_samples, LAMP)
    normal = normals(native, e["triangle"][:1])[0]
    np.testing.assert_allclose(normals(native, e["triangle"]) @ normal, 1, rtol=1e-12)
    domain = stats.SphericalDomain(axis=tuple(normal), res_z=20, res_phi=40, hemisphere=True)

    def cosine(d):
        return np.maximum(d @ normal, 0) / math.pi

    result, _, _ = stats.SphericalChi2(lambda n: e["dir"], cosine, domain, len(e["dir"])).run()
    assert result.passed(LEVEL), result

    # The control: a cos^1.25 lobe (normalised) is rejected.
    def sharper(d):
        return np.maximum(d @ normal, 0) ** 1.25 * 2.25 / (2 * math.pi)

    wrong, _, _ = stats.SphericalChi2(lambda n: e["dir"], sharper, domain, len(e["dir"])).run()
    assert not wrong.passed(LEVEL), wrong
    pmf = _core.light_pmf(native.core)[LAMP]
    area = areas(native, emitter_triangles(scene, native, 2)).sum()
    le = np.asarray(scene.shapes[2].emission, float)
    np.testing.assert_allclose(e["power"], np.tile(le * math.pi * area / pmf, (len(e["dir"]), 1)),
                               rtol=1e-12)  # fmt: skip
    np.testing.assert_allclose(e["vertex_power"], e["power"] / math.pi, rtol=1e-12)


def test_point_light_emits_uniformly(scene, native, emission_samples):
    e = emitted(emission_samples, POINT)
    point = scene.lights[0]
    np.testing.assert_allclose(e["pos"], np.tile(point.position, (len(e["pos"]), 1)), rtol=0)
    domain = stats.SphericalDomain(axis=(0.2, 0.3, 0.9), res_z=20, res_phi=40)
    uniform = stats.SphericalChi2(lambda n: e["dir"], lambda d: np.full(len(d), 0.25 / math.pi),
                                  domain, len(e["dir"]))  # fmt: skip
    result, _, _ = uniform.run()
    assert result.passed(LEVEL), result
    pmf = _core.light_pmf(native.core)[POINT]
    np.testing.assert_allclose(e["power"][0], rgb(point.intensity) * 4 * math.pi / pmf, rtol=1e-12)


def test_spot_emits_uniformly_in_its_cone(scene, native, emission_samples):
    e = emitted(emission_samples, SPOT)
    spot = scene.lights[1]
    axis = (spot.target - spot.position) / np.linalg.norm(spot.target - spot.position)
    cos_cut = math.cos(math.radians(SPOT_CUTOFF))
    # Uniform in the cone: cos theta uniform on [cos cutoff, 1], the azimuth uniform.
    z = e["dir"] @ axis
    basis = stats.frame(axis)
    phi = np.mod(np.arctan2(e["dir"] @ basis[1], e["dir"] @ basis[0]), 2 * math.pi)
    assert stats.ks_test(z, sps.uniform(cos_cut, 1 - cos_cut).cdf) > LEVEL
    assert stats.ks_test(phi, sps.uniform(0, 2 * math.pi).cdf) > LEVEL
    # The control: a cone 2 % narrower in solid angle is rejected.
    narrower = 1 - 0.98 * (1 - cos_cut)
    assert stats.ks_test(z, sps.uniform(narrower, 1 - narrower).cdf) < LEVEL
    pmf = _core.light_pmf(native.core)[SPOT]
    falloff = mitsuba_spot_falloff(e["dir"] @ axis)
    expected = rgb(spot.intensity) * (falloff * 2 * math.pi * (1 - cos_cut) / pmf)[:, None]
    np.testing.assert_allclose(e["power"], expected, rtol=1e-9, atol=1e-12)


def test_directional_light_starts_on_a_disk_covering_the_scene(scene, native, emission_samples):
    e = emitted(emission_samples, SUN)
    sun = scene.lights[2]
    direction = sun.direction / np.linalg.norm(sun.direction)
    np.testing.assert_allclose(e["dir"], np.tile(direction, (len(e["dir"]), 1)), rtol=1e-12)
    radius = 1.01 * native.core.scene_radius
    centre = np.asarray(native.core.scene_center) - direction * radius
    # The disk the core reports is this one.
    core_centre, core_radius = native.core.directional_disk(tuple(direction))
    assert core_radius == pytest.approx(radius, rel=1e-15)
    np.testing.assert_allclose(core_centre, centre, rtol=1e-12, atol=1e-12)
    offset = e["pos"] - centre
    np.testing.assert_allclose(offset @ direction, 0, atol=1e-12)
    r2 = np.einsum("ni,ni->n", offset, offset) / radius**2
    assert r2.max() <= 1 + 1e-12
    basis = stats.frame(direction)
    phi = np.mod(np.arctan2(offset @ basis[1], offset @ basis[0]), 2 * math.pi)
    # Uniform on the disk: r^2 and the azimuth each uniform on their ranges.
    assert stats.ks_test(r2, sps.uniform(0, 1).cdf) > LEVEL
    assert stats.ks_test(phi, sps.uniform(0, 2 * math.pi).cdf) > LEVEL
    assert stats.ks_test(np.sqrt(r2), sps.uniform(0, 1).cdf) < LEVEL  # the control
    pmf = _core.light_pmf(native.core)[SUN]
    expected = rgb(sun.irradiance) * math.pi * radius**2 / pmf
    np.testing.assert_allclose(e["power"], np.tile(expected, (len(e["pos"]), 1)), rtol=1e-12)


def test_each_light_of_the_scene_knows_its_index_in_the_core():
    """Area lights are added to the core first, then the scene's `lights` in order, each
    binding returning its index: light paths pick the medium a light emits into by it."""
    scene = load_scene(
        Path(__file__).resolve().parent.parent / "scenes" / "cbox" / "scene.yaml",
        [
            "lights=[{type: point, position: [0, 0.5, 0], intensity: 1}, "
            "{type: spot, position: [0, 0.9, 0], target: [0, -1, 0], intensity: 1, "
            "cutoff_angle: 30, beam_width: 20}, "
            "{type: directional, direction: [0, -1, 0.1], irradiance: 1}]"
        ],
    )
    native = build_native_scene(scene)
    area = sum(shape.emission is not None for shape in scene.shapes)
    assert area == 1 and native.light_ids == [1, 2, 3] and native.core.light_count == 4
