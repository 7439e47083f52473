"""lt: light tracing (particle tracing to the camera).

Veach 1997, "Robust Monte Carlo methods for light transport simulation", ch. 10;
Arvo and Kirk 1990, "Particle transport and image synthesis". Each iteration
traces ``light_paths`` paths from the lights (``cpp/lightpath.h``) and connects
every vertex, the emission points of area lights included, to the camera
(``cpp/lt.h``, which derives the camera importance). Paths that reach the
camera through a specular surface cannot be connected to a pinhole camera
and are missing: lt sees glass and mirrors as black.
"""

from __future__ import annotations

import numpy as np

from .. import _core
from ..engine import build_native_scene
from ..errors import PgiError
from ..passes import resolve_shadow_rays
from ..scene.model import Scene
from ..tracer import EmbreeTracer, RayBatch
from .lightpath import LightPaths
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


class LightTracing:
    id = "lt"
    parameters = frozenset({"light_paths", "max_records"})

    def __init__(
        self, scene: Scene, *, seed: int, threads: int, params: dict, spp_budget: int | None = None
    ) -> None:
        p = MethodParams(self.id, params, self.parameters)
        pixels = scene.film.width * scene.film.height
        paths = p.integer("light_paths", light_paths_for(pixels, spp_budget), lo=1)
        if spp_budget and (spp_budget * pixels) % paths:
            # lt's spp counts light paths per pixel: the budget must be whole iterations.
            raise PgiError(
                f"method lt: light_paths {paths} must divide --spp x pixels "
                f"({spp_budget} x {pixels})"
            )
        # With an spp budget the default batch is a whole number of paths per pixel: at least
        # the film's size, which can be lowered instead.
        film = " or the film's size" if spp_budget and "light_paths" not in params else ""
        p.light_paths_fit_in_memory("light_paths", paths, f"method.light_paths{film}")
        max_records = p.integer("max_records", _DEFAULT_MAX_RECORDS, lo=1)
        self.method_params = p.used
        self.native = build_native_scene(scene)
        self.tracer = EmbreeTracer(self.native.triangles, threads)
        self.light_paths = LightPaths(
            self.native,
            self.tracer,
            scene,
            seed=seed,
            threads=threads,
            paths=paths,
            paths_param="light_paths",
            max_records=max_records,
            segments=False,
        )
        self.kernel = _core.LightTracer(self.native.core, seed, threads)
        self.connections = RayBatch(paths)
        self.pixels = pixels
        self.iterations = 0

    def _ensure_capacity(self, n: int) -> None:
        if n > len(self.connections.tmax):
            self.connections = RayBatch(max(n, 2 * len(self.connections.tmax)))

    def run_iteration(self, iteration: int) -> None:
        """Trace light paths; connect their vertices to the camera; splat in vertex order."""
        self.light_paths.trace(iteration)
        kernel = self.kernel
        queued = kernel.connect(self.light_paths.kernel)
        self._ensure_capacity(queued)
        if queued:
            resolve_shadow_rays(kernel, self.tracer, self.connections)
        kernel.end_iteration()
        self.iterations += 1

    def image(self) -> np.ndarray:
        return self.kernel.image()

    def stats(self) -> dict:
        light_paths = int(self.kernel.light_paths)
        return {
            "iterations": self.iterations,
            # Light paths per pixel: lt's equivalent of samples per pixel (a fraction when
            # fewer paths than pixels were traced; it read 0).
            "spp": light_paths // self.pixels
            if light_paths % self.pixels == 0
            else light_paths / self.pixels,
            "light_paths": light_paths,
            "light_paths_per_iteration": self.light_paths.paths,
            "rays": int(self.tracer.rays_traced),
            "nonfinite": int(self.kernel.nonfinite),
            "density_lookups": int(self.kernel.density_lookups)
            + int(self.light_paths.kernel.density_lookups),
        }
