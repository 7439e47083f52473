"""Readers of the surfaces: the ``materials`` section and the ``shapes`` section (primitives
and mesh files, placed by their transforms, with their materials, emission and media)."""

from __future__ import annotations

from typing import Any

import numpy as np

from renderer.errors import mitsuba_cause, not_a_file, one_line
from renderer.errors import shorten_repr as _describe
from renderer.scene import primitives
from renderer.scene import transform as xf
from renderer.scene.document import KeyPath
from renderer.scene.limits import MAX_COORDINATE, MAX_LIGHT, MAX_SCENE_SIZE, MIN_SCENE_SIZE
from renderer.scene.media import read_stated_medium
from renderer.scene.model import Material, Medium, Shape
from renderer.scene.validation import Validator

MATERIALS = ("diffuse", "mirror", "dielectric", "null")
MESH_SUFFIXES = (".ply", ".obj")


def read_materials(val: Validator, doc: dict) -> dict[str, Material]:
    """The ``materials`` section: name -> material (absent or empty: none)."""
    return {k: _material(val, k, v) for k, v in val.table(doc, "materials").items()}


def _material(val: Validator, name: str, d: Any) -> Material:
    p: KeyPath = ("materials", name)
    kind = val.kind(d, p, MATERIALS)
    extra = {"diffuse": ("reflectance",), "dielectric": ("ior",)}.get(kind, ())
    val.mapping(d, p, required=("type",), optional=extra)
    if kind == "diffuse":
        return Material(
            name, kind, reflectance=val.rgb(d.get("reflectance", 0.5), p + ("reflectance",), hi=1)
        )
    if kind == "dielectric":
        return Material(
            name,
            kind,
            ior=val.number(d.get("ior", 1.5), p + ("ior",), lo=0, lo_open=True, float32=True),
        )
    return Material(name, kind)


def read_shapes(
    val: Validator, doc: dict, materials: dict[str, Material], media: dict[str, Medium]
) -> list[Shape]:
    """The ``shapes`` section: at least one shape, names unique, the whole of a size the
    renderer is checked for."""
    shapes_doc = doc["shapes"]
    if not isinstance(shapes_doc, list) or not shapes_doc:
        val.fail(("shapes",), f"expected a non-empty list of shapes, got {_describe(shapes_doc)}")
    shapes = [_shape(val, i, d, materials, media) for i, d in enumerate(shapes_doc)]
    names = [s.name for s in shapes]
    for i, n in enumerate(names):
        if n in names[:i]:
            val.fail(("shapes", i, "name"), f"duplicate shape name {n!r}")
    corners = np.concatenate([s.vertices for s in shapes])
    size = float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))
    if not MIN_SCENE_SIZE <= size <= MAX_SCENE_SIZE:
        val.fail(
            ("shapes",),
            f"the shapes span {size:.3g} units; the renderer is checked for scenes "
            f"{MIN_SCENE_SIZE:g} to {MAX_SCENE_SIZE:g} across: scale the scene (and sigma_t "
            "inversely) into that range",
        )
    return shapes


