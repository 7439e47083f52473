"""Scene loader: validation messages (file + key path), overrides, includes, primitives."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import SCENES
from renderer.errors import PgiError
from renderer.scene import load_scene, primitives
from renderer.scene.loader import find_scene_file
from renderer.scene.sources import scene_sources

REPO = Path(__file__).resolve().parents[1]
SHIPPED = ["cbox", "cbox-fog", "cbox-grid", "cbox-glass"]

BASE = {
    "name": "t",
    "description": "test scene",
    "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 40},
    "film": {"width": 8, "height": 6},
    "materials": {"white": {"type": "diffuse", "reflectance": 0.5}},
    "shapes": [
        {"name": "floor", "type": "rectangle", "material": "white"},
        {"name": "lamp", "type": "rectangle", "material": "white", "emission": 1.0,
         "transform": [{"translate": [0, 0, 1]}]},
    ],
}  # fmt: skip


def write(tmp_path: Path, doc: dict | str, name: str = "scene.yaml") -> Path:
    path = tmp_path / name
    path.write_text(doc if isinstance(doc, str) else yaml.safe_dump(doc))
    return path


def edit(**sections) -> dict:
    doc = yaml.safe_load(yaml.safe_dump(BASE))  # deep copy
    doc.update(sections)
    return doc


def expect_error(path: Path, key: str, pattern: str = "", overrides=()) -> str:
    with pytest.raises(PgiError) as info:
        load_scene(path, overrides)
    msg = str(info.value)
    assert str(path) in msg, msg
    assert f": {key}:" in msg, msg
    assert re.search(pattern, msg), msg
    assert "\n" not in msg
    return msg


def test_minimal_scene_loads(tmp_path):
    scene = load_scene(write(tmp_path, BASE))
    assert scene.film.width == 8 and scene.camera.fov_axis == "x"
    assert scene.integrator.max_depth == -1 and scene.integrator.rr_depth == 5
    assert scene.shapes[1].emission == (1.0, 1.0, 1.0)
    assert np.allclose(scene.shapes[1].vertices[:, 2], 1)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenes_load_and_explain_themselves(name):
    scene = load_scene(name)
    assert scene.name == name and scene.path == REPO / "scenes" / name / "scene.yaml"
    assert len(scene.description) > 40 and scene.stresses and scene.expected_winners
    assert (scene.film.width, scene.film.height) == (256, 256)
    assert any(s.emission for s in scene.shapes)


def test_shipped_scenes_share_the_box():
    boxes = [{s.name: s for s in load_scene(n).shapes} for n in SHIPPED]
    for name in ["floor", "ceiling", "back", "left", "right", "short-box", "tall-box", "light"]:
        for other in boxes[1:]:
            assert np.array_equal(boxes[0][name].vertices, other[name].vertices)


def test_scene_path_forms(tmp_path, monkeypatch):
    folder = REPO / "scenes" / "cbox"
    assert find_scene_file("cbox") == folder / "scene.yaml"
    assert find_scene_file(folder) == folder / "scene.yaml"
    assert find_scene_file(folder / "scene.yaml") == folder / "scene.yaml"
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scenes" / "mine").mkdir(parents=True)
    write(tmp_path / "scenes" / "mine", BASE)
    assert load_scene("mine").name == "t"
    with pytest.raises(PgiError, match="not found"):
        load_scene("no-such-scene")
    # run from the repository, its scenes folder is named once, not twice
    from renderer.scene.loader import REPO_ROOT

    monkeypatch.chdir(REPO_ROOT)
    looked = re.escape(f"(looked in {REPO_ROOT / 'scenes'})")
    with pytest.raises(PgiError, match=f"not found {looked}$"):
        load_scene("no-such-scene")
    monkeypatch.chdir(tmp_path)
    # A folder in the working directory named like a scene is used as given; the error
    # says where the scene of that name is.
    (tmp_path / "cbox").mkdir()
    with pytest.raises(PgiError, match=r"^cbox: no scene.yaml in this folder \(a scene of that "):
        load_scene("cbox")
    (tmp_path / "other").mkdir()
    with pytest.raises(PgiError, match=r"^other: no scene.yaml in this folder$"):
        load_scene("other")


def test_broken_yaml(tmp_path):
    path = write(tmp_path, "camera: [1, 2\nfilm: {")
    with pytest.raises(PgiError, match=rf"^{re.escape(str(path))}:\d+: invalid YAML"):
        load_scene(path)


def test_duplicate_yaml_key(tmp_path):
    path = write(tmp_path, yaml.safe_dump(BASE) + "film: {width: 1, height: 1}\n")
    with pytest.raises(PgiError, match="duplicate key 'film'"):
        load_scene(path)


def test_unknown_key(tmp_path):
    doc = edit()
    doc["camera"]["fvo"] = 30
    expect_error(write(tmp_path, doc), "camera.fvo", "unknown key.*fov")
    expect_error(write(tmp_path, edit(colour=1)), "colour", "unknown key")


def test_wrong_type(tmp_path):
    doc = edit()
    doc["film"]["width"] = "wide"
    expect_error(
        write(tmp_path, doc), "film.width", "expected an integer >= 1 and <= 16384, got 'wide'"
    )
    doc = edit()
    doc["camera"]["origin"] = [0, 0]
    expect_error(write(tmp_path, doc), "camera.origin", "list of 3 numbers")
    doc = edit()
    doc["shapes"][0]["type"] = "disc"
    expect_error(write(tmp_path, doc), "shapes[0].type", "rectangle, cube, sphere, mesh")


def test_missing_key(tmp_path):
    doc = edit()
    del doc["shapes"][1]["material"]
    expect_error(write(tmp_path, doc), "shapes[1].material", "missing required key")


def test_missing_mesh_file(tmp_path):
    doc = edit()
    doc["shapes"].append({"type": "mesh", "file": "nope.ply", "material": "white"})
    expect_error(write(tmp_path, doc), "shapes[2].file", "mesh file not found")


@pytest.mark.parametrize("name", ["empty.ply", "empty.obj"])
def test_empty_mesh_file(tmp_path, name):
    (tmp_path / name).write_bytes(b"")
    doc = edit()
    doc["shapes"].append({"type": "mesh", "file": name, "material": "white"})
    expect_error(write(tmp_path, doc), "shapes[2].file", "mesh file is empty")


def test_nesting_too_deep_for_the_yaml_reader(tmp_path):
    path = write(tmp_path, "film: " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(
        PgiError, match=rf"^{re.escape(str(path))}.*: invalid YAML: nested too deeply"
    ):
        load_scene(path)
    # An override says why too, and shows only the start of its value.
    with pytest.raises(PgiError) as e:
        load_scene(write(tmp_path, BASE), ["film.width=" + "[" * 5000 + "]" * 5000])
    shown = "'" + "[" * 36 + "..."
    assert str(e.value) == (
        f"override 'film.width': value {shown} is not valid YAML (nested too deeply)"
    )


@pytest.mark.parametrize(
    "value,why",
    [("{[1]: 2}", "found unhashable key"), ("{a: 1, a: 2}", "duplicate key 'a'")],
)
def test_override_values_yaml_refuses_say_why(tmp_path, value, why):
    with pytest.raises(PgiError) as e:
        load_scene(write(tmp_path, BASE), [f"film.width={value}"])
    assert str(e.value) == f"override 'film.width': value {value!r} is not valid YAML ({why})"


def test_mesh_file_loads_through_mitsuba(tmp_path):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n")
    doc = edit()
    doc["shapes"].append({"type": "mesh", "file": "tri.obj", "material": "white",
                          "transform": [{"translate": [5, 0, 0]}]})  # fmt: skip
    mesh = load_scene(write(tmp_path, doc)).shapes[2]
    assert mesh.faces.shape == (2, 3) and mesh.faces.dtype == np.int32
    assert np.isclose(primitives.area(mesh.vertices, mesh.faces), 1.0)
    assert np.allclose(mesh.vertices.min(axis=0), [5, 0, 0])


def grid_scene(tmp_path: Path, density: np.ndarray, **medium) -> Path:
    np.save(tmp_path / "d.npy", density)
    doc = edit(media={"smoke": {"type": "grid", "density": "d.npy", "albedo": 0.5, **medium}})
    doc["shapes"].append({"type": "cube", "material": "white", "interior": "smoke"})
    return write(tmp_path, doc)


def test_grid_medium(tmp_path):
    d = np.arange(24, dtype=np.float64).reshape(2, 3, 4)
    path = grid_scene(tmp_path, d, transform=[{"scale": 2}, {"translate": [-1, -1, -1]}])
    m = load_scene(path).media["smoke"]
    assert m.density.dtype == np.float32 and m.density.shape == (2, 3, 4)
    assert np.array_equal(m.density, d) and m.source == tmp_path / "d.npy"
    assert np.allclose(m.to_world @ [1, 1, 1, 1], [1, 1, 1, 1])
    assert m.sigma_t == (1.0, 1.0, 1.0) and m.phase.type == "isotropic"


def test_negative_density(tmp_path):
    d = np.ones((2, 2, 2))
    d[1, 0, 1] = -0.5
    msg = expect_error(grid_scene(tmp_path, d), "media.smoke.density", ">= 0")
    assert "[1, 0, 1]" in msg


def test_expected_winners_are_method_ids(tmp_path):
    scene = load_scene(write(tmp_path, edit(expected_winners=["pt", "vrl"])))
    assert scene.expected_winners == ["pt", "vrl"]  # vrl: in the study's table, not built yet
    expect_error(write(tmp_path, edit(expected_winners=["pt", "bpdt"])), "expected_winners[1]",
                 "expected one of: pt, lt, .*bdpt")  # fmt: skip


def test_grid_sigma_t_is_grey(tmp_path):
    # The renderer scales one density by one extinction; RGB would diverge from Mitsuba.
    path = grid_scene(tmp_path, np.ones((2, 2, 2)), sigma_t=[1, 2, 3])
    expect_error(path, "media.smoke.sigma_t", "expected a number")


def test_negative_sigma_t_and_bad_albedo(tmp_path):
    fog = {"type": "homogeneous", "sigma_t": [1, -1, 1], "albedo": 0.5}
    expect_error(write(tmp_path, edit(media={"fog": fog})), "media.fog.sigma_t[1]", ">= 0")
    fog = {"type": "homogeneous", "sigma_t": 1, "albedo": 1.5}
    expect_error(write(tmp_path, edit(media={"fog": fog})), "media.fog.albedo", "<= 1")


@pytest.mark.parametrize("g", [1.0, -1.0, 1.5])
def test_hg_g_out_of_range(tmp_path, g):
    fog = {"type": "homogeneous", "sigma_t": 1, "albedo": 0.5, "phase": {"type": "hg", "g": g}}
    expect_error(write(tmp_path, edit(media={"fog": fog})), "media.fog.phase.g", "> -1 and < 1")


@pytest.mark.parametrize(
    "override, key",
    [
        ("media.fog.phase.g=0.99999999", "media.fog.phase.g"),
        ("camera.fov=179.9999999", "camera.fov"),
        ("materials.glass.ior=1.0e-50", "materials.glass.ior"),
    ],
)
def test_values_that_leave_their_range_in_float32_are_errors(tmp_path, override, key):
    """In range as written, out of it in Mitsuba's float32 (g = 1 fails to load there, a field
    of view of 180 degrees renders black)."""
    fog = {"type": "homogeneous", "sigma_t": 1, "albedo": 0.5, "phase": {"type": "hg", "g": 0.5}}
    doc = edit(media={"fog": fog})
    doc["materials"]["glass"] = {"type": "dielectric", "ior": 1.5}
    expect_error(write(tmp_path, doc), key, "in float32, as Mitsuba stores it", [override])


def test_a_spot_whose_beam_equals_its_cutoff_is_not_refused_in_float32(tmp_path):
    spot = "lights=[{type: spot, position: [0, 1, 0], target: [0, 0, 0], intensity: 1, "
    load_scene(write(tmp_path, BASE), [spot + "cutoff_angle: 0.1, beam_width: 0.1}]"])


@pytest.mark.parametrize("ior", [0, -1.5])
def test_ior_not_positive(tmp_path, ior):
    doc = edit(
        materials={"white": {"type": "diffuse"}, "glass": {"type": "dielectric", "ior": ior}}
    )
    expect_error(write(tmp_path, doc), "materials.glass.ior", "> 0")


def test_zero_area_light(tmp_path):
    doc = edit()
    doc["shapes"][1]["transform"] = [{"scale": [1, 0, 1]}]
    expect_error(write(tmp_path, doc), "shapes[1]", "zero surface area.*emitter")


def test_zero_area_shape_says_whether_its_file_or_its_transform_is_flat(tmp_path):
    (tmp_path / "line.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    doc = edit()
    doc["shapes"][0] = {"type": "mesh", "file": "line.obj", "material": "white"}
    expect_error(write(tmp_path, doc), "shapes[0]", r"zero surface area \(its file .*line.obj "
                 "has no triangle of non-zero area")  # fmt: skip
    doc = edit()
    doc["shapes"][0]["transform"] = [{"scale": [1, 0, 1]}]
    expect_error(write(tmp_path, doc), "shapes[0]", r"zero surface area \(check its transform")


@pytest.mark.parametrize(
    ("where", "key"),
    [("material", "shapes[0].material"), ("interior", "shapes[0].interior")],
)
def test_unknown_reference(tmp_path, where, key):
    doc = edit()
    doc["shapes"][0][where] = "gold"
    expect_error(write(tmp_path, doc), key, "unknown .* 'gold'")


def test_unknown_camera_medium(tmp_path):
    doc = edit()
    doc["camera"]["medium"] = "fog"
    expect_error(write(tmp_path, doc), "camera.medium", "unknown medium 'fog'.*none defined")


def test_degenerate_camera(tmp_path):
    doc = edit()
    doc["camera"]["target"] = [0, 0, 4]
    expect_error(write(tmp_path, doc), "camera.target", "view direction is undefined")
    doc = edit()
    doc["camera"]["up"] = [0, 0, -2]
    expect_error(write(tmp_path, doc), "camera.up", "parallel to the view direction")


def test_scene_without_light(tmp_path):
    doc = edit()
    del doc["shapes"][1]["emission"]
    expect_error(write(tmp_path, doc), "lights", "no light")


def test_lights(tmp_path):
    lights = [
        {"type": "point", "position": [0, 1, 0], "intensity": [1, 2, 3]},
        {"type": "spot", "position": [0, 1, 0], "target": [0, 0, 0], "intensity": 5},
        {"type": "directional", "direction": [0, -2, 0], "irradiance": 1},
    ]
    point, spot, sun = load_scene(write(tmp_path, edit(lights=lights))).lights
    assert point.intensity == (1, 2, 3)
    assert spot.cutoff_angle == 20 and spot.beam_width == 15
    assert np.allclose(sun.direction, [0, -1, 0])
    lights[1]["beam_width"] = 30
    expect_error(write(tmp_path, edit(lights=lights)), "lights[1].beam_width", "<= 20")


def test_lights_and_emitters_may_state_their_medium(tmp_path):
    """Every light type and an emitting shape naming no medium may state the medium it emits
    into: a name from media, or vacuum (docs/scene-format.md, "Where lights emit")."""
    media = {"fog": {"type": "homogeneous", "sigma_t": 1, "albedo": 0.5}}
    lights = [
        {"type": "point", "position": [0, 1, 0], "intensity": 1, "medium": "fog"},
        {"type": "spot", "position": [0, 1, 0], "target": [0, 0, 0], "intensity": 5,
         "medium": "vacuum"},
        {"type": "directional", "direction": [0, -1, 0], "irradiance": 1, "medium": "fog"},
        {"type": "point", "position": [0, 1, 0], "intensity": 1, "medium": None},
    ]  # fmt: skip
    doc = edit(media=media, lights=lights)
    doc["shapes"][1]["medium"] = "vacuum"
    scene = load_scene(write(tmp_path, doc))
    assert [light.medium for light in scene.lights] == ["fog", "vacuum", "fog", None]
    assert [shape.medium for shape in scene.shapes] == [None, "vacuum"]
    doc["shapes"][1]["medium"] = "fog"
    assert load_scene(write(tmp_path, doc)).shapes[1].medium == "fog"
    lights[2]["medium"] = "smoke"
    expect_error(write(tmp_path, edit(media=media, lights=lights)), "lights[2].medium",
                 r"unknown medium 'smoke' \(defined: fog\)")  # fmt: skip


@pytest.mark.parametrize(
    "shape, names, pattern",
    [
        # an emitter that names media emits into its exterior: a medium key contradicts it
        (1, {"interior": "fog"}, "emits into its exterior .*remove medium"),
        (1, {"exterior": "fog"}, "emits into its exterior"),
        (0, {}, "only an emitter .* states the medium"),  # the floor emits nothing
    ],
)
def test_a_stated_medium_where_it_means_nothing_is_an_error(tmp_path, shape, names, pattern):
    doc = edit(media={"fog": {"type": "homogeneous", "sigma_t": 1, "albedo": 0.5}})
    doc["shapes"][shape].update({"medium": "fog", **names})
    expect_error(write(tmp_path, doc), f"shapes[{shape}].medium", pattern)


def test_a_medium_may_not_be_named_vacuum(tmp_path):
    """`vacuum` is what a light states for no medium: no medium may take the name."""
    doc = edit(media={"vacuum": {"type": "homogeneous", "sigma_t": 1, "albedo": 0.5}})
    expect_error(write(tmp_path, doc), "media.vacuum", "name 'vacuum' is reserved")
    expect_error(write(tmp_path, edit()), "media.vacuum", "reserved",
                 ["media.vacuum={type: homogeneous, sigma_t: 1, albedo: 0.5}"])  # fmt: skip


def test_null_material_written_as_yaml_null(tmp_path):
    doc = edit(materials={"white": {"type": "diffuse"}, "boundary": {"type": None}})
    assert load_scene(write(tmp_path, doc)).materials["boundary"].type == "null"


def test_overrides(tmp_path):
    fog = {"type": "homogeneous", "sigma_t": 1, "albedo": 0.5}
    path = write(tmp_path, edit(media={"fog": fog}))
    scene = load_scene(
        path,
        ["film.width=64", "integrator.max_depth=3", "media.fog.scale=2",
         "shapes[1].emission=[1, 2, 3]", "media.fog.albedo = [0.1, 0.2, 0.3]"],
    )  # fmt: skip
    assert scene.film.width == 64 and scene.integrator.max_depth == 3
    assert scene.media["fog"].scale == 2 and scene.media["fog"].albedo == (0.1, 0.2, 0.3)
    assert scene.shapes[1].emission == (1, 2, 3)


def test_bad_overrides(tmp_path):
    path = write(tmp_path, BASE)
    msg = expect_error(path, "film.width", "expected an integer", overrides=["film.width=-3"])
    assert "override 'film.width=-3'" in msg
    with pytest.raises(PgiError, match="expected key.path=value"):
        load_scene(path, ["film.width"])
    with pytest.raises(PgiError, match=r"shapes\[7\] does not exist"):
        load_scene(path, ["shapes[7].material=white"])
    with pytest.raises(PgiError, match=r"list indices count from 0 \(none negative\)"):
        load_scene(path, ["shapes[-1].material=white"])
    with pytest.raises(PgiError, match="list index too large"):
        load_scene(path, ["shapes[99999999999999999999].material=white"])
    # editing a medium the scene lacks names what it has; defining one whole is allowed
    with pytest.raises(PgiError, match="no media entry 'fog' \\(it has: none\\)"):
        load_scene(path, ["media.fog.scale=2"])
    fog = "media.fog={type: homogeneous, sigma_t: 1, albedo: 0.5}"
    assert load_scene(path, [fog]).media["fog"].sigma_t == (1.0, 1.0, 1.0)
    # a reference the override left dangling names the override that emptied its section
    msg = expect_error(path, "shapes[0].material", "unknown material", overrides=["materials={}"])
    assert "(defined after override 'materials={}': none defined)" in msg
    # a key the override itself creates is blamed on the override, not on the file
    msg = expect_error(path, "foo", "unknown key", overrides=["foo.bar=1"])
    assert "override 'foo.bar=1'" in msg
    # includes are merged before overrides: setting one would be silently ignored
    with pytest.raises(PgiError, match="includes are merged before overrides"):
        load_scene(path, ["include=other.yaml"])
    # a scene that includes itself says so
    doc = yaml.safe_load(path.read_text())
    doc["include"] = path.name
    path.write_text(yaml.safe_dump(doc))
    expect_error(path, "include[0]", "a scene cannot include itself")


def test_include(tmp_path):
    base = yaml.safe_load(yaml.safe_dump(BASE))
    del base["name"], base["description"]
    write(tmp_path, base, "common.yaml")
    doc = {
        "include": "common.yaml",
        "film": {"width": 2, "height": 2},
        "materials": {"black": {"type": "diffuse", "reflectance": 0}},
        "shapes": [{"type": "cube", "material": "blak"}],
    }
    path = write(tmp_path, doc)
    # the error names the including file and the shape's index in it
    expect_error(path, "shapes[0].material", "unknown material 'blak'")
    doc["shapes"][0]["material"] = "black"
    scene = load_scene(write(tmp_path, doc))
    assert [s.name for s in scene.shapes] == ["floor", "lamp", "cube2"]
    assert scene.film.width == 2 and set(scene.materials) == {"white", "black"}
    base["shapes"][1]["material"] = "nope"  # an error inside the included file names it
    write(tmp_path, base, "common.yaml")
    with pytest.raises(
        PgiError, match=rf"^{re.escape(str(tmp_path / 'common.yaml'))}: shapes\[1\]"
    ):
        load_scene(path)


def test_an_empty_section_adds_nothing_and_removes_nothing(tmp_path):
    base = yaml.safe_load(yaml.safe_dump(BASE))
    del base["name"], base["description"]
    write(tmp_path, base, "common.yaml")
    base["integrator"] = {"max_depth": 3}
    write(tmp_path, base, "common.yaml")
    path = write(
        tmp_path,
        "include: common.yaml\ncamera:\nfilm:\nintegrator:\nmaterials:\nmedia:\nshapes:\nlights:\n",
    )
    scene = load_scene(path)
    assert set(scene.materials) == {"white"} and [s.name for s in scene.shapes] == ["floor", "lamp"]
    assert scene.integrator.max_depth == 3  # an empty integrator keeps the included one
    assert scene.film.width == base["film"]["width"]


def test_overrides_reach_into_sections_written_empty(tmp_path):
    doc = yaml.safe_dump(BASE) + "integrator:\nmedia:\n"
    path = write(tmp_path, doc)
    fog = "media.haze={type: homogeneous, sigma_t: 0.1, albedo: 0.9}"
    scene = load_scene(path, ["integrator.max_depth=3", fog])
    assert scene.integrator.max_depth == 3 and scene.media["haze"].sigma_t == (0.1, 0.1, 0.1)
    with pytest.raises(PgiError, match="no media entry 'fog' \\(it has: none\\)"):
        load_scene(path, ["media.fog.scale=2"])


def test_rectangle_and_cube_normals():
    v, f = primitives.rectangle()
    n = primitives.face_normals(v, f)
    assert np.allclose(n / np.linalg.norm(n, axis=1)[:, None], [0, 0, 1])
    assert primitives.area(v, f) == pytest.approx(4)
    v, f = primitives.cube()
    n = primitives.face_normals(v, f)
    centres = v[f].mean(axis=1)
    unit = n / np.linalg.norm(n, axis=1)[:, None]
    # each face normal is the axis its triangle's centre lies furthest along
    assert np.allclose(
        unit, np.sign(centres) * (np.abs(centres) == np.abs(centres).max(1)[:, None])
    )
    assert primitives.area(v, f) == pytest.approx(24)


@pytest.mark.parametrize("n", [0, 2, 4])
def test_sphere_outward_and_area(n):
    v, f = primitives.icosphere(n)
    assert len(f) == 20 * 4**n
    assert np.allclose(np.linalg.norm(v, axis=1), 1)
    assert np.all(np.einsum("ij,ij->i", primitives.face_normals(v, f), v[f].mean(axis=1)) > 0)
    assert primitives.area(v, f) == pytest.approx(4 * np.pi, rel=0.5 / 4**n)


def test_mirroring_transform_keeps_normals_outward(tmp_path):
    doc = edit()
    mirrored = [{"scale": [-1, 1, 1]}, {"translate": [3, 0, 0]}]
    doc["shapes"].append({"type": "cube", "material": "white", "transform": mirrored})
    cube = load_scene(write(tmp_path, doc)).shapes[2]
    n = primitives.face_normals(cube.vertices, cube.faces)
    out = cube.vertices[cube.faces].mean(axis=1) - [3, 0, 0]
    assert np.all(np.einsum("ij,ij->i", n, out) > 0)


def test_transform_ops(tmp_path):
    doc = edit()
    doc["shapes"][0]["transform"] = [
        {"scale": [2, 1, 1]},
        {"rotate": {"axis": [0, 0, 1], "angle": 90}},
        {"matrix": [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]},
    ]
    floor = load_scene(write(tmp_path, doc)).shapes[0]
    # corner (1, 1, 0) -> scale (2, 1, 0) -> rotate (-1, 2, 0) -> translate (0, 4, 3)
    assert np.allclose(floor.vertices[2], [0, 4, 3])
    doc["shapes"][0]["transform"] = [{"shear": 1}]
    expect_error(write(tmp_path, doc), "shapes[0].transform[0].shear", "unknown transform op")


def test_values_beyond_float32_and_size_limits_are_errors(tmp_path):
    path = write(tmp_path, BASE)
    expect_error(path, "shapes[1].emission", "<= 1e\\+30", ["shapes[1].emission=1.0e+39"])
    expect_error(path, "shapes[0].transform", "beyond", ["shapes[0].transform=[{scale: 1.0e+300}]"])
    # A mesh file's own coordinates are the file's fault, not the transform's (it has none).
    (tmp_path / "far.obj").write_text("v 1e20 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n")
    doc = edit(shapes=[*BASE["shapes"], {"type": "mesh", "file": "far.obj", "material": "white"}])
    expect_error(write(tmp_path, doc, "far.yaml"), "shapes[2].file", "far.obj: .* reach 1e\\+20")
    expect_error(path, "film.width", "<= 16384", ["film.width=100000"])
    d = np.full((2, 2, 2), 1e39)  # finite in float64, inf in float32
    expect_error(grid_scene(tmp_path, d), "media.smoke.density", "<= 1e\\+30")
    # Finite in float32 but at its edge: the majorant grid's margin overflowed there.
    d = np.full((2, 2, 2), 3.4e38)
    expect_error(grid_scene(tmp_path, d, sigma_t=1e-9), "media.smoke.density", "<= 1e\\+30")
    path = write(tmp_path, BASE, "plain.yaml")  # grid_scene rewrote scene.yaml
    expect_error(path, "camera.origin[2]", "<= 1e\\+15", ["camera.origin=[0, 0, 1.0e+39]"])
    fog = "media.fog={type: homogeneous, sigma_t: 1.0e+20, albedo: 0.5, scale: 1.0e+20}"
    expect_error(path, "media.fog", "sigma_t x scale is 1e\\+40, above 1e\\+30", [fog])
    grid = grid_scene(tmp_path, np.full((2, 2, 2), 1e20), sigma_t=1e20)
    expect_error(grid, "media.smoke", "the densest voxel is 1e\\+40")
    far = grid_scene(tmp_path, np.ones((2, 2, 2)), transform=[{"translate": [1e15, 0, 0]}])
    expect_error(far, "media.smoke.transform", "grid's box beyond")


def test_a_voxel_too_dense_to_track_is_an_error(tmp_path):
    """Optical depth across a voxel is bounded (renders used to hang at 1e17 per voxel, where a
    tracking step rounds to nothing); the longest voxel edge counts, and the transform's scale."""
    d = np.zeros((2, 4, 2))
    d[0, 0, 0] = 1e4  # edges 0.5, 0.25, 0.5 in the unit cube: 5e3 optical depths, allowed
    load_scene(grid_scene(tmp_path, d))
    path = grid_scene(tmp_path, d, scale=3.0)
    expect_error(path, "media.smoke", "1.5e\\+04 optical depths across .* at most 10000")
    path = grid_scene(tmp_path, d, transform=[{"scale": [1, 1, 2.5]}])
    expect_error(path, "media.smoke", "1.25e\\+04 optical depths across")


