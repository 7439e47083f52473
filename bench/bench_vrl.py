"""vrl and vbl against ppb, vpl, vsl, pt and Mitsuba at equal CPU time: relMSE at every budget
and the fitted slope of its fall.

    python bench/bench_vrl.py [--scenes juice fog-perlin cbox-fog] [--size 64]
                              [--budgets 2 4 8 16 32 64] [--seed 1]
                              [--methods vrl vrl-phase vbl vbl-phase ppb vpl vsl pt mitsuba]
                              [--reference-spp N]

Every run renders on one thread and is timed by the CPU time of this process (time.process_time),
not by the wall clock, which the other work on a shared machine disturbs; Mitsuba's CPU time
includes its own threads. Each run's image is taken at the first iteration end past each budget;
relMSE (mean((x-r)^2/(r^2+0.01))) is measured against a Mitsuba reference of two independent
halves (cached under bench/.cache/, as the other scripts'), less the reference's own relMSE
(from the halves; a value within 10x of it is marked *). The slope is the study's log-log fit
(compare.convergence.fit_slope). Numbers are reported, never asserted.
"""

from __future__ import annotations

import argparse
import time

import benchlib
from compare.convergence import fit_slope
from compare.metrics import compare_images, reference_ok
from renderer.methods import get_method

# label -> (method, parameters): the defaults, and vrl and vbl with phase-aware sampling
METHODS = {
    "vrl": ("vrl", {}),
    "vrl-phase": ("vrl", {"phase_sampling": True}),
    "vbl": ("vbl", {}),
    "vbl-phase": ("vbl", {"phase_sampling": True}),
    **{m: (m, {}) for m in ("ppb", "vpl", "vsl", "pt", "mitsuba")},
}
REFERENCE_SPP = {"juice": 4096, "fog-perlin": 4096, "cbox-fog": 8192}


def cpu_time_curve(method, budgets: list[float]):
    """(CPU seconds, image) at the first iteration end past each budget."""
    start, iteration, pending = time.process_time(), 0, list(budgets)
    while pending:
        method.run_iteration(iteration)
        iteration += 1
        spent = time.process_time() - start
        while pending and spent >= pending[0]:
            pending.pop(0)
            yield spent, method.image()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    benchlib.add_common_options(parser, ["juice", "fog-perlin", "cbox-fog"])
    parser.set_defaults(size=64, threads=1)
    parser.add_argument(
        "--methods", nargs="+", default=list(METHODS), choices=METHODS, help="methods to run"
    )
    parser.add_argument(
        "--budgets",
        nargs="+",
        type=benchlib.seconds,
        default=[2, 4, 8, 16, 32, 64],
        help="CPU seconds at which each run's image is measured",
    )
    parser.add_argument(
        "--seed", type=benchlib.at_least(0), default=1, help="the seed of every run"
    )
    parser.add_argument(
        "--reference-spp",
        type=benchlib.at_least(2),
        help="samples per pixel of every Mitsuba reference (default: per scene, REFERENCE_SPP)",
    )
    args = parser.parse_args()
    benchlib.check_options(parser, args)
    budgets = sorted(args.budgets)
    print(
        f"{args.size}x{args.size}, {args.threads} thread(s), seed {args.seed}, "
        f"CPU budgets {budgets} s"
    )
    header = (
        f"{'scene':<12} {'method':<8} " + " ".join(f"{f'{b:g} s':>10}" for b in budgets) + "  slope"
    )
    print(header + "\n" + "-" * len(header))
    for name in args.scenes:
        spp = args.reference_spp or REFERENCE_SPP.get(name, 4096)
        ref, own = benchlib.mitsuba_reference(name, args.size, spp)
        print(f"{name:<12} (reference) own relMSE {own:.3e} ({spp} spp)", flush=True)
        scene = benchlib.scene_at(name, args.size)
        for label in args.methods:
            method_id, params = METHODS[label]
            method = get_method(method_id)(
                scene, seed=args.seed, threads=args.threads, params=params
            )
            times, errors, cells = [], [], []
            for spent, image in cpu_time_curve(method, budgets):
                raw = compare_images(image, ref)["relmse"]
                times.append(spent)
                errors.append(raw - own)
                cells.append(f"{raw - own:9.3e}{' ' if reference_ok(raw, own) else '*'}")
            slope = fit_slope(times, errors).slope
            print(f"{name:<12} {label:<9} {' '.join(cells)} {slope:6.2f}", flush=True)


if __name__ == "__main__":
    main()
