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

from .. import _core
from .base import NativeMethod
from .params import MAX_RADIUS_FRACTION, MIN_RADIUS_FRACTION, MethodParams

DEFAULT_PHOTONS = 1 << 16
# Vertices one iteration may record: the memory bound. Each costs about 200 bytes (the record,
# its copy in a photon map and the kd-tree), so the default bounds an iteration at about 1.7 GB.
DEFAULT_MAX_RECORDS = 1 << 23
# Default radii relative to the scene's bounding-sphere radius.
DEFAULT_RADIUS_SCALE = 0.02


class PhotonMapping(NativeMethod):
    id = "pm"
    parameters = frozenset(
        {"photons", "spp_per_iteration", "radius", "volume_radius", "radius_scale", "max_records"}
    )
    default_radius_scale = DEFAULT_RADIUS_SCALE

    def setup(self, p: MethodParams) -> None:
        self.photons = p.integer("photons", DEFAULT_PHOTONS, lo=1)
        self.spp_per_iteration = p.spp_per_iteration("spp_per_iteration", 1, self.spp_budget)
        p.light_paths_fit_in_memory("photons", self.photons)
        p.camera_paths_fit_in_memory("spp_per_iteration", self.spp_per_iteration, self.scene.film)
        max_records = p.integer("max_records", DEFAULT_MAX_RECORDS, lo=1)
        lo, hi = MIN_RADIUS_FRACTION, MAX_RADIUS_FRACTION
        scale = p.number("radius_scale", self.default_radius_scale, lo=lo, hi=hi)
        size = self.native.core.scene_radius
        smallest, largest = MIN_RADIUS_FRACTION * size, MAX_RADIUS_FRACTION * size
        self.radius = p.number("radius", scale * size, lo=smallest, hi=largest)
        self.volume_radius = p.number("volume_radius", scale * size, lo=smallest, hi=largest)
        both = "radius" in p.params and "volume_radius" in p.params
        p.refuse_unused("radius_scale", not both, "when radius and volume_radius are both given")
        self.alpha, self.volume_alpha = self.read_alphas(p)
        self.light_paths = self.light_paths_wavefront(
            self.photons, "photons", max_records, segments=False
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
            "photon_paths_per_iteration": self.photons,
            "surface_photons": int(kernel.surface_photons),
            "volume_photons": int(kernel.volume_photons),
            "surface_radius": kernel.surface_radius(last),
            "volume_radius": kernel.volume_radius(last),
            "kernel": "constant; surface: 2D disc; media: beam radiance estimate (2D disc)",
            "consistent": False,
        }
