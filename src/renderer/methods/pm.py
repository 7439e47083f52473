"""pm: photon mapping with volumetric photons and the beam radiance estimate.

Jensen 1996, "Global illumination using photon maps"; Jensen and Christensen 1998,
"Efficient simulation of light transport in scenes with participating media using
photon maps"; Jarosz, Zwicker and Jensen 2008, "The beam radiance estimate for
volumetric photon mapping". The kernels are ``cpp/pm.h`` (gathering),
``cpp/photon_map.h`` (kd-tree) and ``cpp/subpaths.h`` (photon tracing).

Each iteration traces new photons, builds their maps and gathers along one
camera path per pixel sample; the image is the mean of the iterations. The
radius is fixed, so pm converges to a blurred (biased) image; sppm shrinks it.
Radii not given are derived from the photons around what the camera sees, by a pilot
before the first iteration (``methods/radii.py``): one for the surfaces, one per medium.
"""

from __future__ import annotations

import numpy as np

from .. import _core
from . import radii
from .base import NativeMethod
from .params import MethodParams

DEFAULT_LIGHT_PATHS = 1 << 16
# Vertices one iteration may record: the memory bound. Each costs about 200 bytes (the record,
# its copy in a photon map and the kd-tree), so the default bounds an iteration at about 1.7 GB.
DEFAULT_MAX_RECORDS = 1 << 23
# Photons a typical query gathers per iteration at the derived radii (methods/radii.py): on
# surfaces, and along a camera segment up to a free flight in a medium. Chosen for equal-time
# error at the study's budgets (docs/methods.md, "Default radii"): with 16 and 20, cbox's
# surface kernel was 0.026 against the old 0.035 and its relMSE at 2 s 30 % higher; with 32
# the scene's cap (the old rule) sets the radii wherever photons are as dense as it assumed.
DEFAULT_SURFACE_NEIGHBOURS = 32
DEFAULT_VOLUME_NEIGHBOURS = 32
# Where the pilot has nothing to go by (no photon, or no query reaches a kernel), and as the
# kernel's first radii until the pilot has run: a fraction of the scene's radius.
FALLBACK_RADIUS_RELATIVE = 0.02


