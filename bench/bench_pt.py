"""pt against raw Embree throughput and against Mitsuba volpath at equal time.

    python bench/bench_pt.py [--scenes cbox cbox-fog cbox-grid] [--seconds 10] [--size 128]
                             [--reference-spp 8192] [--threads 2]

(a) Ray throughput: pt's rays per second over whole waves (after a warm-up wave), against
    raw embreex on the very rays pt traced (one wave's extension and shadow batches, recorded,
    then re-traced alone by the same tracer with the same thread count and the same query:
    closest hit, or occlusion for shadow rays in scenes without null boundaries). Also the time per
    ray of those Embree calls inside pt against the same calls alone: when the two agree, the
    gap between pt's rate and the raw rate is all in pt's own passes.
(b) Equal time: relMSE of pt and of Mitsuba volpath (fastest variant here) after the same
    render time (the iteration end nearest the budget; each run's own time is printed),
    against a high-spp Mitsuba reference cached under bench/.cache/, each less the
    reference's own relMSE (estimated from its two independent halves). A relMSE less than
    10x the reference's own is marked reference-limited and gets no ratio.
(c) Where pt's time goes: wall time per traced ray in Embree (`intersect`) and in each native
    pass (shade, shadow_rays, resolve_shadows, next_rays, begin_wave, end_wave).
Numbers are printed, never asserted: timings on a shared machine are noisy.
"""

from __future__ import annotations

import argparse
import time

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
from renderer.methods import get_method
from renderer.methods.pt import PathTracing
from renderer.progressive import run_for
from renderer.tracer import RayBatch


def raw_embree_rate(scene, threads: int, waves: int = 4) -> tuple[float, float, float, float]:
    """(pt rays/s, raw embreex rays/s, embreex rays/s inside pt, seconds per ray of pt's own
    passes): pt over `waves` warm waves (best wave), then the rays of one more wave, recorded
    (with the time of each Embree call) and re-traced alone by the same tracer (best of 3).
    The recorded wave's time, less its Embree calls and the recording's copies, is pt's own."""
    method = PathTracing(scene, seed=11, threads=threads, params={})
    method.run_iteration(0)  # warm-up: first-touch page faults, thread pools
    pt_rate = 0.0
    for i in range(1, waves + 1):
        rays, start = method.tracer.rays_traced, time.perf_counter()
        method.run_iteration(i)
        seconds = time.perf_counter() - start
        pt_rate = max(pt_rate, (method.tracer.rays_traced - rays) / seconds)

    tracer = method.tracer
    batches = []  # (query, origins, directions, tmax) of each Embree call of the wave
    inside = copying = 0.0  # seconds of the recorded wave's Embree calls and copies

    def recording(query):
        original = getattr(tracer, query)

        def call(batch, n):
            nonlocal inside, copying
            start = time.perf_counter()
            batches.append(
                (
                    query,
                    batch.origins[:n].copy(),
                    batch.directions[:n].copy(),
                    batch.tmax[:n].copy(),
                )
            )
            traced = time.perf_counter()
            result = original(batch, n)
            inside += time.perf_counter() - traced
            copying += traced - start
            return result

        return call

    # Extension rays ask for closest hits; shadow rays in scenes without null boundaries
    # only for occlusion: the replay asks Embree the same questions.
    tracer.intersect, tracer.occluded = recording("intersect"), recording("occluded")
    try:
        start = time.perf_counter()
        method.run_iteration(waves + 1)
        wave = time.perf_counter() - start
    finally:
        del tracer.intersect, tracer.occluded
    rays = sum(len(b[1]) for b in batches)

    replay = []
    for query, o, d, t in batches:
        b = RayBatch(len(o))
        b.origins[:], b.directions[:] = o, d
        replay.append((getattr(tracer, query), b, t))
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        for trace, b, t in replay:
            b.tmax[:] = t
            trace(b, len(t))
        best = min(best, time.perf_counter() - start)
    return pt_rate, rays / best, rays / inside, (wave - inside - copying) / rays


