"""Independent estimates of an image, with standard errors, from our methods and from Mitsuba.

Both renderers produce K independent images (iterations / passes with distinct seeds); the
mean and its standard error per pixel follow from them, so a comparison can be judged by
z-scores built from measured variance alone.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import optimize, stats

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


def iteration_images(method, iterations: int, on_iteration=None) -> np.ndarray:
    """Run a progressive method and return the image of each iteration (stacked). Every
    running image the method returns must be finite and non-negative (the per-iteration
    differences may dip an ulp under zero where an iteration added nothing), and no sample
    may have been dropped as non-finite. on_iteration(n, running_image) sees the running
    image after n iterations."""
    images, previous = [], 0.0
    for i in range(iterations):
        method.run_iteration(i)
        running = method.image()
        assert np.all(np.isfinite(running)) and running.min() >= 0, (i, running.min())
        total = running * (i + 1)  # running mean -> running sum
        images.append(total - previous)
        previous = total
        if on_iteration is not None:
            on_iteration(i + 1, running)
    assert method.stats()["nonfinite"] == 0
    return np.stack(images)


def ours(method_cls, scene: Scene, iterations: int, seed: int = 1, **params) -> Estimate:
    """One image per iteration of a progressive method."""
    method = method_cls(scene, seed=seed, threads=2, params=params)
    return Estimate(iteration_images(method, iterations))


def mitsuba(
    scene: Scene, passes: int, spp: int, seed: int = 1000, integrator: str | None = None
) -> Estimate:
    """Mitsuba images of the same scene, one per seed: as the references render it (volpath;
    one grey render per channel where extinction differs between channels), or by
    ``integrator`` alone."""
    from renderer.mitsuba_env import import_mitsuba
    from renderer.reference import load_reference_scenes, mitsuba_pass
    from renderer.scene.mitsuba_export import load_mitsuba_scene

    mi = import_mitsuba()
    if integrator is None:
        mscenes = load_reference_scenes(scene)
    else:
        mscenes = [load_mitsuba_scene(scene, integrator)]
    images = [mitsuba_pass(mi, mscenes, spp, seed + i) for i in range(passes)]
    return Estimate(np.stack(images))


# False-alarm rate of one check. The suite runs ~200 parity checks (a block check asserts
# twice), so a change that re-rolls the random streams sees a false alarm somewhere with
# probability ~2 %. A 3 % bias in pt's image mean still fails every parity case against
# Mitsuba but two (a point light inside a grid: 5 %; volcaustic: 10 %); the test_*bias_fails
# tests show it.
ALPHA = 1e-4


@dataclass
class Agreement:
    chi2: float
    dof: int
    p_value: float
    max_abs_z: float
    z_limit: float  # Bonferroni bound on |z| at the same false-alarm rate
    signed_z: float  # the z of largest magnitude, with its sign
    # Largest difference, relative to the value, along colour directions too free of noise
    # to test (FLOAT_NOISE); above NOISE_FREE_TOLERANCE the p-value is 0.
    noise_free_deviation: float = 0.0
    alpha: float = ALPHA  # the false-alarm rate of each check

    @property
    def z_ok(self) -> bool:
        """No single value differs beyond the Bonferroni bound."""
        return self.max_abs_z < self.z_limit

    @property
    def passes(self) -> bool:
        """Both checks hold: the largest |z| and the chi-square over all cells."""
        return self.z_ok and self.p_value > self.alpha

    def __str__(self) -> str:
        return (
            f"chi2={self.chi2:.1f} dof={self.dof} p={self.p_value:.2g} "
            f"max|z|={self.max_abs_z:.2f} (limit {self.z_limit:.2f}) "
            f"noise-free deviation {self.noise_free_deviation:.1e}"
        )


# A direction of a cell's colour space whose standard error is below FLOAT_NOISE of the
# cell's value cannot be tested: Mitsuba computes in float32, and its chromaticities differ
# from ours by up to ~2e-5 (measured at max depth 2). Such directions (a gray image's
# chromatic ones, or any colour no path can change) must agree within NOISE_FREE_TOLERANCE.
FLOAT_NOISE, NOISE_FREE_TOLERANCE = 1e-4, 1e-3


def _cellwise(e: Estimate) -> np.ndarray:
    """(K, cells, C): the last axis (colour channels) is a vector per cell."""
    return e.samples.reshape(len(e.samples), -1, e.samples.shape[-1])


def _mean_covariance(x: np.ndarray) -> np.ndarray:
    """(cells, C, C): the covariance of each cell's mean vector from K samples (K, cells, C)."""
    k = len(x)
    c = x - x.mean(axis=0)
    return np.einsum("kni,knj->nij", c, c) / ((k - 1) * k)


