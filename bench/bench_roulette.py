"""Russian roulette in dense white media: every method with Mitsuba's rule (survival
min(max(throughput) eta^2, 0.95)) against pgi's (survival from the throughput, uncapped), at
equal CPU time (the machine may be shared), several seeds each, against a reference rendered
by pgi's pt.

    python bench/bench_roulette.py [--scenes cloud cbox-fog-dense] [--seconds 5] [--size 32]
                                   [--seeds 3] [--methods pt lt pm sppm ppb bdpt mitsuba]
                                   [--reference-iterations 400] [--threads 1]

`cbox-fog-dense` is cbox-fog with sigma_t 50, albedo 0.999 and unbounded depth (an optical
depth of about 100 across the box). Mitsuba's volpath is no reference for either scene (it
returns 0 in the dense box, and its cloud is ~140x as noisy per sample as pt's, with heavy
tails; docs/methods.md, "Where Mitsuba disagrees"), so the reference is
pt with the new rule in two independent halves of ``--reference-iterations`` iterations each
(cached under bench/.cache/), its own error estimated from the halves and printed first.

For every method and rule: the image mean over the reference's per seed (the spread between
seeds shows an estimate whose variance has exploded), and the median over the seeds of the
normalised MSE, mean((x - r)^2) / mean(r)^2, less the reference's own (from its halves). Not the
workflow's relMSE: its 0.01 in the denominator exceeds r^2 in these dim images (means of 1e-2),
so there a black image scores better than a right but noisy one. The `mitsuba` row is
Mitsuba's volpath at equal time, which has only its own rule. Numbers are reported, never asserted.
"""

from __future__ import annotations

import argparse
import hashlib
import time

import numpy as np

from benchlib import CACHE, REFERENCE_SEEDS, at_least, scene_at, seconds
from compare.metrics import reference_error
from renderer.errors import PgiError
from renderer.fingerprint import render_fingerprint
from renderer.imageio import read_exr, write_exr
from renderer.methods import get_method
from renderer.progressive import available_cores, check_threads, run_for
from renderer.scene.sources import scene_content_digest

METHODS = ("pt", "lt", "pm", "sppm", "ppb", "bdpt", "mitsuba")
RULES = ("mitsuba", "throughput")
SCENES = {
    "cloud": ("cloud", []),
    "cbox-fog-dense": (
        "cbox-fog",
        ["media.fog.sigma_t=50", "media.fog.albedo=0.999", "integrator.max_depth=-1"],
    ),
}


def pt_reference(name: str, size: int, iterations: int, threads: int) -> tuple[np.ndarray, float]:
    """pt's image of scene ``name`` (new rule) as two independent halves of ``iterations``
    iterations each, averaged, and its own normalised MSE from them; cached with a key of the
    scene's content, the renderer's code, the size and the iterations."""
    base, overrides = SCENES[name]
    film = [f"film.width={size}", f"film.height={size}", *overrides]
    what = f"{scene_content_digest(base, film)}-{render_fingerprint()}-{size}-{iterations}"
    key = hashlib.sha256(what.encode()).hexdigest()[:16]
    CACHE.mkdir(exist_ok=True)
    scene, halves = scene_at(base, size, overrides), []
    for half, seed in enumerate(REFERENCE_SEEDS):
        path = CACHE / f"pt-{name}-{key}-{half}.exr"
        if not path.exists():
            print(f"  rendering pt's reference of {name}, half {half + 1} of 2 ...", flush=True)
            method = get_method("pt")(scene, seed=seed, threads=threads, params={})
            for i in range(iterations):
                method.run_iteration(i)
            write_exr(path, method.image())
        halves.append(read_exr(path).astype(np.float64))
    reference = 0.5 * (halves[0] + halves[1])
    return reference, reference_error(*halves)["ref_mse"] / reference.mean() ** 2


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scenes", nargs="+", default=list(SCENES), choices=list(SCENES), help="scenes to run"
    )
    parser.add_argument(
        "--methods", nargs="+", default=list(METHODS), choices=METHODS, help="methods to run"
    )
    parser.add_argument("--size", type=at_least(1), default=32, help="film width and height")
    parser.add_argument(
        "--seconds", type=seconds, default=5.0, help="equal-time budget, in CPU seconds"
    )
    parser.add_argument("--seeds", type=at_least(1), default=3, help="runs per method and rule")
    parser.add_argument(
        "--reference-iterations",
        type=at_least(1),
        default=400,
        help="pt iterations in each half of the reference",
    )
    parser.add_argument("--threads", type=at_least(1), default=1, help="render threads")
    args = parser.parse_args()
    try:
        check_threads(args.threads)
    except PgiError as e:
        parser.error(str(e))

    print(f"equal CPU time {args.seconds:g} s, {args.size}x{args.size}, {args.threads} thread(s)")
    header = (
        f"{'scene':<15} {'method':<8} {'rule':<10} {'mean/ref per seed':<28} "
        f"{'spread':>7} {'nMSE-ref':>11}"
    )
    print(header)
    print("-" * len(header))
    for name in args.scenes:
        base, overrides = SCENES[name]
        scene = scene_at(base, args.size, overrides)
        ref, own = pt_reference(name, args.size, args.reference_iterations, available_cores())
        print(
            f"{name:<15} {'(ref)':<8} {'pt':<10} mean {ref.mean():.4g}, own nMSE {own:.3e}",
            flush=True,
        )
        for method_id in args.methods:
            for rule in ("volpath",) if method_id == "mitsuba" else RULES:
                ruled = (
                    scene
                    if method_id == "mitsuba"
                    else scene_at(base, args.size, [*overrides, f"integrator.rr={rule}"])
                )
                ratios, errors = [], []
                for seed in range(1, args.seeds + 1):
                    method = get_method(method_id)(
                        ruled, seed=seed, threads=args.threads, params={}
                    )
                    run_for(method, args.seconds, clock=time.process_time)
                    image = method.image()
                    ratios.append(image.mean() / ref.mean())
                    errors.append(((image - ref) ** 2).mean() / ref.mean() ** 2 - own)
                shown = " ".join(f"{r:.3g}" for r in ratios)
                spread = max(ratios) / min(ratios) if min(ratios) > 0 else float("inf")
                print(
                    f"{name:<15} {method_id:<8} {rule:<10} {shown:<28} {spread:7.3g} "
                    f"{float(np.median(errors)):11.3e}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
