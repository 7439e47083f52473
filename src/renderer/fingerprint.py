"""Fingerprints of the code behind a render and behind a reference.

The workflow records them with every render and reference, so a change of the renderer
reruns what it could change, and nothing else: any renderer source (Python or C++) for the
timed renders; for Mitsuba references, only the modules `pgi reference` runs (scene loading
and baking, the Mitsuba export, image writing) and Mitsuba's version. A fingerprint hashes
file contents, not times: a fresh clone of the same commit gives the same fingerprints.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path

from .errors import PgiError

PACKAGE = Path(__file__).resolve().parent
SOURCE_SUFFIXES = (".py", ".cpp", ".h")
# What `pgi reference` imports; their renderer modules are the reference's code.
REFERENCE_ENTRY_POINTS = ("renderer.cli", "renderer.reference", "renderer.imageio")


def _digest(files: list[Path], versions: dict[str, str]) -> str:
    h = hashlib.sha256()
    for path in sorted(files):
        h.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0")
        h.update(path.read_bytes() + b"\0")
    for name, version in sorted(versions.items()):
        h.update(f"{name}={version}\0".encode())
    return h.hexdigest()[:16]


def _version(distribution: str) -> str:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return "absent"


def render_sources() -> list[Path]:
    """Every source file of the renderer package."""
    return [
        p
        for p in PACKAGE.rglob("*")
        if p.suffix in SOURCE_SUFFIXES and "__pycache__" not in p.parts
    ]


_LIST_LOADED = """
import importlib, sys
for name in sys.argv[1:]:
    importlib.import_module(name)
for name, module in list(sys.modules.items()):
    if (name == "renderer" or name.startswith("renderer.")) and getattr(module, "__file__", None):
        print(module.__file__)
"""


def reference_sources() -> list[Path]:
    """The renderer modules loaded by what `pgi reference` imports, in a fresh interpreter
    (this one may have loaded others)."""
    proc = subprocess.run(
        [sys.executable, "-c", _LIST_LOADED, *REFERENCE_ENTRY_POINTS],
        capture_output=True,
        text=True,
        check=True,
        env={
            **os.environ,
            "PYTHONPATH": os.pathsep.join(
                filter(None, [str(PACKAGE.parent), os.environ.get("PYTHONPATH")])
            ),
        },
    )
    return sorted({Path(line).resolve() for line in proc.stdout.splitlines() if line})


def mitsuba_variant_setting() -> str:
    """The Mitsuba variant asked for (PGI_MITSUBA_VARIANT), or which one the automatic choice
    takes (LLVM when a libLLVM is found), without importing Mitsuba."""
    from .mitsuba_env import find_libllvm

    asked = os.environ.get("PGI_MITSUBA_VARIANT")
    if asked:
        return asked
    return "auto-llvm" if os.environ.get("DRJIT_LIBLLVM_PATH") or find_libllvm() else "auto-scalar"


def check_core_is_current(core: Path, sources: list[Path]) -> None:
    """The render fingerprint hashes the C++ sources, so they must be what the built core was
    compiled from: a source edited after the last build would be recorded as the code of
    renders that ran the old binary."""
    built = core.stat().st_mtime
    newer = sorted(p for p in sources if p.suffix in (".cpp", ".h") and p.stat().st_mtime > built)
    if newer:
        more = f" (and {len(newer) - 1} more)" if len(newer) > 1 else ""
        raise PgiError(
            f"{newer[0].relative_to(PACKAGE.parent).as_posix()}{more} is newer than the built "
            "C++ core, so renders would not run it: rebuild it (./setup.sh --no-run)"
        )


def _libraries() -> dict[str, str]:
    libraries = {name: _version(name) for name in ("mitsuba", "drjit", "embreex")}
    # Which Mitsuba variant runs (renderer.mitsuba_env): llvm and scalar differ in their
    # random streams, so a switch reruns Mitsuba's images.
    libraries["mitsuba-variant"] = mitsuba_variant_setting()
    return libraries


def render_fingerprint() -> str:
    """The render digest of fingerprints() alone (no subprocess): what a render's sidecar
    records as the code it ran."""
    from . import _core

    sources = render_sources()
    check_core_is_current(Path(_core.__file__), sources)
    return _digest(sources, _libraries())


def reference_fingerprint() -> str:
    """The reference digest of fingerprints() alone: it does not need a current C++ core."""
    libraries = {k: v for k, v in _libraries().items() if k != "embreex"}
    return _digest(reference_sources(), libraries)


def fingerprints() -> dict[str, str]:
    """{"render": ..., "reference": ...}: short hex digests of the code behind each."""
    return {"render": render_fingerprint(), "reference": reference_fingerprint()}