def vector_chi2(a: Estimate, b: Estimate) -> tuple[np.ndarray, np.ndarray, float]:
    """Per cell, a chi-square equivalent of the difference of the mean vectors and its dof;
    and the largest difference in untestable directions, relative to the cell's value.

    The channels of one pixel come from the same paths (correlation 0.8-0.998 measured on the
    scenes), so their z-scores are not independent terms of a chi-square. Per cell the
    two-sample Hotelling statistic T^2 = d' (Va + Vb)^-1 d with unequal covariances is
    referred to the F law of Krishnamoorthy and Yu (2004, "Modified Nel and Van der Merwe
    test for the multivariate Behrens-Fisher problem"), which reduces to Welch's test for one
    channel; its tail probability is mapped to the chi-square quantile with as many dof as
    the covariance has rank.
    """
    xa, xb = _cellwise(a), _cellwise(b)
    ka, kb = len(xa), len(xb)
    mean_a, mean_b = xa.mean(axis=0), xb.mean(axis=0)
    d = mean_a - mean_b
    va, vb = _mean_covariance(xa), _mean_covariance(xb)
    lam, vec = np.linalg.eigh(va + vb)
    scale = np.abs(mean_a).max(axis=1) + np.abs(mean_b).max(axis=1)
    # (1e-12 of the largest: eigenvalues below it are rounding noise of eigh itself.)
    kept = lam > np.maximum(1e-12 * lam[:, -1], (FLOAT_NOISE * scale) ** 2)[:, None]
    rank = kept.sum(axis=1)
    inv_lam = np.divide(1.0, lam, out=np.zeros_like(lam), where=kept)
    pinv = np.einsum("nik,nk,njk->nij", vec, inv_lam, vec)
    outside = d - np.einsum("nik,nk,njk,nj->ni", vec, kept.astype(float), vec, d)
    deviation = np.linalg.norm(outside, axis=1) / np.maximum(scale, 1e-300)
    worst = float(deviation.max()) if len(deviation) else 0.0
    noisy = rank > 0
    d, va, vb, pinv, rank = d[noisy], va[noisy], vb[noisy], pinv[noisy], rank[noisy]
    t2 = np.einsum("ni,nij,nj->n", d, pinv, d)
    ma, mb = va @ pinv, vb @ pinv

    def spread(m: np.ndarray, k: int) -> np.ndarray:
        tr = np.trace(m, axis1=1, axis2=2)
        return (np.trace(m @ m, axis1=1, axis2=2) + tr**2) / (k - 1)

    nu = (rank + rank**2) / (spread(ma, ka) + spread(mb, kb))
    f = (nu - rank + 1) / (nu * rank) * t2
    tail = stats.f.sf(f, rank, nu - rank + 1)
    return stats.chi2.isf(tail, rank), rank, worst


