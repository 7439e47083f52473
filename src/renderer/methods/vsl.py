"""vsl: virtual spherical lights in participating media, with a shrinking radius.

Hasan, Krivanek, Walter and Bala 2009, "Virtual spherical lights for many-light rendering of
glossy scenes"; Knaus and Zwicker 2011 for the radius schedule. The kernel ``cpp/vsl.h`` states
the estimator: vpl's (``methods/vpl.py``, ``cpp/vpl.h``) with each virtual light's power spread
over a sphere of radius r_i = r_1 i^(sphere_alpha - 1) about it, whose integral over the cone
of directions the sphere subtends is estimated by MIS over cone, BSDF and phase-function
sampling. The radius shrinks without a floor, so the image converges to the unbiased one.
"""

from __future__ import annotations

from .. import _core
from .params import MethodParams
from .schedules import expected_mse_slopes
from .vpl import VirtualLightMethod

# r_1 relative to the scene's bounding-sphere radius, and the schedule's alpha (d = 1:
# cpp/vsl.h).
DEFAULT_SPHERE_RADIUS = 0.1
DEFAULT_SPHERE_ALPHA = 2 / 3


class VirtualSphericalLights(VirtualLightMethod):
    id = "vsl"
    kernel_class = _core.VirtualSphericalLights
    parameters = VirtualLightMethod.shared_parameters | {
        "sphere_radius_world",
        "sphere_radius_relative",
        "sphere_alpha",
    }

    def read_spread(self, p: MethodParams, size: float) -> None:
        self.sphere_radius = p.radius("sphere_radius", DEFAULT_SPHERE_RADIUS, size)
        # 1 keeps the radius fixed (biased)
        self.sphere_alpha = p.number("sphere_alpha", DEFAULT_SPHERE_ALPHA, lo=0, hi=1, lo_open=True)

    def configure(self, kernel) -> None:
        kernel.set_radius(self.sphere_radius, self.sphere_alpha)

    def method_stats(self) -> dict:
        kernel, last = self.gather.kernel, max(self.iterations - 1, 0)
        return {
            **self.common_stats(),
            # the last iteration's radius, world units
            "sphere_radius_world": float(kernel.radius(last)),
            "initial_sphere_radius_world": self.sphere_radius,
            "sphere_alpha": self.sphere_alpha,
            "consistent": self.sphere_alpha < 1,
            **expected_mse_slopes([(self.sphere_alpha, 1)]),
        }
