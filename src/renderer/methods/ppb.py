"""ppb: progressive photon beams.

Jarosz, Nowrouzezahrai, Thomas, Sloan and Zwicker 2011, "Progressive photon beams"
(ACM TOG 30(6)); the beam x beam 1D estimator of Jarosz, Nowrouzezahrai, Sadeghi and
Jensen 2011, "A comprehensive theory of volumetric radiance estimation using photon
points and beams"; the radius schedule of Knaus and Zwicker 2011 with d = 1.

One iteration is a sequence of passes:

1. trace ``light_paths`` light paths (``cpp/subpaths.h``); their medium segments become
   short photon beams (up to the sampled collision);
2. build the beam BVH (``cpp/beams.h``) with this iteration's radius
   r_i = r_1 * i^(alpha - 1);
3. trace ``spp_per_iteration`` camera paths per pixel (``cpp/ppb.h``): every medium
   segment gathers the beams it passes within r_i of (BB1D); specular surfaces are
   followed; at the first diffuse surface the path ends with emission, next-event
   estimation and a density estimate of the surface photons that arrived there after
   at least one scattering (radius of a d = 2 schedule). Shadow rays are resolved in
   batches. With ``surface_radius_relative=0`` surfaces are path traced as in pt instead, and
   after ``gather_bounces`` + 1 diffuse bounces a camera path stops gathering and
   scatters in media itself (the split keeps every path counted once).

The estimate is consistent: its bias shrinks with the radius, its variance grows as
1/r_i, and the mean over iterations converges with MSE ~ n^-min(alpha, 4 (1 - alpha)).
"""

from __future__ import annotations

from .. import _core
from .base import NativeMethod
from .params import MethodParams
from .schedules import expected_mse_slopes

DEFAULT_LIGHT_PATHS = 1 << 13
# Beams stored per iteration: a bound on memory (up to ~1.5 KB per beam with its pieces
# and BVH, cpp/beams.h; about 0.7 KB measured at 6.5 pieces per beam).
DEFAULT_MAX_BEAMS = 1 << 22
# Light-path records (vertices plus segments) per iteration, as pm's: beams come from them.
DEFAULT_MAX_RECORDS = 1 << 23
# Initial radius and the longest BVH piece of a beam, relative to the scene's radius.
DEFAULT_BEAM_RADIUS = 0.01
DEFAULT_PIECE_LENGTH = 0.2
# alpha = 4 / (d + 4) with d = 1 minimises the asymptotic MSE where the radiance is smooth
# (Knaus & Zwicker 2011; cpp/radius_schedule.h has the rate at edges).
DEFAULT_ALPHA = 0.8
# Surface photons (at the camera path's first diffuse surface): initial radius relative to
# the scene radius (0: path-trace surfaces instead) and alpha = 4 / (d + 4) for d = 2.
DEFAULT_SURFACE_RADIUS = 0.02
DEFAULT_SURFACE_ALPHA = 2 / 3
# Without surface photons: diffuse bounces after which camera paths still gather beams
# (then they path-trace media).
DEFAULT_GATHER_BOUNCES = 0


class ProgressivePhotonBeams(NativeMethod):
    id = "ppb"
    parameters = frozenset(
        {
            "light_paths",
            "spp_per_iteration",
            "beam_radius_world",
            "beam_radius_relative",
            "beam_alpha",
            "max_beams",
            "max_records",
            "piece_length_relative",
            "gather_bounces",
            "surface_radius_world",
            "surface_radius_relative",
            "surface_alpha",
        }
    )
    renamed = {
        "radius": ("beam_radius_relative",),
        "alpha": ("beam_alpha",),
        "surface_radius": ("surface_radius_relative",),
        "piece_length": ("piece_length_relative",),
    }

    def setup(self, p: MethodParams) -> None:
        light_paths = p.integer("light_paths", DEFAULT_LIGHT_PATHS, lo=1)
        spp = p.spp_per_iteration("spp_per_iteration", 1, self.spp_budget)
        p.light_paths_fit_in_memory("light_paths", light_paths)
        p.camera_paths_fit_in_memory("spp_per_iteration", spp, self.scene.film)
        alpha = p.number("beam_alpha", DEFAULT_ALPHA, lo=0, hi=1, lo_open=True)
        size = self.native.core.scene_radius
        radius = p.radius("beam_radius", DEFAULT_BEAM_RADIUS, size)
        piece = p.number("piece_length_relative", DEFAULT_PIECE_LENGTH, lo=0, lo_open=True)
        max_beams = p.integer("max_beams", DEFAULT_MAX_BEAMS, lo=1)
        max_records = p.integer("max_records", DEFAULT_MAX_RECORDS, lo=1)
        gather_bounces = p.integer("gather_bounces", DEFAULT_GATHER_BOUNCES, lo=0)
        # 0: path-traced surfaces
        surface_radius = p.radius(
            "surface_radius", DEFAULT_SURFACE_RADIUS, size, zero_allowed="path-traced surfaces"
        )
        surface_alpha = p.number("surface_alpha", DEFAULT_SURFACE_ALPHA, lo=0, hi=1, lo_open=True)
        traced = "path-traced surfaces (a surface radius of 0)"
        p.refuse_unused("gather_bounces", surface_radius == 0, f"unless with {traced}")
        p.refuse_unused("surface_alpha", surface_radius > 0, f"with {traced}")
        self.light_paths = self.light_paths_wavefront(
            light_paths, "light_paths", max_records, vertices=surface_radius > 0
        )
        integrator = self.scene.integrator
        kernel = _core.ProgressivePhotonBeams(
            self.native.core,
            self.light_paths.kernel,
            integrator.max_depth,
            integrator.rr_depth,
            self.seed,
            spp,
            self.threads,
            max_beams,
            radius,
            alpha,
            piece * size,
            gather_bounces,
        )
        kernel.set_surface_photons(surface_radius, surface_alpha)
        self.camera_paths = self.wavefront(kernel)
        self.spp_per_iteration = spp
        self.alpha, self.surface_alpha = alpha, surface_alpha
        # (alpha, dimension) of each blur, from the kernel's own schedules: 1D beams; 2D surface
        # photons unless surfaces are path-traced
        self.kernels = [tuple(k) for k in kernel.kernels]

    def run_passes(self, iteration: int) -> None:
        # Light paths; then their beams in a BVH with this iteration's radius, and camera paths
        # that gather them along media and path-trace surfaces.
        self.light_paths.run(iteration)
        self.camera_paths.run(iteration)

    def method_stats(self) -> dict:
        kernel, last = self.camera_paths.kernel, max(self.iterations - 1, 0)
        return {
            "spp": int(kernel.samples_per_pixel),
            "spp_per_iteration": self.spp_per_iteration,
            "light_paths_per_iteration": self.light_paths.paths,
            # the last iteration's radii in world units (the parameters are relative)
            "beam_radius_world": float(kernel.radius(last)),
            "surface_radius_world": float(kernel.surface_radius(last)),
            "beam_alpha": self.alpha,
            "surface_alpha": self.surface_alpha,
            # alpha = 1 keeps a radius fixed: the image converges to a blurred one
            "consistent": all(a < 1 for a, _ in self.kernels),
            **expected_mse_slopes(self.kernels),
            "beams": int(kernel.beams_stored),
            "surface_photons": int(kernel.photons_stored),
            "beams_truncated": int(kernel.beams_truncated),
            # light paths that escaped inside an unbounded medium: their flux is missing
            "beams_escaped": int(kernel.beams_escaped),
            "beam_pairs": int(kernel.beam_pairs),
        }
