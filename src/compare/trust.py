"""Whether a reference image can be trusted: checks against an independent unbiased estimate.

Mitsuba is the study's oracle, but not everywhere: in dense, white media its volpath returns
exactly 0 (its Russian roulette is capped at 0.95 and its transmittances are float32), and in a
cloud it is 16 % too dark (docs/methods.md, "Where Mitsuba disagrees"). A reference is checked
against a short render of one of pgi's unbiased methods (the *check*: K independent
iterations) and, where it was rendered in two independent halves with their own variances,
against itself. Three findings make it untrustworthy, each reported in one line:

- **dead pixels**: more than ``DEAD_FRACTION`` of the pixels where the check sees light (their
  mean above 0, their 4x4 block's ``Z_LIT`` standard errors above 0), and at least
  ``DEAD_MIN_PIXELS``, are exactly 0 or not finite in the reference;
- **a mean outside the check's confidence interval**: the image mean of a channel or of the
  luminance differs by more than ``Z_MEAN`` combined standard errors (the check's from its
  iterations, Student's t mapped to a normal score; the reference's from its passes);
- **halves that disagree far beyond their noise**: the mean of the squared z-scores of their
  ``HALVES_BLOCK`` x ``HALVES_BLOCK`` block luminances exceeds ``HALVES_FACTOR`` times its
  expectation under Student's t with the halves' degrees of freedom (with at least
  ``HALVES_MIN_PASSES`` passes per half: fewer make the variance itself too noisy to judge by).

The bounds are wide on purpose: a false alarm would take a scene's verdicts away, and the
failures they are for are gross (100 % dead pixels, a mean 16 % low). tests/test_trust.py
shows each firing on the failure it is for and none on sound references.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats as sps

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 weights
Z_LIT = 5.0
DEAD_FRACTION = 0.01
DEAD_MIN_PIXELS = 3
Z_MEAN = 5.0
HALVES_FACTOR = 4.0
HALVES_BLOCK = 4
HALVES_MIN_PASSES = 4


@dataclass(frozen=True)
class Estimate:
    """An image estimate: its mean (H, W, 3); the variance of that mean per value and of its
    image mean per channel (None where unknown); the degrees of freedom of those variances."""

    mean: np.ndarray
    variance: np.ndarray | None = None
    image_mean_variance: np.ndarray | None = None
    dof: int = 0

    @classmethod
    def from_iterations(cls, images: np.ndarray) -> Estimate:
        """From K >= 2 independent images (K, H, W, 3) of the same expectation (the pixels of
        one may be correlated: the image mean's variance comes from the K image means)."""
        images = np.asarray(images, np.float64)
        k = len(images)
        if k < 2:
            raise ValueError("an estimate from iterations needs at least two of them")
        means = images.reshape(k, -1, 3).mean(axis=1)
        return cls(
            images.mean(axis=0),
            images.var(axis=0, ddof=1) / k,
            means.var(axis=0, ddof=1) / k,
            k - 1,
        )

    @classmethod
    def from_passes(cls, mean: np.ndarray, variance: np.ndarray | None, passes: int) -> Estimate:
        """From a reference's accumulated passes: its pixels independent (Mitsuba's independent
        sampler and box filter), so the image mean's variance is the pixels' summed."""
        mean = np.asarray(mean, np.float64)
        if variance is None or passes < 2:
            return cls(mean)
        variance = np.asarray(variance, np.float64)
        n = mean.shape[0] * mean.shape[1]
        return cls(mean, variance, variance.reshape(-1, 3).sum(axis=0) / n**2, passes - 1)


@dataclass
class TrustVerdict:
    trustworthy: bool
    findings: list[str] = field(default_factory=list)  # why not, one line each
    figures: dict[str, float] = field(default_factory=dict)

    def line(self, reference: str) -> str:
        """One line for a user, e.g. "Mitsuba's reference of cloud is not trustworthy: ..."."""
        if self.trustworthy:
            return f"{reference} passed its checks"
        return f"{reference} is not trustworthy: " + "; ".join(self.findings)


def normal_score(t: float, dof: int) -> float:
    """The normal score of Student's t's tail probability with ``dof`` degrees of freedom
    (dof <= 0: the variance was known, t is already normal)."""
    if dof <= 0 or not math.isfinite(t) or t == 0:
        return t
    return math.copysign(float(sps.norm.isf(sps.t.sf(abs(t), dof))), t)


def dead_pixels(reference: np.ndarray, check: Estimate) -> tuple[int, int]:
    """(pixels where the check sees light and the reference is exactly 0 or not finite, pixels
    where the check sees light). The check sees light in a pixel whose own mean is above 0 and
    whose ``HALVES_BLOCK`` x ``HALVES_BLOCK`` block's luminance lies ``Z_LIT`` standard errors
    above 0 (blocks, because a short check's single pixels are too noisy to tell)."""
    lum = check.mean @ LUMINANCE
    lit = lum > 0
    if check.variance is not None:
        b = HALVES_BLOCK
        h, w = lum.shape
        hb, wb = -(-h // b), -(-w // b)  # partial blocks at the edges count as blocks
        pad = ((0, hb * b - h), (0, wb * b - w))
        block_sum = np.pad(lum, pad).reshape(hb, b, wb, b).sum(axis=(1, 3))
        # the channels' errors added, as if fully correlated (an upper bound)
        se = np.sqrt(np.maximum(check.variance, 0.0)) @ LUMINANCE
        block_var = np.pad(se**2, pad).reshape(hb, b, wb, b).sum(axis=(1, 3))
        block_lit = (block_var > 0) & (block_sum > Z_LIT * np.sqrt(block_var))
        block_lit |= (block_var == 0) & (block_sum > 0)  # noise-free light (a lamp seen directly)
        lit &= np.repeat(np.repeat(block_lit, b, axis=0), b, axis=1)[:h, :w]
    ref = np.asarray(reference, np.float64)
    dead = lit & (np.all(ref == 0, axis=-1) | ~np.all(np.isfinite(ref), axis=-1))
    return int(dead.sum()), int(lit.sum())


def mean_scores(reference: Estimate, check: Estimate) -> dict[str, tuple[float, float]]:
    """For the channels r, g, b and the luminance: (reference mean / check mean - 1, z-score
    of the difference as a normal score)."""
    ref = reference.mean.reshape(-1, 3).mean(axis=0)
    chk = check.mean.reshape(-1, 3).mean(axis=0)
    zero = np.zeros(3)
    v_ref = zero if reference.image_mean_variance is None else reference.image_mean_variance
    v_chk = zero if check.image_mean_variance is None else check.image_mean_variance
    # the smaller dof of the two governs (Welch-Satterthwaite would be exact; this is safe)
    dofs = [d for d in (reference.dof, check.dof) if d > 0]
    dof = min(dofs) if dofs else 0
    out = {}
    for c, name in enumerate("rgb"):
        out[name] = _score(ref[c], chk[c], v_ref[c], v_chk[c], dof)
    # the luminance's variance with the channels fully correlated (an upper bound)
    lum_v = [float(np.sqrt(v) @ LUMINANCE) ** 2 for v in (v_ref, v_chk)]
    out["luminance"] = _score(float(ref @ LUMINANCE), float(chk @ LUMINANCE), *lum_v, dof)
    return out


def _score(ref: float, chk: float, v_ref: float, v_chk: float, dof: int) -> tuple[float, float]:
    rel = ref / chk - 1 if chk > 0 else (0.0 if ref == chk else math.inf)
    se = math.sqrt(v_ref + v_chk)
    if se == 0:
        return rel, (0.0 if ref == chk else math.copysign(math.inf, ref - chk))
    return rel, normal_score((ref - chk) / se, dof)


def halves_excess(first: Estimate, second: Estimate) -> float | None:
    """The mean squared z-score of the halves' block luminances over its expectation under
    Student's t (1 for sound halves); None where their variances cannot tell."""
    if first.variance is None or second.variance is None:
        return None
    if min(first.dof, second.dof) + 1 < HALVES_MIN_PASSES:
        return None
    b = HALVES_BLOCK
    h, w = first.mean.shape[:2]
    h, w = h - h % b, w - w % b
    if h == 0 or w == 0:
        return None

    def blocks(a: np.ndarray) -> np.ndarray:
        return a[:h, :w].reshape(h // b, b, w // b, b, 3).mean(axis=(1, 3))

    diff = (blocks(first.mean) - blocks(second.mean)) @ LUMINANCE
    # a block mean's variance: its pixels' summed (independent pixels) / b^4
    var = [
        np.sqrt(e.variance[:h, :w].reshape(h // b, b, w // b, b, 3).sum(axis=(1, 3)) / b**4)
        @ LUMINANCE
        for e in (first, second)
    ]
    total = var[0] ** 2 + var[1] ** 2
    valid = total > 0
    if not valid.any():
        return None
    z2 = diff[valid] ** 2 / total[valid]
    dof = first.dof + second.dof
    expected = dof / (dof - 2) if dof > 2 else 3.0
    return float(z2.mean() / expected)


def check_reference(
    reference: Estimate,
    check: Estimate,
    halves: tuple[Estimate, Estimate] | None = None,
    check_name: str = "pt",
) -> TrustVerdict:
    """Whether ``reference`` is trustworthy, judged against ``check`` (an independent unbiased
    estimate of the same image) and, where given, its own two independent ``halves``."""
    verdict = TrustVerdict(True)
    dead, lit = dead_pixels(reference.mean, check)
    verdict.figures.update(dead_pixels=dead, lit_pixels=lit)
    if lit and dead >= DEAD_MIN_PIXELS and dead > DEAD_FRACTION * lit:
        verdict.findings.append(
            f"{100 * dead / lit:.0f} % of the pixels where {check_name} sees light are exactly "
            "0 or not finite in it"
        )
    scores = mean_scores(reference, check)
    for name, (rel, z) in scores.items():
        verdict.figures[f"mean_{name}_relative"] = rel
        verdict.figures[f"mean_{name}_z"] = z
    worst = max(scores, key=lambda k: abs(scores[k][1]))
    rel, z = scores[worst]
    if abs(z) > Z_MEAN:
        what = "image mean" if worst == "luminance" else f"{worst} channel's image mean"
        side = "below" if rel < 0 else "above"
        amount = f"{100 * abs(rel):.1f} %" if math.isfinite(rel) else "infinitely"
        verdict.findings.append(f"its {what} is {amount} {side} {check_name}'s (z = {z:+.1f})")
    if halves is not None:
        excess = halves_excess(*halves)
        if excess is not None:
            verdict.figures["halves_excess"] = excess
            if excess > HALVES_FACTOR:
                verdict.findings.append(
                    f"its two halves disagree {excess:.1f}x beyond their own noise"
                )
    verdict.trustworthy = not verdict.findings
    return verdict


def combined(first: Estimate, second: Estimate) -> Estimate:
    """The average of two independent estimates of equal weight (a reference's two halves)."""
    mean = 0.5 * (first.mean + second.mean)
    if first.variance is None or second.variance is None:
        return Estimate(mean)
    image_mean = None
    if first.image_mean_variance is not None and second.image_mean_variance is not None:
        image_mean = 0.25 * (first.image_mean_variance + second.image_mean_variance)
    variance = 0.25 * (first.variance + second.variance)
    return Estimate(mean, variance, image_mean, first.dof + second.dof)


def verdict_record(verdict: TrustVerdict, reference: str, check: str) -> dict:
    """A verdict as a sidecar keeps it: who was checked against what, the verdict, its
    findings, its one line and its figures (non-finite ones as None: JSON has no NaN)."""
    return {
        "reference": reference,
        "checked_against": check,
        "trustworthy": verdict.trustworthy,
        "findings": list(verdict.findings),
        "line": verdict.line(reference),
        "figures": {
            k: (float(v) if math.isfinite(float(v)) else None) for k, v in verdict.figures.items()
        },
    }
