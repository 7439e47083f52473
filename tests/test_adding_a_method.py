"""The worked example of docs/methods.md ("Adding a method"): `direct`, a method made of four
source files (its kernel, its binding, its pass sequence, its registry line), renders what pt
renders with max_depth 2, is deterministic across thread counts, and stays out of the study."""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest

from conftest import ROOT, load_small
from parity import ours, same_image
from renderer.errors import PgiError
from renderer.methods import get_method, method_ids

EXAMPLE_FILES = [
    "src/renderer/cpp/direct_lighting.h",  # the kernel
    "src/renderer/cpp/direct_lighting_bind.cpp",  # its binding
    "src/renderer/methods/direct.py",  # its parameters and passes
    "src/renderer/known_methods.py",  # its registry line
]


def test_the_example_needs_four_source_files():
    """Nothing else in the sources names it: no list of bindings, no build file, no driver."""
    sources = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "src", "CMakeLists.txt",
         "pyproject.toml"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    ).stdout.split()  # fmt: skip
    naming = [
        path
        for path in sources
        if re.search(r"DirectLighting|direct_lighting|\"direct\"", (ROOT / path).read_text())
    ]
    assert sorted(naming) == sorted(EXAMPLE_FILES)


def test_direct_lighting_equals_pt_at_depth_two():
    """Emission seen directly plus next-event estimation at the first surface is pt's image
    at max_depth 2 in a scene without media: image mean and 3x3 blocks agree."""
    scene = load_small("cbox", 12, 12, ("integrator.max_depth=2",))
    direct = ours(get_method("direct"), scene, 24, seed=1, spp_per_iteration=32)
    pt = ours(get_method("pt"), scene, 24, seed=2, spp_per_wave=32)
    ok, why = same_image(direct, pt, alpha=1e-3)
    assert ok, why
    darker = type(direct)(direct.samples * 0.97)  # the check sees a 3 % loss
    assert not same_image(darker, pt, alpha=1e-3)[0]


def test_same_image_whatever_the_thread_count():
    scene = load_small("cbox", 8, 8)
    images = []
    for threads in (1, 2):
        method = get_method("direct")(scene, seed=4, threads=threads, params={})
        method.run_iteration(0)
        images.append(method.image())
    assert np.array_equal(*images) and images[0].max() > 0


def test_the_example_is_no_method_of_the_study():
    assert "direct" not in method_ids()
    with pytest.raises(PgiError, match="renders scenes without media"):
        get_method("direct")(load_small("cbox-fog", 4, 4), seed=0, threads=1, params={})
