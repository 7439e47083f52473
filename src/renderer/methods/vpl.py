"""vpl: virtual point lights (instant radiosity) in participating media, with clamping.

Keller 1997, "Instant radiosity"; equi-angular sampling along camera rays from Kulla and Fajardo
2012, "Importance sampling techniques for path tracing in participating media". The kernel
``cpp/vpl.h`` states the estimator, the clamp and the coverage; the virtual lights, the camera
paths that gather them and the stream of their shadow rays are ``cpp/virtual_lights.h``'s.

One iteration: ``light_paths`` light paths, whose non-specular vertices (area lights' own points,
surface and medium vertices; point, spot and directional lights exactly) become virtual lights;
then ``spp_per_iteration`` camera paths per pixel follow specular chains to their gather points
(the first non-specular surface, and every medium segment on the way) and gather every virtual
light there through a shadow ray. ``clamp`` bounds the geometry term 1 / d^2 by 1 / d_i^2: at
``clamp_distance`` always (``fixed``), relaxing as d_i = d_1 i^(clamp_alpha - 1) (``progressive``,
whose bias vanishes), or not at all (``none``: unbiased, with infinite variance where medium
lights meet surfaces or camera rays nearby).
"""

from __future__ import annotations

from .. import _core
from .base import NativeMethod
from .params import MethodParams, budget_divisor
from .schedules import expected_mse_slopes

# Light paths per iteration: each camera path gathers every virtual light they leave (about
# three to six a path on cbox, ten and more in fog), so an iteration costs pixels x lights
# shadow rays. Fewer paths make shorter iterations at about the same cost per light: at
# 128x128 on one thread, 64 took over 4 CPU seconds an iteration on cbox-fog (a 1 s budget got
# one iteration 4x late), 8 about 0.45 s, with relMSE at 4 s within the seeds' spread.
DEFAULT_LIGHT_PATHS = 8
# Light-path records per iteration: the memory bound (as pm's).
DEFAULT_MAX_RECORDS = 1 << 23
CLAMPS = ("none", "fixed", "progressive")
DEFAULT_CLAMP = "progressive"
# d_1 relative to the scene's bounding-sphere radius, and the progressive schedule's alpha.
# Measured (128x128, one thread, 1-4 CPU seconds, two seeds, 8 light paths): progressive from
# 0.2 had the lowest relMSE on cbox-fog (4.7e-2, 4.5e-2, 2.5e-2; from 0.1: 6.4e-2, 6.0e-2,
# 3.0e-2; fixed at 0.1: 5.8e-2, 5.1e-2, 2.5e-2; none: 2.2e-1, 1.4e-1, 5.5e-2) and was within
# 6 % of the best (fixed at 0.1) on cbox; at these budgets noise dominates the clamp's bias.
DEFAULT_CLAMP_DISTANCE = 0.2
DEFAULT_CLAMP_ALPHA = 2 / 3
DEFAULT_FREE_FLIGHT_FRACTION = 0.0
# Camera samples per pixel and iteration, among which the light-path vertices' lights are
# shared out (share_lights): a pixel still gathers each light once, over more of its area.
DEFAULT_SPP_PER_ITERATION = 4