class _PassTimer:
    """Wraps a kernel or tracer object: wall seconds spent in each of its methods."""

    def __init__(self, target, seconds: dict[str, float]) -> None:
        self._target, self._seconds = target, seconds

    def __getattr__(self, name: str):
        attr = getattr(self._target, name)
        if not callable(attr):
            return attr

        def call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return attr(*args, **kwargs)
            finally:
                self._seconds[name] = self._seconds.get(name, 0.0) + time.perf_counter() - start

        return call


def pass_breakdown(scene, threads: int, waves: int = 10) -> tuple[dict[str, float], int]:
    """Wall seconds per pass (Embree's `intersect` and each native kernel pass) over warm
    waves, and the rays traced meanwhile."""
    method = PathTracing(scene, seed=13, threads=threads, params={})
    method.run_iteration(0)
    seconds: dict[str, float] = {}
    method.kernel = _PassTimer(method.kernel, seconds)
    tracer = method.tracer
    method.tracer = _PassTimer(tracer, seconds)
    rays = tracer.rays_traced
    for i in range(1, waves + 1):
        method.run_iteration(i)
    return seconds, tracer.rays_traced - rays


def timed(
    method_id: str, scene, seconds: float, threads: int, seed: int
) -> tuple[np.ndarray, dict]:
    method = get_method(method_id)(scene, seed=seed, threads=threads, params={})
    elapsed = run_for(method, seconds)  # the workflow's rule: the nearest iteration end
    return method.image(), dict(method.stats(), seconds=elapsed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_common_options(parser, ["cbox", "cbox-fog", "cbox-grid"])
    parser.set_defaults(size=128)
    parser.add_argument(
        "--seconds", type=seconds, default=10.0, help="equal-time budget of pt and Mitsuba"
    )
    parser.add_argument(
        "--reference-spp",
        type=at_least(2),
        default=8192,
        help="samples per pixel of the Mitsuba reference, over its two halves together",
    )
    args = parser.parse_args()
    check_options(parser, args)

    for name in args.scenes:
        scene = scene_at(name, args.size)
        pt_rate, raw_rate, inside_rate, own = raw_embree_rate(scene, args.threads)
        ref, floor = mitsuba_reference(name, args.size, args.reference_spp)
        errors, runs = {}, {}
        for method_id in ("pt", "mitsuba"):
            image, stats = timed(method_id, scene, args.seconds, args.threads, seed=1)
            # The reference's own error adds to each measured one (independent noise).
            errors[method_id] = relmse_less_reference(image, ref, floor)
            limited = "" if errors[method_id][1] else ", reference-limited"
            runs[method_id] = (
                f"{errors[method_id][0]:.3e} ({stats['spp']} spp in {stats['seconds']:.2f} s"
                f"{limited})"
            )
        print(
            f"{name:<10} pt {pt_rate / 1e6:5.2f} Mrays/s  raw embreex {raw_rate / 1e6:5.2f} Mrays/s"
            f"  ({pt_rate / raw_rate:4.0%})  |  relMSE at the iteration end nearest "
            f"{args.seconds:g} s, less the reference's own {floor:.2e}: pt {runs['pt']}, "
            f"mitsuba {runs['mitsuba']}, mitsuba/pt {ratio(errors['mitsuba'], errors['pt'])}",
            flush=True,
        )
        print(
            f"{name:<10} Embree per ray: {1e9 / inside_rate:.0f} ns inside pt, "
            f"{1e9 / raw_rate:.0f} ns alone; pt's own passes: {1e9 * own:.0f} ns per ray",
            flush=True,
        )
        seconds_by_pass, rays = pass_breakdown(scene, args.threads)
        per_ray = ", ".join(
            f"{k} {1e9 * v / rays:.0f}"
            for k, v in sorted(seconds_by_pass.items(), key=lambda kv: -kv[1])
        )
        print(f"{name:<10} wall ns per traced ray by pass: {per_ray}", flush=True)


if __name__ == "__main__":
    main()