@pytest.mark.parametrize("scale, ok", [(1e-9, False), (5e-8, True), (3e11, True), (1e13, False)])
def test_scenes_beyond_the_checked_sizes_are_refused(tmp_path, scale, ok):
    """cbox-fog scaled whole rendered wrong in every method at 3.5e-9 and 3.5e13 units across
    (found by a review); the loader keeps sizes from 1e-7 to 1e12 (here 3 x scale)."""
    doc = edit()
    for shape in doc["shapes"]:
        shape["transform"] = [*shape.get("transform", []), {"scale": scale}]
    if ok:
        load_scene(write(tmp_path, doc))
    else:
        expect_error(
            write(tmp_path, doc), "shapes", "the shapes span .* units; .* 1e-07 to 1e\\+12"
        )


def test_a_rotated_grid_is_refused_on_load(tmp_path):
    """Mitsuba supports only axis-aligned grids: `pgi validate` says so, not the reference."""
    turn = [{"rotate": {"axis": [0, 0, 1], "angle": 30}}]
    expect_error(grid_scene(tmp_path, np.ones((2, 2, 2)), transform=turn), "media.smoke.transform",
                 "rotates the grid")  # fmt: skip
    quarter = [{"rotate": {"axis": [0, 0, 1], "angle": 90}}]  # axes swapped: still a rotation
    expect_error(grid_scene(tmp_path, np.ones((2, 2, 2)), transform=quarter),
                 "media.smoke.transform", "rotates")  # fmt: skip


