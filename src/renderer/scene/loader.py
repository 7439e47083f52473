"""Load and validate a scene file (YAML) into the resolved :class:`Scene`.

The format is documented in docs/scene-format.md. Every user mistake raises one
:class:`PgiError` whose message names the file, the key path (``shapes[2].material``) and what
was expected.

Loading happens in four steps: read the file and its ``include`` files, merge them (remembering
which file each part came from, for messages and relative paths), apply ``key.path=value``
overrides, then validate and resolve into model objects.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import warnings
from collections.abc import Hashable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import yaml

from renderer.errors import PgiError, mitsuba_cause, not_a_file, one_line, shorten
from renderer.errors import shorten_repr as _describe
from renderer.ranges import INT32_MAX, integer_problem, number_problem
from renderer.scene import primitives
from renderer.scene import transform as xf
from renderer.scene.model import (
    RGB,
    Camera,
    DirectionalLight,
    Film,
    Integrator,
    Light,
    Material,
    Medium,
    Phase,
    PointLight,
    Scene,
    Shape,
    SpotLight,
    format_path,
)
from renderer.volumes import MAX_GRID_SIDE, MAX_VDB_COORD

# Mie tables: the largest relative index of refraction, the largest droplet's size parameter,
# and its product with the table's resolution (a few seconds of work at most).
MAX_MIE_IOR = 10.0
MAX_MIE_SIZE = 2100
MAX_MIE_WORK = 4.2e6
# Bounces a path may make before Russian roulette or max_depth can end it.
MAX_UNROULETTED_DEPTH = 10_000

SCENE_FILE = "scene.yaml"
# Bounds that keep every value representable in the float32 of Embree and of the images.
MAX_LIGHT = 1e30  # emitted radiance, intensity, irradiance
# A direction or axis shorter than this cannot be normalised: its squared length underflows.
MIN_LENGTH = 1e-100
MAX_COORDINATE = 1e15  # |vertex coordinate| (float32 spacing there is ~1e8: far beyond any scene)
# The size of the shapes' bounding box. cbox-fog scaled whole (sigma_t inversely) gave every
# method the same image from a size of 1e-8 to 3.5e12, and wrong ones at 3.5e-9 (pt 12 %
# dark, pm 2x, ppb 3x too bright) and at 3.5e13: the range kept leaves a margin of 10x below.
MIN_SCENE_SIZE, MAX_SCENE_SIZE = 1e-7, 1e12
MAX_EXTINCTION = 1e30  # sigma_t x scale (x the densest voxel): Mitsuba multiplies in float32
# A voxel value: float32 with headroom (the majorant grid widens its bounds by a relative
# margin; at the float32 maximum that overflowed to infinity and tracking never advanced).
MAX_DENSITY = 1e30
# Optical depth across one voxel of a grid (its longest edge, at the densest voxel). Tracking
# pays ~1 lookup per unit of majorant optical depth, and past ~1e14 per unit length a step
# rounds to nothing and a path can collide at one point forever. exp(-1e4) is opaque already;
# the shipped grids stay below 1.
MAX_VOXEL_DEPTH = 1e4
MAX_NOISE_FREQUENCY = 1e6
MAX_FILM_SIDE = 16384
REPO_ROOT = Path(__file__).resolve().parents[3]  # src/renderer/scene/loader.py -> repo

TOP_KEYS = {
    "name", "description", "stresses", "expected_winners", "include",
    "camera", "film", "integrator", "materials", "media", "shapes", "lights",
}  # fmt: skip
INCLUDABLE = {"camera", "film", "integrator", "materials", "media", "shapes", "lights"}
FOV_AXES = ("x", "y", "diagonal", "smaller", "larger")
MESH_SUFFIXES = (".ply", ".obj")
ESTIMATORS = ("delta", "ratio", "residual", "raymarch")
MATERIALS = ("diffuse", "mirror", "dielectric", "null")

KeyPath = tuple[str | int, ...]


# --------------------------------------------------------------------------- finding the file


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


# --------------------------------------------------------------------------- reading YAML


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate mapping keys instead of keeping the last one."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # "<<: *anchor": keys given beside
                continue  # it override the anchor's, as YAML's merge means
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, Hashable):  # e.g. {[1]: 2}: the set below would raise
                raise yaml.constructor.ConstructorError(
                    None, None, "found unhashable key", key_node.start_mark
                )
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


# Numbers and booleans as YAML 1.2 reads them, not YAML 1.1 (PyYAML): 1e-3 is a number, not
# text; 1:20 is not 80 (base 60), 0100 not 64 (octal) and 1_000 not 1000 (digit groups), which
# a scene would misread silently: they stay text, and the validator asks for a number. Only
# true/false are booleans: `material: off` names a material "off", not False.
_INT, _FLOAT = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
_BOOL = "tag:yaml.org,2002:bool"
_UniqueKeyLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT, _FLOAT, _BOOL)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_UniqueKeyLoader.add_implicit_resolver(
    _BOOL, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")
)
_UniqueKeyLoader.add_implicit_resolver(
    _INT, re.compile(r"^[-+]?(?:0|[1-9][0-9]*|0x[0-9a-fA-F]+)$"), list("-+0123456789")
)
_UniqueKeyLoader.add_implicit_resolver(
    _FLOAT,
    re.compile(
        r"^(?:[-+]?[0-9]+\.[0-9]*(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?\.[0-9]+(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?[0-9]+[eE][-+]?[0-9]+"
        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
    ),
    list("-+0123456789."),
)


class _TooDeep(yaml.YAMLError):
    """Nesting deeper than the YAML reader's recursion can follow."""

    problem = "nested too deeply"


class _BadScalar(yaml.YAMLError):
    """A scalar YAML's constructors cannot convert (an integer of over 4300 digits)."""

    def __init__(self, problem: str) -> None:
        super().__init__(problem)
        self.problem = problem


def _load_yaml(text: str) -> Any:
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader subclass)
    except RecursionError:
        raise _TooDeep() from None
    except ValueError as e:  # Python's own limit on int() of long digit strings, or a date
        digits = "digits" in str(e)
        raise _BadScalar(
            "an integer of over 4300 digits" if digits else one_line(str(e), 80)
        ) from None


def parse_yaml_value(text: str, where: str) -> Any:
    """A value given on the command line, read as scene files are (1e-3 is a number).
    A value YAML cannot read is a PgiError naming `where`, the value (shortened) and why."""
    try:
        return _load_yaml(text)
    except yaml.YAMLError as e:
        why = getattr(e, "problem", None)
        raise PgiError(
            f"{where}: value {_describe(text)} is not valid YAML"
            + (f" ({shorten(why, 60)})" if why else "")
        ) from None


