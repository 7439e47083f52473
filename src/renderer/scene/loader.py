"""Load and validate a scene file (YAML) into the resolved :class:`Scene`: the entry point,
which finds the scene file and ties together the other modules of this package.

The format is documented in docs/scene-format.md. Every user mistake raises one
:class:`PgiError` whose message names the file, the key path (``shapes[2].material``) and what
was expected.

Loading happens in four steps: read the file and its ``include`` files (yaml_dialect), merge
them, remembering which file each part came from, for messages and relative paths (document),
apply ``key.path=value`` overrides (document), then validate (validation, limits) and resolve
into model objects (the section readers: render_settings, surfaces, media, density, lights).
The files a scene reads are listed, without loading it, by sources.
"""

from __future__ import annotations

import contextlib
import errno
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from renderer.errors import PgiError, not_a_file, shorten
from renderer.known_methods import IMPLEMENTED, NOT_YET_IMPLEMENTED
from renderer.scene.document import TOP_KEYS, KeyPath, Origins, apply_override, merge_includes
from renderer.scene.lights import check_something_emits, read_lights
from renderer.scene.media import read_media
from renderer.scene.model import Scene
from renderer.scene.render_settings import read_camera, read_film, read_integrator
from renderer.scene.surfaces import read_materials, read_shapes
from renderer.scene.validation import Validator
from renderer.scene.yaml_dialect import read_scene_yaml

SCENE_FILE = "scene.yaml"
REPO_ROOT = Path(__file__).resolve().parents[3]  # src/renderer/scene/loader.py -> repo


def find_scene_file(path: str | Path) -> Path:
    """The scene file for ``path``: a scene.yaml, its folder, or a bare name under scenes/."""
    p = Path(path)
    if p.is_file():
        return p
    candidates = [Path.cwd() / "scenes" / p / SCENE_FILE, REPO_ROOT / "scenes" / p / SCENE_FILE]
    bare_name = len(p.parts) == 1 and not p.suffix
    if p.is_dir():
        if (p / SCENE_FILE).is_file():
            return p / SCENE_FILE
        # An existing path is used as given, so a folder named like a scene hides it: say so.
        named = [c.parent for c in candidates if bare_name and c.is_file()]
        hint = (
            f" (a scene of that name is at {named[0]}: give that path, or run from another folder)"
            if named
            else ""
        )
        raise PgiError(f"{p}: no {SCENE_FILE} in this folder{hint}")
    if bare_name:
        for c in candidates:
            if c.is_file():
                return c
        if p.exists() or p.is_symlink():  # here, but not a scene file: say what it is
            raise PgiError(f"{p}: scene file {not_a_file(p)}")
        looked = ", ".join(dict.fromkeys(str(c.parent.parent) for c in candidates))
        raise PgiError(f"scene {str(path)!r} not found (looked in {looked})")
    raise PgiError(f"{p}: scene file {not_a_file(p)}")


def load_scene(path: str | Path, overrides: Sequence[str] = ()) -> Scene:
    """Load, validate and resolve a scene. ``path``: scene.yaml, its folder, or a scene name.

    ``overrides`` are ``key.path=value`` strings (value parsed as YAML) applied after includes
    and before validation, e.g. ``film.width=64`` or ``media.fog.scale=2``.
    """
    # Overflow in a check's arithmetic is found by the check (a non-finite result), and
    # numpy's warning of it would only add lines before the one-line error.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"), names_too_long():
        return _load_scene(path, overrides)


@contextlib.contextmanager
def names_too_long() -> Iterator[None]:
    """A file name longer than the file system allows makes even `Path.is_file` raise: that
    is the user's file name, so a one-line error naming it."""
    try:
        yield
    except OSError as e:
        if e.errno != errno.ENAMETOOLONG:
            raise
        raise PgiError(f"{shorten(str(e.filename), 120)}: file name too long") from None


def _load_scene(path: str | Path, overrides: Sequence[str]) -> Scene:
    file = find_scene_file(path)
    origins = Origins(file)
    doc = merge_includes(file, read_scene_yaml(file), origins)
    for text in overrides:
        apply_override(doc, text, origins)
    val = Validator(origins)
    val.mapping(doc, (), required=("camera", "film", "shapes"), optional=TOP_KEYS)

    # Materials and media first: the camera and the shapes refer to them by name.
    materials = read_materials(val, doc)
    media = read_media(val, doc)
    camera = read_camera(val, doc, media)
    film = read_film(val, doc)
    integrator = read_integrator(val, doc)
    shapes = read_shapes(val, doc, materials, media)
    lights = read_lights(val, doc)
    check_something_emits(val, shapes, lights)

    return Scene(
        # resolved: a scene given as "." or "scene.yaml" from its own folder is named too
        name=val.string(doc.get("name", file.resolve().parent.name), ("name",)),
        path=file, camera=camera, film=film, integrator=integrator,
        materials=materials, media=media, shapes=shapes, lights=lights,
        description=val.string(doc.get("description", ""), ("description",)).strip(),
        stresses=val.strings(doc.get("stresses", []), ("stresses",)),
        expected_winners=_method_names(val, doc.get("expected_winners", []), ("expected_winners",)),
        locate_key=origins.where,
    )  # fmt: skip


def _method_names(val: Validator, v: Any, p: KeyPath) -> list[str]:
    """Method ids, implemented or from the study's table of methods still to come."""
    known = list(IMPLEMENTED) + list(NOT_YET_IMPLEMENTED)
    names = val.strings(v, p)
    for i, name in enumerate(names):
        val.string(name, p + (i,), known)
    return names
