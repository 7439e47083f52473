"""lt (light tracing) and the shared light-path tracer (cpp/subpaths.h).

Parity: lt's image must agree with Mitsuba's volpath and with our pt on cbox and
cbox-fog (32x32), judged by z-scores from measured variance (tests/parity.py); the
camera importance We = 1 / (A_pix cos^4) is what makes the absolute level match.
Lights of every type (point, spot, directional; lights inside a medium, found by the
scene's rule) are checked against pt on small scenes of their own; the rule itself (the
walk from the camera, docs/scene-format.md "Where lights emit") is checked at the end.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from conftest import load_small
from parity import ALPHA, Estimate, agreement, mitsuba, ours, same_image_coarse_and_fine
from renderer.engine import build_native_scene
from renderer.errors import PgiError
from renderer.methods.lt import LightTracing
from renderer.methods.pt import PathTracing
from renderer.scene import load_scene

RES = 32
# (scene, lt iterations x light paths, pt iterations x spp, Mitsuba passes x spp). In fog,
# pt's and Mitsuba's per-pixel estimates are heavy-tailed at a few dozen spp per image (rare
# paths that find the light after scattering: medians well below means), so 32 images
# underestimate their variance and pixel z-scores overshoot (max |z| 6.7 against pt at 16 spp);
# 128 spp per image tames the tails (4.5 and 4.2, where the limit at ALPHA = 1e-4 is 5.5).
CASES = [
    ("cbox", 32, 1 << 15, 32, 16, 32, 32),
    ("cbox-fog", 32, 1 << 15, 32, 128, 32, 128),
]


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def estimates(request):
    name, iters, paths, pt_iters, spp, passes, mspp = request.param
    scene = load_small(name, RES, RES)
    lt = ours(LightTracing, scene, iters, light_paths=paths)
    pt = ours(PathTracing, scene, pt_iters, seed=2, spp_per_wave=spp)
    return name, lt, pt, mitsuba(scene, passes, mspp)


def _agrees(a, b) -> tuple[bool, str]:
    """Image mean; 8x8 blocks (chi-square: their means are close to normal even in fog,
    where 4x4 blocks of 32 images still have heavy tails that inflate it); 4x4 blocks by
    the Bonferroni bound on |z|."""
    return same_image_coarse_and_fine(a, b, ALPHA)


def _check(a, b, label: str) -> None:
    agrees, detail = _agrees(a, b)
    assert agrees, f"{label}: {detail}"


@pytest.mark.parametrize("other", ["pt", "mitsuba"])
def test_lt_mean_and_blocks_match(estimates, other):
    name, lt, pt, mi = estimates
    _check(lt, pt if other == "pt" else mi, f"{name} vs {other}")


@pytest.mark.parametrize("other", ["pt", "mitsuba"])
def test_lt_pixels_match(estimates, other):
    """Pixel by pixel (Bonferroni bound on |z|)."""
    name, lt, pt, mi = estimates
    result = agreement(lt, pt if other == "pt" else mi, ALPHA)
    assert result.z_ok, f"{name} vs {other}: {result}"


@pytest.mark.parametrize("other", ["pt", "mitsuba"])
def test_lt_checks_have_power(estimates, other):
    """The controls of the two tests above: lt's images 3 % darker or brighter fail, and so
    does a 5 % loss in any one quadrant of the image alone, also where the image mean still
    agrees (measured: the lower quadrants' loss passes the mean check on both scenes and
    fails the block checks)."""
    name, lt, pt, mi = estimates
    ref = pt if other == "pt" else mi
    for scale in (0.97, 1.03):
        agrees, detail = _agrees(Estimate(lt.samples * scale), ref)
        assert not agrees, f"{name} vs {other}: lt x {scale} passed: {detail}"
    half = RES // 2
    for rows in (slice(0, half), slice(half, RES)):
        for cols in (slice(0, half), slice(half, RES)):
            samples = lt.samples.copy()
            samples[:, rows, cols] *= 0.95
            agrees, detail = _agrees(Estimate(samples), ref)
            assert not agrees, f"{name} vs {other}: a quadrant 5 % darker passed: {detail}"


# A slab of chromatic fog over a floor (its bottom face below the floor: coplanar faces
# would make the medium at the floor ambiguous), lit by a point light and a spot light above it:
# light paths start in vacuum (where the walk from the camera ends), enter the fog through its null
# boundary, and both emitters are sampled. (Lights inside the fog would give pt's
# next-event estimation infinite variance -- I / r^2 at fog vertices near the light --
# which a z-test cannot judge; cbox-fog covers lights inside a medium.)
_DELTA_LIGHTS = """
    name: delta-lights
    description: point and spot lights above a fog slab
    integrator: {max_depth: 6, rr_depth: 5}
    camera: {origin: [0, 0, 3.9], target: [0, 0, 0], up: [0, 1, 0], fov: 39.3}
    film: {width: 16, height: 16}
    media:
      fog: {type: homogeneous, sigma_t: [0.6, 0.8, 1.0], albedo: 0.8, phase: {type: hg, g: 0.4}}
    materials:
      white: {type: diffuse, reflectance: [0.7, 0.6, 0.5]}
      boundary: {type: "null"}
    shapes:
      - {name: floor, type: rectangle, material: white,
         transform: [{rotate: {axis: [1, 0, 0], angle: -90}}, {translate: [0, -1, 0]}]}
      - {name: back, type: rectangle, material: white, transform: [{translate: [0, 0, -1]}]}
      - {name: fog-slab, type: cube, material: boundary, interior: fog,
         transform: [{scale: [0.99, 0.405, 0.99]}, {translate: [0, -0.605, 0]}]}
    lights:
      - {type: point, position: [0.3, 0.5, 0], intensity: [2, 2, 2]}
      - {type: spot, position: [-0.4, 0.8, -0.2], target: [-0.2, -1, 0], intensity: 6,
         cutoff_angle: 30, beam_width: 20}
