"""mitsuba: Mitsuba 3's ``volpath`` run as a progressive method at the same time budget.

What a user would pick instead of our methods: Mitsuba 3 (Jakob et al., 2022,
https://mitsuba-renderer.org), volumetric path tracing with next-event estimation and MIS,
delta tracking with a single global majorant for heterogeneous media. Each iteration renders
``spp_per_iteration`` samples per pixel with a seed derived from (seed, iteration); the image
is the float64 average of all iterations.
"""

from __future__ import annotations

import numpy as np

from renderer.methods.params import MITSUBA_SAMPLE_BYTES, MethodParams, budget_divisor
from renderer.mitsuba_env import import_mitsuba, set_threads
from renderer.reference import derive_seed
from renderer.scene.mitsuba_export import load_mitsuba_scene
from renderer.scene.model import Scene

# Samples per iteration: 1 spp at 256x256 takes ~0.1-1 s on 2 threads depending on the scene.
_TARGET_SAMPLES = 1 << 16


def default_spp(scene: Scene, spp_budget: int | None) -> int:
    """~65k samples per iteration, and a divisor of the spp budget so the budget is met exactly."""
    return budget_divisor(
        max(1, _TARGET_SAMPLES // (scene.film.width * scene.film.height)), spp_budget
    )


class MitsubaVolpath:
    id = "mitsuba"
    parameters = frozenset({"spp_per_iteration"})

    def __init__(
        self, scene: Scene, *, seed: int, threads: int, params: dict, spp_budget: int | None = None
    ) -> None:
        spp = self.check_parameters(scene, params, spp_budget)
        self.method_params = {"spp_per_iteration": spp}
        self.mi = import_mitsuba()
        set_threads(threads)
        # volpath, what a user would run, even where the references render chromatic media
        # channel by channel (docs/methods.md): the sidecar says which
        self.integrator = "volpath"
        self.scene = load_mitsuba_scene(scene, self.integrator)
        self.seed, self.spp_per_iteration = seed, spp
        # Warm-up (its image is discarded): compiles the LLVM kernels as part of loading. Dr.Jit
        # runs kernels asynchronously: reading the image waits for it, else the first timed
        # iteration would wait (1.4 s on cbox-grid at 128x128).
        self._render(derive_seed("mitsuba-warmup", seed, 0))
        self.sum = np.zeros((scene.film.height, scene.film.width, 3))
        self.iterations = 0
        self.nonfinite = 0

    @classmethod
    def check_parameters(cls, scene: Scene, params: dict, spp_budget: int | None = None) -> int:
        """The samples per iteration the parameters ask for, checked, without loading Mitsuba
        (whose warm-up render can take a minute): what a plan checks before any job."""
        p = MethodParams(cls.id, params, cls.parameters)
        spp = p.spp_per_iteration("spp_per_iteration", default_spp(scene, spp_budget), spp_budget)
        # Mitsuba's LLVM variant traces all of an iteration's samples as one wavefront.
        p.camera_paths_fit_in_memory("spp_per_iteration", spp, scene.film, MITSUBA_SAMPLE_BYTES)
        return spp

    def _render(self, seed: int) -> np.ndarray:
        """One render of spp_per_iteration samples, finished (read back into numpy)."""
        return np.array(self.mi.render(self.scene, spp=self.spp_per_iteration, seed=seed))

    def run_iteration(self, iteration: int) -> None:
        img = self._render(derive_seed("mitsuba", self.seed, iteration))
        bad = ~np.isfinite(img)
        if bad.any():  # counted and reported, never let into the image
            self.nonfinite += int(bad.sum())
            img[bad] = 0.0
        self.sum += img
        self.iterations += 1

    def image(self) -> np.ndarray:
        return self.sum / max(self.iterations, 1)

    def stats(self) -> dict:
        return {
            "iterations": self.iterations,
            "spp": self.iterations * self.spp_per_iteration,
            "spp_per_iteration": self.spp_per_iteration,
            "nonfinite": self.nonfinite,
            "variant": self.mi.variant(),
            "integrator": self.integrator,
        }
