"""The files a scene reads (its scene file, includes and the assets they and the overrides
name) and a digest of what they render, read without loading the scene: the workflow makes
them a render's inputs and reruns the render when they change."""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from renderer.errors import PgiError
from renderer.scene.loader import find_scene_file, names_too_long
from renderer.scene.yaml_dialect import parse_yaml_value, read_scene_yaml


def _scene_documents(main: Path, overrides: Sequence[str] = ()) -> list[tuple[Path, dict | None]]:
    """Every file the scene file ``main`` reads, each with its parsed YAML document (None for
    an asset, or a scene file that cannot be parsed): the main file, its includes, then the
    assets they and the ``key=value`` overrides name (an override's paths are the main
    file's, as the loader reads them). Each file is read once."""
    try:
        doc = read_scene_yaml(main)
    except PgiError:
        return [(main, None)]
    include = doc.get("include") or []
    names = [include] if isinstance(include, str) else include if isinstance(include, list) else []
    files = [main] + [(main.parent / n).resolve() for n in names
                      if isinstance(n, str) and (main.parent / n).is_file()]  # fmt: skip
    found: list[tuple[Path, dict | None]] = []
    for file in files:
        try:
            found.append((file, doc if file == main else read_scene_yaml(file)))
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
    with names_too_long():
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