"""


def _vs_pt(scene, lt_iters: int, paths: int, pt_iters: int, spp: int) -> Estimate:
    """lt agrees with pt, and the check has power: lt's images 5 % darker or brighter fail.
    Returns pt's estimate."""
    lt = ours(LightTracing, scene, lt_iters, light_paths=paths)
    pt = ours(PathTracing, scene, pt_iters, seed=3, spp_per_wave=spp)
    _check(lt, pt, "lt vs pt")
    for scale in (0.95, 1.05):
        agrees, detail = _agrees(Estimate(lt.samples * scale), pt)
        assert not agrees, f"lt x {scale} passed: {detail}"
    return pt


def test_point_and_spot_lights_in_fog_match_pt(tmp_path):
    (tmp_path / "scene.yaml").write_text(textwrap.dedent(_DELTA_LIGHTS))
    _vs_pt(load_scene(tmp_path / "scene.yaml"), 24, 1 << 14, 24, 64)


# The same scene lit by a directional light from above the camera (a disk beyond the
# scene's bounding sphere emits it). The camera stays outside the fog: with the camera
# inside a medium, light tracing has infinite variance (vertices arbitrarily close to
# the camera receive importance ~ 1 / d^2), which a z-test cannot judge.
_DIRECTIONAL = (
    _DELTA_LIGHTS.replace("point and spot lights", "a directional light").split("    lights:")[0]
    + "    lights:\n      - {type: directional, direction: [0.2, -1, -0.5], irradiance: 3}\n"
)


def test_directional_light_matches_pt(tmp_path):
    (tmp_path / "scene.yaml").write_text(textwrap.dedent(_DIRECTIONAL))
    _vs_pt(load_scene(tmp_path / "scene.yaml"), 24, 1 << 14, 24, 64)


def test_directional_light_of_a_scene_away_from_the_origin_matches_pt(tmp_path):
    """The sun's disk is centred on the scene's bounding sphere, not on the world's origin:
    centred there, this scene moved by 1 along x was 20 % dark in lt, and black moved by 3."""
    text = textwrap.dedent(_DIRECTIONAL)
    for old, new in (
        ("origin: [0, 0, 3.9], target: [0, 0, 0]", "origin: [1, 0, 3.9], target: [1, 0, 0]"),
        ("{translate: [0, -1, 0]}", "{translate: [1, -1, 0]}"),
        ("{translate: [0, 0, -1]}", "{translate: [1, 0, -1]}"),
        ("{translate: [0, -0.605, 0]}", "{translate: [1, -0.605, 0]}"),
    ):
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    (tmp_path / "scene.yaml").write_text(text)
    _vs_pt(load_scene(tmp_path / "scene.yaml"), 24, 1 << 14, 24, 64)


