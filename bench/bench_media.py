"""Benchmark of the transmittance estimators and of pt against Mitsuba's volpath on media.

Three tables (numbers are reported, never asserted; timings are noisy on a shared machine):

1. Shadow-ray transmittance on ``smoke`` and ``cbox-grid``: the shadow-ray segments pt
   traces there (recorded from its Embree calls, each weighted alike); per estimator the
   mean density lookups per ray, the mean per-ray variance, and the efficiency 1 / (variance
   x lookups), absolute and relative to delta tracking on the same majorant grid, and
   relative to it by time per sample too (lookups leave out DDA steps and set-up; timed, so
   noisy). The renderer's majorant grid (MAJORANT_CELL voxels per cell) is swept against
   coarser ones up to a single global majorant (Mitsuba's choice). Looser majorants add
   lookups to both; they leave delta tracking's variance at T(1 - T) but shrink ratio
   tracking's (each factor 1 - sigma / majorant nears 1), so ratio tracking's lead grows
   with them; with tight majorants its factors near 0 and it behaves like delta tracking
   that cannot stop early. rel_abs_error: mean |per-ray mean - truth| / mean truth, truth =
   residual ratio tracking with 4096 samples; for the unbiased estimators it is noise, for
   ray marching (step: half a voxel, biased, near-zero variance) it is mostly its bias.
2. Equal-time renders with pt per estimator: relMSE against a long reference (pt, residual
   ratio tracking, another seed; its own error is estimated from two halves), lookups per path.
3. Equal time on ``smoke``: pt with the best estimator against Mitsuba volpath (global
   majorant), relMSE against the same reference.

Run: python bench/bench_media.py [--time 5] [--ref-time 40] [--size 64] [--threads 2]
     [--cells 2 3 4 5 6] [--render-cells 2 4]   (majorant cell sizes to sweep)
"""

from __future__ import annotations

import argparse
import functools
import time

import numpy as np

import renderer.methods.pt as pt_module
from benchlib import add_common_options, at_least, check_options, scene_at, seconds
from compare.metrics import reference_error, relmse_map
from renderer import _core
from renderer.engine import MAJORANT_CELL, build_native_scene, march_step
from renderer.methods.mitsuba import MitsubaVolpath
from renderer.methods.pt import PathTracing
from renderer.progressive import run_for
from renderer.scene import load_scene

ESTIMATORS = dict(_core.Estimator.__members__)  # delta, ratio, residual, raymarch
Ray = tuple[np.ndarray, np.ndarray, float]  # origin, unit direction, length


def rel_mse(x: np.ndarray, ref: np.ndarray) -> float:
    return float(relmse_map(x, ref).mean())


# --------------------------------------------------------------------------- 1. shadow rays


def pt_shadow_rays(name: str, n_rays: int, seed: int, res: int = 32) -> list[Ray]:
    """(origin, direction, length) of the first ``n_rays`` shadow-ray segments whose
    transmittance pt evaluates on scene ``name`` (``res`` x ``res``, one path per pixel and
    wave, waves until there are enough), recorded from its Embree calls: a segment runs to its
    light sample, or to the null boundary where pt starts the next one; segments that an opaque
    surface blocks are left out (pt ends them without a transmittance). In these scenes the
    grid fills exactly the box of its null boundary, so a segment outside the medium meets no
    voxel: it costs no lookup and adds no variance, whichever estimator."""
    scene = scene_at(name, res)
    # One lane (whatever --threads): its batches, and so the segments recorded, come in one
    # order every run.
    method = PathTracing(scene, seed=seed, threads=1, params={"spp_per_wave": 1})
    if method.camera_paths.lanes[0].shadows_any_hit:
        raise SystemExit(f"{name}: no null boundaries, hence no media to measure")
    null = method.native.per_triangle(
        scene, [scene.materials[s.material].type == "null" for s in scene.shapes]
    )
    tracer, rays = method.camera_paths.tracer, []  # the tracer pt's lanes call
    intersect = tracer.intersect

    def recording(batch, n):
        hits = intersect(batch, n)
        if batch is method.camera_paths.shadows[0]:
            tfar, prim = np.asarray(hits[0], np.float64), np.asarray(hits[1])
            arrives = prim < 0
            length = np.where(arrives, batch.tmax[:n], tfar)
            keep = (arrives | null[np.maximum(prim, 0)]) & (length > 0)
            for k in np.flatnonzero(keep):
                rays.append((batch.origins[k].astype(np.float64),
                             batch.directions[k].astype(np.float64), float(length[k])))  # fmt: skip
        return hits

    tracer.intersect = recording
    wave = 0
    while len(rays) < n_rays and wave < 256:
        method.run_iteration(wave)
        wave += 1
    if len(rays) < n_rays:
        raise SystemExit(f"{name}: pt traced only {len(rays)} shadow segments in {wave} waves")
    return rays[:n_rays]