def _read_yaml(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise PgiError(f"{path}: cannot read: {e.strerror}") from e
    except UnicodeDecodeError as e:
        raise PgiError(
            f"{path}: not a UTF-8 text file (byte {e.start}: {e.reason}); scene files are YAML"
        ) from None
    doc = _parse_yaml_file(path, text)
    if doc is None:
        raise PgiError(f"{path}: the file is empty; a scene file is a mapping of scene keys")
    if not isinstance(doc, dict):
        raise PgiError(f"{path}: expected a mapping of scene keys at the top level")
    return doc


def _parse_yaml_file(path: Path, text: str) -> Any:
    """The document in ``text`` (read from ``path``); invalid YAML is a PgiError naming the
    file and the line."""
    try:
        return _load_yaml(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark else str(path)
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise PgiError(f"{where}: invalid YAML: {problem}") from None


def check_yaml_file(path: Path) -> tuple[Any, str] | None:
    """Reads a YAML file as scene files are read, for files another reader loads (workflow
    configs): a key given twice is a PgiError naming the line, not the last one silently kept.
    Returns the document and the text it was read from (None if the file cannot be read:
    that reader says so itself)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    return _parse_yaml_file(path, text), text


# --------------------------------------------------------------------------- key paths, origins


class _Origins:
    """Which file (and which key path inside it) each part of the merged document came from."""

    def __init__(self, main: Path) -> None:
        self.main = main
        self.parts: dict[KeyPath, tuple[Path, KeyPath, str]] = {}
        self.overrides: list[tuple[KeyPath, str]] = []  # (key path, the override as quoted)

    def add(self, merged: KeyPath, file: Path, local: KeyPath, note: str = "") -> None:
        self.parts[merged] = (file, local, note)

    def replaced(self, merged: KeyPath) -> None:
        """An override wrote ``merged`` whole: what earlier wrote inside it is gone, and so
        are the earlier overrides of it or inside it."""
        n = len(merged)
        self.parts = {p: v for p, v in self.parts.items() if len(p) <= n or p[:n] != merged}
        self.overrides = [(p, t) for p, t in self.overrides if p[:n] != merged]

    def locate(self, path: KeyPath) -> tuple[Path, KeyPath, str]:
        for n in range(len(path), 0, -1):
            if path[:n] in self.parts:
                file, local, note = self.parts[path[:n]]
                return file, local + path[n:], note
        return self.main, path, ""

    def file(self, path: KeyPath) -> Path:
        return self.locate(path)[0]

    def where(self, path: KeyPath) -> str:
        """The file and key path the merged ``path`` was written at, as messages give them.
        A check that fails beside an override (another key of its section: camera.target
        when the override set camera.origin) names the overrides of that section too."""
        file, local, note = self.locate(path)
        if not note:
            beside = [text for p, text in self.overrides if p[:1] == path[:1]]
            if beside:
                note = f" (after override {', '.join(beside)})"
        return f"{file}{note}: {format_path(local)}"

    def fail(self, path: KeyPath, msg: str) -> NoReturn:
        raise PgiError(f"{self.where(path)}: {msg}")


def _merge_includes(main: Path, doc: dict, origins: _Origins) -> dict:
    """Merge the ``include`` files of ``doc`` under it: ``doc``'s camera/film/integrator replace
    the included ones, materials/media are united by name (a name may be defined once),
    shapes/lights are concatenated, included ones first."""
    inc = doc.pop("include", None)
    if inc is None:
        return doc
    if isinstance(inc, str):
        inc = [inc]
    if not isinstance(inc, list) or not all(isinstance(i, str) for i in inc):
        origins.fail(("include",), "expected a file path or a list of file paths")
    sources = []
    for n, name in enumerate(inc):
        file = main.parent / name
        if file.is_dir():
            origins.fail(("include", n), f"{file} is a folder; include a scene file in it")
        if not file.is_file():
            origins.fail(("include", n), f"included file {not_a_file(file)}: {file}")
        if file.resolve() == main.resolve():
            origins.fail(("include", n), "a scene cannot include itself")
        for earlier, (other, _) in enumerate(sources):
            if file.resolve() == other.resolve():
                origins.fail(("include", n), f"{name} is already included (include[{earlier}])")
        sources.append((file, _read_yaml(file)))
    sources.append((main, doc))
    merged: dict[str, Any] = {}
    for file, part in sources:
        for key, value in part.items():
            if file != main and key not in INCLUDABLE:
                allowed = ", ".join(sorted(INCLUDABLE))
                raise PgiError(
                    f"{file}: {key}: not allowed in an included file (allowed: {allowed})"
                )
            # Merged sections are checked here: a later file must not hide a broken one.
            if key in ("materials", "media") and not isinstance(value, dict | None):
                raise PgiError(
                    f"{file}: {key}: expected a mapping of name -> definition, "
                    f"got {_describe(value)}"
                )
            if key in ("shapes", "lights") and not isinstance(value, list | None):
                raise PgiError(f"{file}: {key}: expected a list, got {_describe(value)}")
            if value is None and key in ("materials", "media"):  # empty: adds nothing
                value = {}
            if value is None and key in ("shapes", "lights"):
                value = []
            if value is None and key in merged:  # an empty camera/film/integrator: keeps the
                continue  # included one (an empty section adds nothing and removes nothing)
            target = merged.get(key)
            if (
                key in ("materials", "media")
                and isinstance(value, dict)
                and isinstance(target, dict)
            ):
                for name, item in value.items():
                    if name in target:
                        raise PgiError(f"{file}: {key}.{name}: already defined in an included file")
                    target[name] = item
                    # as text, as key paths name a table's entries (a YAML 1 included)
                    origins.add((key, str(name)), file, (key, str(name)))
            elif (
                key in ("shapes", "lights") and isinstance(value, list) and isinstance(target, list)
            ):
                for local, item in enumerate(value):
                    origins.add((key, len(target)), file, (key, local))
                    target.append(item)
            else:
                merged[key] = value
                origins.add((key,), file, (key,))
    return merged


# Sections of named definitions: an override may replace an entry whole, not edit a missing one.
_NAMED_TABLES = ("media", "materials")
_KEY = r"[^.\[\]\s=]+"
# An index has at most 9 digits: no list is longer, and int() refuses over 4300.
_OVERRIDE_PATH = re.compile(rf"{_KEY}(\[\d{{1,9}}\])*(\.{_KEY}(\[\d{{1,9}}\])*)*")


def _apply_override(doc: dict, text: str, origins: _Origins) -> None:
    """Apply one ``key.path=value`` override (value parsed as YAML; ``shapes[2].x`` indexes lists).
    Missing intermediate mappings are created; list items must exist."""
    key, sep, raw = text.partition("=")
    key = key.strip()
    if sep and re.search(r"\[\s*-\s*\d+\s*\]", key):
        raise PgiError(f"override {_describe(text)}: list indices count from 0 (none negative)")
    if sep and re.search(r"\[\d{10,}\]", key):
        raise PgiError(f"override {_describe(text)}: list index too large")
    if not sep or not _OVERRIDE_PATH.fullmatch(key):
        raise PgiError(f"override {_describe(text)}: expected key.path=value, e.g. film.width=64")
    tokens: list[str | int] = [
        int(m.group(2)) if m.group(2) else m.group(1)
        for m in re.finditer(rf"({_KEY})|\[(\d+)\]", key)
    ]
    if tokens[0] == "include":
        raise PgiError(
            f"override {_describe(text)}: includes are merged before overrides apply; "
            "name the file in the scene's `include` instead"
        )
    value = parse_yaml_value(raw, f"override {key!r}")
    node: Any = doc
    created: list[tuple] = []  # mappings the override makes: errors there are the override's
    for n, tok in enumerate(tokens):
        last = n == len(tokens) - 1
        if isinstance(node, dict) and isinstance(tok, str):
            if last:
                node[tok] = value
            elif n == 1 and tokens[0] in _NAMED_TABLES and tok not in node:
                known = ", ".join(map(str, node)) or "none"
                raise PgiError(
                    f"override {_describe(text)}: the scene has no {tokens[0]} entry {tok!r} "
                    f"(it has: {known})"
                )
            else:
                if node.get(tok) is None:  # missing, or a section written empty
                    created.append(tuple(tokens[: n + 1]))
                    node[tok] = {}
                node = node[tok]
        elif isinstance(node, list) and isinstance(tok, int) and tok < len(node):
            if last:
                node[tok] = value
            else:
                node = node[tok]
        else:
            missing = format_path(tokens[: n + 1])
            if n > 0 and not isinstance(node, dict | list):
                # a value, not a section: say who made it one (often an earlier override)
                parent = tuple(tokens[:n])
                raise PgiError(
                    f"override {_describe(text)}: {format_path(parent)} is "
                    f"{_describe(node)}, not a mapping or list, so {missing} cannot be set "
                    f"({origins.where(parent)})"
                )
            raise PgiError(f"override {_describe(text)}: {missing} does not exist in the scene")
    origins.replaced(tuple(tokens))
    for path in [*created, tuple(tokens)]:
        origins.add(path, origins.main, path, f" (override {_describe(text)})")
    origins.overrides.append((tuple(tokens), _describe(text)))


# --------------------------------------------------------------------------- validation


# The section that defines each kind of named reference.
_SECTIONS = {"material": "materials", "medium": "media"}


class _Validator:
    def __init__(self, origins: _Origins) -> None:
        self.o = origins

    def fail(self, path: KeyPath, msg: str) -> NoReturn:
        self.o.fail(path, msg)

    def mapping(
        self, v: Any, path: KeyPath, required: Iterable[str] = (), optional: Iterable[str] = ()
    ) -> dict:
        if not isinstance(v, dict):
            self.fail(path, f"expected a mapping, got {_describe(v)}")
        allowed = set(required) | set(optional)
        for k in v:
            if k not in allowed:
                self.fail(
                    path + (str(k),), f"unknown key (expected one of: {', '.join(sorted(allowed))})"
                )
        for k in required:
            if k not in v:
                self.fail(path + (k,), "missing required key")
        return v

    def kind(self, d: Any, path: KeyPath, choices: Sequence[str]) -> str:
        """The ``type`` of a mapping, one of ``choices`` (YAML null reads as "null")."""
        if not isinstance(d, dict):
            self.fail(
                path,
                f"expected a mapping with a type ({', '.join(choices)}), got {_describe(d)}",
            )
        if "type" not in d:
            self.fail(path + ("type",), f"missing required key (one of: {', '.join(choices)})")
        return self.string("null" if d["type"] is None else d["type"], path + ("type",), choices)

    def table(self, doc: dict, key: str) -> dict[str, Any]:
        """A top-level name -> definition section (absent or empty = no entries)."""
        t = _or_empty(doc.get(key), {})
        if not isinstance(t, dict):
            self.fail((key,), f"expected a mapping of name -> definition, got {_describe(t)}")
        for name in t:
            if not isinstance(name, str):
                self.fail((key, str(name)), f"expected a name (string), got {_describe(name)}")
        return t

    def number(
        self, v: Any, path: KeyPath, lo: float | None = None, hi: float | None = None,
        lo_open: bool = False, hi_open: bool = False, float32: bool = False,
    ) -> float:  # fmt: skip
        """A number within bounds; with float32, also once rounded as Mitsuba stores it."""
        expected = number_problem(v, lo, hi, lo_open, hi_open)
        if expected:
            self.fail(path, f"expected {expected}, got {_describe(v)}")
        if float32:
            rounded = float(np.float32(v))
            lo32, hi32 = (None if b is None else float(np.float32(b)) for b in (lo, hi))
            expected = number_problem(rounded, lo32, hi32, lo_open, hi_open)
            if expected:
                self.fail(
                    path,
                    f"expected {expected} in float32, as Mitsuba stores it; "
                    f"{_describe(v)} rounds to {rounded!r}",
                )
        return float(v)

    def integer(self, v: Any, path: KeyPath, lo: int, hi: int | None = None) -> int:
        expected = integer_problem(v, lo, hi)
        if expected:
            self.fail(path, f"expected {expected}, got {_describe(v)}")
        return v

    def string(self, v: Any, path: KeyPath, choices: Sequence[str] | None = None) -> str:
        if not isinstance(v, str) or (choices is not None and v not in choices):
            want = f"one of: {', '.join(choices)}" if choices else "a string"
            self.fail(path, f"expected {want}, got {_describe(v)}")
        return v

    def strings(self, v: Any, path: KeyPath) -> list[str]:
        if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
            self.fail(path, f"expected a list of strings, got {_describe(v)}")
        return list(v)

    def vec3(self, v: Any, path: KeyPath, nonzero: bool = False) -> np.ndarray:
        """Three numbers, each within +-MAX_COORDINATE (positions, directions, scales)."""
        if not isinstance(v, list) or len(v) != 3:
            self.fail(path, f"expected a list of 3 numbers [x, y, z], got {_describe(v)}")
        bound = MAX_COORDINATE
        a = np.array([self.number(x, path + (i,), -bound, bound) for i, x in enumerate(v)])
        if nonzero and not np.max(np.abs(a)) >= MIN_LENGTH:
            self.fail(path, f"expected a non-zero vector (a component of size >= {MIN_LENGTH:g})")
        return a

    def rgb(self, v: Any, path: KeyPath, hi: float | None = None) -> RGB:
        """A colour: one number (grey) or [r, g, b], each >= 0 (and <= hi if given)."""
        if isinstance(v, list):
            if len(v) != 3:
                self.fail(
                    path,
                    f"expected a number or a list of 3 numbers [r, g, b], got {_describe(v)}",
                )
            r, g, b = (self.number(x, path + (i,), lo=0, hi=hi) for i, x in enumerate(v))
            return (r, g, b)
        x = self.number(v, path, lo=0, hi=hi)
        return (x, x, x)

    def name_ref(self, v: Any, path: KeyPath, table: dict, what: str) -> str:
        name = self.string(v, path)
        if name not in table:
            known = ", ".join(sorted(table)) or "none defined"
            # An override that replaced the whole section is the likelier culprit.
            _, _, note = self.o.locate((_SECTIONS[what],))
            where = f" after {note.strip()[1:-1]}" if note else ""
            self.fail(path, f"unknown {what} {name!r} (defined{where}: {known})")
        return name

    def transform(self, v: Any, path: KeyPath) -> np.ndarray:
        if not isinstance(v, list):
            self.fail(
                path,
                f"expected a list of ops (scale, rotate, translate, matrix), got {_describe(v)}",
            )
        m = np.eye(4)
        for i, op in enumerate(v):
            p = path + (i,)
            if not isinstance(op, dict) or len(op) != 1:
                self.fail(
                    p, "expected one op: {scale: ..}, {rotate: ..}, {translate: ..} or {matrix: ..}"
                )
            ((kind, arg),) = op.items()
            p = p + (kind,)
            if kind == "scale":
                s = self.vec3(arg, p) if isinstance(arg, list) else np.full(3, self.number(arg, p))
                step = xf.scale(s)
            elif kind == "rotate":
                r = self.mapping(arg, p, required=("axis", "angle"))
                step = xf.rotate(self.vec3(r["axis"], p + ("axis",), nonzero=True),
                                 self.number(r["angle"], p + ("angle",)))  # fmt: skip
            elif kind == "translate":
                step = xf.translate(self.vec3(arg, p))
            elif kind == "matrix":
                if (
                    not isinstance(arg, list)
                    or len(arg) != 4
                    or not all(isinstance(row, list) and len(row) == 4 for row in arg)
                ):
                    self.fail(p, "expected 4 rows of 4 numbers")
                step = np.array([[self.number(x, p + (r, c)) for c, x in enumerate(row)]
                                 for r, row in enumerate(arg)])  # fmt: skip
                if not np.array_equal(step[3], [0, 0, 0, 1]):
                    self.fail(p, "expected an affine matrix (last row 0 0 0 1)")
            else:
                self.fail(p, "unknown transform op (expected scale, rotate, translate or matrix)")
            m = step @ m
        return m


# --------------------------------------------------------------------------- sections


def _camera(val: _Validator, d: Any) -> Camera:
    p: KeyPath = ("camera",)
    d = val.mapping(
        d, p, required=("origin", "target", "up", "fov"), optional=("fov_axis", "medium")
    )
    origin, target = val.vec3(d["origin"], p + ("origin",)), val.vec3(d["target"], p + ("target",))
    up = val.vec3(d["up"], p + ("up",), nonzero=True)
    view = target - origin
    if not np.max(np.abs(view)) >= MIN_LENGTH:
        val.fail(p + ("target",), "equals camera.origin, so the view direction is undefined")
    view, up = view / np.max(np.abs(view)), up / np.max(np.abs(up))  # no underflow below
    if np.linalg.norm(np.cross(view, up)) <= 1e-9 * np.linalg.norm(view) * np.linalg.norm(up):
        val.fail(p + ("up",), "is parallel to the view direction (target - origin)")
    return Camera(
        origin=origin, target=target, up=up,
        fov=val.number(
            d["fov"], p + ("fov",), lo=0, hi=180, lo_open=True, hi_open=True, float32=True
        ),
        fov_axis=val.string(d.get("fov_axis", "x"), p + ("fov_axis",), FOV_AXES),
        medium=d.get("medium"),
    )  # fmt: skip


def _material(val: _Validator, name: str, d: Any) -> Material:
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


PHASES = ("isotropic", "hg", "rayleigh", "tabulated", "mie")


def _phase(val: _Validator, d: Any, p: KeyPath) -> Phase:
    kind = val.kind(d, p, PHASES)
    if kind in ("isotropic", "rayleigh"):
        val.mapping(d, p, required=("type",))
        return Phase(kind)
    if kind == "hg":
        val.mapping(d, p, required=("type", "g"))
        g = val.number(d["g"], p + ("g",), lo=-1, hi=1, lo_open=True, hi_open=True, float32=True)
        return Phase("hg", g=g)
    if kind == "tabulated":
        val.mapping(d, p, required=("type",), optional=("values", "file"))
        if ("values" in d) == ("file" in d):
            given = "both" if "values" in d else "neither"
            val.fail(p, f"give either values (a list) or file (.npy or text); {given} given")
        if "values" in d:
            raw = d["values"]
            if not isinstance(raw, list):
                val.fail(p + ("values",), f"expected a list of numbers, got {_describe(raw)}")
            values = np.array([val.number(x, p + ("values", i), lo=0) for i, x in enumerate(raw)])
        else:
            file = val.o.file(p).parent / val.string(d["file"], p + ("file",))
            if file.suffix == ".npy":
                values = _read_npy(val, file, p + ("file",))
            else:
                if not file.is_file():
                    val.fail(p + ("file",), f"file {not_a_file(file)}: {file}")
                try:
                    with warnings.catch_warnings():  # an empty file: numpy warns, we say so
                        warnings.simplefilter("ignore", UserWarning)
                        values = np.loadtxt(file, ndmin=1)
                except (OSError, ValueError) as e:
                    why = one_line(str(e))
                    if "number of columns changed" in why:  # numpy's words for ragged rows
                        why = "its lines hold different counts of numbers"
                    val.fail(
                        p + ("file",),
                        f"cannot read {file}: {why}; write one number per line, or all on one",
                    )
                if values.size == 0:
                    val.fail(p + ("file",), f"{file} holds no numbers")
            if values.dtype.kind not in "fiu":
                val.fail(p + ("file",), f"{file}: expected numbers, got {values.dtype}")
            # (squeezed as a plain array: numpy's squeeze of a one-value memory map fails)
            if np.squeeze(np.asarray(values)).ndim > 1:  # e.g. a column of angles beside them
                val.fail(
                    p + ("file",),
                    f"{file}: expected one list of values, got a table of shape "
                    f"{list(values.shape)}",
                )
            values = np.asarray(values, np.float64).ravel()
            if not np.all(np.isfinite(values)) or np.any(values < 0):
                val.fail(p + ("file",), f"{file}: values must be finite and >= 0")
        if len(values) < 2 or not values.max() > 0:
            why = f"a tabulated phase function needs >= 2 values, not all 0, got {len(values)}"
            if "file" in d:  # the file's fault: named, with its key
                val.fail(p + ("file",), f"{file}: {why}")
            val.fail(p, why)
        # Only the shape matters (both renderers normalise); scaled to a peak of 1 it sums
        # without overflow and survives Mitsuba's float32.
        return Phase("tabulated", values=values / values.max())
    # mie: a Lorenz-Mie table for water droplets, computed at load (renderer.volumes)
    keys = ("effective_radius", "effective_variance", "wavelength", "ior", "resolution")
    val.mapping(d, p, required=("type",), optional=keys)
    from renderer.volumes import mie_largest_radius, mie_phase_table

    radius = val.number(d.get("effective_radius", 2.0), p + ("effective_radius",), lo=0.01, hi=50)
    variance = val.number(
        d.get("effective_variance", 0.1), p + ("effective_variance",), lo=0.01, hi=0.5
    )
    wavelength = val.number(d.get("wavelength", 0.55), p + ("wavelength",), lo=0.1, hi=10)
    # Droplets, not gems: the series' recurrence runs |ior| x size parameter terms.
    ior = val.number(d.get("ior", 1.333), p + ("ior",), lo=1.0, lo_open=True, hi=MAX_MIE_IOR)
    resolution = val.integer(d.get("resolution", 2048), p + ("resolution",), 16, 1 << 13)
    # The table's series runs over the largest droplet's size parameter for each of 64 radii,
    # at each of `resolution` angles: both are bounded, and so is their product (measured:
    # 3-4 s at each corner of these bounds).
    size = 2 * np.pi * mie_largest_radius(radius, variance) / wavelength
    if size > MAX_MIE_SIZE or size * resolution > MAX_MIE_WORK:
        val.fail(
            p,
            f"droplets up to {mie_largest_radius(radius, variance):.3g} um at wavelength "
            f"{wavelength:g} um have size parameter {size:.0f}; the table would take minutes "
            f"to compute (size parameter at most {MAX_MIE_SIZE:g}, and times resolution at "
            f"most {MAX_MIE_WORK:.2g})",
        )
    table = mie_phase_table(radius, variance, wavelength, ior, resolution)
    return Phase("tabulated", values=np.array(table))


DENSITY_SOURCES = ("npy", "vdb", "perlin", "step")


def _read_npy(val: _Validator, file: Path, p: KeyPath) -> np.ndarray:
    """One array from a .npy file (no pickles), mapped, not read: its shape can be checked
    before a header that claims terabytes allocates anything."""
    if not file.is_file():
        val.fail(p, f"file {not_a_file(file)}: {file}")
    try:
        a = np.load(file, allow_pickle=False, mmap_mode="r")
    except MemoryError:
        raise
    except Exception as e:  # a garbled header fails in numpy's parser with any error
        lines = str(e).splitlines()
        with open(file, "rb") as f:
            npy = f.read(6) == b"\x93NUMPY"  # numpy says "pickled data" for any other file
        if "pickle" in str(e) or "Python objects" in str(e):
            why = ("it holds Python objects, which pgi does not load; save a numeric array"
                   if npy else "not a numpy .npy file")  # fmt: skip
        elif "greater than file size" in str(e):  # mapping it found the data short
            why = "its header's shape needs more data than the file holds (truncated?)"
        elif "must be positive" in str(e):
            why = "its header gives a negative size"
        else:
            why = one_line(lines[0]) if lines else "not a numpy .npy file"
        val.fail(p, f"cannot read {file} as a .npy array: {why}")
    if not isinstance(a, np.ndarray):
        val.fail(p, f"{file}: expected one array, got {type(a).__name__}")
    extra = file.stat().st_size - (getattr(a, "offset", 0) + a.nbytes)
    if isinstance(a, np.memmap) and extra > 0:  # numpy maps the header's shape, ignores the rest
        val.fail(
            p,
            f"cannot read {file} as a .npy array: it holds {extra} bytes more than its header's "
            f"shape {list(a.shape)} of {a.dtype} needs (written with another shape?)",
        )
    return a


def _load_npy(val: _Validator, file: Path, p: KeyPath) -> np.ndarray:
    a = _read_npy(val, file, p)
    if a.ndim != 3 or a.dtype.kind not in "fiu" or 0 in a.shape:
        val.fail(
            p,
            f"{file}: expected a 3-D numeric array indexed [x, y, z], got shape "
            f"{list(a.shape)} of {a.dtype}",
        )
    if max(a.shape) > MAX_GRID_SIDE:
        val.fail(p, f"{file}: shape {list(a.shape)}, at most {MAX_GRID_SIDE} voxels per axis")
    return np.array(a)  # read now that its size is known


def _resolution(val: _Validator, v: Any, p: KeyPath) -> tuple[int, int, int]:
    if isinstance(v, list):
        if len(v) != 3:
            val.fail(p, f"expected a number or [x, y, z], got {_describe(v)}")
        return tuple(val.integer(n, p + (i,), 1, MAX_GRID_SIDE) for i, n in enumerate(v))  # type: ignore
    n = val.integer(v, p, 1, MAX_GRID_SIDE)
    return (n, n, n)


def _load_density(
    val: _Validator, v: Any, p: KeyPath
) -> tuple[np.ndarray, np.ndarray | None, Path]:
    """The baked density [x, y, z] of a grid medium, the 4x4 placing its unit cube that the
    source itself defines (an OpenVDB transform; None otherwise), and where it came from.

    ``v`` is a file name (.npy or .vdb) or a mapping with a ``type`` in DENSITY_SOURCES."""
    here = val.o.file(p).parent
    if isinstance(v, str):
        kind = "vdb" if v.lower().endswith(".vdb") else "npy"
        d: dict = {"type": kind, "file": v}
    else:
        d = v
        kind = val.kind(d, p, DENSITY_SOURCES)
    placement = None
    source = val.o.file(p)
    if kind in ("npy", "vdb"):
        optional = ("grid", "bbox") if kind == "vdb" else ()
        val.mapping(d, p, required=("type", "file"), optional=optional)
        file = here / val.string(d["file"], p + ("file",))
        source = file
        if not file.is_file():
            val.fail(p, f"density file {not_a_file(file)}: {file}")
        if kind == "npy":
            a = _load_npy(val, file, p)
        else:
            from renderer.volumes import read_vdb

            bbox = None
            if "bbox" in d:
                b = d["bbox"]
                if not (isinstance(b, list) and len(b) == 2 and
                        all(isinstance(r, list) and len(r) == 3 for r in b)):  # fmt: skip
                    val.fail(p + ("bbox",), "expected [[i0, j0, k0], [i1, j1, k1]] (inclusive)")
                bbox = tuple(
                    tuple(
                        val.integer(x, p + ("bbox", r, c), -MAX_VDB_COORD, MAX_VDB_COORD)
                        for c, x in enumerate(row)
                    )  # fmt: skip
                    for r, row in enumerate(b)
                )
            grid = val.string(d.get("grid", "density"), p + ("grid",))
            try:
                a, placement = read_vdb(file, grid, bbox)
            except PgiError as e:
                val.fail(p, str(e))
    elif kind == "perlin":
        keys = ("octaves", "frequency", "lacunarity", "gain", "offset", "seed")
        val.mapping(d, p, required=("type", "resolution"), optional=keys)
        from renderer.volumes import perlin_density

        octaves = val.integer(d.get("octaves", 4), p + ("octaves",), 1, 16)
        # Upper bounds keep gain^k finite over 16 octaves, and the lattice coordinates of the
        # finest octave in range (they are cast to int64; finer than a voxel is aliasing).
        frequency = val.number(d.get("frequency", 4.0), p + ("frequency",), lo=0, hi=1e4)
        lacunarity = val.number(d.get("lacunarity", 2.0), p + ("lacunarity",), lo=0, hi=16)
        finest = frequency * lacunarity ** (octaves - 1)
        if finest > MAX_NOISE_FREQUENCY:
            val.fail(p, f"the finest octave's frequency, frequency x lacunarity^(octaves - 1), "
                        f"is {finest:g}; at most {MAX_NOISE_FREQUENCY:g}")  # fmt: skip
        a = perlin_density(
            _resolution(val, d["resolution"], p + ("resolution",)),
            octaves=octaves,
            frequency=frequency,
            lacunarity=lacunarity,
            gain=val.number(d.get("gain", 0.5), p + ("gain",), lo=0, hi=16),
            offset=val.number(d.get("offset", 0.0), p + ("offset",), lo=-1e6, hi=1e6),
            seed=val.integer(d.get("seed", 0), p + ("seed",), 0),
        )
    else:  # step
        val.mapping(d, p, required=("type", "resolution", "values"), optional=("axis", "position"))
        from renderer.volumes import step_density

        values = d["values"]
        if not isinstance(values, list) or len(values) != 2:
            val.fail(p + ("values",), f"expected [below, above], got {_describe(values)}")
        axis = val.string(d.get("axis", "x"), p + ("axis",), ("x", "y", "z"))
        a = step_density(
            _resolution(val, d["resolution"], p + ("resolution",)),
            axis="xyz".index(axis),
            position=val.number(d.get("position", 0.5), p + ("position",), lo=0, hi=1),
            values=tuple(
                val.number(x, p + ("values", i), lo=0, hi=MAX_DENSITY) for i, x in enumerate(values)
            ),
        )
    if not np.all(np.isfinite(a)):
        val.fail(p, f"{source}: density has non-finite values")
    if np.abs(a).max() > np.float32(MAX_DENSITY):  # 1e30 itself rounds up in float32
        val.fail(
            p,
            f"{source}: density values must be <= {MAX_DENSITY:g} (float32, with headroom), "
            f"got {np.abs(a).max():g}",
        )
    if a.min() < 0:
        idx = tuple(int(i) for i in np.unravel_index(np.argmin(a), a.shape))
        val.fail(p, f"{source}: density must be >= 0, got {a.min():g} at [x, y, z] = {list(idx)}")
    return np.ascontiguousarray(a, dtype=np.float32), placement, source


def _medium(val: _Validator, name: str, d: Any) -> Medium:
    p: KeyPath = ("media", name)
    kind = val.kind(d, p, ("homogeneous", "grid"))
    common = ("albedo", "scale", "phase")
    if kind == "homogeneous":
        val.mapping(d, p, required=("type", "sigma_t", "albedo"), optional=common)
    else:
        val.mapping(
            d, p, required=("type", "density", "albedo"), optional=common + ("sigma_t", "transform")
        )
    if kind == "grid":  # grid extinction is grey: the density carries the variation
        grey = val.number(d.get("sigma_t", 1.0), p + ("sigma_t",), lo=0)
        sigma_t = (grey, grey, grey)
    else:
        sigma_t = val.rgb(d["sigma_t"], p + ("sigma_t",))
    albedo = val.rgb(d["albedo"], p + ("albedo",), hi=1)
    scale = val.number(d.get("scale", 1.0), p + ("scale",), lo=0)
    phase = _phase(val, d["phase"], p + ("phase",)) if "phase" in d else Phase()

    def check_extinction(peak: float, what: str) -> None:
        if max(sigma_t) * scale * peak > MAX_EXTINCTION * (1 + 1e-6):  # float32's rounding
            val.fail(p, f"{what} is {max(sigma_t) * scale * peak:g}, above {MAX_EXTINCTION:g}")

    if kind == "homogeneous":
        check_extinction(1.0, "sigma_t x scale")
        return Medium(name, kind, sigma_t, albedo, scale, phase)
    density, placement, source = _load_density(val, d["density"], p + ("density",))
    check_extinction(float(density.max(initial=0.0)), "sigma_t x scale x the densest voxel")
    to_world = val.transform(d.get("transform", []), p + ("transform",))
    if placement is not None:  # an OpenVDB file places its grid; the transform moves it on
        to_world = to_world @ placement
    linear = to_world[:3, :3]
    # Relative to the box's edge lengths: a tiny grid is fine, a flat one is not; nor one
    # so small that the world-to-grid map overflows (subnormal scales).
    # (A box too large for its determinant is left to the bound on its corners below.)
    det = abs(np.linalg.det(linear))
    flat = np.isfinite(det) and det <= 1e-12 * np.prod(np.linalg.norm(linear, axis=0))
    if flat or not np.all(np.isfinite(np.linalg.inv(linear))):
        val.fail(p + ("transform",), "is singular: the grid's box would have no volume")
    if np.any(linear - np.diag(np.diag(linear))):
        # Mitsuba bounds a grid by the axis-aligned box of its transformed cube and extends
        # edge values into the rest of that box: only axis-aligned grids mean the same there.
        val.fail(
            p + ("transform",),
            "rotates the grid; Mitsuba supports only axis-aligned grids (scale and translate)",
        )
    corners = np.array([[x, y, z, 1.0] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    if not np.all(np.abs(corners @ to_world.T)[:, :3] < MAX_COORDINATE):
        val.fail(p + ("transform",), f"places the grid's box beyond +-{MAX_COORDINATE:g}")
    voxel = float((np.abs(np.diag(linear)) / np.array(density.shape)).max())
    voxel_depth = max(sigma_t) * scale * float(density.max(initial=0.0)) * voxel
    if voxel_depth > MAX_VOXEL_DEPTH:
        val.fail(
            p,
            f"the densest voxel is {voxel_depth:.3g} optical depths across (sigma_t x scale x "
            f"density x voxel edge {voxel:.3g}); at most {MAX_VOXEL_DEPTH:g} can be tracked, "
            f"and it is opaque long before: lower scale",
        )
    return Medium(name, kind, sigma_t, albedo, scale, phase, density, to_world, source)


# What Mitsuba's PLY loader says of faces with four vertices or more (ASCII, binary).
_PLY_NOT_TRIANGLES = ("trailing tokens after end of PLY file", "is this a triangle mesh")


def _mesh_file(val: _Validator, v: Any, p: KeyPath) -> tuple[np.ndarray, np.ndarray]:
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


def _shape(val: _Validator, i: int, d: Any, materials: dict, media: dict) -> Shape:
    p: KeyPath = ("shapes", i)
    kind = val.kind(d, p, ("rectangle", "cube", "sphere", "mesh"))
    common = ("name", "transform", "emission", "interior", "exterior")
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

    return Shape(
        name=val.string(d.get("name", f"{kind}{i}"), p + ("name",)),
        vertices=v, faces=f,
        material=val.name_ref(d["material"], p + ("material",), materials, "material"),
        emission=emission, interior=medium_ref("interior"), exterior=medium_ref("exterior"),
    )  # fmt: skip


def _emits(light: Light) -> bool:
    power = light.irradiance if isinstance(light, DirectionalLight) else light.intensity
    return any(c > 0 for c in power)


def _light(val: _Validator, i: int, d: Any) -> Light:
    p: KeyPath = ("lights", i)
    kind = val.kind(d, p, ("point", "spot", "directional"))
    if kind == "point":
        val.mapping(d, p, required=("type", "position", "intensity"))
        return PointLight(
            val.vec3(d["position"], p + ("position",)),
            val.rgb(d["intensity"], p + ("intensity",), hi=MAX_LIGHT),
        )
    if kind == "directional":
        val.mapping(d, p, required=("type", "direction", "irradiance"))
        direction = val.vec3(d["direction"], p + ("direction",), nonzero=True)
        return DirectionalLight(
            direction / np.linalg.norm(direction),
            val.rgb(d["irradiance"], p + ("irradiance",), hi=MAX_LIGHT),
        )
    val.mapping(
        d,
        p,
        required=("type", "position", "target", "intensity"),
        optional=("cutoff_angle", "beam_width"),
    )
    pos, target = val.vec3(d["position"], p + ("position",)), val.vec3(d["target"], p + ("target",))
    if not np.max(np.abs(target - pos)) >= MIN_LENGTH:
        val.fail(p + ("target",), "equals the light's position, so its axis is undefined")
    cutoff = val.number(
        d.get("cutoff_angle", 20.0), p + ("cutoff_angle",), lo=0, hi=90, lo_open=True, float32=True
    )
    beam = val.number(
        d.get("beam_width", cutoff * 0.75),
        p + ("beam_width",),
        lo=0,
        hi=cutoff,
        lo_open=True,
        float32=True,
    )
    intensity = val.rgb(d["intensity"], p + ("intensity",), hi=MAX_LIGHT)
    return SpotLight(pos, target, intensity, cutoff, beam)


# --------------------------------------------------------------------------- entry point


def load_scene(path: str | Path, overrides: Sequence[str] = ()) -> Scene:
    """Load, validate and resolve a scene. ``path``: scene.yaml, its folder, or a scene name.

    ``overrides`` are ``key.path=value`` strings (value parsed as YAML) applied after includes
    and before validation, e.g. ``film.width=64`` or ``media.fog.scale=2``.
    """
    # Overflow in a check's arithmetic is found by the check (a non-finite result), and
    # numpy's warning of it would only add lines before the one-line error.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"), _names_too_long():
        return _load_scene(path, overrides)


@contextlib.contextmanager
def _names_too_long() -> Iterator[None]:
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
    origins = _Origins(file)
    doc = _merge_includes(file, _read_yaml(file), origins)
    for text in overrides:
        _apply_override(doc, text, origins)
    val = _Validator(origins)
    val.mapping(doc, (), required=("camera", "film", "shapes"), optional=TOP_KEYS)

    materials = {k: _material(val, k, v) for k, v in val.table(doc, "materials").items()}
    media = {k: _medium(val, k, v) for k, v in val.table(doc, "media").items()}

    camera = _camera(val, doc["camera"])
    if camera.medium is not None:
        val.name_ref(camera.medium, ("camera", "medium"), media, "medium")
    film_doc = val.mapping(doc["film"], ("film",), required=("width", "height"))
    film = Film(val.integer(film_doc["width"], ("film", "width"), 1, MAX_FILM_SIDE),
                val.integer(film_doc["height"], ("film", "height"), 1, MAX_FILM_SIDE))  # fmt: skip
    integ = val.mapping(
        _or_empty(doc.get("integrator"), {}),
        ("integrator",),
        optional=("max_depth", "rr_depth", "estimator", "march_step"),
    )
    integrator = Integrator(
        # Depths reach the native core and Mitsuba as 32-bit ints.
        max_depth=val.integer(
            integ.get("max_depth", -1), ("integrator", "max_depth"), -1, INT32_MAX
        ),
        rr_depth=val.integer(integ.get("rr_depth", 5), ("integrator", "rr_depth"), 1, INT32_MAX),
        estimator=val.string(
            integ.get("estimator", "ratio"), ("integrator", "estimator"), ESTIMATORS
        ),
        march_step=val.number(integ.get("march_step", 0.0), ("integrator", "march_step"), lo=0),
    )
    # Before rr_depth nothing but max_depth ends a path: in a closed scene that loses no
    # energy, an iteration would not end (and no time budget is checked inside one).
    unrouletted = min(integrator.rr_depth, integrator.max_depth % (INT32_MAX + 1))
    if unrouletted > MAX_UNROULETTED_DEPTH:
        val.fail(
            ("integrator", "rr_depth"),
            f"{integrator.rr_depth} with max_depth {integrator.max_depth}: paths could run "
            f"{unrouletted} bounces before Russian roulette or the depth limit may end them; "
            f"lower rr_depth or max_depth to at most {MAX_UNROULETTED_DEPTH}",
        )

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
    lights_doc = _or_empty(doc.get("lights"), [])
    if not isinstance(lights_doc, list):
        val.fail(("lights",), f"expected a list of lights, got {_describe(lights_doc)}")
    lights = [_light(val, i, d) for i, d in enumerate(lights_doc)]
    if not any(map(_emits, lights)) and not any(s.emission and any(s.emission) for s in shapes):
        # Point at the emitter written dark (often by an override) rather than at `lights`.
        dark = [("shapes", i, "emission") for i, s in enumerate(shapes) if s.emission]
        dark += [("lights", i) for i in range(len(lights))]
        what = "this emitter is black and no other light emits" if dark else "no light emits"
        val.fail(
            dark[0] if dark else ("lights",),
            f"{what}: add a light or give a shape a non-zero emission",
        )

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


def _or_empty(value: Any, empty: Any) -> Any:
    """An optional section: absent or written empty (`lights:`) means no entries; any other
    value is checked by its reader (`lights: 0` is a mistake, not an empty list)."""
    return empty if value is None else value


def _scene_documents(main: Path, overrides: Sequence[str] = ()) -> list[tuple[Path, dict | None]]:
    """Every file the scene file ``main`` reads, each with its parsed YAML document (None for
    an asset, or a scene file that cannot be parsed): the main file, its includes, then the
    assets they and the ``key=value`` overrides name (an override's paths are the main
    file's, as the loader reads them). Each file is read once."""
    try:
        doc = _read_yaml(main)
    except PgiError:
        return [(main, None)]
    include = doc.get("include") or []
    names = [include] if isinstance(include, str) else include if isinstance(include, list) else []
    files = [main] + [(main.parent / n).resolve() for n in names
                      if isinstance(n, str) and (main.parent / n).is_file()]  # fmt: skip
    found: list[tuple[Path, dict | None]] = []
    for file in files:
        try:
            found.append((file, doc if file == main else _read_yaml(file)))
        except PgiError:
            found.append((file, None))
    parts = [(file.parent, part) for file, part in found if part is not None]
    for kv in overrides:
        key, _, raw = kv.partition("=")
        try:
            value = parse_yaml_value(raw, f"--set {key}")
        except PgiError:
            continue  # loading the scene reports it
        last = re.sub(r"(\[\d+\])+$", "", key.strip().rsplit(".", 1)[-1])
        parts.append((main.parent, {last: value}))
    seen = set(files)
    for here, part in parts:
        for asset in _named_assets(part, here):
            if asset.is_file() and asset not in seen:
                seen.add(asset)
                found.append((asset, None))
    return found


def scene_sources(path: str | Path, overrides: Sequence[str] = ()) -> list[Path]:
    """Every file a scene reads: its scene file, the files it includes and the assets they and
    the ``overrides`` name (meshes, density grids, phase tables), each resolved as the loader
    resolves it. Files that cannot be found or read are left out (loading the scene reports
    them); a workflow makes these its inputs so that editing any of them reruns what depends
    on the scene."""
    with _names_too_long():
        main = find_scene_file(path).resolve()  # resolved: ".." after a symlink: its target's
        return [file for file, _ in _scene_documents(main, overrides)]


# Keys only the report reads: editing them changes no image.
REPORT_ONLY_KEYS = ("description", "stresses", "expected_winners")


def scene_content_digest(path: str | Path, overrides: Sequence[str] = ()) -> str:
    """A digest of what a scene renders: its YAML files as parsed, without the report-only
    keys (so comments, layout and a scene's description do not count), and the bytes of
    the assets they and the overrides name (and of scene files that cannot be parsed). The
    workflow reruns a scene's renders and references when it changes."""
    h = hashlib.sha256()
    main = find_scene_file(path).resolve()
    for file, doc in _scene_documents(main, overrides):
        h.update(os.path.relpath(file, main.parent).encode() + b"\0")  # stable if moved
        if doc is None:
            data = file.read_bytes()
        else:
            kept = {k: v for k, v in doc.items() if k not in REPORT_ONLY_KEYS}
            data = json.dumps(kept, sort_keys=True, default=str).encode()
        h.update(data + b"\0")
    return h.hexdigest()[:16]


def resolved(path: Path) -> Path | None:
    """``path`` with its links followed, or None where it has no such form (links that loop,
    a NUL character in the name): no scene can read it, and loading says why."""
    try:
        return path.resolve()
    except (OSError, RuntimeError, ValueError):
        return None


def _named_assets(node: Any, here: Path, visited: set[int] | None = None) -> Iterable[Path]:
    """Paths a scene document names: ``file:`` values, and a grid's ``density`` given as a
    .npy/.vdb file name. Each list or mapping is visited once: YAML aliases can make a
    document recursive, or exponentially large (a "billion laughs"), before it is validated."""
    visited = set() if visited is None else visited
    if not isinstance(node, (list, dict)) or id(node) in visited:
        return
    visited.add(id(node))
    if isinstance(node, list):
        for item in node:
            yield from _named_assets(item, here, visited)
        return
    for key, value in node.items():
        if isinstance(value, str) and (
            key == "file" or (key == "density" and value.lower().endswith((".npy", ".vdb")))
        ):
            if (file := resolved(here / value)) is not None:  # else loading reports it
                yield file
        else:
            yield from _named_assets(value, here, visited)


def _method_names(val: _Validator, v: Any, p: KeyPath) -> list[str]:
    """Method ids, implemented or from the study's table of methods still to come."""
    from renderer.methods import NOT_YET_IMPLEMENTED, method_ids

    known = method_ids() + list(NOT_YET_IMPLEMENTED)
    names = val.strings(v, p)
    for i, name in enumerate(names):
        val.string(name, p + (i,), known)
    return names
