"""pt against raw Embree throughput and against Mitsuba volpath at equal time.

    python bench/bench_pt.py [--scenes cbox cbox-fog cbox-grid] [--seconds 10] [--size 128]
                             [--reference-spp 8192] [--threads 2]

(a) Ray throughput: pt's rays per second over whole waves (after a warm-up wave), against
    raw embreex on the very rays pt traced (one wave's extension and shadow batches, recorded
    per lane, then traced again by Embree alone on as many threads, asking the same queries:
    closest hit, or occlusion for shadow rays in scenes without null boundaries; the faster
    of pt's own batches and one whole batch per query split across the threads). Also the
    time per ray of those Embree calls inside pt against the same calls alone: when the two
    agree, the gap between pt's rate and the raw rate is all in pt's own passes.
(b) Equal time: relMSE of pt and of Mitsuba volpath (fastest variant here) after the same
    render time (the iteration end nearest the budget; each run's own time is printed),
    against a high-spp Mitsuba reference cached under bench/.cache/, each less the
    reference's own relMSE (estimated from its two independent halves). A relMSE less than
    10x the reference's own is marked reference-limited and gets no ratio.
(c) From the equal-time runs: samples per second of pt and Mitsuba, pt's ray rate, and the
    ray rate Mitsuba would have at pt's rays per sample (Mitsuba does not count its rays).
(d) Where pt's time goes: time per traced ray in Embree (`intersect`, `occluded`) and in each
    native pass of the lanes (next_rays, shade, shadow_rays, resolve_shadows or
    resolve_occlusion), summed over the lanes and divided by their number.
Numbers are printed, never asserted: timings on a shared machine are noisy.
"""

from __future__ import annotations