def shadow_table(name: str, cell: int, rays: list[Ray], samples: int = 256) -> list[dict]:
    """Rows per estimator for majorant cells of ``cell`` voxels (0: one global majorant)."""
    scene = load_scene(name, ["film.width=8", "film.height=8"])
    n_rays = len(rays)
    # The core numbers media in the scene's order.
    medium, grid = next((i, m) for i, m in enumerate(scene.media.values()) if m.type == "grid")
    native = build_native_scene(scene, majorant_cell=cell or max(grid.density.shape))
    core = native.core
    step = march_step(grid, 0.0)  # half the smallest voxel
    truth = []
    _core.configure_medium(core, medium, ESTIMATORS["residual"], 0.0)
    for i, (o, d, dist) in enumerate(rays):
        t, _ = _core.transmittance_samples(core, medium, tuple(o), tuple(d), dist, 10_000 + i, 4096)
        truth.append(t.mean())
    truth = np.array(truth)
    rows = []
    for est, code in ESTIMATORS.items():
        _core.configure_medium(core, medium, code, step)
        variances, lookups, means = [], 0, []
        t0 = time.perf_counter()
        for i, (o, d, dist) in enumerate(rays):
            t, k = _core.transmittance_samples(core, medium, tuple(o), tuple(d), dist, i, samples)
            variances.append(t.var(ddof=1))
            means.append(t.mean())
            lookups += k
        seconds = time.perf_counter() - t0
        var = float(np.mean(variances))
        per_ray = lookups / (n_rays * samples)
        bias = float(np.mean(np.abs(np.array(means) - truth)) / max(truth.mean(), 1e-12))
        rows.append({"scene": name, "majorant_cell": cell or "global", "estimator": est,
                     "lookups_per_ray": per_ray,
                     "variance": var, "us_per_ray": 1e6 * seconds / (n_rays * samples),
                     "efficiency": 1 / (var * per_ray) if var > 0 and per_ray > 0 else np.inf,
                     "rel_abs_error": bias})  # fmt: skip
    delta = next(r for r in rows if r["estimator"] == "delta")
    for r in rows:
        # Ray marching's variance hides its bias: an efficiency would mean nothing there.
        biased = r["estimator"] == "raymarch"
        r["efficiency_vs_delta"] = float("nan") if biased else r["efficiency"] / delta["efficiency"]
        # The same by time per sample: lookups leave out the DDA steps and each ray's set-up
        # (timed, hence noisy on a shared machine).
        by_time = (delta["variance"] * delta["us_per_ray"]) / (r["variance"] * r["us_per_ray"])
        r["time_efficiency_vs_delta"] = float("nan") if biased else by_time
    return rows


# --------------------------------------------------------------------------- 2, 3. renders


def timed(method, seconds: float) -> tuple[np.ndarray, dict, float]:
    """Iterations until the end nearest ``seconds`` of render time (loading excluded), as the
    workflow meets a budget."""
    elapsed = run_for(method, seconds)
    return method.image(), method.stats(), elapsed


def reference(scene, seconds: float, threads: int) -> tuple[np.ndarray, float]:
    """A long pt render (residual estimator) and the relMSE of one half against the other,
    an estimate of the reference's own error (x 1/2 for the average of both halves)."""
    halves = []
    for seed in (101, 102):
        m = PathTracing(scene, seed=seed, threads=threads, params={"spp_per_wave": 8})
        image, _, _ = timed(m, seconds / 2)
        halves.append(image)
    ref = 0.5 * (halves[0] + halves[1])
    return ref, reference_error(*halves)["ref_relmse"]


def render_table(name: str, res: int, seconds: float, ref_seconds: float, threads: int,
                 cells: list[int]):  # fmt: skip
    """Rows per estimator and majorant cell size (the reference uses the renderer's)."""
    base = [f"film.width={res}", f"film.height={res}"]
    ref_scene = load_scene(name, [*base, "integrator.estimator=residual"])
    ref, ref_err = reference(ref_scene, ref_seconds, threads)
    rows = []
    try:
        for cell in cells:
            # The cell size is no scene option: swap the builder pt uses (bench only).
            pt_module.build_native_scene = functools.partial(build_native_scene, majorant_cell=cell)
            for est in ESTIMATORS:
                scene = load_scene(name, [*base, f"integrator.estimator={est}"])
                m = PathTracing(scene, seed=1, threads=threads, params={"spp_per_wave": 2})
                image, st, used = timed(m, seconds)
                paths = st["spp"] * res * res
                method = f"pt/{est}" if len(cells) == 1 else f"pt/{est} cell {cell}"
                rows.append({"scene": name, "method": method, "seconds": used, "spp": st["spp"],
                             "lookups_per_path": st["density_lookups"] / max(paths, 1),
                             "relMSE": rel_mse(image, ref), "ref_relMSE": ref_err})  # fmt: skip
    finally:
        pt_module.build_native_scene = build_native_scene
    return rows, ref, ref_err


