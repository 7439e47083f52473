"""pt against raw Embree throughput and against Mitsuba volpath at equal time.

    python bench/bench_pt.py [--scenes cbox cbox-fog cbox-grid] [--seconds 10] [--size 128]
                             [--reference-spp 8192]

(a) Ray throughput: pt's rays per second over whole waves (after a warm-up wave), against
    raw embreex on the very rays pt traced (one wave's extension and shadow batches, recorded,
    then re-traced alone by the same tracer with the same thread count and the same query:
    closest hit, or occlusion for shadow rays in scenes without null boundaries). Also the time per
    ray of those Embree calls inside pt against the same calls alone: when the two agree, the
    gap between pt's rate and the raw rate is all in pt's own passes.
(b) Equal time: relMSE of pt and of Mitsuba volpath (fastest variant here) after the same
    render time, against a high-spp Mitsuba reference cached under bench/.cache/, each less
    the reference's own relMSE (estimated from its two independent halves).
(c) Where pt's time goes: wall time per traced ray in Embree (`intersect`) and in each native
    pass (shade, shadow_rays, resolve_shadows, next_rays, begin_wave, end_wave).
Numbers are printed, never asserted: timings on a shared machine are noisy.
"""

from __future__ import annotations

import argparse
import hashlib
import time
from pathlib import Path

import numpy as np

from compare.metrics import compare_images, reference_error
from renderer.fingerprint import fingerprints
from renderer.imageio import read_exr, write_exr
from renderer.methods import get_method
from renderer.methods.pt import PathTracing
from renderer.progressive import run_for
from renderer.reference import render_reference
from renderer.scene import load_scene
from renderer.scene.loader import scene_content_digest
from renderer.tracer import RayBatch

CACHE = Path(__file__).resolve().parent / ".cache"


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


def reference(scene, name: str, size: int, spp: int) -> tuple[np.ndarray, float]:
    """Mitsuba's reference as two independent halves of spp / 2, and the reference's own
    relMSE estimated from them (compare.metrics.reference_error). Cached under a key of
    what the reference depends on: the scene's content, the reference code and Mitsuba's
    version (the workflow's fingerprint), the size and the spp."""
    what = f"{scene_content_digest(name)}-{fingerprints()['reference']}-{size}-{spp}"
    key = hashlib.sha256(what.encode()).hexdigest()[:16]
    halves = []
    for half, seed in enumerate((12345, 54321)):
        path = CACHE / f"{name}-{key}-{half}.exr"
        if not path.exists():
            print(f"  rendering the reference of {name}, half {half + 1} of 2 ...", flush=True)
            image, _ = render_reference(scene, spp // 2, seed=seed)
            write_exr(path, image)
        halves.append(read_exr(path).astype(np.float64))
    return 0.5 * (halves[0] + halves[1]), reference_error(*halves)["ref_relmse"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cbox", "cbox-fog", "cbox-grid"])
    parser.add_argument("--seconds", type=float, default=10.0, help="equal-time budget")
    parser.add_argument("--size", type=int, default=128, help="film width and height")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--reference-spp", type=int, default=8192)
    args = parser.parse_args()

    rows = []
    for name in args.scenes:
        scene = load_scene(name, [f"film.width={args.size}", f"film.height={args.size}"])
        pt_rate, raw_rate, inside_rate, own = raw_embree_rate(scene, args.threads)
        ref, floor = reference(scene, name, args.size, args.reference_spp)
        errors = {}
        for method_id in ("pt", "mitsuba"):
            image, stats = timed(method_id, scene, args.seconds, args.threads, seed=1)
            # The reference's own error adds to each measured one (independent noise).
            errors[method_id] = (compare_images(image, ref)["relmse"] - floor, stats)
        rows.append((name, pt_rate, raw_rate, errors))
        print(
            f"{name:<10} pt {pt_rate / 1e6:5.2f} Mrays/s  raw embreex {raw_rate / 1e6:5.2f} Mrays/s"
            f"  ({pt_rate / raw_rate:4.0%})  |  relMSE at {args.seconds:g} s, less the "
            f"reference's own {floor:.2e}: "
            f"pt {errors['pt'][0]:.3e} ({errors['pt'][1]['spp']} spp), "
            f"mitsuba {errors['mitsuba'][0]:.3e} ({errors['mitsuba'][1]['spp']} spp), "
            f"mitsuba/pt {errors['mitsuba'][0] / errors['pt'][0]:.2f}x",
            flush=True,
        )
        print(
            f"{name:<10} Embree per ray: {1e9 / inside_rate:.0f} ns inside pt, "
            f"{1e9 / raw_rate:.0f} ns alone; pt's own passes: {1e9 * own:.0f} ns per ray",
            flush=True,
        )
        seconds, rays = pass_breakdown(scene, args.threads)
        per_ray = ", ".join(
            f"{k} {1e9 * v / rays:.0f}" for k, v in sorted(seconds.items(), key=lambda kv: -kv[1])
        )
        print(f"{name:<10} wall ns per traced ray by pass: {per_ray}", flush=True)


if __name__ == "__main__":
    main()
