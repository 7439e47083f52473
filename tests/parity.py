"""Independent estimates of an image, with standard errors, from our methods and from Mitsuba.

Both renderers produce K independent images (iterations / passes with distinct seeds); the
mean and its standard error per pixel follow from them, so a comparison can be judged by
z-scores built from measured variance alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from renderer.scene.model import Scene


@dataclass
class Estimate:
    samples: np.ndarray  # (K, H, W, 3): K independent images

    @property
    def mean(self) -> np.ndarray:
        return self.samples.mean(axis=0)

    def blocks(self, size: int) -> Estimate:
        """Average size x size pixel blocks (the CLT applies better to block means)."""
        k, h, w, c = self.samples.shape
        s = self.samples[:, : h - h % size, : w - w % size]
        s = s.reshape(k, h // size, size, w // size, size, c).mean(axis=(2, 4))
        return Estimate(s)

    def image_mean(self) -> Estimate:
        return Estimate(self.samples.mean(axis=(1, 2), keepdims=True))

    @property
    def stderr(self) -> np.ndarray:
        return self.samples.std(axis=0, ddof=1) / np.sqrt(len(self.samples))


def ours(method_cls, scene: Scene, iterations: int, seed: int = 1, **params) -> Estimate:
    """One image per iteration of a progressive method."""
    method = method_cls(scene, seed=seed, threads=2, params=params)
    images, previous = [], 0.0
    for i in range(iterations):
        method.run_iteration(i)
        total = method.image() * (i + 1)  # running mean -> running sum
        images.append(total - previous)
        previous = total
        assert method.stats()["nonfinite"] == 0
    return Estimate(np.stack(images))


def mitsuba(scene: Scene, passes: int, spp: int, seed: int = 1000) -> Estimate:
    """Mitsuba volpath images of the same scene, one per seed."""
    from renderer.mitsuba_env import import_mitsuba
    from renderer.scene.mitsuba_export import load_mitsuba_scene

    mi = import_mitsuba()
    ms = load_mitsuba_scene(scene)
    images = [
        np.array(mi.render(ms, spp=spp, seed=seed + i), dtype=np.float64) for i in range(passes)
    ]
    return Estimate(np.stack(images))


# False-alarm rate of one check. The suite runs ~200 parity checks (a block check asserts
# twice), so a change that re-rolls the random streams sees a false alarm somewhere with
# probability ~2 %; a 3 % bias still fails every parity case (test_parity.py shows it).
ALPHA = 1e-4


@dataclass
class Agreement:
    chi2: float
    dof: int
    p_value: float
    max_abs_z: float
    z_limit: float  # Bonferroni bound on |z| at the same false-alarm rate
    signed_z: float  # the z of largest magnitude, with its sign

    def __str__(self) -> str:
        return (
            f"chi2={self.chi2:.1f} dof={self.dof} p={self.p_value:.2g} "
            f"max|z|={self.max_abs_z:.2f} (limit {self.z_limit:.2f})"
        )


def agreement(a: Estimate, b: Estimate, alpha: float = ALPHA) -> Agreement:
    """Two-sample z-scores of the means; chi-square of their squares and the largest |z|.

    The variances are estimated from K images each, so each difference over its standard
    error follows Student's t with the Welch-Satterthwaite degrees of freedom, not a normal
    law; it is mapped to the normal quantile of the same tail probability before the
    chi-square and the |z| bound are applied. Values with zero variance on both sides (e.g.
    pixels that see nothing) must agree exactly.
    """
    diff = a.mean - b.mean
    var_a, var_b = a.stderr**2, b.stderr**2
    var = var_a + var_b
    exact = var == 0
    if np.any(exact):
        assert np.allclose(diff[exact], 0, atol=1e-12), "noise-free values differ"
    ka, kb = len(a.samples), len(b.samples)
    va, vb = var_a[~exact], var_b[~exact]
    dof = (va + vb) ** 2 / (va**2 / (ka - 1) + vb**2 / (kb - 1))
    t = diff[~exact] / np.sqrt(var[~exact])
    z = stats.norm.isf(stats.t.sf(np.abs(t), dof)) * np.sign(t)
    chi2 = float(np.sum(z**2))
    n = int(z.size)
    z_limit = float(stats.norm.isf(alpha / (2 * max(n, 1))))
    worst = float(z.flat[int(np.argmax(np.abs(z)))]) if n else 0.0
    p_value = float(stats.chi2.sf(chi2, n))
    return Agreement(chi2, n, p_value, float(np.abs(z).max()) if n else 0.0, z_limit, worst)
