"""Equal-time relMSE of methods at their default parameters, this checkout against another.

    python bench/bench_defaults.py [--scenes ...] [--methods pm sppm ppb] [--size 128]
                                   [--budgets 1 2 4 8] [--seeds 1 2 3] [--threads 2]
                                   [--reference-spp 2048] [--baseline CHECKOUT]

What the default study measures (configs/default.yaml: budgets 1, 2, 4, 8 s, seeds 1-3,
128 x 128, relMSE against a Mitsuba reference of two halves of 1024 spp each), for any scenes
and methods, without the workflow: every run is `pgi render --snapshots` in a subprocess, so
loading is excluded and snapshots are taken at the iteration end nearest each budget, as the
workflow takes them. With `--baseline CHECKOUT` each run is also made with the `pgi` of
another checkout (its `.venv`), the two alternating run by run so that both see the same load
on a shared machine, and the table gives both means over the seeds, with their standard
errors, the ratio after / before and Welch's t of the difference of the log errors (a run
whose t is above 3, worse beyond its noise, is marked !). The reference's own relMSE is
printed with it; errors within 10x of it are marked * (reference-limited). References are
cached as bench_pt.py's (bench/.cache). Numbers are reported, never asserted.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchlib import at_least, check_options, mitsuba_reference, seconds
from compare.metrics import compare_images, reference_ok
from renderer.imageio import read_exr
from renderer.methods import method_ids

SCENES = [
    "cbox", "cbox-fog", "cbox-glass", "cbox-grid", "crepuscular",
    "fog-perlin", "fog-step", "juice", "smoke", "volcaustic",
]  # fmt: skip


def render(
    pgi: Path, scene: str, method: str, seed: int, args: argparse.Namespace, out: Path
) -> list[tuple[np.ndarray, dict]]:
    """(image, sidecar) of each budget's snapshot of one run of `pgi render`."""
    budgets = ",".join(f"{b:g}" for b in args.budgets)
    command = [
        str(pgi), "render", scene, "--method", method, "--seed", str(seed),
        "--threads", str(args.threads), "--snapshots", budgets, "-q", "-o", str(out / "run.exr"),
        "--set", f"film.width={args.size}", "--set", f"film.height={args.size}",
        *[item for kv in args.set for item in ("--set", kv)],
    ]  # fmt: skip
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    runs = []
    for budget in args.budgets:
        path = out / f"run.t{budget:g}.exr"
        sidecar = json.loads(path.with_suffix(".json").read_text())
        runs.append((read_exr(path).astype(np.float64), sidecar))
    return runs


def log_error_t(after: np.ndarray, before: np.ndarray) -> float:
    """Welch's t of mean(log after) - mean(log before) over the seeds."""
    a, b = np.log(after), np.log(before)
    se = np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b)) if len(a) > 1 else np.nan
    return float((a.mean() - b.mean()) / se) if se > 0 else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=SCENES, help="shipped scenes to run")
    parser.add_argument(
        "--methods", nargs="+", default=["pm", "sppm", "ppb"], help="method ids to run"
    )
    parser.add_argument("--size", type=at_least(1), default=128, help="film width and height")
    parser.add_argument(
        "--budgets", nargs="+", type=seconds, default=[1.0, 2.0, 4.0, 8.0], help="snapshots (s)"
    )
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3], help="one run each")
    parser.add_argument("--threads", type=at_least(1), default=2, help="worker threads")
    parser.add_argument(
        "--reference-spp",
        type=at_least(2),
        default=2048,
        help="samples per pixel of the Mitsuba reference, over its two halves together",
    )
    parser.add_argument("--set", action="append", default=[], help="KEY=VALUE for every run")
    parser.add_argument(
        "--baseline", type=Path, help="another checkout (with its .venv), run alternately"
    )
    args = parser.parse_args()
    args.budgets = sorted(args.budgets)
    if unknown := [m for m in args.methods if m not in method_ids()]:
        parser.error(f"unknown method(s) {unknown}; known: {', '.join(method_ids())}")
    check_options(parser, args)
    ours = Path(sys.executable).with_name("pgi")
    builds = {"after": ours}
    if args.baseline:
        builds = {"before": args.baseline / ".venv" / "bin" / "pgi", "after": ours}
    for label, pgi in builds.items():
        if not pgi.exists():
            parser.error(f"no pgi for {label} at {pgi}")

    print(f"{args.size}x{args.size}, {args.threads} threads, seeds {args.seeds}, relMSE")
    for scene in args.scenes:
        ref, own = mitsuba_reference(scene, args.size, args.reference_spp)
        print(f"{scene}: the reference's own relMSE {own:.3e}", flush=True)
        for method in args.methods:
            errors = {label: [] for label in builds}  # per build: seeds x budgets
            iterations = {label: [] for label in builds}
            for seed in args.seeds:
                for label, pgi in builds.items():
                    with tempfile.TemporaryDirectory() as tmp:
                        runs = render(pgi, scene, method, seed, args, Path(tmp))
                    errors[label].append([compare_images(im, ref)["relmse"] for im, _ in runs])
                    iterations[label].append(runs[-1][1]["iterations"])
            for k, budget in enumerate(args.budgets):
                cells = []
                for label in builds:
                    e = np.array([seed_errors[k] for seed_errors in errors[label]])
                    se = e.std(ddof=1) / np.sqrt(len(e)) if len(e) > 1 else float("nan")
                    mark = "" if reference_ok(float(e.mean()), own) else "*"
                    cells.append(f"{label} {e.mean():.3e} +- {se:.1e}{mark}")
                line = f"  {method:5s} {budget:4g} s  " + "  ".join(cells)
                if len(builds) == 2:
                    b = np.array([s[k] for s in errors["before"]])
                    a = np.array([s[k] for s in errors["after"]])
                    t = log_error_t(a, b)
                    line += f"  after/before {a.mean() / b.mean():.2f} (t {t:+.1f}){' !' * (t > 3)}"
                print(line, flush=True)
            its = "  ".join(f"{label} {np.mean(v):.0f}" for label, v in iterations.items())
            print(f"  {method:5s} iterations at {args.budgets[-1]:g} s: {its}", flush=True)


if __name__ == "__main__":
    main()
