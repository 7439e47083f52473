"""Light-side methods against pt and Mitsuba volpath at equal time, with convergence slopes.

    python bench/bench_light_methods.py [--scenes cbox-fog cbox-glass volcaustic]
                                        [--seconds 8] [--size 64] [--threads 2]

For every scene and method (pt, lt, pm, sppm, mitsuba) one timed run records snapshots at
seconds/8, /4, /2 and the full budget; each snapshot's relMSE (mean((x-r)^2/(r^2+0.01)))
against a high-spp Mitsuba reference (cached under bench/.cache/, shared with
bench_pt.py) gives the error curve, and its fitted log-log slope is printed beside the
equal-time error (theory: -1 for unbiased methods, about -2/3 for sppm with alpha = 2/3,
0 in the limit for pm, whose fixed radius leaves a bias: its relative bias of the image
mean is printed too). lt cannot see glass (paths through specular surfaces to a pinhole
camera cannot be connected), so on glass scenes its error includes that missing light.
Numbers are reported, never asserted: timings on a shared 2-core machine are noisy.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from compare.convergence import fit_slope
from compare.metrics import compare_images
from renderer.imageio import read_exr, write_exr
from renderer.methods import get_method
from renderer.progressive import iterate_to
from renderer.reference import render_reference
from renderer.scene import load_scene

CACHE = Path(__file__).resolve().parent / ".cache"
SCENES_DIR = Path(__file__).resolve().parent.parent / "scenes"
METHODS = ("pt", "lt", "pm", "sppm", "mitsuba")


def reference(scene, name: str, size: int, spp: int, second: bool = False) -> np.ndarray:
    """Cached Mitsuba reference; ``second``: an independent one (another seed)."""
    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"{name}-{size}-{spp}{'-b' if second else ''}.exr"
    if not path.exists():
        print(f"  rendering the reference of {name} ({spp} spp at {size}x{size}) ...", flush=True)
        image, _ = render_reference(scene, spp, seed=54321 if second else 12345)
        write_exr(path, image)
    return read_exr(path).astype(np.float64)


def timed_curve(method_id: str, scene, seconds: float, threads: int, ref: np.ndarray):
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
    parser.add_argument("--scenes", nargs="+", default=["cbox-fog", "cbox-glass", "volcaustic"])
    parser.add_argument("--methods", nargs="+", default=list(METHODS))
    parser.add_argument("--seconds", type=float, default=8.0, help="equal-time budget")
    parser.add_argument("--size", type=int, default=64, help="film width and height")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--reference-spp", type=int, default=8192)
    parser.add_argument(
        "--reference-error",
        action="store_true",
        help="render a second, independent reference and print the references' own error "
        "(half the relMSE between the two): methods near it are limited by the reference",
    )
    args = parser.parse_args()

    header = (
        f"{'scene':<11} {'method':<8} {'relMSE':>10} {'slope':>6} {'iters':>6} "
        f"{'spp':>7} {'rel. bias of mean':>18}"
    )
    print(f"equal time {args.seconds:g} s, {args.size}x{args.size}, {args.threads} threads")
    print(header)
    print("-" * len(header))
    for name in args.scenes:
        if not (SCENES_DIR / name).exists():
            print(f"{name:<11} (scene not present, skipped)")
            continue
        scene = load_scene(name, [f"film.width={args.size}", f"film.height={args.size}"])
        ref = reference(scene, name, args.size, args.reference_spp)
        if args.reference_error:
            other = reference(scene, name, args.size, args.reference_spp, second=True)
            own = compare_images(other, ref)["relmse"] / 2
            print(f"{name:<11} {'(ref)':<8} {own:10.3e}  <- the reference's own error", flush=True)
        for method_id in args.methods:
            times, errors, image, stats = timed_curve(
                method_id, scene, args.seconds, args.threads, ref
            )
            fit = fit_slope(times, errors)
            bias = image.mean() / ref.mean() - 1
            print(
                f"{name:<11} {method_id:<8} {errors[-1]:10.3e} {fit.slope:6.2f} "
                f"{stats['iterations']:6d} {stats.get('spp', 0):7d} {bias:+18.2%}",
                flush=True,
            )


if __name__ == "__main__":
    main()
