"""The records of complete light subpaths (cpp/path_records.h): every vertex, delta ones and the
light's own included, with the densities MIS needs. Each density is recomputed here from the
vertices' positions alone (the scene's geometry, BSDFs, phase function and lights, and the
fog's extent for the free-flight probability) and must agree with the kernel's."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from renderer import _core
from renderer.methods.lt import LightTracing
from renderer.scene import load_scene
from renderer.scene.loader import find_scene_file

SIGMA = 1.0  # the fog's extinction
# The fog encloses the whole box, so that no straight piece between vertices inside it crosses
# a boundary: paths cross one only to leave by the open front or, from the directional light,
# to come in. (Every crossing offsets the next ray by ~1e-5 off the straight line from the last
# vertex, which at grazing incidence shifts a piece's length by up to ~1e-3 of the fog's.)
FOG_BOX = (np.full(3, -1.01), np.full(3, 1.01))
GLASS_BOX = (np.array([0.0, -0.5, -0.1]), np.array([0.4, -0.1, 0.3]))
IOR = 1.5
HG_G = 0.5


@pytest.fixture(scope="module")
def subpaths(tmp_path_factory):
    """Complete subpaths through a fog-filled box with a glass block in it, from an area light,
    a point light and a spot light in the fog and a directional light outside it."""
    folder = tmp_path_factory.mktemp("records")
    box = find_scene_file("cbox").parent / "box.yaml"
    (folder / "scene.yaml").write_text(
        textwrap.dedent(f"""\
        include: {box}
        film: {{width: 8, height: 8}}
        integrator: {{max_depth: 8, rr_depth: 8}}
        media: {{fog: {{type: homogeneous, sigma_t: {SIGMA}, albedo: 0.8,
                       phase: {{type: hg, g: {HG_G}}}}}}}
        materials:
          boundary: {{type: "null"}}
          glass: {{type: dielectric, ior: {IOR}}}
        shapes:
          - {{name: fog, type: cube, material: boundary, interior: fog,
              transform: [{{scale: 1.01}}]}}
          - {{name: block, type: cube, material: glass, exterior: fog,
              transform: [{{scale: 0.2}}, {{translate: [0.2, -0.3, 0.1]}}]}}
        lights:
          - {{type: point, position: [0.3, 0.5, 0.2], intensity: 2}}
          - {{type: spot, position: [-0.5, 0.8, 0.3], target: [-0.4, -1, 0.2], intensity: 3,
              cutoff_angle: 30}}
          - {{type: directional, direction: [0.1, -0.3, -1], irradiance: 1}}
        """)
    )
    scene = load_scene(folder / "scene.yaml")
    subpaths.scene_file = folder / "scene.yaml"
    lt = LightTracing(scene, seed=4, threads=2, params={"light_paths": 4096})
    wave = lt.light_paths_wavefront(4096, "light_paths", 1 << 22)
    wave.kernel.set_recording(True, False, True)
    wave.run(0)
    return scene, lt.native, wave.kernel.vertices()


@pytest.fixture(scope="module")
def camera_subpaths(subpaths):
    """Camera subpaths through the same scene (bdpt's), 64 samples per pixel."""
    from renderer.methods.bdpt import BidirectionalPathTracing

    scene, _, _ = subpaths
    bdpt = BidirectionalPathTracing(scene, seed=5, threads=2, params={"spp_per_iteration": 64})
    bdpt.camera_paths.run(0)
    return scene, bdpt.native, bdpt.camera_paths.kernel.vertices()


def inside_length(a: np.ndarray, b: np.ndarray, box) -> float:
    """Length of the segment a -> b inside an axis-aligned box (slab test)."""
    lo, hi = box
    d = b - a
    t0, t1 = 0.0, 1.0
    for k in range(3):
        if d[k] == 0:
            if not lo[k] <= a[k] <= hi[k]:
                return 0.0
            continue
        ta, tb = sorted(((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]))
        t0, t1 = max(t0, ta), min(t1, tb)
    return max(0.0, t1 - t0) * float(np.linalg.norm(d))


def transmittance(a: np.ndarray, b: np.ndarray) -> float:
    """The fog fills its box but for the glass block."""
    fog = inside_length(a, b, FOG_BOX) - inside_length(a, b, GLASS_BOX)
    return math.exp(-SIGMA * fog)


def hg(cos_theta: float) -> float:
    denom = 1 + HG_G * HG_G - 2 * HG_G * cos_theta
    return (1 - HG_G * HG_G) / (4 * math.pi * denom**1.5)


def fresnel(cos_i: float, eta: float) -> float:
    sin2_t = (1 - cos_i * cos_i) / (eta * eta)
    if sin2_t >= 1:
        return 1.0
    cos_t = math.sqrt(1 - sin2_t)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


class Geometry:
    """What the densities need of the scene, in the core's numbering."""

    def __init__(self, scene, native) -> None:
        self.normals = native.normals
        materials = [scene.materials[s.material].type for s in scene.shapes]
        self.material = native.per_triangle(scene, materials)
        self.light_kind = {}  # core light index -> kind, area lights first
        area = sum(1 for s in scene.shapes if s.emission is not None)
        for i in range(area):
            self.light_kind[i] = "area"
        for i, light in enumerate(scene.lights):
            self.light_kind[native.light_ids[i]] = type(light).__name__
        self.lights = {native.light_ids[i]: light for i, light in enumerate(scene.lights)}
        pick = _core.light_pmf(native.core)
        self.pick = pick
        from renderer.engine import camera_basis

        self.forward, self.right, self.up = camera_basis(scene.camera, scene.film)
        self.disk_radius = {
            i: native.core.directional_disk(tuple(light.direction))[1]
            for i, light in self.lights.items()
            if type(light).__name__ == "DirectionalLight"
        }

    def direction_pdf(self, v: dict, out: np.ndarray, came_from: np.ndarray | None) -> float:
        """Density of sampling direction `out` at vertex v; `came_from` is the unit direction
        towards the vertex the walk arrived from (None at a light)."""
        kind = v["kind"]
        if kind == 3:  # the camera: uniform over the film, per solid angle 1 / (A cos^3)
            cos_theta = float(out @ self.forward)
            q = out / cos_theta
            inside = abs(q @ self.right) <= self.right @ self.right
            inside &= abs(q @ self.up) <= self.up @ self.up
            area = 4 * np.linalg.norm(self.right) * np.linalg.norm(self.up)
            return 1 / (area * cos_theta**3) if cos_theta > 0 and inside else 0.0
        if kind == 0:  # the light's own vertex
            light = self.light_kind[v["light"]]
            if light == "area":
                return max(0.0, float(self.normals[v["triangle"]] @ out)) / math.pi
            if light == "PointLight":
                return 1 / (4 * math.pi)
            if light == "SpotLight":
                cos_cutoff = math.cos(math.radians(self.lights[v["light"]].cutoff_angle))
                return 1 / (2 * math.pi * (1 - cos_cutoff))
            return 1 / (math.pi * self.disk_radius[v["light"]] ** 2)  # directional: its disk
        if kind == 2:
            return hg(float(-came_from @ out))  # the angle between the travel in and out
        n = self.normals[v["triangle"]]
        material = self.material[v["triangle"]]
        if material == "diffuse":
            return max(0.0, float(n @ out)) / math.pi
        assert material == "dielectric"
        cos_wi = float(came_from @ n)
        reflected = (float(out @ n) > 0) == (cos_wi > 0)
        F = fresnel(abs(cos_wi), IOR if cos_wi > 0 else 1 / IOR)
        return F if reflected else 1 - F

    def change_of_measure(self, v: dict, towards: np.ndarray) -> float:
        """|cos| at a surface vertex for the unit direction `towards` it, or the extinction."""
        if v["kind"] == 2:
            return SIGMA
        return abs(float(self.normals[v["triangle"]] @ towards))


def as_paths(vertices: dict) -> list[list[dict]]:
    order = np.lexsort((vertices["depth"], vertices["path"]))
    rows = [{k: vertices[k][i] for k in vertices} for i in order]
    paths: dict[int, list[dict]] = {}
    for row in rows:
        paths.setdefault(int(row["path"]), []).append(row)
    return list(paths.values())


def test_complete_subpaths_keep_every_vertex(subpaths):
    """One vertex per event, the light's first (every light type), delta vertices flagged."""
    _, _, vertices = subpaths
    paths = as_paths(vertices)
    assert len(paths) == 4096
    for path in paths:
        assert [int(v["depth"]) for v in path] == list(range(len(path)))
        assert path[0]["kind"] == 0 and path[0]["light"] >= 0
    kinds = {int(v["light"]) for path in paths for v in path[:1]}
    assert len(kinds) == 4  # the area light and the three others all emitted
    delta_surfaces = vertices["delta"][vertices["kind"] == 1]
    assert delta_surfaces.any() and not delta_surfaces.all()


def test_densities_are_what_the_walk_sampled(subpaths):
    """pdf_fwd of every vertex and pdf_rev of every vertex with two after it, recomputed."""
    scene, native, vertices = subpaths
    geometry = Geometry(scene, native)
    fwd_checked = rev_checked = crossing = 0
    for path in as_paths(vertices):
        light = path[0]
        kind = geometry.light_kind[int(light["light"])]
        pick = geometry.pick[int(light["light"])]
        if kind == "area":
            area = 0.5 * 0.4  # box.yaml's lamp
            assert light["pdf_fwd"] == pytest.approx(pick / area, rel=1e-9)
            assert not light["delta"]
        else:
            assert light["pdf_fwd"] == pytest.approx(pick, rel=1e-12) and light["delta"]
            assert light["pdf_rev"] == 0
        for i in range(1, len(path)):
            prev, v = path[i - 1], path[i]
            a, b = prev["position"], v["position"]
            d = b - a
            dist = float(np.linalg.norm(d))
            out = d / dist
            came_from = None if i == 1 else prev["wi"]
            pdf_dir = geometry.direction_pdf(prev, out, came_from)
            flight = transmittance(a, b) * geometry.change_of_measure(v, -out)
            at_infinity = i == 1 and kind == "DirectionalLight"
            expected = pdf_dir * flight / (1 if at_infinity else dist * dist)
            # An edge that crosses the fog's boundary (into the box from the directional light,
            # or out by the open front) carries the offset of the ray spawned there: at grazing
            # incidence its piece in the fog is off by up to ~10 offsets (~4e-4).
            crosses = inside_length(a, b, FOG_BOX) < dist * (1 - 1e-12)
            rel = 2e-3 if crosses else 1e-7
            assert v["pdf_fwd"] == pytest.approx(expected, rel=rel, abs=1e-300), (i, v, prev)
            fwd_checked += 1
            crossing += crosses
            if i + 1 < len(path) and not (prev["kind"] == 0 and prev["delta"]):
                nxt = path[i + 1]["position"] - b
                nxt = nxt / np.linalg.norm(nxt)
                pdf_back = geometry.direction_pdf(v, -out, nxt)
                back = transmittance(b, a) * geometry.change_of_measure(prev, out)
                expected = pdf_back * back / (dist * dist)
                assert prev["pdf_rev"] == pytest.approx(expected, rel=rel, abs=1e-300), (i, prev)
                rev_checked += 1
    assert fwd_checked > 10_000 and rev_checked > 5_000 and crossing < fwd_checked / 10


def test_connectible_records_carry_no_densities(subpaths):
    """What lt, pm and ppb record by default: no densities, no light vertex but an area
    light's, no delta surface."""
    scene, _, _ = subpaths
    lt = LightTracing(scene, seed=4, threads=2, params={"light_paths": 1024})
    wave = lt.light_paths_wavefront(1024, "light_paths", 1 << 22)
    wave.run(0)
    v = wave.kernel.vertices()
    assert not v["pdf_fwd"].any() and not v["pdf_rev"].any()
    assert not v["delta"].any()
    assert np.all(v["triangle"][v["kind"] == 0] >= 0)


def test_grid_flight_depth_is_exact_where_the_density_is_constant():
    """The stand-in optical depth in a density grid (medium.h, flight_depth) through cells of
    constant density (fog-step's halves): the closed form."""
    from conftest import load_small
    from renderer.engine import build_native_scene

    scene = load_small("fog-step", 8, 8)
    native = build_native_scene(scene)
    sigma = float(scene.media["fog"].sigma_t[0])
    thin, dense = (0.1, 2.0)  # the step's values (scene file), left and right half
    for x0, value in ((-0.9, thin), (0.3, dense)):
        origin, length = (x0, 0.0, 0.0), 0.5
        tau = native.core.flight_depth(0, origin, (1.0, 0.0, 0.0), length)
        assert tau == pytest.approx(sigma * value * length, rel=1e-6)  # float32 grid values
    assert native.core.flight_depth(0, (-0.6, -0.2, 0.1), (1.0, 0.0, 0.0), 0.0) == 0


@pytest.mark.parametrize("name", ["fog-step", "cloud"])
def test_grid_flight_depth_is_the_integral_of_the_density(name):
    """Anywhere else the stand-in is the exact integral of the interpolated density (Simpson's
    rule between voxel-centre planes, where the trilinear density is a cubic): against a fine
    midpoint quadrature on random lines through the grid, across fog-step's step and through
    the cloud's ragged edge, where cells hold both core and vacuum (the mean of a cell's bounds
    was off there by optical depths of 10 and more)."""
    from conftest import load_small
    from renderer.engine import build_native_scene

    scene = load_small(name, 8, 8)
    native = build_native_scene(scene)
    sigma = float(next(iter(scene.media.values())).sigma_t[0])
    rng = np.random.default_rng(7)
    for _ in range(40):
        origin = rng.uniform(-1.2, 1.2, 3)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        length = rng.uniform(0.01, 2.5)
        tau = native.core.flight_depth(0, tuple(origin), tuple(direction), length)
        n = 200_000
        t = (np.arange(n) + 0.5) / n * length
        points = np.ascontiguousarray(origin + t[:, None] * direction)
        density = native.core.density(0, points)
        true = sigma * density.mean() * length
        # The quadrature's own error: the density jumps to 0 where the line leaves the grid's
        # box (up to half a step's worth at each of two crossings); elsewhere it is smooth.
        jumps = 2 * sigma * density.max() * length / n
        assert tau == pytest.approx(true, rel=1e-6, abs=jumps + 1e-9), (origin, direction, length)


def test_camera_subpaths_densities_are_what_the_walk_sampled(camera_subpaths):
    """Camera subpaths (bdpt's): the camera's vertex first (density 1), the first hit sampled
    uniformly over the film (1 / (A_film cos^3) per solid angle), then as light paths do: each
    pdf_fwd and each pdf_rev with two vertices after it, recomputed from the positions."""
    scene, native, vertices = camera_subpaths
    geometry = Geometry(scene, native)
    fwd_checked = rev_checked = 0
    for path in as_paths(vertices):
        assert path[0]["kind"] == 3 and path[0]["pdf_fwd"] == 1
        assert [int(v["depth"]) for v in path] == list(range(len(path)))
        for i in range(1, len(path)):
            prev, v = path[i - 1], path[i]
            a, b = prev["position"], v["position"]
            dist = float(np.linalg.norm(b - a))
            out = (b - a) / dist
            pdf_dir = geometry.direction_pdf(prev, out, None if i == 1 else prev["wi"])
            expected = pdf_dir * transmittance(a, b) * geometry.change_of_measure(v, -out) / dist**2
            crosses = inside_length(a, b, FOG_BOX) < dist * (1 - 1e-12)
            rel = 2e-3 if crosses else 1e-7
            assert v["pdf_fwd"] == pytest.approx(expected, rel=rel, abs=1e-300), (i, v, prev)
            fwd_checked += 1
            if i + 1 < len(path) and prev["kind"] != 3:
                nxt = path[i + 1]["position"] - b
                nxt = nxt / np.linalg.norm(nxt)
                back = geometry.direction_pdf(v, -out, nxt)
                expected = back * transmittance(b, a) * geometry.change_of_measure(prev, out)
                expected /= dist**2
                assert prev["pdf_rev"] == pytest.approx(expected, rel=rel, abs=1e-300), (i, prev)
                rev_checked += 1
    assert fwd_checked > 5000 and rev_checked > 1000, (fwd_checked, rev_checked)
