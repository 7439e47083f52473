"""direct: direct lighting at the first surface, in scenes without media.

The worked example of docs/methods.md ("Adding a method"), not one of the study's methods:
its kernel is ``cpp/direct_lighting.h`` (which states the estimator), its binding
``cpp/direct_lighting_bind.cpp``, its registry line in ``renderer/known_methods.py``. This file
holds its parameters and the pass sequence of one iteration.
"""

from __future__ import annotations

from .. import _core
from ..errors import PgiError
from .base import NativeMethod
from .params import MethodParams


class DirectLighting(NativeMethod):
    id = "direct"
    parameters = frozenset({"spp_per_iteration"})

    def setup(self, p: MethodParams) -> None:
        if self.scene.media:
            raise PgiError(f"{self.scene.path}: method direct renders scenes without media")
        self.spp_per_iteration = p.spp_per_iteration("spp_per_iteration", 4, self.spp_budget)
        p.camera_paths_fit_in_memory("spp_per_iteration", self.spp_per_iteration, self.scene.film)
        kernel = _core.DirectLighting(
            self.native.core,
            self.scene.integrator.max_depth,
            self.seed,
            self.spp_per_iteration,
            self.threads,
        )
        self.camera_paths = self.wavefront(kernel)

    def run_passes(self, iteration: int) -> None:
        self.camera_paths.run(iteration)

    def method_stats(self) -> dict:
        return {"spp": int(self.camera_paths.kernel.samples_per_pixel)}
