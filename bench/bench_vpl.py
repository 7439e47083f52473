"""vpl (each clamp), vsl, pt, ppb and Mitsuba at equal time: relMSE at every budget and the
fitted slope of its fall.

    python bench/bench_vpl.py [--scenes cbox cbox-fog crepuscular smoke] [--size 128]
                              [--budgets 1 2 4 8 16 32 64] [--threads 2] [--seed 1]
                              [--methods vpl-none vpl-fixed vpl-progressive vsl pt ppb mitsuba]
                              [--reference-spp N] [--set method.KEY=VALUE ...] [--cpu-time]

One run per scene and method renders to the largest budget, its image taken at the iteration end
nearest each budget (the workflow's rule, renderer.progressive.iterate_to); relMSE
(mean((x-r)^2/(r^2+0.01))) is measured against a Mitsuba reference of two independent halves
(cached under bench/.cache/, as the other scripts'), less the reference's own relMSE (from the
halves; a value within 10x of it is marked *). The slope is the least-squares fit of
log(relMSE - reference's) against log(render seconds) over the budgets whose value is
positive. `vpl-X` is vpl with clamp=X (its other parameters at their defaults), `vsl` and the
others at their defaults; `--set` adds parameters to every vpl and vsl run. Numbers are
reported, never asserted: timings on a shared 2-core machine are noisy (`--cpu-time` with
`--threads 1` measures budgets in the process's CPU seconds instead, which others' work on the
machine does not inflate).
"""

from __future__ import annotations

import argparse
import time

from benchlib import (
    add_common_options,
    at_least,
    check_options,
    mitsuba_reference,
    scene_at,
    seconds,
)
from compare.convergence import fit_slope
from compare.metrics import compare_images, reference_ok
from renderer.errors import PgiError
from renderer.methods import check_method_parameters, get_method
from renderer.progressive import iterate_to
from renderer.scene.yaml_dialect import parse_yaml_value

METHODS = {
    "vpl-none": ("vpl", {"clamp": "none"}),
    "vpl-fixed": ("vpl", {"clamp": "fixed"}),
    "vpl-progressive": ("vpl", {"clamp": "progressive"}),
    "vsl": ("vsl", {}),
    "pt": ("pt", {}),
    "ppb": ("ppb", {}),
    "mitsuba": ("mitsuba", {}),
}
# Reference samples per pixel (both halves together): enough that its own error is well below
# the methods' at the largest budget; the smoke grid is slow for Mitsuba's global majorant.
REFERENCE_SPP = {"cbox": 8192, "cbox-fog": 16384, "crepuscular": 8192, "smoke": 2048}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_common_options(parser, ["cbox", "cbox-fog", "crepuscular", "smoke"])
    parser.set_defaults(size=128)
    parser.add_argument(
        "--methods", nargs="+", default=list(METHODS), choices=METHODS, help="methods to run"
    )
    parser.add_argument(
        "--budgets",
        nargs="+",
        type=seconds,
        default=[1, 2, 4, 8, 16, 32, 64],
        help="render seconds at which each run's image is measured",
    )
    parser.add_argument("--seed", type=at_least(0), default=1, help="the seed of every run")
    parser.add_argument(
        "--reference-spp",
        type=at_least(2),
        help="samples per pixel of every Mitsuba reference (default: per scene, REFERENCE_SPP)",
    )
    parser.add_argument(
        "--set", action="append", default=[], help="method.KEY=VALUE for every vpl and vsl run"
    )
    parser.add_argument(
        "--cpu-time",
        action="store_true",
        help="budgets in CPU seconds of the process (time.process_time), not wall-clock: fair "
        "on a shared machine with --threads 1",
    )
    args = parser.parse_args()
    check_options(parser, args)
    extra = {}
    for kv in args.set:
        key, _, value = kv.partition("=")
        if not key.startswith("method.") or not value:
            parser.error(f"--set {kv}: expected method.KEY=VALUE")
        extra[key.removeprefix("method.")] = parse_yaml_value(value, f"--set {key}")
    for name in {"vpl", "vsl"} & {METHODS[m][0] for m in args.methods}:
        try:  # a parameter the method does not know, before any work
            check_method_parameters(name, extra)
        except PgiError as e:
            parser.error(str(e))
    budgets = sorted(args.budgets)
    clock = time.process_time if args.cpu_time else None
    print(
        f"{args.size}x{args.size}, {args.threads} threads, seed {args.seed}, budgets {budgets} "
        f"{'CPU ' if args.cpu_time else ''}s"
    )
    cells = " ".join(f"{f'{b:g} s':>10}" for b in budgets)
    header = f"{'scene':<12} {'method':<16} {cells} {'slope':>6} {'it@1st':>6}"
    print(header)
    print("-" * len(header))
    for name in args.scenes:
        spp = args.reference_spp or REFERENCE_SPP.get(name, 8192)
        ref, own = mitsuba_reference(name, args.size, spp)
        print(f"{name:<12} {'(reference)':<16} own relMSE {own:.3e} ({spp} spp)", flush=True)
        scene = scene_at(name, args.size)
        for label in args.methods:
            method_id, params = METHODS[label]
            params = {**params, **(extra if method_id in ("vpl", "vsl") else {})}
            method = get_method(method_id)(
                scene, seed=args.seed, threads=args.threads, params=params
            )
            times, errors, marks, first_iterations = [], [], [], None
            for _, elapsed in iterate_to(method, budgets, clock):
                if first_iterations is None:
                    first_iterations = method.stats()["iterations"]
                raw = compare_images(method.image(), ref)["relmse"]
                times.append(elapsed)
                errors.append(raw - own)
                marks.append(" " if reference_ok(raw, own) else "*")
            values = " ".join(f"{e:9.3e}{m}" for e, m in zip(errors, marks, strict=True))
            print(
                f"{name:<12} {label:<16} {values} {fit_slope(times, errors).slope:6.2f} "
                f"{first_iterations:6d}",
                flush=True,
            )


if __name__ == "__main__":
    main()