import argparse
import threading
import time
from collections import defaultdict
from concurrent.futures import ThreadPoolExecutor

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
    (with the time of each Embree call, per lane) and traced again by Embree alone, best of
    3, in the faster of two ways: each lane's batches on its own thread, all at once (as pt
    traced them), or every ray of a query in one batch split evenly across the threads
    (embreex's best case: no small batches). The recorded wave's time on all lanes, less
    their Embree calls and the recording's copies, is pt's own; per ray, it is divided by
    the lanes, as wall time on that many cores."""
    method = PathTracing(scene, seed=11, threads=threads, params={})
    method.run_iteration(0)  # warm-up: first-touch page faults, thread pools
    pt_rate = 0.0
    for i in range(1, waves + 1):
        rays, start = method.tracer.rays_traced, time.perf_counter()
        method.run_iteration(i)
        seconds = time.perf_counter() - start
        pt_rate = max(pt_rate, (method.tracer.rays_traced - rays) / seconds)

    tracer = method.camera_paths.tracer  # the one pt's lanes call
    batches = defaultdict(list)  # lane thread -> (query, origins, directions, tmax) per call
    inside = copying = 0.0  # thread-seconds of the recorded wave's Embree calls and copies
    lock = threading.Lock()

    def recording(query):
        original = getattr(tracer, query)

        def call(batch, n):
            nonlocal inside, copying
            start = time.perf_counter()
            rays = batch.origins[:n].copy(), batch.directions[:n].copy(), batch.tmax[:n].copy()
            record = (query, *rays)
            traced = time.perf_counter()
            result = original(batch, n)
            done = time.perf_counter()
            with lock:
                batches[threading.get_ident()].append(record)
                inside += done - traced
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
    lanes = list(batches.values())
    rays = sum(len(b[1]) for lane in lanes for b in lane)

    def as_batches(records):
        """Per call: the query, and a batch for each of 3 replays (Embree writes its tmax)."""
        out = []
        for query, o, d, t in records:
            copies = []
            for _ in range(3):
                b = RayBatch(len(o))
                b.origins[:], b.directions[:], b.tmax[:] = o, d, t
                copies.append(b)
            out.append((getattr(tracer, query), copies))
        return out

    def trace_all(replay, round_):
        for trace, copies in replay:
            trace(copies[round_], len(copies[round_].tmax))

    def best_of_3(parts) -> float:
        best = np.inf
        with ThreadPoolExecutor(max(1, len(parts))) as pool:
            for round_ in range(3):
                start = time.perf_counter()
                list(pool.map(trace_all, parts, [round_] * len(parts)))
                best = min(best, time.perf_counter() - start)
        return best

    as_traced = [as_batches(lane) for lane in lanes]
    merged = []  # per query, every ray in one batch, then split across the threads
    for query in ("intersect", "occluded"):
        records = [b for lane in lanes for b in lane if b[0] == query]
        if records:
            o, d, t = (np.concatenate([r[i] for r in records]) for i in (1, 2, 3))
            chunks = np.array_split(np.arange(len(t)), threads)
            merged += [(query, o[c], d[c], t[c]) for c in chunks]
    whole = [as_batches(merged[i::threads]) for i in range(threads)]
    raw = min(best_of_3(as_traced), best_of_3(whole))
    own = (wave * len(lanes) - inside - copying) / len(lanes)
    return pt_rate, rays / raw, rays / (inside / len(lanes)), own / rays


class _PassTimer:
    """Wraps a kernel, lane or tracer object: seconds spent in each of its methods, summed
    over the threads that call them."""

    def __init__(self, target, seconds: dict[str, float], lock: threading.Lock) -> None:
        self._target, self._seconds, self._lock = target, seconds, lock

    def __getattr__(self, name: str):
        attr = getattr(self._target, name)
        if not callable(attr):
            return attr

        def call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return attr(*args, **kwargs)
            finally:
                with self._lock:
                    self._seconds[name] = self._seconds.get(name, 0.0) + time.perf_counter() - start

        return call


def pass_breakdown(scene, threads: int, waves: int = 10) -> tuple[dict[str, float], int]:
    """Seconds per pass (Embree's `intersect` and `occluded`, each native lane pass), summed
    over the lanes and divided by their number, over warm waves, and the rays traced
    meanwhile."""
    method = PathTracing(scene, seed=13, threads=threads, params={})
    method.run_iteration(0)
    seconds: dict[str, float] = {}
    lock = threading.Lock()
    wave = method.camera_paths
    wave.lanes = [_PassTimer(lane, seconds, lock) for lane in wave.lanes]
    tracer = wave.tracer
    wave.tracer = _PassTimer(tracer, seconds, lock)
    rays = tracer.rays_traced
    for i in range(1, waves + 1):
        method.run_iteration(i)
    return {k: v / len(wave.lanes) for k, v in seconds.items()}, tracer.rays_traced - rays


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
        errors, runs, sample_rates = {}, {}, {}
        for method_id in ("pt", "mitsuba"):
            image, stats = timed(method_id, scene, args.seconds, args.threads, seed=1)
            sample_rates[method_id] = stats["spp"] * image[..., 0].size / stats["seconds"]
            if method_id == "pt":
                pt_timed_rate = stats["rays"] / stats["seconds"]  # start-up included, as Mitsuba's
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
        # Mitsuba does not count its rays; its paths follow the same rules (max depth,
        # roulette, one shadow ray per vertex), so at pt's rays per sample its samples per
        # second say roughly what ray rate the same measure would give it. Both from the
        # timed runs (first iteration included), not from pt's best warm wave above.
        rays_per_sample = pt_timed_rate / sample_rates["pt"]
        mitsuba_rays = sample_rates["mitsuba"] * rays_per_sample
        print(
            f"{name:<10} timed runs: pt {sample_rates['pt'] / 1e6:.3f} M samples/s, "
            f"{pt_timed_rate / 1e6:.2f} Mrays/s ({pt_timed_rate / raw_rate:.0%} of raw embreex); "
            f"mitsuba {sample_rates['mitsuba'] / 1e6:.3f} M samples/s, at pt's "
            f"{rays_per_sample:.2f} rays per sample {mitsuba_rays / 1e6:.2f} Mrays/s "
            f"({mitsuba_rays / raw_rate:.0%} of raw embreex)",
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
