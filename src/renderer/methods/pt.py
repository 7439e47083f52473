"""pt: volumetric path tracing with next-event estimation and MIS.

Kajiya 1986, "The rendering equation"; Veach 1997, "Robust Monte Carlo
methods for light transport simulation" (ch. 9, MIS); Pharr, Jakob and
Humphreys, "Physically Based Rendering" 4th ed. (ch. 14, volumetric paths).
The estimator is the native kernel ``cpp/pt.h``, whose header states it and its
step order; this file is its parameters and the one pass sequence of an iteration.

An iteration is a wave of ``spp_per_wave`` camera paths per pixel, streamed through one
lane per thread: each lane keeps ``slots_per_lane`` paths in flight and refills a slot from
the wave as soon as its path ends, and runs its passes (trace, shade, shadow rays, next
rays) on its own thread, Embree calls included. The image does not depend on the number of
lanes or slots.
"""

from __future__ import annotations

import math

from .. import _core
from .base import NativeMethod
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


class PathTracing(NativeMethod):
    id = "pt"
    parameters = frozenset({"spp_per_wave", "slots_per_lane"})

    def setup(self, p: MethodParams) -> None:
        film = self.scene.film
        default_spp = wave_spp(film.width * film.height, self.spp_budget)
        self.spp_per_wave = p.spp_per_iteration("spp_per_wave", default_spp, self.spp_budget)
        p.camera_paths_fit_in_memory(
            "spp_per_wave", self.spp_per_wave, film, PT_WAVE_PATH_BYTES, PT_PIXEL_BYTES
        )
        slots = p.integer("slots_per_lane", _SLOTS_PER_LANE, lo=1, hi=1 << 20)
        integrator = self.scene.integrator
        self.camera_paths = self.wavefront(
            _core.PathTracing(
                self.native.core,
                integrator.max_depth,
                integrator.rr_depth,
                self.seed,
                self.spp_per_wave,
                self.threads,  # lanes
                slots,
            )
        )

    def run_passes(self, iteration: int) -> None:
        self.camera_paths.run(iteration)

    def method_stats(self) -> dict:
        kernel = self.camera_paths.kernel
        segments = kernel.media_segments
        return {
            "spp": int(kernel.samples_per_pixel),
            "spp_per_iteration": self.spp_per_wave,
            "media_segments": int(segments),
            "lookups_per_media_segment": kernel.density_lookups / segments if segments else 0.0,
            "dropped_degenerate_triangles": self.native.dropped_triangles,
        }