def test_exponents_without_a_dot_are_numbers(tmp_path):
    # YAML 1.1 reads 1e-3 as a string; scene files and overrides read it as a number
    path = write(tmp_path, BASE.copy() | {"film": {"width": 8, "height": 6}})
    fog = "media.fog={type: homogeneous, sigma_t: 1e-3, albedo: 5E-1}"
    m = load_scene(path, [fog]).media["fog"]
    assert m.sigma_t == (1e-3,) * 3 and m.albedo == (0.5,) * 3


def test_unreadable_files_are_one_line_errors(tmp_path):
    (tmp_path / "latin1.yaml").write_bytes('description: "Lumi\xe8re"\n'.encode("latin-1"))
    with pytest.raises(PgiError, match="not a UTF-8 text file"):
        load_scene(tmp_path / "latin1.yaml")
    (tmp_path / "d.npy").write_text("not numpy\n")
    doc = edit(media={"smoke": {"type": "grid", "density": "d.npy", "albedo": 0.5}})
    expect_error(write(tmp_path, doc), "media.smoke.density", "not a numpy .npy file")
    np.save(tmp_path / "d.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    expect_error(write(tmp_path, doc), "media.smoke.density", "holds Python objects")
    (tmp_path / "empty.yaml").write_text("")
    with pytest.raises(PgiError, match="empty.yaml: the file is empty"):
        load_scene(tmp_path / "empty.yaml")
    (tmp_path / "folder").mkdir()
    expect_error(write(tmp_path, edit(include="folder")), "include[0]", "is a folder")
    # A .npy header that breaks numpy's own parser (found by a review: a traceback)
    (tmp_path / "d.npy").write_bytes(b"\x93NUMPY\x01\x00\x10\x00{'descr': 'zz', }   \n" + b"x" * 40)
    expect_error(write(tmp_path, doc), "media.smoke.density", "cannot read .*d.npy as a .npy")
    msg = expect_error(grid_scene(tmp_path, np.ones((4, 4))), "media.smoke.density", "3-D")
    assert "shape [4, 4] of float64" in msg
    # A header that claims 4e15 voxels over 64 bytes: the file is mapped, not read, so this
    # is no "out of memory" that names no file.
    with open(tmp_path / "d.npy", "wb") as f:
        header = {"descr": "<f4", "fortran_order": False, "shape": (100000, 100000, 100000)}
        np.lib.format.write_array_header_1_0(f, header)
        f.write(b"x" * 64)
    expect_error(write(tmp_path, doc), "media.smoke.density", "d.npy as a .npy array: its header")
    # A header whose shape is smaller than the data: numpy maps the first voxels silently.
    with open(tmp_path / "d.npy", "wb") as f:
        header = {"descr": "<f4", "fortran_order": False, "shape": (2, 2, 2)}
        np.lib.format.write_array_header_1_0(f, header)
        f.write(np.ones(27, np.float32).tobytes())
    msg = expect_error(write(tmp_path, doc), "media.smoke.density", "76 bytes more than")
    assert "shape [2, 2, 2] of float32" in msg


def test_a_broken_included_section_is_not_hidden(tmp_path):
    write(tmp_path, {"materials": [1, 2]}, "common.yaml")
    doc = edit(include="common.yaml")
    with pytest.raises(PgiError, match=r"common\.yaml: materials: expected a mapping"):
        load_scene(write(tmp_path, doc))


def test_a_name_that_is_not_text_is_blamed_on_its_own_file(tmp_path):
    """A material named 1 in the including file: the message names that file, not the
    included one whose materials the merge started from."""
    base = yaml.safe_load(yaml.safe_dump(BASE))
    del base["name"], base["description"]
    write(tmp_path, base, "common.yaml")
    path = write(tmp_path, "include: common.yaml\nmaterials:\n  1: {type: diffuse}\n")
    with pytest.raises(
        PgiError, match=rf"^{re.escape(str(path))}: materials\.1: expected a name \(string\)"
    ):
        load_scene(path)


def test_lights_that_emit_nothing_do_not_count(tmp_path):
    path = write(tmp_path, BASE)
    expect_error(path, "shapes[1].emission", "this emitter is black and no other light emits",
                 ["shapes[1].emission=0"])  # fmt: skip
    doc = yaml.safe_load(yaml.safe_dump(BASE))
    del doc["shapes"][1]["emission"]
    expect_error(write(tmp_path, doc), "lights", r"lights: no light emits: add a light")


def test_scene_sources_are_every_file_a_scene_reads(tmp_path: Path) -> None:
    """The workflow's inputs of a scene: its file, its includes and the assets they name."""
    scenes = find_scene_file("cbox").resolve().parents[1]

    def names(scene: str) -> list[str]:
        return [p.relative_to(scenes).as_posix() for p in scene_sources(scene)]

    assert names("cbox-grid") == ["cbox-grid/scene.yaml", "cbox/box.yaml", "cbox-grid/density.npy"]
    assert names("smoke") == ["smoke/scene.yaml", "smoke/plume.vdb"]
    assert names("juice") == ["juice/scene.yaml", "cbox/box.yaml", "juice/juice.ply"]
    # an asset named inside an included file is resolved next to that file; missing files and
    # unreadable includes are left to the loader to report
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "parts.yaml").write_text(
        "media: {g: {type: grid, density: {type: npy, file: d.npy}, albedo: 1}}\n"
        "shapes: [{type: mesh, file: gone.ply}]\n"
    )
    (tmp_path / "lib" / "d.npy").write_bytes(b"")
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "scene.yaml").write_text("include: [../lib/parts.yaml, ../lib/none.yaml]\n")
    found = [p.relative_to(tmp_path).as_posix() for p in scene_sources(tmp_path / "s")]
    assert found == ["s/scene.yaml", "lib/parts.yaml", "lib/d.npy"]
    # through a symlinked scene folder, ".." is taken from the folder it points to (as the
    # loader's file reads do)
    (tmp_path / "links").mkdir()
    (tmp_path / "links" / "s").symlink_to(tmp_path / "s")
    found = [p.relative_to(tmp_path).as_posix() for p in scene_sources(tmp_path / "links" / "s")]
    assert found == ["s/scene.yaml", "lib/parts.yaml", "lib/d.npy"]
    for broken in ("include: [\n", "include: 3\n", "include: {a: b}\n"):  # left to the loader
        (tmp_path / "s" / "scene.yaml").write_text(broken)
        assert scene_sources(tmp_path / "s") == [tmp_path / "s" / "scene.yaml"]


