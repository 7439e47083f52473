"""Can the reference be trusted? The dense-media issue's case with the real renderers: in
cbox-fog made dense and white (optical depth ~100 across the box, albedo 0.999, no depth
limit) Mitsuba's volpath returns 0 in every pixel; the check against pgi's pt finds it, and
the reference plan hands the scene to pgi's pt. The workflow's side (labels, tables, report)
is in test_workflow.py, with a stand-in renderer."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from compare.runs import check_reference_files
from compare.sizing import half_args, plan_from_files
from renderer.imageio import read_exr

DENSE = [
    "--set", "film.width=16", "--set", "film.height=16", "--set", "media.fog.sigma_t=50",
    "--set", "media.fog.albedo=0.999", "--set", "integrator.max_depth=-1",
]  # fmt: skip


def reference(out: Path, source: str, spp: int, seed: int) -> None:
    cmd = [sys.executable, "-m", "renderer.cli", "reference", "cbox-fog", "--source", source]
    cmd += ["--spp", str(spp), "--seed", str(seed), "--check", "0", "--threads", "2", "-q"]
    r = subprocess.run([*cmd, *DENSE, "-o", str(out)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr


@pytest.fixture(scope="module")
def dense(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Mitsuba's two pilot halves (16 spp) and pt's two check halves (512 spp, 32 passes
    each: 20 s of rendering on a busy machine), seeds fixed: the same images on every run.
    pt's noise is high here (a path must wander near the light to see it): at 2 x 256 spp
    Mitsuba's black image lies 5.4 standard errors below pt's mean, at 2 x 128 only 4.5."""
    folder = tmp_path_factory.mktemp("dense")
    for h in (0, 1):
        reference(folder / f"pilot{h}.exr", "mitsuba", 16, h)
        reference(folder / f"check{h}.exr", "pgi", 512, h)
    return folder


def test_mitsubas_black_reference_of_a_dense_white_medium_is_found(dense: Path) -> None:
    for h in (0, 1):
        assert not read_exr(dense / f"pilot{h}.exr").any()  # the failure the check is for
        side = json.loads((dense / f"check{h}.json").read_text())
        assert side["source"] == "pgi" and side["passes"] == 32
    halves = [dense / f"pilot{h}.exr" for h in (0, 1)]
    checks = [dense / f"check{h}.exr" for h in (0, 1)]
    trust = check_reference_files(halves, checks, "Mitsuba's reference of cbox-fog")
    assert not trust["trustworthy"], trust
    assert trust["line"].startswith("Mitsuba's reference of cbox-fog is not trustworthy: ")
    assert "100.0 % below pt's" in trust["line"], trust["line"]
    assert "100 % of the pixels where pt sees light are exactly 0" in trust["line"]


def test_the_plan_hands_it_to_pt(dense: Path) -> None:
    """Sized, the plan renders the halves with pgi's pt, sized from pt's check, which they
    extend (their stores are the check's)."""
    check = [str(dense / f"check{h}.exr") for h in (0, 1)]
    spec = {
        "out": str(dense / "plan.json"),
        "scene": "cbox-fog",
        "source": "mitsuba",
        "check": check,
        "pilot": [str(dense / f"pilot{h}.exr") for h in (0, 1)],
        "runs": {"pt": check},  # any images of the scene stand for the study's runs here
        "target": 1.0,
        "max_seconds": 5.0,
    }
    plan = plan_from_files(spec)
    assert plan["source"] == "pgi" and plan["fallback"] and not plan["trust"]["trustworthy"]
    assert plan["pilot_spp"] == 512
    assert "--source pgi" in half_args(plan, dense, 1)
    assert half_args(plan, dense, 1).endswith(f"{dense / 'store' / 'pgi-half1.npz'}")
