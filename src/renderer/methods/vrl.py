"""vrl: virtual ray lights in participating media.

Novak, Nowrouzezahrai, Dachsbacher and Jarosz 2012, "Virtual ray lights for rendering scenes with
participating media" (SIGGRAPH). The kernel ``cpp/vrl.h`` states the passes and the coverage,
``cpp/ray_lights.h`` the estimators and their sampling densities; the camera paths, the gather
jobs, the point lights and their shadow-ray stream are vpl's (``methods/vpl.py``, ``cpp/vpl.h``).

One iteration: ``light_paths`` light paths, whose medium segments become ray lights and whose
other non-specular vertices (area lights' own points, surface vertices; point, spot and
directional lights exactly) point lights; then ``spp_per_iteration`` camera paths per pixel
gather every light at their gather points: along a camera segment a ray light by a pair of
points (one on the ray light, by the density that cancels the inverse-square distance to the
camera ray, one on the camera ray equi-angularly about it), at a surface by one point on the
ray light. The point lights' geometry term at surfaces is clamped as vpl's (``clamp``).
``phase_sampling`` draws the equi-angular points by the phase functions' fitted product (for
strongly anisotropic media) instead of uniformly in their angle.
"""

from __future__ import annotations

from .. import _core
from .params import MethodParams
from .vpl import VirtualPointLights


class VirtualRayLights(VirtualPointLights):
    id = "vrl"
    kernel_class = _core.VirtualRayLights
    record_segments = True
    parameters = VirtualPointLights.parameters | {"phase_sampling"}

    def read_spread(self, p: MethodParams, size: float) -> None:
        super().read_spread(p, size)
        self.phase_sampling = p.flag("phase_sampling", False)

    def configure(self, kernel) -> None:
        super().configure(kernel)
        kernel.set_phase_sampling(self.phase_sampling)

    def method_stats(self) -> dict:
        return {**super().method_stats(), "phase_sampling": self.phase_sampling}