def test_lights_placed_on_surfaces_match_pt():
    """A spot set into the ceiling and a point light on the floor: light paths start an offset
    off the light, as pt's shadow rays stop short of it. Started on the light itself, every
    path hit the ceiling's back at distance 0 and lt was black; the floor light's paths
    bounced off the floor first (its reflectance, 0.725, too little light)."""
    lights = (
        "lights=[{type: spot, position: [0.6, 1, 0], target: [0.6, -1, 0], intensity: 5, "
        "cutoff_angle: 60}, {type: point, position: [-0.3, -1, 0.2], intensity: 1}]"
    )
    scene = load_small("cbox", 16, 16, ("shapes[7].emission=0", lights))
    _vs_pt(scene, 16, 1 << 13, 16, 64)


def test_an_emitter_of_unequal_triangles_matches_pt_and_mitsuba():
    """Emitting triangles are picked by area, by pt's light sampling and by the light tracer's
    emission. Rectangles are two triangles of equal area, where a uniform pick gives the same
    image; this lamp is a flat box of 12 triangles of 0.008 to 0.1 in area (picked uniformly,
    pt was 9 % too bright and lt 39 %)."""
    lamp = (
        "shapes[7]={name: light, type: cube, material: light, emission: [18.4, 14.0, 6.75], "
        "transform: [{scale: [0.25, 0.02, 0.2]}, {translate: [0, 0.95, 0]}]}"
    )
    scene = load_small("cbox", 16, 16, (lamp,))
    pt = _vs_pt(scene, 16, 1 << 13, 32, 64).image_mean()
    mi = mitsuba(scene, 32, 64).image_mean()
    assert agreement(pt, mi, ALPHA).z_ok, agreement(pt, mi, ALPHA)
    for scale in (0.95, 1.05):  # the check has power
        assert not agreement(Estimate(pt.samples * scale), mi, ALPHA).z_ok, scale


def test_a_camera_on_a_medium_boundary_ends_its_connections():
    """A connection reaching a camera that sits on a null boundary used to cross the boundary,
    turn back at the camera and cross again: ~4500 rays per light path and a render that
    overran its time budget by 30 s. It now arrives: as many rays as with the camera just
    inside (about 9 per path both)."""
    rays = []
    for z in (0.99, 0.98):  # on the fog's front face, then inside
        scene = load_small("cbox-fog", 16, 16, (f"camera.origin=[0, 0, {z}]", "camera.medium=fog"))
        lt = LightTracing(scene, seed=1, threads=2, params={"light_paths": 4096})
        lt.run_iteration(0)
        rays.append(lt.stats()["rays"])
    assert rays[0] < 1.1 * rays[1], rays


def test_density_grid_matches_pt():
    """cbox-grid: connections through a heterogeneous medium (ratio tracking)."""
    _vs_pt(load_small("cbox-grid", 16, 16), 16, 1 << 13, 16, 256)


def test_max_depth_two_is_direct_light_only():
    """max_depth = 2 (Mitsuba: emitters and direct light) gives pt's image."""
    scene = load_small("cbox-fog", 16, 16, ("integrator.max_depth=2",))
    _vs_pt(scene, 24, 1 << 14, 24, 512)


def test_max_depth_one_sees_only_emitters():
    """max_depth = 1: only the emission points connect; the light seen through fog."""
    scene = load_small("cbox-fog", 16, 16, ("integrator.max_depth=1",))
    _vs_pt(scene, 16, 1 << 13, 16, 1024)
    lt = LightTracing(scene, seed=0, threads=2, params={"light_paths": 1 << 13})
    lt.run_iteration(0)
    lit = lt.image().max(axis=-1) > 0
    assert 0 < lit.sum() < 16  # the light's few pixels at the top of the image
    assert lit[:4].sum() == lit.sum()


def _render(name: str, threads: int, **params) -> np.ndarray:
    method = LightTracing(load_small(name, 16, 16), seed=5, threads=threads, params=params)
    for i in range(2):
        method.run_iteration(i)
    return method.image()


