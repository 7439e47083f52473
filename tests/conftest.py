"""Shared fixtures: the repository root, the shipped scenes, a small-film scene loader."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


def load_small(name: str, width: int = 32, height: int = 32, extra: tuple[str, ...] = ()):
    """A shipped scene at reduced resolution."""
    from renderer.scene import load_scene

    return load_scene(SCENES / name, [f"film.width={width}", f"film.height={height}", *extra])
