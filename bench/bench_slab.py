"""Every method on the slab of fog whose image has a closed form (tests/slab.py), at equal time.

    python bench/bench_slab.py [--methods pt pm sppm ppb] [--seconds 6] [--seeds 1 2 3]
                               [--width 1000] [--size 32] [--threads 2] [--set KEY=VALUE]

Each method runs at its defaults (or with `--set method.KEY=VALUE`) for the iterations that end
nearest `--seconds` of render time, once per seed; the table gives the ratio of its image mean
to the closed form (mean over the seeds, with the standard error from their spread, and each
seed's), its 8 x 8 pixel blocks' largest relative deviation (of the seeds' mean image), the
iterations reached and the radii the method used. The iterations a method reaches here are
those tests/test_slab.py renders for "6 s". Numbers are printed, never asserted.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchlib import at_least, seconds
from renderer.cli import split_sets
from renderer.errors import PgiError
from renderer.methods import get_method, method_ids
from renderer.progressive import check_threads, run_for

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from slab import closed_form, slab_scene  # noqa: E402  (the scene and its closed form)


def method_params(items: list[str], methods: list[str]) -> dict:
    """The --set items as method parameters (pgi render's parsing), each known to at least one
    of ``methods`` (every method gets the ones it knows)."""
    overrides, params = split_sets(items)
    if overrides:
        raise PgiError(f"--set {overrides[0]}: expected method.KEY=VALUE (the slab is fixed)")
    for key in params:
        if not any(key in get_method(m).parameters for m in methods):
            raise PgiError(f"--set method.{key}: no method of {', '.join(methods)} takes it")
    return params


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", nargs="+", default=["pt", "pm", "sppm", "ppb"])
    parser.add_argument("--seconds", type=seconds, default=6.0, help="render time per run")
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3], help="one run each")
    parser.add_argument("--width", type=float, default=1000.0, help="of the slab (>= 4)")
    parser.add_argument("--size", type=at_least(8), default=32, help="film width and height")
    parser.add_argument("--threads", type=at_least(1), default=2, help="worker threads")
    parser.add_argument("--set", action="append", default=[], help="method.KEY=VALUE for all")
    args = parser.parse_args()
    ours = [m for m in method_ids() if m != "mitsuba"]
    try:
        check_threads(args.threads)
        if bad := [m for m in args.methods if m not in ours]:
            raise PgiError(f"unknown method(s) {bad}; known: {', '.join(ours)}")
        params = method_params(args.set, args.methods)
        if not args.width >= 4:
            raise PgiError(f"--width must be at least 4 (the closed form's), got {args.width:g}")
    except (PgiError, argparse.ArgumentTypeError) as e:
        parser.error(str(e))

    with tempfile.TemporaryDirectory() as tmp:
        scene = slab_scene(Path(tmp), args.width, args.size)
        exact = closed_form(scene).mean(axis=-1)
    n = args.size // 8

    def blocks(image: np.ndarray) -> np.ndarray:
        return image[: 8 * n, : 8 * n].reshape(n, 8, n, 8).mean(axis=(1, 3))

    print(f"slab {args.width:g} wide, {args.size}x{args.size}, {args.seconds:g} s, "
          f"{args.threads} threads, closed-form mean {exact.mean():.6f}")  # fmt: skip
    for method_id in args.methods:
        cls = get_method(method_id)
        known = {k: v for k, v in params.items() if k in cls.parameters}
        ratios, iterations, images, radii = [], [], [], None
        for seed in args.seeds:
            method = cls(scene, seed=seed, threads=args.threads, params=known)
            run_for(method, args.seconds)
            iterations.append(method.iterations)
            image = method.image().mean(axis=-1)
            images.append(image)
            ratios.append(image.mean() / exact.mean())
            radii = method.stats().get("radii")
        r = np.array(ratios)
        se = r.std(ddof=1) / np.sqrt(len(r)) if len(r) > 1 else float("nan")
        worst = float(np.abs(blocks(np.mean(images, axis=0)) / blocks(exact) - 1).max())
        used = {k: round(v["world"], 3) for k, v in radii.items()} if radii else ""
        each = " ".join(f"{x:.4f}" for x in r)
        print(
            f"{method_id:5s} {r.mean():.4f} +- {se:.4f} (seeds: {each})  blocks within "
            f"{worst:.1%}  iterations {iterations}  radii {used}",
            flush=True,
        )


if __name__ == "__main__":
    main()