def mitsuba_row(name: str, res: int, seconds: float, threads: int, ref, ref_err) -> dict:
    scene = scene_at(name, res)
    m = MitsubaVolpath(scene, seed=1, threads=threads, params={"spp_per_iteration": 2})
    image, st, used = timed(m, seconds)
    return {"scene": name, "method": "mitsuba volpath", "seconds": used, "spp": st["spp"],
            "lookups_per_path": float("nan"), "relMSE": rel_mse(image, ref),
            "ref_relMSE": ref_err}  # fmt: skip


def print_table(rows: list[dict], columns: list[str]) -> None:
    print(" | ".join(f"{c:>18}" for c in columns))
    for r in rows:
        cells = []
        for c in columns:
            v = r[c]
            cells.append(f"{v:>18.4g}" if isinstance(v, float) else f"{v!s:>18}")
        print(" | ".join(cells))
    print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_common_options(ap, ["smoke", "cbox-grid"])
    ap.set_defaults(size=64)
    ap.add_argument("--time", type=seconds, default=5.0, help="seconds per timed render")
    ap.add_argument(
        "--ref-time", type=seconds, default=40.0, help="seconds of each pt reference (two halves)"
    )
    ap.add_argument(
        "--cells",
        nargs="+",
        type=at_least(0),
        default=None,
        help="majorant cells (voxels) for table 1, 0 = global "
        f"(default {MAJORANT_CELL}, x2, x4, global)",
    )
    ap.add_argument(
        "--shadow-rays",
        type=at_least(1),
        default=8000,
        help="pt's shadow-ray segments per scene for table 1 (default 8000: on smoke, ratio "
        "tracking's lead over delta tracking then varies by 0.2 %% between seeds)",
    )
    ap.add_argument(
        "--render-cells",
        nargs="+",
        type=at_least(1),
        default=[MAJORANT_CELL],
        help="majorant cells (voxels) for the equal-time renders of table 2",
    )
    args = ap.parse_args()
    check_options(ap, args)
    for name in args.scenes:
        if not any(m.type == "grid" for m in scene_at(name, 8).media.values()):
            ap.error(f"{name}: no grid medium, whose transmittance estimators this measures")

    print(f"1. Shadow-ray transmittance ({args.shadow_rays} of pt's shadow-ray segments per scene;")
    print(f"   majorant cells of {MAJORANT_CELL} voxels are the renderer's; coarser to compare)\n")
    cells = args.cells or [MAJORANT_CELL, 2 * MAJORANT_CELL, 4 * MAJORANT_CELL, 0]
    rows = []
    for s in args.scenes:
        rays = pt_shadow_rays(s, args.shadow_rays, seed=1)
        rows += [r for c in cells for r in shadow_table(s, c, rays)]
    columns = ["scene", "majorant_cell", "estimator", "lookups_per_ray", "variance", "us_per_ray",
               "efficiency", "efficiency_vs_delta", "time_efficiency_vs_delta",
               "rel_abs_error"]  # fmt: skip
    print_table(rows, columns)

    print(f"2./3. Equal-time renders, {args.size}x{args.size}, {args.time:g} s each\n")
    all_rows = []
    for s in args.scenes:
        rows, ref, ref_err = render_table(s, args.size, args.time, args.ref_time, args.threads,
                                          args.render_cells)  # fmt: skip
        if s == "smoke":
            rows.append(mitsuba_row(s, args.size, args.time, args.threads, ref, ref_err))
            excluded = ("pt/raymarch", "mitsuba volpath")  # biased, or not ours
            unbiased = [r for r in rows if not r["method"].startswith(excluded)]
            best = min(unbiased, key=lambda r: r["relMSE"])
            ratio = rows[-1]["relMSE"] / best["relMSE"]
            rows.append({"scene": s, "method": f"mitsuba/{best['method']}", "seconds": float("nan"),
                         "spp": "", "lookups_per_path": float("nan"), "relMSE": ratio,
                         "ref_relMSE": ref_err})  # fmt: skip
        all_rows += rows
    print_table(all_rows, ["scene", "method", "seconds", "spp", "lookups_per_path", "relMSE",
                           "ref_relMSE"])  # fmt: skip


if __name__ == "__main__":
    main()
