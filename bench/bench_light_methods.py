"""Light-side methods against pt and Mitsuba volpath at equal time, with convergence slopes.

    python bench/bench_light_methods.py [--scenes cbox-fog cbox-glass volcaustic]
                                        [--seconds 8] [--size 64] [--threads 2]
                                        [--methods pt lt pm sppm mitsuba] [--reference-spp 8192]

For every scene and method (pt, lt, pm, sppm, mitsuba) one timed run records snapshots at
the iteration ends nearest seconds/8, /4, /2 and the full budget; each snapshot's relMSE
(mean((x-r)^2/(r^2+0.01))) against a high-spp Mitsuba reference of two independent halves
(cached under bench/.cache/, as bench_pt.py's) gives the error curve, and its fitted log-log
slope is printed beside the final error and the run's render time (theory: -1 for unbiased
methods, about -2/3 for sppm with alpha = 2/3, 0 in the limit for pm, whose fixed radius
leaves a bias: its relative bias of the image mean is printed too). The reference's own
relMSE, estimated from its halves, is printed first; errors within 10x of it are marked *
(reference-limited). lt cannot see glass (paths through specular surfaces to a pinhole
camera cannot be connected), so on glass scenes its error includes that missing light.
Numbers are reported, never asserted: timings on a shared 2-core machine are noisy.
"""

from __future__ import annotations

import argparse

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
from renderer.methods import get_method
from renderer.progressive import iterate_to

METHODS = ("pt", "lt", "pm", "sppm", "mitsuba")


def timed_curve(method_id: str, scene, seconds: float, threads: int, ref):
    """(times, relMSEs, final image, stats) of one run with snapshots at seconds/8 .. seconds."""
    method = get_method(method_id)(scene, seed=1, threads=threads, params={})
    times, errors = [], []
    # at the iteration end nearest each checkpoint, as the workflow takes snapshots
    for _, elapsed in iterate_to(method, [seconds / 8, seconds / 4, seconds / 2, seconds]):
        if not times or elapsed > times[-1]:  # one end may serve two checkpoints
            times.append(elapsed)
            errors.append(compare_images(method.image(), ref)["relmse"])
    return times, errors, method.image(), dict(method.stats(), seconds=times[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_common_options(parser, ["cbox-fog", "cbox-glass", "volcaustic"])
    parser.set_defaults(size=64)
    parser.add_argument(
        "--methods", nargs="+", default=list(METHODS), choices=METHODS, help="methods to run"
    )
    parser.add_argument("--seconds", type=seconds, default=8.0, help="equal-time budget")
    parser.add_argument(
        "--reference-spp",
        type=at_least(2),
        default=8192,
        help="samples per pixel of the Mitsuba reference, over its two halves together",
    )
    args = parser.parse_args()
    check_options(parser, args)

    header = (
        f"{'scene':<11} {'method':<8} {'relMSE':>11} {'slope':>6} {'seconds':>7} {'iters':>6} "
        f"{'spp':>9} {'rel. bias of mean':>18}"
    )
    print(f"equal time {args.seconds:g} s, {args.size}x{args.size}, {args.threads} threads")
    print(header)
    print("-" * len(header))
    for name in args.scenes:
        scene = scene_at(name, args.size)
        ref, own = mitsuba_reference(name, args.size, args.reference_spp)
        print(f"{name:<11} {'(ref)':<8} {own:11.3e}  <- the reference's own error", flush=True)
        for method_id in args.methods:
            times, errors, image, stats = timed_curve(
                method_id, scene, args.seconds, args.threads, ref
            )
            fit = fit_slope(times, errors)
            bias = image.mean() / ref.mean() - 1
            limited = " " if reference_ok(errors[-1], own) else "*"
            print(
                f"{name:<11} {method_id:<8} {errors[-1]:10.3e}{limited} {fit.slope:6.2f} "
                f"{stats['seconds']:7.2f} {stats['iterations']:6d} {stats.get('spp', 0):9.4g} "
                f"{bias:+18.2%}",
                flush=True,
            )


if __name__ == "__main__":
    main()
