"""ppb against pt and Mitsuba volpath at equal time, with fitted convergence slopes.

    python bench/bench_ppb.py [--scenes volcaustic cbox-fog] [--budgets 2 4 8 16]
                              [--size 48] [--threads 2] [--seeds 1] [--ppb KEY=VALUE ...]

Each method runs once per seed up to the largest budget; its image is taken at the iteration
end nearest each budget (one run gives the whole error-vs-time curve, as the workflow's
snapshots do). relMSE is measured against a Mitsuba reference rendered as two independent
halves (cached under bench/.cache/) and printed less the reference's own relMSE, estimated
from the halves; a mean within 10x of it is marked reference-limited and gets no ratio. The
log-log slope of that error is fitted against the measured render times, one point per
iteration end (compare.convergence.fit_slope_over_budgets: NaN unless three budgets or more
span 4x).

Targets (reported, never asserted; timings on a shared machine are noisy):
  - volcaustic, largest budget: ppb's relMSE at least 10x below both pt and Mitsuba;
  - cbox-fog: ppb's fitted relMSE slope steeper than -0.5.
The full study (budgets 2..64 s, 256 x 256, several seeds) needs references of about
10^5 spp on volcaustic (its caustic is found by Mitsuba's volpath only by chance: the
reference error must stay well below ppb's) and about 1.5 h of renders per scene and seed
on two cores: run it with the workflow (configs/) rather than this script.
"""

from __future__ import annotations

import argparse

import numpy as np

from benchlib import (
    add_common_options,
    at_least,
    check_options,
    mitsuba_reference,
    ratio,
    relmse_less_reference,
    scene_at,
    seconds,
)
from compare.convergence import fit_slope_over_budgets
from compare.metrics import reference_ok
from renderer.methods import get_method
from renderer.methods.ppb import ProgressivePhotonBeams
from renderer.progressive import iterate_to

METHODS = ("pt", "ppb", "mitsuba")
# Reference samples per pixel over both halves: the caustic scene needs many more.
REFERENCE_SPP = {"volcaustic": 32768, "cbox-fog": 4096}
INTEGER_PARAMETERS = ("light_paths", "spp_per_iteration", "max_beams", "max_records",
                      "gather_bounces")  # fmt: skip


def curve(
    method_id: str, scene, budgets: list[float], threads: int, seed: int, params: dict
) -> list[dict]:
    """Images of one run at each budget of render time (budgets ascending)."""
    method = get_method(method_id)(scene, seed=seed, threads=threads, params=params)
    # at the iteration end nearest each budget, as the workflow takes snapshots
    return [
        dict(budget=budget, seconds=elapsed, image=method.image())
        for budget, elapsed in iterate_to(method, budgets)
    ]


def ppb_parameter(text: str) -> tuple[str, float | int]:
    """argparse type of --ppb: KEY=VALUE, KEY one of ppb's parameters."""
    key, sep, value = text.partition("=")
    if not sep or key not in ProgressivePhotonBeams.parameters:
        known = ", ".join(sorted(ProgressivePhotonBeams.parameters))
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE with KEY one of {known}")
    try:
        return key, int(value) if key in INTEGER_PARAMETERS else float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{key}: {value!r} is not a number") from None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_common_options(parser, ["volcaustic", "cbox-fog"])
    parser.set_defaults(size=48)
    parser.add_argument(
        "--methods", nargs="+", default=list(METHODS), choices=METHODS, help="methods to run"
    )
    parser.add_argument(
        "--budgets",
        nargs="+",
        type=seconds,
        default=[2, 4, 8, 16],
        help="render times at which each run's image is measured (seconds)",
    )
    parser.add_argument("--seeds", type=at_least(1), default=1, help="runs per method")
    parser.add_argument(
        "--reference-spp",
        type=at_least(2),
        default=0,
        help="samples per pixel of the Mitsuba reference over its two halves (default: "
        + ", ".join(f"{k} {v}" for k, v in REFERENCE_SPP.items())
        + ", else 8192)",
    )
    parser.add_argument(
        "--ppb",
        action="append",
        default=[],
        type=ppb_parameter,
        metavar="KEY=VALUE",
        help=f"a ppb parameter ({', '.join(sorted(ProgressivePhotonBeams.parameters))})",
    )
    args = parser.parse_args()
    check_options(parser, args)
    budgets = sorted(set(args.budgets))
    ppb_params = dict(args.ppb)

    for name in args.scenes:
        scene = scene_at(name, args.size)
        spp = args.reference_spp or REFERENCE_SPP.get(name, 8192)
        ref, ref_err = mitsuba_reference(name, args.size, spp)
        print(
            f"\n{name} ({args.size}x{args.size}; reference relMSE ~ {ref_err:.2e}); relMSE "
            "less the reference's at the iteration end nearest each budget (* reference-"
            "limited), mean over seeds, and its slope against the measured render times",
            flush=True,
        )
        final = {}
        for method_id in args.methods:
            errors = np.zeros((args.seeds, len(budgets)))
            times, points, point_budgets = [], [], []
            for seed in range(args.seeds):
                params = ppb_params if method_id == "ppb" else {}
                snaps = curve(method_id, scene, budgets, args.threads, seed, params)
                previous = None
                for k, snap in enumerate(snaps):
                    errors[seed, k], _ = relmse_less_reference(snap["image"], ref, ref_err)
                    if snap["seconds"] != previous:  # one iteration end may serve two budgets
                        times.append(snap["seconds"])
                        points.append(errors[seed, k])
                        point_budgets.append(snap["budget"])
                    previous = snap["seconds"]
            mean = errors.mean(axis=0)
            usable = [reference_ok(e + ref_err, ref_err) for e in mean]
            fit = fit_slope_over_budgets(times, points, point_budgets)
            final[method_id] = (mean[-1], usable[-1])
            cells = "  ".join(
                f"{b:g}s {e:.2e}{'' if ok else '*'}"
                for b, e, ok in zip(budgets, mean, usable, strict=True)
            )
            print(
                f"  {method_id:<8} relMSE {cells}  slope {fit.slope:+.2f} (r2 {fit.r2:.2f}, "
                f"{fit.n} points)",
                flush=True,
            )
        if not {"pt", "ppb", "mitsuba"} <= set(final):
            continue
        print(
            f"  at {budgets[-1]:g} s, ppb's error is lower than pt's by "
            f"{ratio(final['pt'], final['ppb'])} and than Mitsuba's by "
            f"{ratio(final['mitsuba'], final['ppb'])}",
            flush=True,
        )


if __name__ == "__main__":
    main()