# cbox-grid: ratio tracking on the connections draws from their own random streams
@pytest.mark.parametrize("name", ["cbox-fog", "cbox-glass", "cbox-grid"])
def test_same_seed_same_image_whatever_the_thread_count(name):
    a = _render(name, 1, light_paths=4096)
    b = _render(name, 2, light_paths=4096)
    assert np.array_equal(a, b)
    assert a.sum() > 0


def test_record_bound_is_an_error():
    method = LightTracing(
        load_small("cbox-fog", 8, 8),
        seed=1,
        threads=1,
        params={"light_paths": 4096, "max_records": 1000},
    )
    with pytest.raises(PgiError, match=r"exceed the configured bound .*method\.light_paths"):
        method.run_iteration(0)


def test_fewer_light_paths_than_pixels_are_a_fraction_of_a_sample_per_pixel():
    lt = LightTracing(load_small("cbox", 16, 16), seed=0, threads=1, params={"light_paths": 96})
    lt.run_iteration(0)
    assert lt.stats()["spp"] == 96 / 256
    lt.run_iteration(1)
    lt.run_iteration(2)
    lt.run_iteration(3)
    assert lt.stats()["spp"] == 1.5 and isinstance(lt.stats()["spp"], float)
    lt = LightTracing(load_small("cbox", 16, 16), seed=0, threads=1, params={"light_paths": 512})
    lt.run_iteration(0)
    assert lt.stats()["spp"] == 2 and isinstance(lt.stats()["spp"], int)


def test_unknown_parameter_is_a_clear_error():
    with pytest.raises(PgiError, match="unknown parameter"):
        LightTracing(load_small("cbox", 8, 8), seed=0, threads=1, params={"spp": 3})


def _light_paths(
    name: str,
    paths: int = 1 << 14,
    overrides: tuple[str, ...] = (),
    threads: int = 2,
    **kw,
):
    """One iteration of `paths` light paths through scene `name` (seed 9), as lt traces them."""
    scene = load_small(name, 8, 8, overrides)
    lt = LightTracing(scene, seed=9, threads=threads, params={"light_paths": paths})
    lp = lt.light_paths_wavefront(paths, "light_paths", 1 << 22, **kw)
    lp.run(0)
    return lp


def test_emission_vertices_carry_the_emitted_flux():
    """Area light: power of each emission vertex = Le * A / pick, so their mean is Le * A."""
    lp = _light_paths("cbox")
    v = lp.kernel.vertices()
    emission = v["kind"] == 0
    assert emission.sum() == lp.paths  # one per path: the scene has one area light
    area = 0.5 * 0.4
    expected = np.array([18.4, 14.0, 6.75]) * area
    assert np.allclose(v["throughput"][emission].mean(axis=0), expected, rtol=1e-9)
    assert np.all(v["depth"][emission] == 0)


def test_light_paths_refract_into_a_liquid_without_the_radiance_scale():
    """Light paths carry flux: refraction does not scale it by 1 / eta^2 (that factor belongs
    to radiance, on camera paths). With the juice white and non-absorbing, a medium vertex of
    depth 2 (emitted, refracted through the glass into the juice, first collision) carries
    exactly the emitted flux per path; scaled as radiance it carried 1 / 1.33^2 = 0.565 of it.
    Entering and leaving a dielectric cancel, so images of lights outside the glass miss it."""
    lp = _light_paths("juice", overrides=("media.juice.sigma_t=2", "media.juice.albedo=1"))
    v = lp.kernel.vertices()
    flux = v["throughput"][v["kind"] == 0].mean(axis=0) * np.pi  # Le pi A / pick
    inside = (v["kind"] == 2) & (v["depth"] == 2)
    assert inside.sum() > 50
    np.testing.assert_allclose(v["throughput"][inside] / flux, 1.0, rtol=1e-9)