def test_assets_named_by_overrides_are_sources_and_change_the_digest(tmp_path: Path) -> None:
    """A study's `set: [media.smoke.density=other.npy]` reads other.npy: editing it must rerun
    the scene's renders (the workflow once said "nothing to be done")."""
    from renderer.scene.sources import scene_content_digest

    scene = tmp_path / "grid"
    shutil.copytree(find_scene_file("cbox-grid").parent, scene)
    (scene / "scene.yaml").write_text(
        (scene / "scene.yaml").read_text().replace("../cbox/", str(SCENES / "cbox") + "/")
    )
    np.save(scene / "other.npy", np.ones((2, 2, 2), np.float32))
    sets = ["film.width=8", "media.smoke.density=other.npy", "shapes[0]={type: mesh, file: x.ply}"]
    assert [p.name for p in scene_sources(scene, sets)] == [
        "scene.yaml", "box.yaml", "density.npy", "other.npy",
    ]  # fmt: skip
    before, unread = scene_content_digest(scene, sets), scene_content_digest(scene)
    np.save(scene / "other.npy", 3 * np.ones((2, 2, 2), np.float32))
    assert scene_content_digest(scene, sets) != before
    assert scene_content_digest(scene) == unread  # without the override it is not read


# --------------------------------------------------------------------------- found by review


