"""lt: light tracing (particle tracing to the camera).

Veach 1997, "Robust Monte Carlo methods for light transport simulation", ch. 10;
Arvo and Kirk 1990, "Particle transport and image synthesis". Each iteration
traces ``light_paths`` paths from the lights (``cpp/subpaths.h``) and connects
every vertex, the emission points of area lights included, to the camera
(``cpp/lt.h``, which derives the camera importance). Paths that reach the
camera through a specular surface cannot be connected to a pinhole camera
and are missing: lt sees glass and mirrors as black.
"""

from __future__ import annotations

from .. import _core
from ..errors import PgiError
from .base import NativeMethod
from .params import MethodParams, budget_divisor

_DEFAULT_PATHS = 1 << 16
# Vertices one iteration may record: the memory bound. Each costs about 270 bytes with its
# connection ray and splat, so the default bounds an iteration at about 2.3 GB.
_DEFAULT_MAX_RECORDS = 1 << 23


def light_paths_for(pixels: int, spp_budget: int | None) -> int:
    """Light paths per iteration: about _DEFAULT_PATHS; with an spp budget (light paths per
    pixel) a whole number per pixel that divides it, so the run stops exactly there."""
    if not spp_budget:
        return _DEFAULT_PATHS
    return pixels * budget_divisor(max(1, _DEFAULT_PATHS // pixels), spp_budget)


class LightTracing(NativeMethod):
    id = "lt"
    parameters = frozenset({"light_paths", "max_records"})

    def setup(self, p: MethodParams) -> None:
        film, budget = self.scene.film, self.spp_budget
        self.pixels = film.width * film.height
        paths = p.integer("light_paths", light_paths_for(self.pixels, budget), lo=1)
        if budget and (budget * self.pixels) % paths:
            # lt's spp counts light paths per pixel: the budget must be whole iterations.
            raise PgiError(
                f"method lt: light_paths {paths} must divide --spp x pixels "
                f"({budget} x {self.pixels})"
            )
        # With an spp budget the default batch is a whole number of paths per pixel: at least
        # the film's size, which can be lowered instead.
        film_remedy = " or the film's size" if budget and "light_paths" not in p.params else ""
        p.light_paths_fit_in_memory("light_paths", paths, f"method.light_paths{film_remedy}")
        max_records = p.integer("max_records", _DEFAULT_MAX_RECORDS, lo=1)
        self.light_paths = self.light_paths_wavefront(
            paths, "light_paths", max_records, segments=False
        )
        self.connections = self.wavefront(
            _core.LightTracing(self.native.core, self.light_paths.kernel, self.seed, self.threads)
        )

    def run_passes(self, iteration: int) -> None:
        """Trace light paths; connect their vertices to the camera; splat in vertex order."""
        self.light_paths.run(iteration)
        self.connections.run(iteration)

    def method_stats(self) -> dict:
        light_paths = int(self.connections.kernel.light_paths)
        return {
            # Light paths per pixel: lt's equivalent of samples per pixel (a fraction when
            # fewer paths than pixels were traced; it read 0).
            "spp": light_paths // self.pixels
            if light_paths % self.pixels == 0
            else light_paths / self.pixels,
            "light_paths": light_paths,
            "light_paths_per_iteration": self.light_paths.paths,
        }