def _shape(val: Validator, i: int, d: Any, materials: dict, media: dict) -> Shape:
    p: KeyPath = ("shapes", i)
    kind = val.kind(d, p, ("rectangle", "cube", "sphere", "mesh"))
    common = ("name", "transform", "emission", "interior", "exterior", "medium")
    extra = {"sphere": ("subdivisions",), "mesh": ("file",)}.get(kind, ())
    val.mapping(d, p, required=("type", "material") + (("file",) if kind == "mesh" else ()),
                optional=common + extra)  # fmt: skip
    if kind == "rectangle":
        v, f = primitives.rectangle()
    elif kind == "cube":
        v, f = primitives.cube()
    elif kind == "sphere":
        v, f = primitives.icosphere(
            val.integer(d.get("subdivisions", 3), p + ("subdivisions",), 0, 7)
        )
    else:
        v, f = _mesh_file(val, d["file"], p + ("file",))
        if not np.all(np.abs(v) < MAX_COORDINATE):  # the file's own, before any transform
            val.fail(
                p + ("file",),
                f"{d['file']}: vertex coordinates reach {np.abs(v).max():g}, beyond "
                f"+-{MAX_COORDINATE:g}",
            )
    m = val.transform(d.get("transform", []), p + ("transform",))
    v_file = v
    with np.errstate(over="ignore", invalid="ignore"):
        v = xf.apply_points(m, v)
    if not np.all(np.abs(v) < MAX_COORDINATE):
        val.fail(p + ("transform",), f"places vertices beyond +-{MAX_COORDINATE:g}")
    if np.linalg.det(m[:3, :3]) < 0:  # a mirroring transform: keep normals on the stated side
        f = f[:, ::-1].copy()
    emission = val.rgb(d["emission"], p + ("emission",), hi=MAX_LIGHT) if "emission" in d else None
    if len(f) == 0 or primitives.area(v, f) <= 0:
        if emission:
            what = "an emitter needs area"
        elif kind == "mesh" and primitives.area(v_file, f) <= 0:
            what = f"its file {d['file']} has no triangle of non-zero area"
        else:
            what = "check its transform"
        val.fail(p, f"shape has zero surface area ({what})")

    def medium_ref(key: str) -> str | None:
        return None if d.get(key) is None else val.name_ref(d[key], p + (key,), media, "medium")

    interior, exterior = medium_ref("interior"), medium_ref("exterior")
    stated = read_stated_medium(val, d, p, media)
    if stated is not None and emission is None:
        val.fail(
            p + ("medium",),
            "only an emitter (a shape with emission) states the medium it emits into; a shape "
            "bounds a medium with interior and exterior",
        )
    if stated is not None and (interior is not None or exterior is not None):
        val.fail(
            p + ("medium",),
            "an emitter that names interior or exterior emits into its exterior (its front "
            "side): remove medium, or name the medium there as exterior",
        )
    return Shape(
        name=val.string(d.get("name", f"{kind}{i}"), p + ("name",)),
        vertices=v, faces=f,
        material=val.name_ref(d["material"], p + ("material",), materials, "material"),
        emission=emission, interior=interior, exterior=exterior, medium=stated,
    )  # fmt: skip


# What Mitsuba's PLY loader says of faces with four vertices or more (ASCII, binary).
_PLY_NOT_TRIANGLES = ("trailing tokens after end of PLY file", "is this a triangle mesh")


def _mesh_file(val: Validator, v: Any, p: KeyPath) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of a .ply/.obj file as Mitsuba's own loader reads them."""
    file = val.o.file(p).parent / val.string(v, p)
    if file.suffix.lower() not in MESH_SUFFIXES:
        val.fail(p, f"expected a .ply or .obj file, got {file.name!r}")
    if not file.is_file():
        val.fail(p, f"mesh file {not_a_file(file)}: {file}")
    if file.stat().st_size == 0:  # Mitsuba's own message for it names another cause
        val.fail(p, f"mesh file is empty: {file}")
    from renderer.mitsuba_env import import_mitsuba

    mi = import_mitsuba()
    try:
        mesh = mi.load_dict(
            {"type": file.suffix.lower()[1:], "filename": str(file), "face_normals": True}
        )
    except Exception as e:  # Mitsuba raises RuntimeError with its parser's message
        lines = str(e).strip().splitlines()
        why = one_line(mitsuba_cause(lines[-1])) if lines else f"not a readable {file.suffix} mesh"
        if file.suffix.lower() == ".ply" and any(s in why for s in _PLY_NOT_TRIANGLES):
            why += " (Mitsuba reads PLY faces of three vertices only: triangulate the mesh)"
        val.fail(p, f"cannot load {file}: {why}")
    v = np.array(mesh.vertex_positions_buffer(), dtype=np.float64).reshape(-1, 3)
    f = np.array(mesh.faces_buffer(), dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        val.fail(p, f"{file} holds no triangles")
    if f.min() < 0 or f.max() >= len(v):  # Mitsuba's PLY reader does not check
        val.fail(p, f"{file}: a face refers to vertex {int(f.max())}, but there are {len(v)}")
    return v, f.astype(np.int32)