def test_yaml_merge_keys_are_read(tmp_path):
    """`<<: *anchor` merges a mapping; keys given beside it win, as YAML means."""
    text = yaml.safe_dump(BASE).replace(
        "materials:\n  white:\n", "materials:\n  grey: &grey\n    type: diffuse\n    "
        "reflectance: 0.2\n  white:\n    <<: *grey\n"
    )  # fmt: skip
    text = text.replace("    reflectance: 0.5\n    type: diffuse\n", "    reflectance: 0.5\n")
    scene = load_scene(write(tmp_path, text))
    assert scene.materials["white"].reflectance == (0.5,) * 3
    assert scene.materials["white"].type == "diffuse"
    # Duplicates among the keys written out are still refused.
    twice = text.replace("    reflectance: 0.5\n", "    reflectance: 0.5\n    reflectance: 0.6\n")
    with pytest.raises(PgiError, match="duplicate key 'reflectance'"):
        load_scene(write(tmp_path, twice, "twice.yaml"))


@pytest.mark.parametrize("key", ["max_depth", "rr_depth"])
def test_depths_fit_32_bit_ints(tmp_path, key):
    expect_error(write(tmp_path, BASE), f"integrator.{key}", "<= 2147483647",
                 [f"integrator.{key}=2147483648"])  # fmt: skip


