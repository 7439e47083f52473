"""vbl: progressive virtual beam lights in participating media.

Novak, Nowrouzezahrai, Dachsbacher and Jarosz 2012, "Progressive virtual beam lights" (EGSR).
vrl (``methods/vrl.py``) with each ray light thickened into a beam: the flux of each of its points
spread uniformly over the disc of radius r_i about it, perpendicular to the ray light, which
bounds the inverse-square distance to a camera ray or a surface point near it
(``cpp/ray_lights.h``). The radius shrinks as r_i = r_1 i^(beam_alpha - 1) with no floor, so the
image converges to vrl's; ``cpp/vbl.h`` states the rate and why.
"""

from __future__ import annotations

from .params import MethodParams
from .schedules import expected_mse_slopes
from .vrl import VirtualRayLights

# r_1 relative to the scene's bounding-sphere radius, and the schedule's alpha (cpp/vbl.h:
# r_i = r_1 i^(alpha - 1), the MSE falls at least as n^-min(alpha, 2 (1 - alpha))).
DEFAULT_BEAM_RADIUS = 0.02
DEFAULT_BEAM_ALPHA = 2 / 3


class VirtualBeamLights(VirtualRayLights):
    id = "vbl"
    parameters = VirtualRayLights.parameters | {
        "beam_radius_world",
        "beam_radius_relative",
        "beam_alpha",
    }

    def read_spread(self, p: MethodParams, size: float) -> None:
        super().read_spread(p, size)
        self.beam_radius = p.radius("beam_radius", DEFAULT_BEAM_RADIUS, size)
        # 1 keeps the radius fixed (biased)
        self.beam_alpha = p.number("beam_alpha", DEFAULT_BEAM_ALPHA, lo=0, hi=1, lo_open=True)

    def configure(self, kernel) -> None:
        super().configure(kernel)
        kernel.set_beam_radius(self.beam_radius, self.beam_alpha)

    def method_stats(self) -> dict:
        kernel, last = self.gather.kernel, max(self.iterations - 1, 0)
        # the beams' schedule, and the point lights' clamp where it shrinks too (cpp/vbl.h: a
        # bias of order r, d = 1)
        kernels = [(self.beam_alpha, 1)]
        if self.clamp == "progressive":
            kernels.append((self.clamp_alpha, 1))
        return {
            **super().method_stats(),
            # the last iteration's radius, world units
            "beam_radius_world": float(kernel.beam_radius(last)),
            "initial_beam_radius_world": self.beam_radius,
            "beam_alpha": self.beam_alpha,
            "consistent": self.clamp != "fixed" and self.beam_alpha < 1,
            **expected_mse_slopes(kernels),
        }