def test_records_follow_depth_and_medium_rules():
    lp = _light_paths("cbox-fog")
    v, s = lp.kernel.vertices(), lp.kernel.segments()
    max_depth = 12
    assert v["depth"].max() < max_depth and s["depth"].max() + 1 < max_depth
    medium = v["kind"] == 2
    assert medium.any() and np.all(v["medium"][medium] == 0)
    # The light sits inside the fog: every path starts with a segment in it.
    first = s["depth"] == 0
    assert first.sum() == lp.paths
    assert np.all(s["length"] <= s["t_surface"] + 1e-9)
    # A segment that ends in a collision is followed by a medium vertex at its end.
    hit = s["scattered"].astype(bool) & (s["depth"] == 0)
    ends = s["origin"][hit] + s["direction"][hit] * s["length"][hit, None]
    starts = v["position"][medium & (v["depth"] == 1)]
    assert len(ends) == len(starts) and np.allclose(ends, starts)
    # Surface vertices are made only on diffuse surfaces (not on the null fog boundary), lit
    # from the front: wi, a unit vector, points back to the previous vertex, on the side of
    # the normal (checked against each triangle's normal below).
    surf = v["kind"] == 1
    assert np.allclose(np.einsum("ij,ij->i", v["wi"][surf], v["wi"][surf]), 1)
    scene = load_small("cbox-fog", 8, 8)
    native = build_native_scene(scene)
    tri = native.triangles[v["triangle"][surf]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("ij,ij->i", v["wi"][surf], normal) > 0)
    boundary = next(i for i, sh in enumerate(scene.shapes) if sh.material == "boundary")
    first = sum(len(sh.faces) for sh in scene.shapes[:boundary])  # no triangle is dropped here
    assert native.dropped_triangles == 0
    on_boundary = (v["triangle"][surf] >= first) & (
        v["triangle"][surf] < first + len(scene.shapes[boundary].faces)
    )
    assert surf.sum() > 1000 and not on_boundary.any()


def test_vertex_order_is_deterministic_across_threads():
    a, b = _light_paths("cbox-fog", 4096, threads=2), _light_paths("cbox-fog", 4096, threads=1)
    va, vb = a.kernel.vertices(), b.kernel.vertices()
    for key in va:
        assert np.array_equal(va[key], vb[key]), key


def _emission_media(scene) -> tuple[np.ndarray, np.ndarray]:
    """(per triangle, per scene light) medium the core's light paths start in (-1: vacuum),
    as the core holds them."""
    native = build_native_scene(scene)
    per_triangle, per_light = native.core.emission_media()
    assert np.array_equal(per_triangle, native.emission.per_triangle)
    return per_triangle, per_light[native.light_ids]


def _shape_triangles(scene, index: int) -> slice:
    """The core's triangles of shape ``index`` (no triangle dropped before it)."""
    first = sum(len(s.faces) for s in scene.shapes[:index])
    return slice(first, first + len(scene.shapes[index].faces))


def _lamp_shape(scene) -> int:
    return next(i for i, s in enumerate(scene.shapes) if s.emission is not None)


def _lamp_media(scene) -> np.ndarray:
    """The media the triangles of the scene's first emitting shape emit into."""
    per_triangle, _ = _emission_media(scene)
    return per_triangle[_shape_triangles(scene, _lamp_shape(scene))]


@pytest.mark.parametrize(
    "name, expected, overrides",
    [
        ("cbox-fog", "fog", ()),
        ("cbox", None, ()),
        ("volcaustic", "fog", ()),
        # the fog box built exactly on the walls, floor and ceiling: the walk enters it through
        # its front face and passes the walls, which name no medium (random probes used to hit
        # a wall and the fog's face at one distance and step past the face: vacuum, and lt
        # +38 %, pm -53 %, ppb -62 % against pt)
        ("cbox-fog", "fog", ("shapes[8].transform=[]",)),
    ],
    ids=["cbox-fog", "cbox", "volcaustic", "cbox-fog-box-on-the-walls"],
)
def test_lights_emit_into_their_medium(name, expected, overrides):
    """cbox-fog: inside a fog box the walk from the camera enters; volcaustic: in the camera's
    fog, which no shape bounds around the lamp (the walk passes the ball only beside it)."""
    scene = load_small(name, 8, 8, overrides)
    want = -1 if expected is None else list(scene.media).index(expected)
    assert np.all(_lamp_media(scene) == want)


