"""pm: photon mapping with volumetric photons and the beam radiance estimate.

Jensen 1996, "Global illumination using photon maps"; Jensen and Christensen 1998,
"Efficient simulation of light transport in scenes with participating media using
photon maps"; Jarosz, Zwicker and Jensen 2008, "The beam radiance estimate for
volumetric photon mapping". The kernels are ``cpp/pm.h`` (gathering),
``cpp/photon_map.h`` (kd-tree) and ``cpp/lightpath.h`` (photon tracing).

Each iteration traces new photons, builds their maps and gathers along one
camera path per pixel sample; the image is the mean of the iterations. The
radius is fixed, so pm converges to a blurred (biased) image; sppm shrinks it.
"""

from __future__ import annotations

import numpy as np

from .. import _core
from ..engine import build_native_scene
from ..errors import PgiError
from ..scene.model import Scene
from ..tracer import EmbreeTracer, RayBatch
from .lightpath import LightPaths
from .params import MAX_RADIUS_FRACTION, MIN_RADIUS_FRACTION, MethodParams

DEFAULT_PHOTONS = 1 << 16
# Vertices one iteration may record: the memory bound. Each costs about 200 bytes (the record,
# its copy in a photon map and the kd-tree), so the default bounds an iteration at about 1.7 GB.
DEFAULT_MAX_RECORDS = 1 << 23
# Default radii relative to the scene's bounding-sphere radius.
DEFAULT_RADIUS_SCALE = 0.02


class PhotonMapping:
    id = "pm"
    parameters = frozenset(
        {"photons", "spp_per_iteration", "radius", "volume_radius", "radius_scale", "max_records"}
    )

    def __init__(
        self, scene: Scene, *, seed: int, threads: int, params: dict, spp_budget: int | None = None
    ) -> None:
        p = MethodParams(self.id, params, self.parameters)
        photons = p.integer("photons", DEFAULT_PHOTONS, lo=1)
        spp = p.spp_per_iteration("spp_per_iteration", 1, spp_budget)
        p.light_paths_fit_in_memory("photons", photons)
        p.camera_paths_fit_in_memory("spp_per_iteration", spp, scene.film)
        max_records = p.integer("max_records", DEFAULT_MAX_RECORDS, lo=1)
        scale = p.number(
            "radius_scale", DEFAULT_RADIUS_SCALE, lo=MIN_RADIUS_FRACTION, hi=MAX_RADIUS_FRACTION
        )
        self.native = build_native_scene(scene)
        self.tracer = EmbreeTracer(self.native.triangles, threads)
        size = self.native.core.scene_radius
        smallest, largest = MIN_RADIUS_FRACTION * size, MAX_RADIUS_FRACTION * size
        self.radius = p.number("radius", scale * size, lo=smallest, hi=largest)
        self.volume_radius = p.number("volume_radius", scale * size, lo=smallest, hi=largest)
        both = "radius" in params and "volume_radius" in params
        p.refuse_unused("radius_scale", not both, "when radius and volume_radius are both given")
        self.method_params = p.used
        self.light_paths = LightPaths(
            self.native,
            self.tracer,
            scene,
            seed=seed,
            threads=threads,
            paths=photons,
            paths_param="photons",
            max_records=max_records,
            segments=False,
        )
        self.kernel = _core.PhotonGatherer(
            self.native.core, scene.integrator.max_depth, seed, spp, threads
        )
        self.camera = RayBatch(self.kernel.capacity)
        self.photons = photons
        self.spp_per_iteration = spp
        self.iterations = 0

    def radii(self, iteration: int) -> tuple[float, float]:
        """(surface, volume) radius of an iteration: fixed for pm."""
        return self.radius, self.volume_radius

    def run_iteration(self, iteration: int) -> None:
        """Photon pass, photon maps, then camera paths gathering with this iteration's radii."""
        self.light_paths.trace(iteration)
        kernel, rays = self.kernel, self.camera
        try:
            kernel.build_maps(self.light_paths.kernel)
        except MemoryError as e:  # pragma: no cover - depends on the machine
            raise PgiError(f"method {self.id}: photon maps do not fit in memory: {e}") from e
        surface_radius, volume_radius = self.radii(iteration)
        active = kernel.begin_camera(iteration, *rays.buffers)
        while active:
            kernel.shade(*self.tracer.intersect(rays, active), surface_radius, volume_radius)
            active = kernel.next_rays(*rays.buffers)
        kernel.end_iteration()
        self.iterations += 1
        self._last_radii = (surface_radius, volume_radius)

    def image(self) -> np.ndarray:
        return self.kernel.image()

    def stats(self) -> dict:
        surface, volume = self.radii(max(0, self.iterations - 1))
        return {
            "iterations": self.iterations,
            "spp": int(self.kernel.samples_per_pixel),
            "photon_paths_per_iteration": self.photons,
            "surface_photons": int(self.kernel.surface_photons),
            "volume_photons": int(self.kernel.volume_photons),
            "surface_radius": surface,
            "volume_radius": volume,
            "kernel": "constant; surface: 2D disc; media: beam radiance estimate (2D disc)",
            "consistent": False,
            "rays": int(self.tracer.rays_traced),
            "nonfinite": int(self.kernel.nonfinite),
            "density_lookups": int(self.kernel.density_lookups)
            + int(self.light_paths.kernel.density_lookups),
        }
