"""The bias of the light-side methods at their defaults, measured for tests/test_light_methods.py.

    python bench/bench_light_bias.py [--scenes ...] [--methods pm sppm ppb] [--iterations 128]
                                     [--seed 11] [--threads 2] [--reference 64 2048]

For each scene and method, at the test's 16 x 16 film and settings (the defaults, 16 camera
paths per pixel and iteration), one run of `--iterations` against pt (`--reference`: 64 images
of 2048 spp by default): the relative deviation of the image mean, of each quadrant and of each
4 x 4 pixel block from pt's, with its standard error (both runs' noise). The printed c at each
scale is the largest |deviation| + 2 standard errors over its cells, over r, the mean over the
run's iterations of the method's widest kernel radius: the test allows a bias of c r at that
scale, r its own run's (its schedule and iterations). The last line of each scene is the entry
of BIAS there.
Numbers are printed, never asserted.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from benchlib import at_least, check_options
from renderer.methods import get_method
from renderer.methods.pt import PathTracing

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from conftest import load_small  # noqa: E402
from parity import Estimate, iteration_images, ours  # noqa: E402
from test_light_methods import PARAMS, RES, SCENES, mean_radius  # noqa: E402


def deviations(est: Estimate, ref: Estimate, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Per cell of size x size pixels: relative deviation (gray) and its standard error."""
    a, b = est.blocks(size), ref.blocks(size)
    value = b.mean.mean(-1)
    return a.mean.mean(-1) / value - 1, np.sqrt(
        a.stderr.mean(-1) ** 2 + b.stderr.mean(-1) ** 2
    ) / value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=SCENES, help="shipped scenes to run")
    parser.add_argument(
        "--methods", nargs="+", default=["pm", "sppm", "ppb"], choices=["pm", "sppm", "ppb"],
        help="consistent methods to measure",
    )  # fmt: skip
    parser.add_argument("--iterations", type=at_least(2), default=128, help="of each run")
    parser.add_argument("--seed", type=int, default=11, help="of the methods' runs")
    parser.add_argument("--threads", type=at_least(1), default=2, help="worker threads")
    parser.add_argument(
        "--reference", nargs=2, type=at_least(2), default=[64, 2048], metavar=("IMAGES", "SPP"),
        help="pt's reference: images and samples per pixel of each",
    )  # fmt: skip
    args = parser.parse_args()
    check_options(parser, args)
    for name in args.scenes:
        scene = load_small(name, RES, RES)
        images, spp = args.reference
        ref = ours(PathTracing, scene, images, seed=99, spp_per_wave=spp)
        entry = {}
        for method_id in args.methods:
            params = PARAMS[method_id]
            method = get_method(method_id)(
                scene, seed=args.seed, threads=args.threads, params=params
            )
            est = Estimate(iteration_images(method, args.iterations))
            r = mean_radius(method, args.iterations)
            c = []
            for label, size in (("mean", RES), ("quadrants", RES // 2), ("blocks", 4)):
                dev, se = deviations(est, ref, size)
                # (cells pt leaves black have no relative deviation: nan, left out)
                worst = float(np.nanmax(np.abs(dev) + 2 * se))
                c.append(round(worst / r, 2 if worst / r < 10 else 1))
                print(f"{name} {method_id} {label}: deviations {np.round(dev, 4).ravel().tolist()}"
                      f" +- {np.round(se, 4).ravel().tolist()}")  # fmt: skip
            print(f"{name} {method_id}: r {r:.4g}, c {c}", flush=True)
            entry[method_id] = tuple(c)
        print(f'    "{name}": {entry},', flush=True)


if __name__ == "__main__":
    main()
