"""What every method of ours shares, so that a method's own file holds only its parameters and
its sequence of passes.

A method subclasses ``NativeMethod`` and writes two things:

- ``setup(p)``: read its parameters from ``p`` (``MethodParams``: each checked, with a one-line
  error naming the key), then make its native kernels and wrap each in a ``Wavefront``
  (``self.wavefront(kernel)``; light paths: ``self.light_paths_wavefront(...)``). Parameters
  are read before ``self.native`` is first used, so a wrong one is reported before the scene
  is built.
- ``run_passes(iteration)``: run its wavefronts in order, e.g. light paths, then a gather.

The base builds the native scene and the Embree tracer on first use, counts iterations, and
reports the stats every method shares (iterations, rays, non-finite samples dropped, density
lookups of every kernel); ``image()`` is the film of the method's last kernel, and
``method_stats()`` adds what is the method's own.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np

from .. import _core
from ..engine import NativeScene, build_native_scene
from ..errors import PgiError
from ..scene.model import Scene
from ..tracer import EmbreeTracer
from ..wavefront import Wavefront
from .lightpath import check_emission_media, warn_about_peaked_phase_functions
from .params import MethodParams


class NativeMethod:
    id: str
    parameters: frozenset[str]  # the KEYs `--set method.KEY=VALUE` may set
    renamed: dict[str, tuple[str, ...]] = {}  # old parameter names -> the names they now go by

    def __init__(
        self, scene: Scene, *, seed: int, threads: int, params: dict, spp_budget: int | None = None
    ) -> None:
        self.scene, self.seed, self.threads = scene, seed, max(1, threads)
        self.spp_budget = spp_budget
        self.iterations = 0
        self.wavefronts: list[Wavefront] = []
        p = MethodParams(self.id, params, self.parameters, self.renamed)
        self.setup(p)
        self.method_params = p.used  # each parameter that applies, with the value used

    def setup(self, p: MethodParams) -> None:
        raise NotImplementedError

    def run_passes(self, iteration: int) -> None:
        raise NotImplementedError

    def method_stats(self) -> dict:
        return {}

    @cached_property
    def native(self) -> NativeScene:
        return build_native_scene(self.scene)

    @cached_property
    def tracer(self) -> EmbreeTracer:
        return EmbreeTracer(self.native.triangles, self.threads)

    def wavefront(self, kernel: Any) -> Wavefront:
        """``kernel`` run by the driver; the last one made holds the method's image."""
        wave = Wavefront(kernel, self.tracer)
        self.wavefronts.append(wave)
        return wave

    def light_paths_wavefront(
        self,
        paths: int,
        paths_param: str,
        max_records: int,
        vertices: bool = True,
        segments: bool = True,
        complete: bool = False,
        warn_of_peaked_phase: bool = True,
    ) -> Wavefront:
        """``paths`` light paths per iteration (cpp/subpaths.h), recording vertices and medium
        segments as asked, or complete subpaths with their densities. Records beyond
        ``max_records`` stop the render with an error that names ``paths_param`` (the parameter
        that sets ``paths``) and max_records. ``warn_of_peaked_phase``: for methods that
        evaluate the phase function where light and camera paths meet with no other strategy
        to weigh against (not bdpt, whose MIS gives such joins little weight)."""
        if warn_of_peaked_phase:
            warn_about_peaked_phase_functions(self.scene)
        kernel = _core.LightPaths(
            self.native.core,
            self.scene.integrator.max_depth,
            self.scene.integrator.rr_depth,
            self.seed,
            paths,
            self.threads,
            max_records,
        )
        kernel.set_recording(vertices, segments, complete)
        check_emission_media(self.native)  # the kernel reads each light's medium from its scene
        return RecordsWavefront(kernel, self.tracer, paths_param, self.wavefronts)

    def run_iteration(self, iteration: int) -> None:
        self.run_passes(iteration)
        self.iterations += 1

    @property
    def film(self) -> Any:
        """The kernel whose film holds the image: the last one made."""
        return self.wavefronts[-1].kernel

    def image(self) -> np.ndarray:
        return self.film.image()

    def stats(self) -> dict:
        return {
            "iterations": self.iterations,
            **self.method_stats(),
            "rays": int(self.tracer.rays_traced),
            "nonfinite": int(self.film.nonfinite),
            "density_lookups": sum(int(w.kernel.density_lookups) for w in self.wavefronts),
        }


class RecordsWavefront(Wavefront):
    """Subpaths (light or camera paths), whose records may exceed their bound: the error says
    what to change. Registers itself among the method's wavefronts."""

    def __init__(self, kernel: Any, tracer: EmbreeTracer, paths_param: str, registry: list) -> None:
        super().__init__(kernel, tracer)
        self.paths = kernel.paths_per_iteration
        self.paths_param = paths_param  # the method parameter that sets `paths`, for errors
        registry.append(self)

    def run(self, iteration: int) -> None:
        try:
            super().run(iteration)
        except ValueError as e:
            raise PgiError(
                f"{e} (lower method.{self.paths_param} or raise method.max_records)"
            ) from e
