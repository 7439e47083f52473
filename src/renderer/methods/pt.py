"""pt: volumetric path tracing with next-event estimation and MIS.

Kajiya 1986, "The rendering equation"; Veach 1997, "Robust Monte Carlo
methods for light transport simulation" (ch. 9, MIS); Pharr, Jakob and
Humphreys, "Physically Based Rendering" 4th ed. (ch. 14, volumetric paths).
The estimator itself is the native kernel in ``cpp/pt.cpp``; this file is
the sequence of passes of one iteration.

An iteration is a wave of ``spp_per_wave`` camera paths per pixel, streamed through one
lane per thread: each lane keeps ``slots_per_lane`` paths in flight and refills a slot from
the wave as soon as its path ends, and runs its passes (trace, shade, shadow rays, next
rays) on its own thread, Embree calls included. The image does not depend on the number of
lanes or slots.
"""

from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor, wait

import numpy as np

from .. import _core
from ..engine import build_native_scene
from ..passes import resolve_shadow_rays
from ..scene.model import Scene
from ..tracer import EmbreeTracer, RayBatch
from .params import PT_PIXEL_BYTES, PT_WAVE_PATH_BYTES, MethodParams, budget_divisor

# Paths per wave: enough that the wave's tail (its last, longest paths, traced in ever smaller
# batches) is short against the wave.
_TARGET_WAVE_PATHS = 1 << 15
# Paths in flight per lane: enough rays per Embree call and per pass to amortise their calls
# from Python, few enough that a lane's path and shadow-ray state stays near the core.
_SLOTS_PER_LANE = 4096


def wave_spp(pixels: int, spp_budget: int | None) -> int:
    """Samples per pixel in one wave: enough paths to amortise the passes, and a
    divisor of the spp budget so that a budget is met exactly."""
    return budget_divisor(max(1, math.ceil(_TARGET_WAVE_PATHS / pixels)), spp_budget)


def trace_lane(
    lane, tracer: EmbreeTracer, paths: RayBatch, shadows: RayBatch, stop: threading.Event
) -> None:
    """One lane's share of a wave: trace / shade / shadows / next rays until the wave has no
    path left to start and every path of the lane has ended, or until `stop` is set. If the
    lane fails, it sets `stop`: the others end at their next step instead of finishing their
    share of the wave first."""
    try:
        active = lane.next_rays(*paths.buffers)
        while active and not stop.is_set():
            if lane.shade(*tracer.intersect(paths, active)):
                resolve_shadow_rays(lane, tracer, shadows)
            active = lane.next_rays(*paths.buffers)
    except BaseException:
        stop.set()
        raise


class PathTracing:
    id = "pt"
    parameters = frozenset({"spp_per_wave", "slots_per_lane"})

    def __init__(
        self, scene: Scene, *, seed: int, threads: int, params: dict, spp_budget: int | None = None
    ) -> None:
        pixels = scene.film.width * scene.film.height
        p = MethodParams(self.id, params, self.parameters)
        spp_per_wave = p.spp_per_iteration("spp_per_wave", wave_spp(pixels, spp_budget), spp_budget)
        p.camera_paths_fit_in_memory(
            "spp_per_wave", spp_per_wave, scene.film, PT_WAVE_PATH_BYTES, PT_PIXEL_BYTES
        )
        slots = p.integer("slots_per_lane", _SLOTS_PER_LANE, lo=1, hi=1 << 20)
        self.method_params = p.used
        self.native = build_native_scene(scene)
        lanes = max(1, threads)
        # Each lane traces its own batches on its own thread: the tracer never splits them.
        self.tracer = EmbreeTracer(self.native.triangles, 1)
        self.kernel = _core.PathTracer(
            self.native.core,
            scene.integrator.max_depth,
            scene.integrator.rr_depth,
            seed,
            spp_per_wave,
            lanes,
            slots,
        )
        self.lanes = [self.kernel.lane(i) for i in range(lanes)]
        self.paths = [RayBatch(slots) for _ in range(lanes)]
        self.shadows = [RayBatch(slots) for _ in range(lanes)]
        self._pool = ThreadPoolExecutor(lanes - 1) if lanes > 1 else None
        self.spp_per_wave = spp_per_wave
        self.iterations = 0

    def run_iteration(self, iteration: int) -> None:
        """One wave: spp_per_wave camera paths per pixel, streamed through the lanes (the
        first on this thread, the others on the pool's). Every lane has ended when this
        returns or raises: if one fails, or a signal arrives, the others stop at their next
        step, and the error raised is this thread's (a signal's exception, say) or else the
        first lane's that is not an interrupt."""
        self.kernel.begin_wave(iteration)
        stop = threading.Event()
        batches = zip(self.lanes, self.paths, self.shadows, strict=True)
        work = [(lane, self.tracer, paths, shadows, stop) for lane, paths, shadows in batches]
        others = [self._pool.submit(trace_lane, *w) for w in work[1:]] if self._pool else []
        error, cut_short = None, False
        try:
            trace_lane(*work[0])
        except BaseException as e:
            error = e
        while True:  # until every lane has ended, whatever arrives meanwhile
            if error is not None and others and not cut_short:
                stop.set()
                _core.request_interrupt()  # a pass through dense media ends now, too
                cut_short = True
            try:
                # In short waits: a signal that arrives just before this thread blocks is
                # handled within one of them, not once the other lanes end (seconds later).
                if not wait(others, timeout=0.05).not_done:
                    break
            except BaseException as e:  # a signal's handler raised while this thread waited
                error = error or e
        failures = [f.exception() for f in others if f.exception() is not None]
        if cut_short or failures:
            _core.clear_interrupt()  # every lane has ended: the flag stops nothing more
        if error is not None:
            raise error
        if failures:
            real = [e for e in failures if not isinstance(e, KeyboardInterrupt)]
            raise (real or failures)[0]
        self.kernel.end_wave()
        self.iterations += 1

    def image(self) -> np.ndarray:
        return self.kernel.image()

    def stats(self) -> dict:
        return {
            "iterations": self.iterations,
            "spp": int(self.kernel.samples_per_pixel),
            "spp_per_iteration": self.spp_per_wave,
            "rays": int(self.tracer.rays_traced),
            "nonfinite": int(self.kernel.nonfinite),
            "density_lookups": int(self.kernel.density_lookups),
            "media_segments": int(self.kernel.media_segments),
            "lookups_per_media_segment": (
                self.kernel.density_lookups / self.kernel.media_segments
                if self.kernel.media_segments
                else 0.0
            ),
            "dropped_degenerate_triangles": self.native.dropped_triangles,
        }