class VirtualLightMethod(NativeMethod):
    """What vpl and vsl share: light paths, the gathering kernel, its counts."""

    kernel_class: type
    # whether the light paths record their medium segments (vrl, vbl: the ray lights)
    record_segments = False
    shared_parameters = frozenset(
        {"light_paths", "spp_per_iteration", "share_lights", "free_flight_fraction", "max_records"}
    )

    def read_spread(self, p: MethodParams, size: float) -> None:
        raise NotImplementedError

    def configure(self, kernel) -> None:
        raise NotImplementedError

    def setup(self, p: MethodParams) -> None:
        self.light_paths_per_iteration = p.integer("light_paths", DEFAULT_LIGHT_PATHS, lo=1)
        self.spp_per_iteration = p.spp_per_iteration(
            "spp_per_iteration",
            budget_divisor(DEFAULT_SPP_PER_ITERATION, self.spp_budget),
            self.spp_budget,
        )
        self.share_lights = p.flag("share_lights", True)
        p.light_paths_fit_in_memory("light_paths", self.light_paths_per_iteration)
        p.camera_paths_fit_in_memory("spp_per_iteration", self.spp_per_iteration, self.scene.film)
        fraction = p.number(
            "free_flight_fraction", DEFAULT_FREE_FLIGHT_FRACTION, lo=0, hi=1, hi_open=True
        )
        max_records = p.integer("max_records", DEFAULT_MAX_RECORDS, lo=1)
        self.read_spread(p, self.native.core.scene_radius)
        self.light_paths = self.light_paths_wavefront(
            self.light_paths_per_iteration,
            "light_paths",
            max_records,
            segments=self.record_segments,
        )
        integrator = self.scene.integrator
        kernel = self.kernel_class(
            self.native.core,
            self.light_paths.kernel,
            integrator.max_depth,
            integrator.rr_depth,
            self.seed,
            self.spp_per_iteration,
            self.threads,
        )
        kernel.set_free_flight_fraction(fraction)
        kernel.set_share_lights(self.share_lights)
        self.configure(kernel)
        self.gather = self.wavefront(kernel)

    def run_passes(self, iteration: int) -> None:
        # Light paths (their vertices are the iteration's virtual lights), then camera paths that
        # gather them.
        self.light_paths.run(iteration)
        self.gather.run(iteration)

    def common_stats(self) -> dict:
        kernel = self.gather.kernel
        return {
            "spp": int(kernel.samples_per_pixel),
            "spp_per_iteration": self.spp_per_iteration,
            "share_lights": self.share_lights,
            "light_paths_per_iteration": self.light_paths_per_iteration,
            "virtual_lights": int(kernel.virtual_lights),
            "gather_jobs": int(kernel.gather_jobs),
            "pairs": int(kernel.pairs),
            "shadow_rays": int(kernel.shadow_rays_aimed),
            # camera paths go on past gather points where the scene has specular surfaces
            "continuations": bool(kernel.continuations),
        }


class VirtualPointLights(VirtualLightMethod):
    id = "vpl"
    kernel_class = _core.VirtualPointLights
    parameters = VirtualLightMethod.shared_parameters | {
        "clamp",
        "clamp_distance_world",
        "clamp_distance_relative",
        "clamp_alpha",
    }

    def read_spread(self, p: MethodParams, size: float) -> None:
        self.clamp = p.choice("clamp", DEFAULT_CLAMP, CLAMPS)
        self.clamp_distance = p.radius("clamp_distance", DEFAULT_CLAMP_DISTANCE, size)
        self.clamp_alpha = p.number(
            "clamp_alpha", DEFAULT_CLAMP_ALPHA, lo=0, hi=1, lo_open=True, hi_open=True
        )
        for key in ("clamp_distance_world", "clamp_distance_relative"):
            p.refuse_unused(key, self.clamp != "none", "with clamp=none")
        p.refuse_unused("clamp_alpha", self.clamp == "progressive", f"with clamp={self.clamp}")

    def configure(self, kernel) -> None:
        kernel.set_clamp(_core.Clamp.__members__[self.clamp], self.clamp_distance, self.clamp_alpha)

    def method_stats(self) -> dict:
        kernel, last = self.gather.kernel, max(self.iterations - 1, 0)
        stats = {
            **self.common_stats(),
            "clamp": self.clamp,
            # the last iteration's bound on the distance in G = 1 / max(d^2, d_i^2)
            "clamp_distance_world": float(kernel.clamp_distance(last)),
            "consistent": self.clamp != "fixed",
        }
        if self.clamp == "progressive":
            stats["clamp_alpha"] = self.clamp_alpha
            stats.update(expected_mse_slopes([(self.clamp_alpha, 1)]))
        elif self.clamp == "none":
            stats.update(expected_mse_slopes([]))
        return stats
