"""bdpt: bidirectional path tracing in participating media, every connection strategy, MIS.

Lafortune and Willems 1993/1996; Veach 1997, "Robust Monte Carlo methods for light transport
simulation", ch. 10; the media formulation of Mitsuba 0.6's and SmallUPBP's volumetric
bidirectional path tracers. The kernel ``cpp/bdpt.h`` states the strategies, their
contributions and the MIS weights; the subpaths are ``cpp/subpaths.h``'s, with the densities
of ``cpp/path_records.h``.

One iteration: ``spp_per_iteration`` light subpaths per pixel, as many camera subpaths (one
light subpath per camera sample), then every strategy joining them, each with a shadow ray
where it needs one. With ``strategy_images`` the render also writes, beside its image, the
weighted and the unweighted contributions of each strategy (s light vertices, t camera
vertices) as images named ``<output>.s<s>t<t>.exr`` and ``<output>.s<s>t<t>-unweighted.exr``.
"""

from __future__ import annotations

import numpy as np

from .. import _core
from .base import NativeMethod, RecordsWavefront
from .params import LIGHT_PATH_BYTES, MethodParams

# Records of one iteration's subpaths (each side): the memory bound, at ~120 bytes a record.
DEFAULT_MAX_RECORDS = 1 << 23
# Connections (s >= 2 and t >= 2) stop at this many vertices on either side: their count grows
# as the product of the subpaths' lengths (cpp/bdpt.h). 4 was the best all-round value of 2, 4,
# 8 and 16 at equal time (docs/methods.md, bdpt): deeper connections cost cbox and juice more
# shadow rays than they return.
DEFAULT_MAX_CONNECT = 4
# A camera sample holds a camera subpath, a light subpath and their connections (about 200
# bytes each with its shadow ray): counted as two light paths.
SAMPLE_BYTES = 2 * LIGHT_PATH_BYTES


class BidirectionalPathTracing(NativeMethod):
    id = "bdpt"
    parameters = frozenset({"spp_per_iteration", "max_connect", "strategy_images", "max_records"})

    def setup(self, p: MethodParams) -> None:
        film = self.scene.film
        self.spp_per_iteration = p.spp_per_iteration("spp_per_iteration", 1, self.spp_budget)
        p.camera_paths_fit_in_memory(
            "spp_per_iteration", self.spp_per_iteration, film, SAMPLE_BYTES
        )
        max_connect = p.integer("max_connect", DEFAULT_MAX_CONNECT, lo=2, hi=10_000)
        self.strategy_images = p.flag("strategy_images", False)
        max_records = p.integer("max_records", DEFAULT_MAX_RECORDS, lo=1)
        samples = film.width * film.height * self.spp_per_iteration
        integrator, core = self.scene.integrator, self.native.core
        self.light_paths = self.light_paths_wavefront(
            samples,
            "spp_per_iteration",
            max_records,
            segments=False,
            complete=True,
            warn_of_peaked_phase=False,
        )
        cameras = _core.CameraPaths(
            core,
            integrator.max_depth,
            integrator.rr_depth,
            self.seed,
            self.spp_per_iteration,
            self.threads,
            max_records,
        )
        self.camera_paths = RecordsWavefront(
            cameras, self.tracer, "spp_per_iteration", self.wavefronts
        )
        kernel = _core.BidirectionalPathTracing(
            core,
            self.light_paths.kernel,
            cameras,
            integrator.max_depth,
            self.seed,
            self.spp_per_iteration,
            self.threads,
            max_connect,
        )
        kernel.set_strategy_images(self.strategy_images)
        self.connections = self.wavefront(kernel)

    def run_passes(self, iteration: int) -> None:
        self.light_paths.run(iteration)
        self.camera_paths.run(iteration)
        self.connections.run(iteration)

    def method_stats(self) -> dict:
        kernel = self.connections.kernel
        return {
            "spp": int(kernel.samples_per_pixel),
            "spp_per_iteration": self.spp_per_iteration,
            "connections": int(kernel.connections),
        }

    def extra_images(self) -> dict[str, np.ndarray]:
        """With strategy_images: each strategy's weighted and unweighted image, by name."""
        images: dict[str, np.ndarray] = {}
        if self.strategy_images:
            for (s, t), (weighted, unweighted) in sorted(
                self.connections.kernel.strategy_images().items()
            ):
                images[f"s{s}t{t}"] = weighted
                images[f"s{s}t{t}-unweighted"] = unweighted
        return images