def test_vectors_too_short_to_normalise_are_refused(tmp_path):
    path = write(tmp_path, BASE)
    sun = "lights=[{type: directional, direction: [0, 0, -1.0e-200], irradiance: 1}]"
    expect_error(path, "lights[0].direction", "non-zero vector", [sun])
    expect_error(path, "camera.target", "view direction is undefined",
                 ["camera.origin=[0, 0, 0]", "camera.target=[0, 0, -1.0e-200]"])  # fmt: skip
    turn = "shapes[0].transform=[{rotate: {axis: [1.0e-200, 1.0e-200, 0], angle: 30}}]"
    expect_error(path, "shapes[0].transform[0].rotate.axis", "non-zero vector", [turn])
    # Short but normalisable: a camera 1e-90 from its target still loads.
    load_scene(path, ["camera.origin=[0, 0, 1.0e-90]", "camera.target=[0, 0, 0]"])


def test_mesh_files_that_hold_no_usable_triangles(tmp_path):
    header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    header += "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
    (tmp_path / "oob.ply").write_text(header + "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    (tmp_path / "words.obj").write_text("hello\n")
    (tmp_path / "noise.ply").write_bytes(np.random.default_rng(0).bytes(300))
    # Mitsuba's cause, not the plugin context it wraps it in (which filled the message)
    (tmp_path / "short.ply").write_text(header + "end_header\n0 0 0\n1 0 0\n3 0 1 2\n")
    # A quad: Mitsuba's PLY loader reads triangles only, and its message did not say so.
    quad = header.replace("vertex 3", "vertex 4") + "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
    (tmp_path / "quad.ply").write_text(quad + "4 0 1 2 3\n")
    binary = quad.replace("ascii", "binary_little_endian").split("end_header")[0].encode()
    binary += (
        b"end_header\n" + np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "<f4").tobytes()
    )
    (tmp_path / "binquad.ply").write_bytes(binary + b"\x04" + np.arange(4, dtype="<i4").tobytes())
    triangles_only = "PLY faces of three vertices only"
    cases = [("oob.ply", "refers to vertex 7, but there are 3"), ("words.obj", "no triangles"),
             ("noise.ply", "cannot load"),
             ("short.ply", 'short.ply: could not parse "int" value for field'),
             ("quad.ply", triangles_only), ("binquad.ply", triangles_only)]  # fmt: skip
    for name, pattern in cases:
        doc = edit(shapes=[*BASE["shapes"], {"type": "mesh", "file": name, "material": "white"}])
        expect_error(write(tmp_path, doc, f"{name}.yaml"), "shapes[2].file", pattern)


@pytest.mark.parametrize(
    ("content", "pattern"),
    [
        (np.array(["a", "b"]), "expected numbers"),
        (np.array([1 + 2j, 3]), "expected numbers"),
        (np.array([True, False]), "expected numbers"),
        (b"", "cannot read"),
        (np.ones((3, 3)), "a table of shape \\[3, 3\\]"),
        ("0 1\n90 2\n180 5\n", "a table of shape \\[3, 2\\]"),  # angles beside values
        ("0.5 0.8\n2.0\n9.0\n", "lines hold different counts of numbers; write one number per"),
        ("", "holds no numbers"),
        # One value in a .npy (read as a memory map, which numpy's squeeze once failed on).
        (np.array([1.0]), "needs >= 2 values"),
        (np.array([[1.0]]), "needs >= 2 values"),
    ],
)
def test_tabulated_phase_files_of_the_wrong_kind(tmp_path, content, pattern):
    name = "table.txt" if isinstance(content, str) else "table.npy"
    file = tmp_path / name
    if isinstance(content, str):
        file.write_text(content)
    elif isinstance(content, bytes):
        file.write_bytes(content)
    else:
        np.save(file, content)
    fog = "media.fog={type: homogeneous, sigma_t: 1, albedo: 0.5, "
    fog += f"phase: {{type: tabulated, file: {name}}}}}"
    expect_error(write(tmp_path, BASE), "media.fog.phase.file", pattern, [fog])


@pytest.mark.parametrize("value", [1e-50, 1e308])
def test_tabulated_phase_values_are_scaled_to_a_peak_of_one(tmp_path, value):
    """Only the shape matters: tiny values must not vanish in Mitsuba's float32, huge ones
    must not overflow their sum."""
    fog = "media.fog={type: homogeneous, sigma_t: 1, albedo: 0.5, "
    fog += f"phase: {{type: tabulated, values: [{value!r}, {value!r}, {value / 2!r}]}}}}"
    phase = load_scene(write(tmp_path, BASE), [fog]).media["fog"].phase
    np.testing.assert_allclose(phase.values, [1, 1, 0.5])


def test_grid_size_does_not_make_it_singular(tmp_path):
    tiny = grid_scene(tmp_path, np.ones((2, 2, 2)), transform=[{"scale": 1e-5}])
    assert load_scene(tiny).media["smoke"].to_world[0, 0] == pytest.approx(1e-5)
    flat = grid_scene(tmp_path, np.ones((2, 2, 2)), transform=[{"scale": [1, 1, 0]}])
    expect_error(flat, "media.smoke.transform", "singular")


def test_perlin_octaves_beyond_the_lattice_are_refused(tmp_path):
    noise = {"type": "perlin", "resolution": 4, "octaves": 16, "frequency": 1e4,
             "lacunarity": 16, "gain": 16}  # fmt: skip
    doc = edit(media={"fog": {"type": "grid", "density": noise, "albedo": 0.5}})
    expect_error(write(tmp_path, doc), "media.fog.density", "finest octave")
    noise |= {"octaves": 2, "offset": 1e300}
    expect_error(write(tmp_path, doc), "media.fog.density.offset", "<= 1e\\+06")


