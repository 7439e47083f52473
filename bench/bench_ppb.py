"""ppb against pt and Mitsuba volpath at equal time, with fitted convergence slopes.

    python bench/bench_ppb.py [--scenes volcaustic cbox-fog] [--budgets 2 4 8 16]
                              [--size 48] [--threads 2] [--seeds 1]

Each method runs once per seed up to the largest budget; its image is taken at the iteration
end nearest each budget (one run gives the whole error-vs-time curve, as the workflow's
snapshots do). relMSE is measured against a Mitsuba reference rendered as two independent
halves (cached under bench/.cache/); the halves' own relMSE bounds the reference error and
is printed next to the results. The log-log slope of relMSE against time is fitted over the
budgets (compare.convergence.fit_slope).

Targets (reported, never asserted; timings on a shared machine are noisy):
  - volcaustic, largest budget: ppb's relMSE at least 10x below both pt and Mitsuba;
  - cbox-fog: ppb's fitted MSE slope steeper than -0.5.
The full study (budgets 2..64 s, 256 x 256, several seeds) needs references of about
10^5 spp on volcaustic (its caustic is found by Mitsuba's volpath only by chance: the
reference error must stay well below ppb's) and about 1.5 h of renders per scene and seed
on two cores: run it with the workflow (configs/) rather than this script.
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
METHODS = ("pt", "ppb", "mitsuba")
# Reference samples per pixel per half: the caustic scene needs many more.
REFERENCE_SPP = {"volcaustic": 16384, "cbox-fog": 2048}


def curve(
    method_id: str, scene, budgets: list[float], threads: int, seed: int, params: dict
) -> list[dict]:
    """Images of one run at each budget of render time."""
    method = get_method(method_id)(scene, seed=seed, threads=threads, params=params)
    # at the iteration end nearest each budget, as the workflow takes snapshots
    return [
        dict(budget=budget, seconds=elapsed, image=method.image())
        for budget, elapsed in iterate_to(method, budgets)
    ]


def reference(scene, name: str, size: int, spp: int) -> tuple[np.ndarray, float]:
    """The merged reference and the relMSE between its two halves."""
    halves = []
    for half in (0, 1):
        path = CACHE / f"ppb-{name}-{size}-{spp}-half{half}.exr"
        if not path.exists():
            print(f"  reference {name}: half {half}, {spp} spp at {size}x{size} ...", flush=True)
            image, _ = render_reference(scene, spp, seed=7919 * (half + 1))
            write_exr(path, image)
        halves.append(read_exr(path).astype(np.float64))
    merged = 0.5 * (halves[0] + halves[1])
    # relMSE of one half against the other is about 4x that of the merged mean.
    return merged, compare_images(halves[0], halves[1])["relmse"] / 4


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["volcaustic", "cbox-fog"])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--budgets", nargs="+", type=float, default=[2, 4, 8, 16])
    parser.add_argument("--size", type=int, default=48, help="film width and height")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--reference-spp", type=int, default=0, help="per half; 0: per scene")
    parser.add_argument(
        "--ppb", action="append", default=[], metavar="KEY=VALUE", help="a ppb parameter"
    )
    args = parser.parse_args()
    CACHE.mkdir(exist_ok=True)
    ppb_params = {k: float(v) for k, v in (kv.split("=", 1) for kv in args.ppb)}
    for key in ("light_paths", "spp_per_iteration", "max_beams", "gather_bounces"):
        if key in ppb_params:
            ppb_params[key] = int(ppb_params[key])

    for name in args.scenes:
        scene = load_scene(name, [f"film.width={args.size}", f"film.height={args.size}"])
        spp = args.reference_spp or REFERENCE_SPP.get(name, 4096)
        ref, ref_err = reference(scene, name, args.size, spp)
        print(
            f"\n{name} ({args.size}x{args.size}; reference relMSE ~ {ref_err:.2e}); "
            "relMSE at each budget, in brackets minus the reference's; slope of the latter",
            flush=True,
        )
        final = {}
        for method_id in args.methods:
            errors = np.zeros((args.seeds, len(args.budgets)))
            for seed in range(args.seeds):
                params = ppb_params if method_id == "ppb" else {}
                snaps = curve(method_id, scene, args.budgets, args.threads, seed, params)
                for k, snap in enumerate(snaps):
                    errors[seed, k] = compare_images(snap["image"], ref)["relmse"]
            # relMSE against a noisy reference ~ the method's own + the reference's: the
            # corrected column subtracts the latter (estimated from the halves).
            mean = errors.mean(axis=0) - ref_err
            fit = fit_slope(args.budgets, mean)
            final[method_id] = mean[-1]
            cells = "  ".join(
                f"{b:g}s {e + ref_err:.2e} ({e:.2e})"
                for b, e in zip(args.budgets, mean, strict=True)
            )
            print(
                f"  {method_id:<8} relMSE {cells}  slope {fit.slope:+.2f} (r2 {fit.r2:.2f})",
                flush=True,
            )
        largest = args.budgets[-1]
        if not {"pt", "ppb", "mitsuba"} <= set(final):
            continue
        print(
            f"  at {largest:g} s: pt/ppb {final['pt'] / final['ppb']:.1f}x, "
            f"mitsuba/ppb {final['mitsuba'] / final['ppb']:.1f}x lower error for ppb",
            flush=True,
        )


if __name__ == "__main__":
    main()
