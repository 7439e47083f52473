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
Radii not given are derived from the beams (photons) around what the camera sees, by a pilot
before the first iteration (``methods/radii.py``): one per medium, and the surface photons'.
"""

from __future__ import annotations

import numpy as np

from .. import _core
from . import radii
from .base import NativeMethod
from .params import MethodParams
from .schedules import expected_mse_slopes

DEFAULT_LIGHT_PATHS = 1 << 13
# Beams stored per iteration: a bound on memory (up to ~1.5 KB per beam with its pieces
# and BVH, cpp/beams.h; about 0.7 KB measured at 6.5 pieces per beam).
DEFAULT_MAX_BEAMS = 1 << 22
# Light-path records (vertices plus segments) per iteration, as pm's: beams come from them.
DEFAULT_MAX_RECORDS = 1 << 23
# Beams a typical camera segment (up to a free flight) gathers per iteration at the derived
# first radius, and surface photons a typical surface estimate (methods/radii.py). The beams'
# keep cbox-fog's radius as it was at 0.01 of the scene's radius; 2 surface photons gave cbox
# 0.028 against the old 0.035 and 40 % more relMSE at equal time, 4 give 0.041
# (docs/methods.md, "Default radii").
DEFAULT_BEAM_NEIGHBOURS = 16
DEFAULT_SURFACE_NEIGHBOURS = 4
# Where the pilot has nothing to go by, and as the kernels' radii until it has run: fractions
# of the scene's radius.
FALLBACK_BEAM_RADIUS = 0.01
FALLBACK_SURFACE_RADIUS = 0.02
# The longest BVH piece of a beam, relative to the scene's radius.
DEFAULT_PIECE_LENGTH = 0.2
# alpha = 4 / (d + 4) with d = 1 minimises the asymptotic MSE where the radiance is smooth
# (Knaus & Zwicker 2011; cpp/radius_schedule.h has the rate at edges).
DEFAULT_ALPHA = 0.8
# Surface photons (at the camera path's first diffuse surface; a radius of 0: path-trace
# surfaces instead): alpha = 4 / (d + 4) for d = 2.
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
            "beam_radius_neighbours",
            "beam_alpha",
            "max_beams",
            "max_records",
            "piece_length_relative",
            "gather_bounces",
            "surface_radius_world",
            "surface_radius_relative",
            "surface_radius_neighbours",
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
        # Each radius given (world units or relative), or else derived by the pilot.
        beam_given = p.given_radius("beam_radius", size)
        piece = p.number("piece_length_relative", DEFAULT_PIECE_LENGTH, lo=0, lo_open=True)
        max_beams = p.integer("max_beams", DEFAULT_MAX_BEAMS, lo=1)
        max_records = p.integer("max_records", DEFAULT_MAX_RECORDS, lo=1)
        gather_bounces = p.integer("gather_bounces", DEFAULT_GATHER_BOUNCES, lo=0)
        # 0: path-traced surfaces
        surface_given = p.given_radius("surface_radius", size, zero_allowed="path-traced surfaces")
        surface_photons = surface_given != 0
        self.beam_neighbours = p.neighbours("beam_radius", beam_given, DEFAULT_BEAM_NEIGHBOURS)
        self.surface_neighbours = 0
        if surface_photons:
            self.surface_neighbours = p.neighbours(
                "surface_radius", surface_given, DEFAULT_SURFACE_NEIGHBOURS
            )
        else:
            p.refuse_unused("surface_radius_neighbours", False, "with path-traced surfaces")
        surface_alpha = p.number("surface_alpha", DEFAULT_SURFACE_ALPHA, lo=0, hi=1, lo_open=True)
        traced = "path-traced surfaces (a surface radius of 0)"
        p.refuse_unused("gather_bounces", not surface_photons, f"unless with {traced}")
        p.refuse_unused("surface_alpha", surface_photons, f"with {traced}")
        self.fallback = {
            "beam": FALLBACK_BEAM_RADIUS * size,
            "surface": FALLBACK_SURFACE_RADIUS * size,
        }
        self.light_paths = self.light_paths_wavefront(
            light_paths, "light_paths", max_records, vertices=surface_photons
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
            beam_given or self.fallback["beam"],
            alpha,
            piece * size,
            gather_bounces,
        )
        surface_radius = surface_given if surface_given is not None else self.fallback["surface"]
        kernel.set_surface_photons(surface_radius, surface_alpha)
        self.camera_paths = self.wavefront(kernel)
        self.spp_per_iteration = spp
        self.alpha, self.surface_alpha = alpha, surface_alpha
        # (alpha, dimension) of each blur, from the kernel's own schedules: 1D beams; 2D surface
        # photons unless surfaces are path-traced
        self.kernels = [tuple(k) for k in kernel.kernels]
        # The first radius of each kernel and how it was set: "surface" (surface photons), then
        # each medium's beams by the medium's name; None until the pilot has run.
        self.given: dict[str, radii.DerivedRadius] = {}
        for name, value in (("beam_radius", beam_given), ("surface_radius", surface_given)):
            if value is not None and value > 0:
                self.given[name] = radii.given(value, p.given_radius_key(name))
        self.radii: dict[str, radii.DerivedRadius] | None = None
        if not self.beam_neighbours and not self.surface_neighbours:
            self.radii = self.with_given_radii({})

    def with_given_radii(self, derived: dict) -> dict[str, radii.DerivedRadius]:
        """Every kernel's first radius: the given ones, else those in ``derived``."""
        out = {}
        if self.surface_neighbours or "surface_radius" in self.given:
            out["surface"] = self.given.get("surface_radius") or derived["surface"]
        for medium in self.native.medium_ids:
            out[medium] = self.given.get("beam_radius") or derived[medium]
        return out

    def derive_radii(self, iteration: int) -> None:
        """The pilot (methods/radii.py) on ``iteration``'s light paths: the radii not given, from
        the k nearest beams (surface photons) of the places where the camera paths gather, set
        as each kernel's first."""
        radii.run_pilot(self, self.surface_neighbours, self.beam_neighbours, iteration)
        kernel = self.camera_paths.kernel
        minimum = 1e-9 * self.native.core.scene_radius

        def derive(index: int, neighbours: int, kind: str, what: str) -> radii.DerivedRadius:
            # No free-path cap (pm's, in grids): a short beam's length per volume is the fluence,
            # which is continuous where the density jumps, and the camera side weighs it by
            # sigma_s at its own point, so a beam from a dense part adds nothing to a camera ray
            # in empty space. Capped at a free path, the cloud's beams got half the radius of the
            # scene's cap, and twice the error at equal time (docs/methods.md).
            distances, extent, _ = kernel.pilot_result(index)
            relative = FALLBACK_BEAM_RADIUS if kind == "beam" else FALLBACK_SURFACE_RADIUS
            ids = self.native.medium_ids
            # the scene's cap: beams in grid media only (docs/methods.md)
            return radii.from_pilot(
                np.asarray(distances), extent, neighbours, what, self.fallback[kind],
                f"{relative:g} of the scene's radius", minimum,
                scene_cap=kind == "beam" and radii.is_grid(self.scene, ids, index),
            )  # fmt: skip

        derived = {}
        if self.surface_neighbours:
            derived["surface"] = derive(
                -1, self.surface_neighbours, "surface", "camera-path vertices on diffuse surfaces"
            )
            kernel.set_surface_photons(derived["surface"].world, self.surface_alpha)
        if self.beam_neighbours:
            for medium, index in self.native.medium_ids.items():
                derived[medium] = derive(
                    index, self.beam_neighbours, "beam", f"camera-path segments in {medium}"
                )
                kernel.set_beam_radius(index, derived[medium].world)
        self.radii = self.with_given_radii(derived)

    def run_passes(self, iteration: int) -> None:
        # (The pilot after the first light paths, if a radius is to be derived.)
        # Light paths; then their beams in a BVH with this iteration's radius, and camera paths
        # that gather them along media and path-trace surfaces.
        self.light_paths.run(iteration)
        if self.radii is None:
            self.derive_radii(iteration)
        self.camera_paths.run(iteration)

    def method_stats(self) -> dict:
        kernel, last = self.camera_paths.kernel, max(self.iterations - 1, 0)
        derived = self.radii is not None
        return {
            "spp": int(kernel.samples_per_pixel),
            "spp_per_iteration": self.spp_per_iteration,
            "light_paths_per_iteration": self.light_paths.paths,
            # the last iteration's radii in world units (None before the pilot): the beams' by
            # medium, the surface photons' (0: path-traced surfaces)
            "beam_radius_world": {
                medium: float(kernel.radius(last, index)) if derived else None
                for medium, index in self.native.medium_ids.items()
            },
            "surface_radius_world": float(kernel.surface_radius(last)) if derived else None,
            # each kernel's first radius and how it was set
            "radii": {k: r.record() for k, r in self.radii.items()} if derived else None,
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
