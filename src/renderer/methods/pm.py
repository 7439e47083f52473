"""pm: photon mapping with volumetric photons and the beam radiance estimate.

Jensen 1996, "Global illumination using photon maps"; Jensen and Christensen 1998,
"Efficient simulation of light transport in scenes with participating media using
photon maps"; Jarosz, Zwicker and Jensen 2008, "The beam radiance estimate for
volumetric photon mapping". The kernels are ``cpp/pm.h`` (gathering),
``cpp/photon_map.h`` (kd-tree) and ``cpp/subpaths.h`` (photon tracing).

Each iteration traces new photons, builds their maps and gathers along one
camera path per pixel sample; the image is the mean of the iterations. The
radius is fixed, so pm converges to a blurred (biased) image; sppm shrinks it.
"""

from __future__ import annotations

from .. import _core
from .base import NativeMethod
from .params import MethodParams

DEFAULT_LIGHT_PATHS = 1 << 16
# Vertices one iteration may record: the memory bound. Each costs about 200 bytes (the record,
# its copy in a photon map and the kd-tree), so the default bounds an iteration at about 1.7 GB.
DEFAULT_MAX_RECORDS = 1 << 23
# Default radii relative to the scene's bounding-sphere radius.
DEFAULT_RADIUS_RELATIVE = 0.02


class PhotonMapping(NativeMethod):
    id = "pm"
    parameters = frozenset(
        {
            "light_paths",
            "spp_per_iteration",
            "surface_radius_world",
            "surface_radius_relative",
            "volume_radius_world",
            "volume_radius_relative",
            "max_records",
        }
    )
    renamed = {
        "photons": ("light_paths",),
        "radius": ("surface_radius_world",),
        "volume_radius": ("volume_radius_world",),
        "radius_scale": ("surface_radius_relative", "volume_radius_relative"),
    }
    default_radius_relative = DEFAULT_RADIUS_RELATIVE

    def setup(self, p: MethodParams) -> None:
        self.light_paths_per_iteration = p.integer("light_paths", DEFAULT_LIGHT_PATHS, lo=1)
        self.spp_per_iteration = p.spp_per_iteration("spp_per_iteration", 1, self.spp_budget)
        p.light_paths_fit_in_memory("light_paths", self.light_paths_per_iteration)
        p.camera_paths_fit_in_memory("spp_per_iteration", self.spp_per_iteration, self.scene.film)
        max_records = p.integer("max_records", DEFAULT_MAX_RECORDS, lo=1)
        size = self.native.core.scene_radius
        self.radius = p.radius("surface_radius", self.default_radius_relative, size)
        self.volume_radius = p.radius("volume_radius", self.default_radius_relative, size)
        self.alpha, self.volume_alpha = self.read_alphas(p)
        self.light_paths = self.light_paths_wavefront(
            self.light_paths_per_iteration, "light_paths", max_records, segments=False
        )
        self.camera_paths = self.wavefront(
            _core.PhotonMapping(
                self.native.core,
                self.light_paths.kernel,
                self.scene.integrator.max_depth,
                self.seed,
                self.spp_per_iteration,
                self.threads,
                self.radius,
                self.alpha,
                self.volume_radius,
                self.volume_alpha,
            )
        )

    def read_alphas(self, p: MethodParams) -> tuple[float, float]:
        """(surface, volume) alpha of the radius schedules: 1, a fixed radius, for pm."""
        return 1.0, 1.0

    def run_passes(self, iteration: int) -> None:
        """Photon pass, then camera paths gathering with this iteration's radii."""
        self.light_paths.run(iteration)
        self.camera_paths.run(iteration)

    def method_stats(self) -> dict:
        kernel = self.camera_paths.kernel
        last = max(0, self.iterations - 1)
        return {
            "spp": int(kernel.samples_per_pixel),
            "light_paths_per_iteration": self.light_paths_per_iteration,
            "surface_photons": int(kernel.surface_photons),
            "volume_photons": int(kernel.volume_photons),
            # the last iteration's radii, in world units
            "surface_radius_world": kernel.surface_radius(last),
            "volume_radius_world": kernel.volume_radius(last),
            "kernel": "constant; surface: 2D disc; media: beam radiance estimate (2D disc)",
            "consistent": False,
        }