def test_the_walk_follows_the_transitions_through_nested_media(tmp_path):
    """A box of smoke inside a box of fog, the camera outside both: the walk enters the fog
    (vacuum -> fog), then the smoke (fog -> smoke), and leaves them in turn. A point light and
    a small lamp inside the smoke emit into it, a spot light between the boxes into the fog,
    and the box's own lamp, outside both, into vacuum. The walk's probe answers for any point;
    the line to the centre of the box passes exactly through the edge that the two triangles
    of the fog's front face share, and enters the fog all the same (edges are inclusive:
    excluded, the walk there ended in vacuum)."""
    from renderer.scene.loader import find_scene_file

    (tmp_path / "scene.yaml").write_text(textwrap.dedent(f"""\
        include: {find_scene_file("cbox").parent / "box.yaml"}
        camera: {{origin: [0, 0, 4], target: [0, 0, 0], up: [0, 1, 0], fov: 39.3}}
        media:
          fog: {{type: homogeneous, sigma_t: 0.5, albedo: 0.8}}
          smoke: {{type: homogeneous, sigma_t: 2.0, albedo: 0.9}}
        materials: {{boundary: {{type: "null"}}}}
        shapes:
          - {{name: fog-box, type: cube, material: boundary, interior: fog,
              transform: [{{scale: 0.75}}]}}
          - {{name: smoke-box, type: cube, material: boundary, interior: smoke, exterior: fog,
              transform: [{{scale: 0.2}}, {{translate: [0.3, -0.3, 0.2]}}]}}
          - {{name: small-lamp, type: rectangle, material: white, emission: 2,
              transform: [{{scale: 0.05}}, {{rotate: {{axis: [1, 0, 0], angle: 90}}}},
                          {{translate: [0.3, -0.2, 0.2]}}]}}
        lights:
          - {{type: point, position: [0.25, -0.35, 0.15], intensity: 1}}
          - {{type: spot, position: [-0.5, 0.4, -0.3], target: [0, -1, 0], intensity: 1}}
        """))  # fmt: skip
    scene = load_scene(tmp_path / "scene.yaml")
    fog, smoke = 0, 1
    per_triangle, per_light = _emission_media(scene)
    names = [s.name for s in scene.shapes]
    assert np.all(per_triangle[_shape_triangles(scene, names.index("small-lamp"))] == smoke)
    assert np.all(per_triangle[_shape_triangles(scene, names.index("light"))] == -1)
    assert per_light.tolist() == [smoke, fog]
    core = build_native_scene(scene).core
    # In the smoke; in the fog beside it; at the centre (through the face's shared edge);
    # behind the box; in the fog after crossing the smoke.
    points = [[0.3, -0.3, 0.2], [0.6, 0.5, 0.6], [0, 0, 0], [0, 0, -3], [0.3, -0.3, -0.5]]
    assert core.walk_media(np.array(points, np.float64)).tolist() == [smoke, fog, fog, -1, fog]


def test_a_stated_medium_overrides_the_walk_with_a_warning(tmp_path, capsys):
    """A light or emitting shape that states a medium emits into it. Where the walk from the
    camera ends in another, the light-side methods and `pgi validate` say so, one line each
    naming the file, the light and both media; pt says nothing. Stating the medium the walk
    finds is silent."""
    from renderer import cli
    from renderer.methods import get_method

    lights = "lights=[{type: point, position: [0, 0.5, 0], intensity: 1, medium: vacuum}]"
    overrides = (lights, "shapes[7].medium=vacuum")  # cbox-fog's lamp and light: in the fog
    scene = load_small("cbox-fog", 8, 8, overrides)
    assert np.all(_lamp_media(scene) == -1) and _emission_media(scene)[1].tolist() == [-1]
    unstated = load_small("cbox-fog", 8, 8, (lights.replace(", medium: vacuum", ""),))
    assert np.all(_lamp_media(unstated) == 0) and _emission_media(unstated)[1].tolist() == [0]
    capsys.readouterr()
    for method in ("lt", "pm", "sppm", "ppb"):
        get_method(method)(scene, seed=0, threads=1, params={})
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 2, err
        lamp, light = err  # named where each is written: the lamp in the included box.yaml
        assert light.startswith(f"pgi: warning: {scene.path} (override 'lights="), light
        assert "): lights[0]: states" in light, light
        box = scene.path.parent / "../cbox/box.yaml"
        assert lamp.startswith(f"pgi: warning: {box} (after override 'shapes[7].medium"), lamp
        assert "): shapes[7] (light): states" in lamp, lamp
        for line in err:
            assert "states medium vacuum" in line and "ends in fog" in line, line
    PathTracing(scene, seed=0, threads=1, params={})
    assert capsys.readouterr().err == ""
    args = ["validate", "cbox-fog", "--set", lights, "--set", "shapes[7].medium=vacuum"]
    assert cli.main(args) == 0
    out = capsys.readouterr()
    assert "ok (" in out.out and len(out.err.strip().splitlines()) == 2, out.err
    assert "lights[0]: states medium vacuum" in out.err, out.err
    agreeing = load_small("cbox-fog", 8, 8, ("shapes[7].medium=fog",))
    LightTracing(agreeing, seed=0, threads=1, params={})
    assert capsys.readouterr().err == ""


