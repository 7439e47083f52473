"""The benchmark scripts are not tests (their numbers are printed, never asserted), but their
options are: each explains every option and refuses a bad one in one line, before any work
(a review found NaN budgets that ran forever, tracebacks, and threads beyond the cores)."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "bench"
SCRIPTS = (
    "bench_pt",
    "bench_ppb",
    "bench_media",
    "bench_light_methods",
    "bench_slab",
    "bench_defaults",
    "bench_vpl",
    "bench_bdpt",
    "bench_roulette",
    "bench_vrl",
)
sys.path.insert(0, str(BENCH))

import benchlib  # noqa: E402


def run(script: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(BENCH / f"{script}.py"), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_option_is_explained(script):
    r = run(script, "--help")
    assert r.returncode == 0, r.stderr
    options = [line.split()[0] for line in r.stdout.splitlines() if line.startswith("  --")]
    assert "--threads" in options and ("--scenes" in options or script == "bench_slab")
    for line in r.stdout.split("\n  --")[1:]:
        assert len(line.split()) > 2, f"{script}: option without help: --{line}"


@pytest.mark.parametrize(
    "script, args, message",
    [
        ("bench_pt", ["--seconds", "nan"], "expected a finite number of seconds > 0"),
        ("bench_pt", ["--threads", "64"], "--threads 64 asked for"),
        ("bench_pt", ["--reference-spp", "1"], "expected an integer >= 2"),
        ("bench_ppb", ["--budgets", "1", "-1"], "expected a finite number of seconds > 0"),
        ("bench_ppb", ["--ppb", "radius"], "expected KEY=VALUE with KEY one of"),
        ("bench_ppb", ["--scenes", "no-such-scene"], "scene 'no-such-scene' not found"),
        ("bench_media", ["--render-cells", "0"], "expected an integer >= 1"),
        ("bench_media", ["--scenes", "cbox-fog"], "cbox-fog: no grid medium"),
        ("bench_light_methods", ["--methods", "bdpt"], "invalid choice: 'bdpt'"),
        ("bench_light_methods", ["--size", "0"], "expected an integer >= 1"),
        ("bench_slab", ["--width", "2"], "--width must be at least 4"),
        ("bench_defaults", ["--methods", "nosuch"], "unknown method(s) ['nosuch']"),
        ("bench_vpl", ["--budgets", "1", "nan"], "expected a finite number of seconds > 0"),
        ("bench_vpl", ["--set", "clamp=none"], "expected method.KEY=VALUE"),
        ("bench_bdpt", ["--seconds", "0"], "expected a finite number of seconds > 0"),
        ("bench_roulette", ["--seeds", "0"], "expected an integer >= 1"),
        ("bench_roulette", ["--threads", "64"], "--threads 64 asked for"),
        ("bench_vrl", ["--methods", "vrl-none"], "invalid choice: 'vrl-none'"),
        ("bench_vrl", ["--budgets", "0"], "expected a finite number of seconds > 0"),
    ],
)
def test_a_bad_option_is_one_line_before_any_work(script, args, message):
    r = run(script, *args)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert message in r.stderr.splitlines()[-1] and r.stdout == "", r.stderr


def test_ratios_need_a_reference_ten_times_better():
    assert benchlib.ratio((2e-3, True), (1e-3, True)) == "2.00x"
    for limited in (((2e-3, False), (1e-3, True)), ((2e-3, True), (-1e-4, True))):
        assert benchlib.ratio(*limited).startswith("n/a (reference-limited")
    with pytest.raises(argparse.ArgumentTypeError):
        benchlib.seconds("inf")
    assert benchlib.at_least(0)("0") == 0
