"""sppm: stochastic progressive photon mapping with volume photons, probabilistic form.

Hachisuka, Ogaki and Jensen 2008, "Progressive photon mapping"; Hachisuka and Jensen
2009, "Stochastic progressive photon mapping"; Knaus and Zwicker 2011, "Progressive
photon mapping: a probabilistic approach". Each iteration is pm's estimator
(``methods/pm.py``, ``cpp/pm.h``) with new photons, new camera paths and its own
radii r_i = r_1 i^((alpha - 1) / d) (``cpp/radius_schedule.h``); the image is the
mean of the iterations, whose bias and variance both vanish.

Kernel dimensions: surfaces use a 2D disc (d = 2). Media use the beam radiance
estimate, a 2D disc around the camera ray (point x beam, 2D blur), so d = 2 as
well. With the default alpha = 2/3 = 4 / (d + 4) the MSE falls as n^(-2/3) at best.
"""

from __future__ import annotations

from .params import MethodParams
from .pm import PhotonMapping
from .schedules import expected_mse_slopes

DEFAULT_ALPHA = 2.0 / 3.0


class StochasticProgressivePhotonMapping(PhotonMapping):
    id = "sppm"
    parameters = PhotonMapping.parameters | {"surface_alpha", "volume_alpha"}
    renamed = {**PhotonMapping.renamed, "alpha": ("surface_alpha",)}
    # sppm starts wider than pm, since the radius shrinks with the iterations: its derived first
    # radii hold 4 times pm's photons (twice the radius of a 2D kernel where photons are
    # dense), and its fallback and scene's cap are 0.04 of the scene's radius
    neighbours_scale = 4

    def read_alphas(self, p: MethodParams) -> tuple[float, float]:
        """Knaus-Zwicker alphas of the surface and volume schedules (volume: the surface's by
        default)."""
        alpha = p.number("surface_alpha", DEFAULT_ALPHA, lo=0, hi=1, lo_open=True, hi_open=True)
        volume_alpha = p.number("volume_alpha", alpha, lo=0, hi=1, lo_open=True, hi_open=True)
        return alpha, volume_alpha

    def method_stats(self) -> dict:
        s = super().method_stats()
        s.update(
            surface_alpha=self.alpha,
            volume_alpha=self.volume_alpha,
            consistent=True,
            **expected_mse_slopes([tuple(k) for k in self.camera_paths.kernel.kernels]),
        )
        return s