def test_vdb_bbox_near_the_end_of_int32_is_refused(tmp_path):
    """OpenVDB crashed (a segmentation fault) reading a box at 2^31 - 4096."""
    shutil.copy(SCENES / "smoke" / "plume.vdb", tmp_path / "p.vdb")
    box = {"type": "vdb", "file": "p.vdb", "bbox": [[2147479552, 0, 0], [2147479552, 0, 0]]}
    doc = edit(media={"fog": {"type": "grid", "density": box, "albedo": 0.5}})
    expect_error(write(tmp_path, doc), "media.fog.density.bbox[0][0]", "<= 1073741824")
    # The same from a file's own active voxels, with no bbox given.
    vdb = pytest.importorskip("pyopenvdb")
    grid = vdb.FloatGrid()
    grid.name = "density"
    grid.getAccessor().setValueOn((2147479552, 5, 5), 1.0)
    vdb.write(str(tmp_path / "far.vdb"), grids=[grid])
    doc = edit(media={"fog": {"type": "grid", "density": "far.vdb", "albedo": 0.5}})
    expect_error(write(tmp_path, doc), "media.fog.density", "reaches beyond \\+-2\\^30 voxels")


def test_loader_hard_cases_from_fuzzing(tmp_path):
    """Inputs that crashed, hung or printed a traceback or warnings before the error."""
    grid = edit(media={"fog": {"type": "grid", "density": {"type": "step", "resolution": 4,
                                                             "values": [0, 1]},
                               "albedo": 0.5}})  # fmt: skip
    path = write(tmp_path, grid)
    # A subnormal scale: relative to the box it is not flat, but the inverse overflows (the
    # core then crashed).
    subnormal = "media.fog.transform=[{scale: [1.0e-310, 2.0, 2.0]}]"
    expect_error(path, "media.fog.transform", "is singular", [subnormal])
    # A value beyond float32 is a bound on the key, not "non-finite values" after the cast.
    expect_error(path, "media.fog.density.values[0]", "<= 1e\\+30",
                 ["media.fog.density.values=[1.0e300, 1]"])  # fmt: skip
    # A step grid of one voxel across its other axes: a broadcast view with zero strides,
    # which the core refused with a TypeError.
    from renderer.engine import build_native_scene

    build_native_scene(load_scene(path, ["media.fog.density.resolution=[4, 1, 1]"]))
    # Without Russian roulette nothing ends a path in a closed lossless scene.
    expect_error(path, "integrator.rr_depth", "at most 10000", ["integrator.rr_depth=10001"])
    load_scene(path, ["integrator.rr_depth=100000", "integrator.max_depth=10000"])
    # Integers past float's range (hex literals may be thousands of digits) and list indices
    # too long for int(): one line each, not an OverflowError or ValueError.
    expect_error(
        path, "camera.fov", "got an integer of about 400 digits", ["camera.fov=" + "9" * 400]
    )
    expect_error(
        path, "film.width", "an integer of about 4816 digits", ["film.width=0x" + "f" * 4000]
    )
    with pytest.raises(PgiError, match="list index too large"):
        load_scene(path, [f"shapes[{'1' * 4400}].x=1"])
    # Python refuses int() of over 4300 digits: a YAML error, not a ValueError.
    with pytest.raises(PgiError, match="an integer of over 4300 digits"):
        load_scene(path, ["film.width=" + "9" * 5000])
    (tmp_path / "big.yaml").write_text("film: {width: " + "9" * 5000 + ", height: 8}\n")
    with pytest.raises(PgiError, match="big.yaml: invalid YAML: an integer of over 4300"):
        load_scene(tmp_path / "big.yaml")


def test_build_stage_errors_name_the_file_a_shape_is_written_in(tmp_path):
    """Shapes are merged, included ones first: a shape's index in the merged list is not
    where the user wrote it."""
    from renderer.engine import build_native_scene

    box = SCENES / "cbox" / "box.yaml"
    tiny = {"name": "tiny", "type": "rectangle", "material": "white", "emission": 1.0,
            "transform": [{"scale": 1.0e-9}, {"translate": [0, 1000, 0]}]}  # fmt: skip
    path = write(tmp_path, {"include": str(box), "shapes": [tiny]})
    scene = load_scene(path)
    assert len(scene.shapes) > 1 and scene.shapes[-1].name == "tiny"
    where = re.escape(f"{path}: shapes[0] (tiny): every triangle of this emitter is degenerate")
    with pytest.raises(PgiError, match=where):
        build_native_scene(scene)


def test_mie_tables_that_would_take_minutes_are_refused(tmp_path):
    path = write(tmp_path, edit(media={"fog": {"type": "homogeneous", "sigma_t": 1,
                                               "albedo": 0.5}}))  # fmt: skip
    huge = "media.fog.phase={type: mie, effective_radius: 50, effective_variance: 0.5, "
    expect_error(path, "media.fog.phase", "size parameter 20913; the table would take minutes",
                 [huge + "wavelength: 0.1, resolution: 16}"])  # fmt: skip
    expect_error(path, "media.fog.phase.resolution", "<= 8192",
                 ["media.fog.phase={type: mie, resolution: 65536}"])  # fmt: skip
    expect_error(path, "media.fog.phase.ior", "<= 10", ["media.fog.phase={type: mie, ior: 1.0e5}"])


def test_a_truncated_vdb_is_a_short_error(tmp_path):
    (tmp_path / "t.vdb").write_bytes((SCENES / "smoke" / "plume.vdb").read_bytes()[:2000])
    doc = edit(media={"fog": {"type": "grid", "density": "t.vdb", "albedo": 0.5}})
    msg = expect_error(write(tmp_path, doc), "media.fog.density", "cannot read as an OpenVDB")
    assert len(msg) < 400
    # OpenVDB's own words ("Map is not registered") did not say the file is damaged
    for size, why in [(100, "corrupt or truncated"), (0, "the file is empty")]:
        (tmp_path / "t.vdb").write_bytes((SCENES / "smoke" / "plume.vdb").read_bytes()[:size])
        expect_error(write(tmp_path, doc), "media.fog.density", f"OpenVDB file: {why}")


@pytest.mark.parametrize(
    ("key", "text"),
    [
        ("camera.fov", "1:20"),
        ("film.width", "0100"),
        ("film.width", "2_56"),
        ("camera.fov", "1_0.5"),
    ],
)
def test_yaml_1_1_number_forms_are_not_read_silently(tmp_path, key, text):
    """YAML 1.1 read 1:20 as 80 (base 60), 0100 as 64 (octal) and 2_56 as 256 (digit groups);
    YAML 1.2, and pgi, do not."""
    expect_error(write(tmp_path, BASE), key, f"got '{text}'", [f"{key}={text}"])
    field = {"camera.fov": "fov: 40", "film.width": "width: 8"}[key]
    doc = yaml.safe_dump(BASE).replace(field, field.split(":")[0] + f": {text}")
    expect_error(write(tmp_path, doc, "file.yaml"), key, f"got '{text}'")