class PhotonMapping(NativeMethod):
    id = "pm"
    parameters = frozenset(
        {
            "light_paths",
            "spp_per_iteration",
            "surface_radius_world",
            "surface_radius_relative",
            "surface_radius_neighbours",
            "volume_radius_world",
            "volume_radius_relative",
            "volume_radius_neighbours",
            "max_records",
        }
    )
    renamed = {
        "photons": ("light_paths",),
        "radius": ("surface_radius_world",),
        "volume_radius": ("volume_radius_world",),
        "radius_scale": ("surface_radius_relative", "volume_radius_relative"),
    }
    # sppm gathers 4 times the photons of pm at its first radii: twice the radius on 2D kernels
    neighbours_scale = 1

    def setup(self, p: MethodParams) -> None:
        self.light_paths_per_iteration = p.integer("light_paths", DEFAULT_LIGHT_PATHS, lo=1)
        self.spp_per_iteration = p.spp_per_iteration("spp_per_iteration", 1, self.spp_budget)
        p.light_paths_fit_in_memory("light_paths", self.light_paths_per_iteration)
        p.camera_paths_fit_in_memory("spp_per_iteration", self.spp_per_iteration, self.scene.film)
        max_records = p.integer("max_records", DEFAULT_MAX_RECORDS, lo=1)
        size = self.native.core.scene_radius
        # Each radius given (world units or relative), or else derived by the pilot from k
        # nearest photons: (radius or None, k)
        self.surface_given = p.given_radius("surface_radius", size)
        self.volume_given = p.given_radius("volume_radius", size)
        scale = self.neighbours_scale
        self.surface_neighbours = p.neighbours(
            "surface_radius", self.surface_given, DEFAULT_SURFACE_NEIGHBOURS * scale
        )
        self.volume_neighbours = p.neighbours(
            "volume_radius", self.volume_given, DEFAULT_VOLUME_NEIGHBOURS * scale
        )
        self.fallback_radius = FALLBACK_RADIUS_RELATIVE * self.neighbours_scale**0.5 * size
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
                self.surface_given or self.fallback_radius,
                self.alpha,
                self.volume_given or self.fallback_radius,
                self.volume_alpha,
            )
        )
        # The initial radius of each kernel and how it was set: "surface", then each medium's
        # name; None until the pilot has run (when a radius is not given).
        self.radii: dict[str, radii.DerivedRadius] | None = None
        self.given = {}
        for name, value in (
            ("surface_radius", self.surface_given),
            ("volume_radius", self.volume_given),
        ):
            if value is not None:
                self.given[name] = radii.given(value, p.given_radius_key(name))
        if len(self.given) == 2:
            self.radii = self.with_given_radii({})

    def with_given_radii(self, derived: dict) -> dict[str, radii.DerivedRadius]:
        """Every kernel's radius: the given ones, else those in ``derived``."""
        out = {"surface": self.given.get("surface_radius") or derived["surface"]}
        for medium in self.native.medium_ids:
            out[medium] = self.given.get("volume_radius") or derived[medium]
        return out

    def derive_radii(self, iteration: int) -> None:
        """The pilot (methods/radii.py) on ``iteration``'s photons: the radii not given, from
        the k nearest photons of the places where the camera paths estimate, set as each
        kernel's first radius."""
        radii.run_pilot(self, self.surface_neighbours, self.volume_neighbours, iteration)
        kernel = self.camera_paths.kernel
        scale = FALLBACK_RADIUS_RELATIVE * self.neighbours_scale**0.5
        fallback = f"{scale:g} of the scene's radius"
        minimum = 1e-9 * self.native.core.scene_radius

        def derive(index: int, neighbours: int, what: str) -> radii.DerivedRadius:
            distances, extent, free_paths = kernel.pilot_result(index)
            ids = self.native.medium_ids
            return radii.from_pilot(
                np.asarray(distances), extent, neighbours, what, self.fallback_radius, fallback,
                minimum,
                np.asarray(free_paths) if radii.is_grid(self.scene, ids, index) else None,
            )  # fmt: skip

        derived = {}
        if "surface_radius" not in self.given:
            derived["surface"] = derive(
                -1, self.surface_neighbours, "camera-path vertices on diffuse surfaces"
            )
            kernel.set_surface_radius(derived["surface"].world)
        if "volume_radius" not in self.given:
            for medium, index in self.native.medium_ids.items():
                derived[medium] = derive(
                    index, self.volume_neighbours, f"camera-path segments in {medium}"
                )
                kernel.set_volume_radius(index, derived[medium].world)
        self.radii = self.with_given_radii(derived)

    def read_alphas(self, p: MethodParams) -> tuple[float, float]:
        """(surface, volume) alpha of the radius schedules: 1, a fixed radius, for pm."""
        return 1.0, 1.0

    def run_passes(self, iteration: int) -> None:
        """Photon pass, then camera paths gathering with this iteration's radii (the pilot in
        between, on the first iteration run, if a radius is to be derived)."""
        self.light_paths.run(iteration)
        if self.radii is None:
            self.derive_radii(iteration)
        self.camera_paths.run(iteration)

    def method_stats(self) -> dict:
        kernel = self.camera_paths.kernel
        last = max(0, self.iterations - 1)
        derived = self.radii is not None
        return {
            "spp": int(kernel.samples_per_pixel),
            "light_paths_per_iteration": self.light_paths_per_iteration,
            "surface_photons": int(kernel.surface_photons),
            "volume_photons": int(kernel.volume_photons),
            # the last iteration's radii, in world units (None before the pilot), per medium
            "surface_radius_world": kernel.surface_radius(last) if derived else None,
            "volume_radius_world": {
                medium: kernel.volume_radius(last, index) if derived else None
                for medium, index in self.native.medium_ids.items()
            },
            # each kernel's first radius and how it was set
            "radii": {k: r.record() for k, r in self.radii.items()} if derived else None,
            "kernel": "constant; surface: 2D disc; media: beam radiance estimate (2D disc), "
            "parallel to the medium's boundary near it",
            "consistent": False,
        }