def agreement(a: Estimate, b: Estimate, alpha: float = ALPHA) -> Agreement:
    """Two-sample z-scores of the means, their largest |z|, and a chi-square over all cells.

    The variances are estimated from K images each, so each difference over its standard
    error follows Student's t with the Welch-Satterthwaite degrees of freedom, not a normal
    law; it is mapped to the normal quantile of the same tail probability before the |z|
    bound (Bonferroni over all values, valid whatever their correlation) is applied. The
    chi-square treats each cell's channels as one vector (vector_chi2). Values with zero
    variance on both sides (e.g. pixels that see nothing) must agree exactly.
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
    n = int(z.size)
    cell_chi2, cell_dof, deviation = vector_chi2(a, b)
    chi2, chi2_dof = float(cell_chi2.sum()), int(cell_dof.sum())
    z_limit = float(stats.norm.isf(alpha / (2 * max(n, 1))))
    worst = float(z.flat[int(np.argmax(np.abs(z)))]) if n else 0.0
    p_value = float(stats.chi2.sf(chi2, chi2_dof)) if chi2_dof else 1.0
    if deviation > NOISE_FREE_TOLERANCE:  # a difference where there is no noise to explain it
        p_value = 0.0
    max_abs_z = float(np.abs(z).max()) if n else 0.0
    return Agreement(chi2, chi2_dof, p_value, max_abs_z, z_limit, worst, deviation, alpha)


def losses(fraction: float, channels: int = 3) -> list[np.ndarray]:
    """Per-channel scales for the controls of an agreement check: ``fraction`` less and more
    light in every channel, then less in each channel alone (a colour shift)."""
    scales = [np.full(channels, 1 - fraction), np.full(channels, 1 + fraction)]
    for c in range(channels):
        scales.append(np.where(np.arange(channels) == c, 1 - fraction, 1.0))
    return scales


def darken_one_block(a: Estimate, b: Estimate, size: int, z_extra: float = 3.0):
    """The control of a block check: ``a`` with one size x size block darkened by z_extra
    standard errors beyond the check's Bonferroni bound, the block whose relative standard
    error is smallest (the one a bug there would have to hide in the least). Returns the
    estimate and the fraction of light taken from that block."""
    ba, bb = a.blocks(size), b.blocks(size)
    limit = agreement(ba, bb).z_limit
    se = np.sqrt(ba.stderr**2 + bb.stderr**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(ba.mean > 0, se / ba.mean, np.inf).max(axis=-1)  # worst channel
    row, col = np.unravel_index(int(np.argmin(rel)), rel.shape)
    fraction = float(min(1.0, (limit + z_extra) * rel[row, col]))
    samples = a.samples.copy()
    samples[:, row * size : (row + 1) * size, col * size : (col + 1) * size] *= 1 - fraction
    return Estimate(samples), fraction


def assert_block_check_has_power(a: Estimate, b: Estimate, label: str, size: int = 4) -> None:
    """One size x size block of ``a`` darkened (darken_one_block) fails a block check of
    size x size blocks alone (same_image's); the multiscale check's power is
    assert_multiscale_check_has_power's."""
    darker, fraction = darken_one_block(a, b, size)
    result = agreement(darker.blocks(size), b.blocks(size))
    print(f"{label}: one block {fraction:.1%} darker: {result}")
    assert fraction < 1 and not result.passes, f"{label}: a {fraction:.1%} loss passed: {result}"


def same_image(a: Estimate, b: Estimate, alpha: float, block: int = 3) -> tuple[bool, str]:
    """Two renders of one image: block means and the image mean agree (chi-square and largest
    |z| at ``alpha``), and why, for the assertion message."""
    blocks = agreement(a.blocks(block), b.blocks(block), alpha=alpha)
    mean = agreement(a.image_mean(), b.image_mean(), alpha=alpha)
    return blocks.passes and mean.passes, f"blocks {blocks}; mean {mean}"


def mean_agrees(a: Estimate, b: Estimate) -> tuple[bool, str]:
    """The image means agree: largest |z| over the channels and their chi-square."""
    result = agreement(a.image_mean(), b.image_mean(), ALPHA)
    return result.passes, str(result)


# --------------------------------------------------------------------------- bias allowances
# Consistent methods (pm, sppm, ppb) are biased at any finite radius: their checks allow a
# measured bias and test only what lies beyond it.


def within_allowance(a: Estimate, reference: Estimate, allowance: float) -> Estimate:
    """``a`` with each value's difference from the reference's moved towards 0 by at most
    ``allowance`` times the reference's magnitude (a relative bound on a's bias), so that a
    value's |z| judges only the part of its difference the allowance does not explain."""
    if allowance == 0:
        return a
    diff = a.mean - reference.mean
    shift = np.sign(diff) * np.minimum(np.abs(diff), allowance * np.abs(reference.mean))
    return Estimate(a.samples - shift)


def nearest_within_allowance(a: Estimate, reference: Estimate, allowance: float) -> Estimate:
    """``a`` less the bias b, |b_c| <= ``allowance`` |reference_c| in each channel c of each
    cell, that brings its mean nearest the reference's in the chi-square's own metric (the
    inverse covariance of the cell's difference, untestable colour directions weighted as if
    their noise were FLOAT_NOISE). Moving each channel alone (within_allowance) is right for
    each channel's |z| but not for a cell's colour vector: with channels 0.99 correlated, a
    bias of 4.4 % in green and blue and 3.6 % in red, clamped to 3.5 % each, leaves a colour
    difference that the precise chromatic directions reject, although a bias within the
    allowance (3.5 %, 3.5 %, 2.9 %) explains it up to a grey remainder within the noise."""
    if allowance == 0:
        return a
    xa, xb = _cellwise(a), _cellwise(reference)
    d = xa.mean(axis=0) - xb.mean(axis=0)
    cov = _mean_covariance(xa) + _mean_covariance(xb)
    # (lsq_linear wants lower bounds below upper ones: a channel that is 0 gets a bound of 1e-300)
    bound = np.maximum(allowance * np.abs(xb.mean(axis=0)), 1e-300)
    scale = np.abs(xa.mean(axis=0)).max(axis=1) + np.abs(xb.mean(axis=0)).max(axis=1)
    shift = np.zeros_like(d)
    for n in range(len(d)):
        lam, vec = np.linalg.eigh(cov[n])
        lam = np.maximum(lam, (FLOAT_NOISE * scale[n]) ** 2)
        if not np.all(lam > 0):  # a cell that is 0 on both sides: nothing to shift
            continue
        root = (vec / np.sqrt(lam)).T  # |root x|^2 = x' cov^-1 x
        bounds = (-bound[n], bound[n])
        shift[n] = optimize.lsq_linear(root, root @ d[n], bounds=bounds, method="bvls").x
    return Estimate(a.samples - shift.reshape(a.samples.shape[1:]))


def agreement_beyond(a: Estimate, reference: Estimate, allowance: float) -> Agreement:
    """agreement() of ``a`` with the reference beyond a relative bias ``allowance``: each
    value's |z| after within_allowance, the chi-square after nearest_within_allowance (each the
    most lenient shift the allowance admits for that statistic)."""
    by_value = agreement(within_allowance(a, reference, allowance), reference)
    if allowance == 0:
        return by_value
    by_cell = agreement(nearest_within_allowance(a, reference, allowance), reference)
    return replace(by_cell, max_abs_z=by_value.max_abs_z, signed_z=by_value.signed_z)


# The scales of a multiscale check: the image mean, its quadrants, and blocks of BLOCK pixels.
BLOCK = 4


@dataclass(frozen=True)
class Scales:
    """Relative bias allowed at each scale of multiscale_agreement (0: none, an unbiased method)."""

    mean: float = 0.0
    quadrants: float = 0.0
    blocks: float = 0.0


UNBIASED = Scales()


def multiscale_agreement(
    a: Estimate,
    b: Estimate,
    allowance: Scales = UNBIASED,
    block: int = BLOCK,
    chi2: bool = True,
) -> tuple[bool, str]:
    """The image mean, the four quadrants and the ``block`` x ``block`` pixel blocks of ``a``
    agree with ``b``'s beyond the allowance of each scale: the largest |z| of each scale within
    its Bonferroni bound and, with ``chi2``, each scale's chi-square at parity.ALPHA. The
    quadrants catch an error spread over a quarter of the image that no single block resolves;
    the blocks, a local one. The chi-square takes cells as independent: where one photon or
    beam reaches many of them (kernels wider than a block, the slab of test_slab) it is left
    out, and the Bonferroni bound, valid whatever the correlation, decides alone."""
    h, w = a.samples.shape[1:3]
    scales = (
        ("mean", Estimate.image_mean, allowance.mean),
        ("quadrants", lambda e: e.blocks(min(h, w) // 2), allowance.quadrants),
        ("blocks", lambda e: e.blocks(block), allowance.blocks),
    )
    results = []
    for label, cells, allowed in scales:
        ref = cells(b)
        results.append((label, agreement_beyond(cells(a), ref, allowed)))
    detail = "; ".join(f"{label}: {r}" for label, r in results)
    return all(r.z_ok and (r.passes or not chi2) for _, r in results), detail


def injected_errors(a: Estimate, loss: float) -> list[tuple[str, Estimate]]:
    """The controls of a multiscale check: ``a`` with ``loss`` of its light taken from each
    quadrant in turn, and with light moved between quadrants (one ``loss`` brighter, the
    opposite one as much darker: the image mean hardly changes, as in a blur)."""
    h, w = a.samples.shape[1:3]
    rows, cols = (slice(0, h // 2), slice(h // 2, h)), (slice(0, w // 2), slice(w // 2, w))
    halves = [(r, c) for r in rows for c in cols]
    out = []
    for k, (r, c) in enumerate(halves):
        s = a.samples.copy()
        s[:, r, c] *= 1 - loss
        out.append((f"quadrant {k} {loss:.0%} darker", Estimate(s)))
    for k, j in ((0, 3), (1, 2)):
        s = a.samples.copy()
        s[:, halves[k][0], halves[k][1]] *= 1 + loss
        s[:, halves[j][0], halves[j][1]] *= 1 - loss
        out.append((f"{loss:.0%} moved from quadrant {j} to {k}", Estimate(s)))
    return out


def assert_multiscale_check_has_power(
    a: Estimate,
    b: Estimate,
    label: str,
    loss: float = 0.05,
    allowance: Scales = UNBIASED,
    block: int = BLOCK,
    chi2: bool = True,
) -> None:
    """Each of injected_errors(a, loss) fails multiscale_agreement against b."""
    for what, changed in injected_errors(a, loss):
        agrees, detail = multiscale_agreement(changed, b, allowance, block, chi2)
        print(f"{label}: {what}: {'passed' if agrees else 'failed'}")
        assert not agrees, f"{label}: {what} passed: {detail}"


def same_image_coarse_and_fine(
    a: Estimate, b: Estimate, alpha: float = ALPHA, coarse: int = 8, fine: int = 4
) -> tuple[bool, str]:
    """Two renders of one image, for estimates whose pixels are heavy-tailed (fog, virtual
    lights): the image mean (largest |z|); coarse x coarse blocks (chi-square and |z|: their
    means are close to normal even where fine blocks of a few dozen images still have heavy
    tails that inflate a chi-square); fine x fine blocks by the Bonferroni bound on |z|."""
    mean = agreement(a.image_mean(), b.image_mean(), alpha)
    coarse_blocks = agreement(a.blocks(coarse), b.blocks(coarse), alpha)
    fine_blocks = agreement(a.blocks(fine), b.blocks(fine), alpha)
    ok = mean.z_ok and coarse_blocks.passes and fine_blocks.z_ok
    return ok, f"mean {mean}; {coarse}x{coarse} {coarse_blocks}; {fine}x{fine} {fine_blocks}"