def test_an_emitter_a_medium_boundary_crosses_is_refused(tmp_path, capsys):
    """Light paths start in one medium per emitting triangle, found from its centroid. Ground
    fog reaching through the box's back wall, lit: the lower half of the wall emits into the
    fog, the upper half into vacuum. lt rendered it 14 % dark (one triangle 0.06 instead of
    1.1), pm and ppb their fog 11-16 % dark (found by a review). The light-path methods now
    refuse the scene with the reason and the fix, and `pgi validate` warns of it; pt renders
    it. Every shipped scene passes."""
    from renderer import cli
    from renderer.methods.lightpath import check_emission_media
    from renderer.scene.loader import find_scene_file

    (tmp_path / "scene.yaml").write_text(
        textwrap.dedent(f"""\
        include: {find_scene_file("cbox").parent / "box.yaml"}
        media: {{fog: {{type: homogeneous, sigma_t: 2.0, albedo: 0.8}}}}
        materials: {{boundary: {{type: "null"}}}}
        shapes:
          - {{name: fog-boundary, type: cube, material: boundary, interior: fog,
              transform: [{{scale: [0.99, 0.505, 1.0]}}, {{translate: [0, -0.505, -0.01]}}]}}
        """)
    )
    lit = ["--set", "shapes[2].emission=[1, 1, 1]", "--set", "film.width=8",
           "--set", "film.height=8", "--spp", "1", "-q"]  # fmt: skip
    for method in ("lt", "pm", "sppm", "ppb"):
        out = tmp_path / f"{method}.exr"
        code = cli.main(["render", str(tmp_path), "--method", method, *lit, "-o", str(out)])
        assert code == 2 and not out.exists()
        err = capsys.readouterr().err.strip()  # one line naming the file, no traceback
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert err.startswith("pgi: error:") and "box.yaml (after override 'shapes[2]" in err
        assert "): shapes[2] (back): a boundary of a medium crosses this emitter" in err, err
    scene = load_scene(tmp_path / "scene.yaml", ["shapes[2].emission=[1, 1, 1]"])
    native = build_native_scene(scene)
    # The wall is written in the included box.yaml, not in the scene file.
    crosses = r"box.yaml \(after override .*\): shapes\[2\] \(back\): a boundary of a medium"
    with pytest.raises(PgiError, match=crosses):
        check_emission_media(native)
    assert cli.main(["validate", str(tmp_path), "--set", "shapes[2].emission=[1, 1, 1]"]) == 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("pgi: warning:") and len(err.splitlines()) == 1, err
    assert "shapes[2] (back): a boundary of a medium crosses this emitter" in err, err
    assert "lt, pm, sppm and ppb refuse this scene" in err, err
    out = tmp_path / "pt.exr"
    assert cli.main(["render", str(tmp_path), "--method", "pt", *lit, "-o", str(out)]) == 0
    unlit = load_scene(tmp_path / "scene.yaml")  # the ceiling's lamp lies outside the fog
    check_emission_media(build_native_scene(unlit))
    assert np.all(_lamp_media(unlit) == -1)
    # The camera's fog fills the room (no shape names it) and a small smoke cube sits between
    # a lamp corner and the camera: no boundary crosses the lamp. Random probes from that
    # corner used to miss the cube and say vacuum (found by a review); the walk crosses the
    # cube, into the smoke and out into the fog again.
    (tmp_path / "cube.yaml").write_text(textwrap.dedent(f"""\
        include: {find_scene_file("cbox").parent / "box.yaml"}
        camera: {{origin: [0, 0, 3.9], target: [0, 0, 0], up: [0, 1, 0], fov: 39.3,
                 medium: fog}}
        media:
          fog: {{type: homogeneous, sigma_t: 0.05, albedo: 0.8}}
          smoke: {{type: homogeneous, sigma_t: 1.0, albedo: 0.8}}
        materials: {{boundary: {{type: "null"}}}}
        shapes:
          - {{name: smokebox, type: cube, material: boundary, interior: smoke, exterior: fog,
              transform: [{{scale: 0.06}}, {{translate: [0.175, 0.686, 1.31]}}]}}
        """))  # fmt: skip
    cube = load_scene(tmp_path / "cube.yaml")
    native = build_native_scene(cube)
    check_emission_media(native)
    assert np.all(_lamp_media(cube) == 0)
    # The cube does lie on the walk to a lamp corner.
    lamp = cube.shapes[_lamp_shape(cube)]
    corner = lamp.vertices[np.argmax(lamp.vertices @ [1, 0, 1])]
    camera = cube.camera.origin
    at_the_cube = camera + (camera[2] - 1.31) / (camera[2] - corner[2]) * (corner - camera)
    assert native.core.walk_media(at_the_cube[None]).tolist() == [1]
    shipped = sorted(p.parent.name for p in find_scene_file("cbox").parents[1].glob("*/scene.yaml"))
    for name in shipped:
        native = build_native_scene(load_small(name, 8, 8))
        check_emission_media(native)
        assert not native.emission.stated_elsewhere, name