def test_yaml_1_1_booleans_are_text(tmp_path):
    """YAML 1.1 read `off` as False: a material named off was "expected a name, got False"."""
    doc = yaml.safe_load(yaml.safe_dump(BASE))
    doc["materials"] = {"off": doc["materials"]["white"]}
    for shape in doc["shapes"]:
        shape["material"] = "off"
    text = yaml.safe_dump(doc).replace("'off'", "off")  # unquoted, as a person writes it
    assert "material: off" in text
    assert load_scene(write(tmp_path, text, "file.yaml")).shapes[0].material == "off"
    expect_error(write(tmp_path, BASE), "camera.fov", "got true$", ["camera.fov=true"])
    expect_error(write(tmp_path, BASE), "camera.fov", "got 'yes'", ["camera.fov=yes"])


def test_a_scene_without_a_name_is_named_by_its_folder_however_it_is_given(tmp_path, monkeypatch):
    """ "." and "scene.yaml" from inside the folder named the scene "" (the sidecar then
    recorded no scene)."""
    folder = tmp_path / "mybox"
    shutil.copytree(SCENES / "cbox", folder)
    text = (folder / "scene.yaml").read_text()
    (folder / "scene.yaml").write_text(re.sub(r"(?m)^name:.*\n", "", text))
    assert load_scene(folder).name == "mybox"
    monkeypatch.chdir(folder)
    assert load_scene(".").name == "mybox" and load_scene("scene.yaml").name == "mybox"


def test_a_value_of_nested_aliases_is_quoted_without_expanding_it(tmp_path):
    """Eight levels of YAML aliases, ten deep each, make a 1 KB file a list of 10^8 strings:
    the message quoting it built its whole repr first (10 s and 750 MB; one level more,
    7.5 GB). Quoted now with bounded depth and length: the check allocates little."""
    import tracemalloc

    lines = ["stresses:", "  - &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"  - &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 7)]
    doc = yaml.safe_load("\n".join(lines))
    tracemalloc.start()
    try:
        msg = expect_error(write(tmp_path, edit(**doc)), "stresses", "expected a list of strings")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(msg) < 300 and peak < 20e6, (msg, peak)


@pytest.mark.parametrize(
    ("override", "key", "shown"),
    [
        ("camera.fov=true", "camera.fov", "got true"),
        ("film.height=null", "film.height", "got null"),
        ("camera.fov=2001-01-01", "camera.fov", "got 2001-01-01"),
    ],
)
def test_values_are_quoted_as_yaml_writes_them(tmp_path, override, key, shown):
    """Not as Python's True, None and datetime.date(2001, 1, 1) (a review)."""
    msg = expect_error(write(tmp_path, BASE), key, re.escape(shown), [override])
    assert msg.endswith(shown), msg


def test_inputs_that_are_not_regular_files_say_what_they_are(tmp_path, monkeypatch):
    """A folder, a pipe or a symbolic link to nothing where a file was expected is named as
    such (each was "not found" before, which sent the user looking for a missing file)."""
    (tmp_path / "d.npy").mkdir()
    os.mkfifo(tmp_path / "pipe.ply")
    (tmp_path / "loop.yaml").symlink_to(tmp_path / "loop.yaml")
    grid = {"fog": {"type": "grid", "density": "d.npy", "sigma_t": 1, "albedo": 0.5}}
    expect_error(write(tmp_path, edit(media=grid)), "media.fog.density", "density file is a folder")
    mesh = {"type": "mesh", "file": "pipe.ply", "material": "white"}
    doc = edit(shapes=[*BASE["shapes"], mesh])
    expect_error(write(tmp_path, doc), "shapes[2].file", "mesh file is not a regular file")
    with pytest.raises(PgiError, match="scene file is a symbolic link to nothing"):
        load_scene(tmp_path / "loop.yaml")
    monkeypatch.chdir(tmp_path)  # a bare name that exists here, not a scene of that name
    with pytest.raises(PgiError, match="^pipe.ply: scene file is not a regular file"):
        load_scene("pipe.ply")


def test_a_file_included_twice_is_named(tmp_path):
    base = yaml.safe_load(yaml.safe_dump(BASE))
    del base["name"], base["description"]
    write(tmp_path, base, "common.yaml")
    path = write(tmp_path, "include: [common.yaml, ./common.yaml]\n")
    expect_error(path, "include[1]", r"already included \(include\[0\]\)")


def test_a_tabulated_phase_needs_values_or_a_file(tmp_path):
    both = {"type": "tabulated", "values": [1], "file": "p.txt"}
    for phase, given in (({"type": "tabulated"}, "neither"), (both, "both")):
        fog = {"fog": {"type": "homogeneous", "sigma_t": 1, "albedo": 0.5, "phase": phase}}
        expect_error(write(tmp_path, edit(media=fog)), "media.fog.phase", f"; {given} given$")


def test_a_check_that_fails_beside_an_override_names_it(tmp_path):
    """camera.target equals camera.origin only because an override moved the origin: the
    message says so, though the key it names (target) is the file's."""
    path = write(tmp_path, BASE)
    target = BASE["camera"]["target"]
    msg = expect_error(path, "camera.target", "equals camera.origin",
                       overrides=["film.width=8", f"camera.origin={target}"])  # fmt: skip
    assert f"(after override 'camera.origin={target}')" in msg and "film.width" not in msg


def test_an_override_replaced_by_a_later_one_is_not_blamed(tmp_path):
    """`film.width=64` then `film={height: 32}`: the second override removed the width, so
    the missing width is the second's doing (the first was once named)."""
    path = write(tmp_path, BASE)
    msg = expect_error(path, "film.width", "missing required key",
                       overrides=["film.width=64", "film={height: 32}"])  # fmt: skip
    assert "(override 'film={height: 32}')" in msg and "film.width=64" not in msg, msg
    msg = expect_error(path, "camera.target", "equals camera.origin",
                       overrides=["camera.origin=[5, 5, 5]", "camera={origin: [0, 0, 0], "
                                  "target: [0, 0, 0], up: [0, 1, 0], fov: 40}"])  # fmt: skip
    assert "camera.origin=[5, 5, 5]" not in msg, msg


def test_an_override_into_a_value_blames_what_made_it_a_value(tmp_path):
    """`film=3` then `film.width=8`: film is no section any more, and the message says so and
    names the override that made it 3 (it once said film.width did not exist)."""
    path = write(tmp_path, BASE)
    with pytest.raises(PgiError) as e:
        load_scene(path, ["film=3", "film.width=8"])
    msg = str(e.value)
    assert "film is 3, not a mapping or list, so film.width cannot be set" in msg, msg
    assert "(override 'film=3')" in msg, msg
    with pytest.raises(PgiError, match=r"film.width is \d+, not a mapping or list"):
        load_scene(path, ["film.width.x=8"])


def test_the_kinds_a_scene_names_are_the_cores():
    """The loader checks names without the native core (Mitsuba's export needs none); the
    core binds its kinds under the same names, and its bindings refuse a value that is none
    of them (a phase function number 7, or a name given as a string)."""
    from renderer import _core
    from renderer.scene.media import PHASES
    from renderer.scene.render_settings import ESTIMATORS
    from renderer.scene.surfaces import MATERIALS

    assert list(_core.MaterialType.__members__) == list(MATERIALS)
    assert list(_core.Estimator.__members__) == list(ESTIMATORS)
    # "mie" is a tabulated phase function whose table the loader computes.
    assert list(_core.PhaseType.__members__) == [k for k in PHASES if k != "mie"]
    for not_a_kind in (7, "hg"):
        with pytest.raises(TypeError):
            _core.eval_phase(not_a_kind, 0.0, (0.0, 0.0, 1.0), np.array([[0.0, 0.0, 1.0]]))
