"""Import structure of the renderer package: no module imports another in a circle, and the
scene loader loads without the method registry."""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Container
from pathlib import Path

import pytest

import renderer

PACKAGE = Path(renderer.__file__).resolve().parent


def test_the_scene_loader_does_not_import_the_method_registry():
    """The registry reads overrides with the scene package's YAML dialect, so the loader
    checks `expected_winners` against renderer.known_methods instead. In a fresh interpreter:
    this one has loaded both."""
    code = "import sys, renderer.scene.loader; assert 'renderer.methods' not in sys.modules"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def _imports(name: str, file: Path, modules: Container[str]) -> set[str]:
    """The renderer modules that module `name` (in `file`) imports, at its top or inside a
    function: for `from a.b import c`, a.b and a.b.c if that is a module, and the packages
    above them, which an import from outside them runs first."""
    package = file.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(file.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                here = name.split(".")
                here = here[: len(here) - node.level + package]
                base = ".".join(here + ([node.module] if node.module else []))
            targets = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for target in targets:
            parts = target.split(".")
            for n in range(1, len(parts) + 1):
                outer = ".".join(parts[:n])
                # a package `name` is inside of is being imported already
                if outer in modules and not f"{name}.".startswith(f"{outer}."):
                    found.add(outer)
    return found


def test_renderer_modules_import_no_circle():
    """Read from the sources, so that imports inside functions count: a circle of those works
    only while each side imports the other late enough."""
    modules: dict[str, Path] = {}
    for file in PACKAGE.rglob("*.py"):
        parts = file.relative_to(PACKAGE.parent).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = file
    graph = {name: _imports(name, file, modules) for name, file in modules.items()}
    assert "renderer.scene.loader" in graph["renderer.scene"]  # the reader finds imports
    done: set[str] = set()

    def visit(name: str, path: list[str]) -> None:
        if name in path:
            pytest.fail("imports in a circle: " + " -> ".join([*path[path.index(name) :], name]))
        if name not in done:
            for imported in sorted(graph[name]):
                visit(imported, [*path, name])
            done.add(name)

    for name in sorted(graph):
        visit(name, [])


def test_the_native_interface_has_a_typed_stub():
    """The build writes a stub of renderer._core beside the module (CMakeLists.txt), so editors
    and readers see the native interface: every class and function the module has, and each
    kernel with the passes of the iteration protocol (cpp/passes.h), typed and documented."""
    from renderer import _core

    text = (Path(_core.__file__).with_name("_core.pyi")).read_text()
    public = [name for name in dir(_core) if not name.startswith("_")]
    for name in public:
        kind = "class" if isinstance(getattr(_core, name), type) else "def"
        assert f"{kind} {name}" in text, f"{name} is not in the stub: rebuild (pip install -e .)"
    kernels = ["PathTracing", "LightPaths", "LightTracing", "PhotonMapping"]
    kernels.append("ProgressivePhotonBeams")
    for kernel in kernels:
        body = text.split(f"class {kernel}:")[1].split("\nclass ")[0]
        assert "def begin(self, iteration: int) -> None:" in body, kernel
        assert "def end(self) -> None:" in body and "def lane(self, index: int)" in body, kernel
    assert text.count("def next_rays(self, o: Annotated[NDArray[numpy.float32]") >= len(kernels)
    assert "Writes the rays of the paths in flight" in text