def test_sun_outside_a_fog_filled_room_starts_in_vacuum():
    """crepuscular: the camera's fog fills a room, and the sun shines in through null windows
    that name the fog as their interior and vacuum outside: a shape names the camera's
    medium, so the sun is outside it, in vacuum. Stated, the sun emits into its medium."""
    scene = load_small("crepuscular", 8, 8)
    assert _emission_media(scene)[1].tolist() == [-1]
    stated = load_small("crepuscular", 8, 8, ("lights[0].medium=fog",))
    assert _emission_media(stated)[1].tolist() == [0]


def test_sun_shining_into_an_unbounded_grid_starts_in_it():
    """A smoke grid no shape bounds, the camera in it, lit by the sun: the sun's light paths
    start in the smoke (outside its box, where the density is zero), as pt's shadow rays
    towards the sun travel in it; with the camera outside every medium they start in vacuum;
    with the grid bounded by a shape, in vacuum too, unless the sun states the smoke."""
    open_grid = (
        "camera.medium=smoke",
        "shapes=[{name: floor, type: rectangle, material: floor, "
        "transform: [{scale: 0.98}, {rotate: {axis: [1, 0, 0], angle: -90}}]}]",
        "lights=[{type: directional, direction: [0.3, -1, -0.2], irradiance: 2}]",
    )
    bounded = (
        open_grid[0],
        open_grid[1][:-1] + ", {name: box, type: cube, material: floor, interior: smoke}]",
        open_grid[2],
    )
    stated = (*bounded[:2], open_grid[2][:-2] + ", medium: smoke}]")
    for extra, want in ((open_grid, 0), (open_grid[1:], -1), (bounded, -1), (stated, 0)):
        scene = load_small("smoke", 8, 8, extra)
        assert _emission_media(scene)[1].tolist() == [want], extra


@pytest.mark.parametrize("method", ["lt", "pm", "sppm", "ppb"])
def test_light_side_methods_warn_about_near_delta_phase_functions(method, capsys):
    """At |g| >= 0.999 the light-side methods' images are far too dark at any budget we run
    (docs/media.md): each says so when it starts; at 0.99 none does."""
    from renderer.methods import get_method

    for g, warned in ((0.99, False), (-0.999, True)):
        scene = load_small("cbox-fog", 4, 4, (f"media.fog.phase={{type: hg, g: {g}}}",))
        get_method(method)(scene, seed=0, threads=1, params={})
        err = capsys.readouterr().err
        assert ("media.fog.phase.g = -0.999: lt, pm, sppm and ppb" in err) == warned, err
