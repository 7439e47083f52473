"""The scene document before validation: a scene file merged with its ``include`` files, then
``key.path=value`` overrides applied, remembering where each part was written (which file, at
which key path, after which override) so that messages name the file and key the user wrote.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, NoReturn

from renderer.errors import PgiError, not_a_file
from renderer.errors import shorten_repr as _describe
from renderer.scene.model import format_path
from renderer.scene.yaml_dialect import parse_yaml_value, read_scene_yaml

TOP_KEYS = {
    "name", "description", "stresses", "expected_winners", "include",
    "camera", "film", "integrator", "materials", "media", "shapes", "lights",
}  # fmt: skip
INCLUDABLE = {"camera", "film", "integrator", "materials", "media", "shapes", "lights"}

# A place in the document: keys of mappings and indices of lists (shapes[2].material).
KeyPath = tuple[str | int, ...]


class Origins:
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


def merge_includes(main: Path, doc: dict, origins: Origins) -> dict:
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
        sources.append((file, read_scene_yaml(file)))
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


def apply_override(doc: dict, text: str, origins: Origins) -> None:
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
