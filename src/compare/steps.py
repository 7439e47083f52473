"""Command-line entry points of the workflow jobs: ``python -m compare.steps <step> ...``.

Thin adaptors: each parses its arguments and calls the library function that does the work.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from .metrics import DETERMINED_FRACTION


def _reference_plan(a: argparse.Namespace) -> None:
    from .sizing import plan_from_files

    plan = plan_from_files(json.loads(a.spec))
    print(json.dumps(plan, indent=1, default=str))


def _reference_args(a: argparse.Namespace) -> None:
    """The `pgi reference` options a plan gives one half: what the reference-half job runs."""
    from renderer.imageio import read_json

    from .sizing import half_args

    print(half_args(read_json(a.plan), Path(a.plan).parent, int(a.half)))


def _merge_reference(a: argparse.Namespace) -> None:
    from .runs import merge_reference

    info = merge_reference(a.half_a, a.half_b, a.out_exr, a.out_json, a.plan, a.check)
    print(
        f"reference: half-vs-half relMSE {info['halves_relmse']:.4g}, "
        f"estimated reference relMSE {info['ref_relmse']:.4g}"
    )
    if info.get("trust"):
        print(info["trust"]["line"])


def _compare_run(a: argparse.Namespace) -> None:
    from .runs import compare_run

    budgets = [float(b) for b in a.budgets.split(",")]
    df = compare_run(
        a.snapshots,
        budgets,
        a.ref,
        a.ref_json,
        a.o,
        scene=a.scene,
        method=a.method,
        seed=a.seed,
        threads=a.threads,
    )
    print(df.to_string())


_METRICS_PATH = re.compile(r"metrics/(?P<scene>[^/]+)/(?P<method>[^/]+)/s(?P<seed>\d+)\.csv$")


def _tables(a: argparse.Namespace) -> None:
    from .tables import load_runs, write_tables

    bench = {}
    for p in a.metrics:
        m = _METRICS_PATH.search(Path(p).as_posix())
        if m:
            key = (m["scene"], m["method"], int(m["seed"]))
            tsv = Path(a.results) / "benchmarks" / "render" / m["scene"] / m["method"]
            bench[key] = tsv / f"s{m['seed']}.tsv"
    runs = load_runs(a.metrics, bench)
    tables = write_tables(
        runs,
        a.o,
        metric=a.metric,
        baseline=a.baseline,
        scenes=a.scenes.split(",") if a.scenes else (),
        methods=a.methods.split(",") if a.methods else (),
        determined_fraction=a.determined_fraction,
    )
    print(tables["best"].to_string())


def _report_scene(a: argparse.Namespace) -> None:
    from .report.build import build_scene_page

    build_scene_page(json.loads(a.spec))


def _report_index(a: argparse.Namespace) -> None:
    from .report.build import build_index

    build_index(json.loads(a.spec))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m compare.steps", description=__doc__)
    sub = ap.add_subparsers(dest="step", required=True)

    p = sub.add_parser("reference-plan", help="how many samples a reference needs (spec as JSON)")
    p.add_argument("spec")
    p.set_defaults(fn=_reference_plan)

    p = sub.add_parser("reference-args", help="print the `pgi reference` options of a plan")
    p.add_argument("plan")
    p.add_argument("half", help="0 or 1")
    p.set_defaults(fn=_reference_args)

    p = sub.add_parser("merge-reference", help="average two reference halves, record error")
    p.add_argument("half_a")
    p.add_argument("half_b")
    p.add_argument("out_exr")
    p.add_argument("out_json")
    p.add_argument("--plan", help="the reference's plan (reference-plan), recorded with it")
    p.add_argument(
        "--check", nargs=2, help="the two halves of pgi's pt check (a Mitsuba reference is checked)"
    )
    p.set_defaults(fn=_merge_reference)

    p = sub.add_parser("compare-run", help="metrics of every snapshot of one run")
    p.add_argument("snapshots", nargs="+")
    p.add_argument("--scene", required=True)
    p.add_argument("--method", required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--threads", type=int, required=True)
    p.add_argument("--budgets", required=True, help="comma separated, one per snapshot")
    p.add_argument("--ref", required=True)
    p.add_argument("--ref-json", required=True)
    p.add_argument("-o", required=True)
    p.set_defaults(fn=_compare_run)

    p = sub.add_parser("tables", help="aggregate metrics CSVs into tables")
    p.add_argument("metrics", nargs="+")
    p.add_argument("--results", required=True, help="results folder (for benchmark files)")
    p.add_argument("--metric", default="relmse")
    p.add_argument("--baseline", default="pt")
    p.add_argument(
        "--determined-fraction",
        type=float,
        default=DETERMINED_FRACTION,
        help="flag cells whose corrected error is not known to within this fraction",
    )
    p.add_argument("--scenes", default="", help="comma-separated: the order of rows")
    p.add_argument("--methods", default="", help="comma-separated: the order of rows")
    p.add_argument("-o", required=True, help="output folder")
    p.set_defaults(fn=_tables)

    p = sub.add_parser("report-scene", help="one scene's report page (spec as JSON)")
    p.add_argument("spec")
    p.set_defaults(fn=_report_scene)

    p = sub.add_parser("report-index", help="the report's index page (spec as JSON)")
    p.add_argument("spec")
    p.set_defaults(fn=_report_index)

    a = ap.parse_args(argv)
    a.fn(a)
    return 0


if __name__ == "__main__":
    sys.exit(main())
