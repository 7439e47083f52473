"""pt: volumetric path tracing with next-event estimation and MIS.

Kajiya 1986, "The rendering equation"; Veach 1997, "Robust Monte Carlo
methods for light transport simulation" (ch. 9, MIS); Pharr, Jakob and
Humphreys, "Physically Based Rendering" 4th ed. (ch. 14, volumetric paths).
The estimator itself is the native kernel in ``cpp/pt.cpp``; this file is
the sequence of passes of one iteration.
"""

from __future__ import annotations

import math

import numpy as np

from .. import _core
from ..engine import build_native_scene
from ..passes import trace_camera_wave
from ..scene.model import Scene
from ..tracer import EmbreeTracer, RayBatch
from .params import MethodParams, budget_divisor

# Paths per wave: enough to amortise the Python passes over the native kernels, few enough
# that a wave's path and shadow-ray state (~10 MB) stays in cache between passes: at 128x128
# on 2 cores, 2 spp per wave traced 8-12 % more rays per second than 4 (and than 1).
_TARGET_WAVE_PATHS = 1 << 15


def wave_spp(pixels: int, spp_budget: int | None) -> int:
    """Samples per pixel in one wave: enough paths to amortise the passes, and a
    divisor of the spp budget so that a budget is met exactly."""
    return budget_divisor(max(1, math.ceil(_TARGET_WAVE_PATHS / pixels)), spp_budget)


class PathTracing:
    id = "pt"
    description = "volumetric path tracing, next-event estimation and MIS"
    parameters = frozenset({"spp_per_wave"})

    def __init__(
        self, scene: Scene, *, seed: int, threads: int, params: dict, spp_budget: int | None = None
    ) -> None:
        pixels = scene.film.width * scene.film.height
        p = MethodParams(self.id, params, self.parameters)
        spp_per_wave = p.spp_per_iteration("spp_per_wave", wave_spp(pixels, spp_budget), spp_budget)
        p.camera_paths_fit_in_memory("spp_per_wave", spp_per_wave, scene.film)
        self.method_params = p.used
        self.native = build_native_scene(scene)
        self.tracer = EmbreeTracer(self.native.triangles, threads)
        self.kernel = _core.PathTracer(
            self.native.core,
            scene.integrator.max_depth,
            scene.integrator.rr_depth,
            seed,
            spp_per_wave,
            threads,
        )
        self.paths = RayBatch(self.kernel.capacity)
        self.shadows = RayBatch(self.kernel.capacity)
        self.spp_per_wave = spp_per_wave
        self.iterations = 0

    def run_iteration(self, iteration: int) -> None:
        """One wave: spp_per_wave camera paths per pixel, traced bounce by bounce."""
        trace_camera_wave(self.kernel, self.tracer, self.paths, self.shadows, iteration)
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
