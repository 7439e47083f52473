"""Checks of the values in a scene document (mappings, numbers, colours, vectors, names,
transforms): each returns the value checked or fails with a PgiError naming the file and key
path it was written at."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, NoReturn

import numpy as np

from renderer.errors import shorten_repr as _describe
from renderer.ranges import integer_problem, number_problem
from renderer.scene import transform as xf
from renderer.scene.document import KeyPath, Origins
from renderer.scene.limits import MAX_COORDINATE, MIN_LENGTH
from renderer.scene.model import RGB

# The section that defines each kind of named reference.
_SECTIONS = {"material": "materials", "medium": "media"}


class Validator:
    """The checks section readers use; ``o`` says where each part of the document came from."""

    def __init__(self, origins: Origins) -> None:
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
        t = or_empty(doc.get(key), {})
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


def or_empty(value: Any, empty: Any) -> Any:
    """An optional section: absent or written empty (`lights:`) means no entries; any other
    value is checked by its reader (`lights: 0` is a mistake, not an empty list)."""
    return empty if value is None else value
