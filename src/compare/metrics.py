"""Image-error metrics on linear HDR images, and per-pixel error maps.

All metrics compare a *test* image ``x`` against a *reference* ``r``; both are
linear RGB arrays of shape (H, W, 3) (a (H, W) or (H, W, 1) array is treated
as grey). Values are accumulated in float64. Definitions (N = H*W*3 values,
``eps = 0.01``):

- ``mse``            mean((x - r)^2)
- ``rmse``           sqrt(mse)
- ``relmse``         mean((x - r)^2 / (r^2 + eps))
- ``relmse_trimmed`` relMSE after dropping the ``floor(0.001 * H*W)`` pixels with
                     the largest per-pixel relMSE (per-pixel = mean over the 3
                     channels); with fewer than 1000 pixels nothing is dropped.
                     Robust to a few fireflies.
- ``mape``           mean(|x - r| / (|r| + eps))
- ``smape``          mean(|x - r| / (|x| + |r| + eps)), in [0, 1] (1 only by rounding)
- ``flip``           mean HDR-FLIP (NVIDIA ``flip-evaluator``), in [0, 1]
- ``one_minus_ssim`` 1 - SSIM as Wang et al. 2004 define it (Gaussian window of
                     sigma 1.5, 11x11; population covariances; scikit-image, mean
                     over channels) on the images tonemapped to display sRGB:
                     clip(x, 0, 1) then the sRGB transfer curve, data range 1.
                     NaN for images smaller than the window.

Inputs are validated before anything reaches ``flip-evaluator``, which calls
``sys.exit`` on bad input: shapes must match, values must be finite. Negative
values (possible with some unbiased estimators) are clamped to 0 for FLIP only.
An all-black reference makes FLIP's automatic exposure range undefined; then
FLIP is evaluated at the single exposure 0. A reference whose peak luminance is
below ``DIM_PEAK`` (1e-6) is scaled to a peak of 1, with the test image, first:
below float epsilon flip-evaluator's range comes out empty, and scaling both
images alike does not change HDR-FLIP. Cost: FLIP takes most of a comparison's
time, on one core (measured: 7 s at 1024x1024, 34 s at 2048x2048); a whole
comparison peaks at about 360 bytes of memory per pixel (6 GB at 4096x4096).
"""

from __future__ import annotations

import math

import numpy as np

EPS = 0.01
TRIM_FRACTION = 0.001
METRICS: tuple[str, ...] = (
    "mse",
    "rmse",
    "relmse",
    "relmse_trimmed",
    "mape",
    "smape",
    "flip",
    "one_minus_ssim",
)


def as_rgb(img: np.ndarray, name: str = "image") -> np.ndarray:
    """Return ``img`` as a float64 (H, W, 3) array; raise ValueError if it cannot be."""
    a = np.asarray(img)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4):
        raise ValueError(f"{name}: expected an (H, W, 3) image, got shape {a.shape}")
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    elif a.shape[2] == 4:
        a = a[:, :, :3]  # drop alpha
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"{name}: empty image of shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number):
        raise ValueError(f"{name}: expected a numeric array, got dtype {a.dtype}")
    return a.astype(np.float64, copy=False)


def validate_pair(
    test: np.ndarray, ref: np.ndarray, names: tuple[str, str] = ("test image", "reference image")
) -> tuple[np.ndarray, np.ndarray]:
    """Check shapes and finiteness; return both images as float64 (H, W, 3). `names` are
    the two images' names in messages."""
    x = as_rgb(test, names[0])
    r = as_rgb(ref, names[1])
    if x.shape != r.shape:
        raise ValueError(
            f"shape mismatch: {names[0]} is {x.shape[1]}x{x.shape[0]} "
            f"but {names[1]} is {r.shape[1]}x{r.shape[0]} (width x height)"
        )
    for name, a in zip(names, (x, r), strict=True):
        bad = ~np.isfinite(a)
        if bad.any():
            n = int(bad.any(axis=2).sum())
            y, xx = np.argwhere(bad.any(axis=2))[0]
            raise ValueError(
                f"{name} has {n} pixel(s) with non-finite values (NaN/Inf), first at x={xx}, y={y}"
            )
    return x, r


# --- per-pixel maps -------------------------------------------------------------------------


def relmse_map(test: np.ndarray, ref: np.ndarray, eps: float = EPS) -> np.ndarray:
    """Per-pixel relative squared error, mean over channels: (H, W) float64."""
    x, r = validate_pair(test, ref)
    return np.mean((x - r) ** 2 / (r * r + eps), axis=2)


def abs_error_map(test: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-pixel absolute error, mean over channels: (H, W) float64."""
    x, r = validate_pair(test, ref)
    return np.mean(np.abs(x - r), axis=2)


def flip_map(test: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, float]:
    """HDR-FLIP error map (H, W) in [0, 1] and its mean."""
    x, r = validate_pair(test, ref)
    return _flip(x, r)


# A reference whose peak luminance lies below this is scaled up, with the test image, before
# HDR-FLIP (8x above where flip-evaluator's automatic exposure range breaks).
DIM_PEAK = 1e-6


def _flip(x: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, float]:
    import flip_evaluator

    xf = np.ascontiguousarray(np.maximum(x, 0.0), dtype=np.float32)
    rf = np.ascontiguousarray(np.maximum(r, 0.0), dtype=np.float32)
    params: dict[str, float] = {}
    lum = 0.2126 * rf[..., 0] + 0.7152 * rf[..., 1] + 0.0722 * rf[..., 2]
    peak = float(lum.max())
    # flip-evaluator derives its exposure range from the reference's peak and median
    # luminance, the median clamped to float epsilon (1.2e-7), and exits the process when the
    # range comes out empty: below that peak it does.
    if not peak > 0.0:  # all black: pin the range
        params = {"startExposure": 0.0, "stopExposure": 0.0}
    elif peak < DIM_PEAK:
        # HDR-FLIP exposes both images alike over a range that follows the reference, so
        # scaling both by one factor leaves it unchanged: bring the peak to 1 (in float64, the
        # test image held to float32's range: 1e40 times a denormal peak is error 1 anyway)
        big = np.finfo(np.float32).max
        xf = np.minimum(xf.astype(np.float64) / peak, big).astype(np.float32)
        rf = np.minimum(rf.astype(np.float64) / peak, big).astype(np.float32)
    err_map, mean, _ = flip_evaluator.evaluate(
        rf, xf, "HDR", inputsRGB=True, applyMagma=False, computeMeanError=True, parameters=params
    )
    return np.asarray(err_map, dtype=np.float64).reshape(x.shape[:2]), float(mean)


# --- tonemapping / SSIM -----------------------------------------------------------------------


def tonemap_srgb(img: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """Linear HDR -> display sRGB in [0, 1]: scale by 2^exposure, clip, sRGB curve."""
    a = np.clip(np.asarray(img, dtype=np.float64) * (2.0**exposure), 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1.0 / 2.4) - 0.055)


# Wang et al. 2004: a Gaussian window of sigma 1.5, which scikit-image truncates at 3.5 sigma.
SSIM_SIGMA = 1.5
SSIM_WINDOW = 2 * int(3.5 * SSIM_SIGMA + 0.5) + 1


def _ssim(x: np.ndarray, r: np.ndarray) -> float:
    from skimage.metrics import structural_similarity

    if min(x.shape[0], x.shape[1]) < SSIM_WINDOW:
        return math.nan  # the standard window does not fit
    return float(
        structural_similarity(
            tonemap_srgb(x),
            tonemap_srgb(r),
            gaussian_weights=True,
            sigma=SSIM_SIGMA,
            use_sample_covariance=False,
            channel_axis=2,
            data_range=1.0,
        )
    )


# --- scalar metrics ---------------------------------------------------------------------------


def trimmed_mean(per_pixel: np.ndarray, fraction: float = TRIM_FRACTION) -> float:
    """Mean of ``per_pixel`` after dropping its floor(fraction * size) largest values."""
    v = np.ravel(per_pixel)
    k = int(math.floor(fraction * v.size))
    if k <= 0:
        return float(v.mean())
    kept = np.partition(v, v.size - k)[: v.size - k]
    return float(kept.mean())


def compare_images(test: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """All metrics of ``test`` against ``ref`` (linear HDR, (H, W, 3)).

    Raises ValueError on a shape mismatch or non-finite input. Keys: see ``METRICS``.
    """
    x, r = validate_pair(test, ref)
    d = x - r
    sq = d * d
    mse = float(sq.mean())
    rel = sq / (r * r + EPS)
    rel_px = rel.mean(axis=2)
    ad = np.abs(d)
    _, flip_mean = _flip(x, r)
    return {
        "mse": mse,
        "rmse": math.sqrt(mse),
        "relmse": float(rel.mean()),
        "relmse_trimmed": trimmed_mean(rel_px),
        "mape": float((ad / (np.abs(r) + EPS)).mean()),
        "smape": float((ad / (np.abs(x) + np.abs(r) + EPS)).mean()),
        "flip": flip_mean,
        "one_minus_ssim": 1.0 - _ssim(x, r),
    }


# What reference_error returns, and what the workflow's ref.json records of its reference.
REFERENCE_ERROR_KEYS = ("halves_relmse", "ref_relmse", "halves_mse", "ref_mse")


def reference_error(
    half_a: np.ndarray, half_b: np.ndarray, names: tuple[str, str] = ("half 0", "half 1")
) -> dict[str, float]:
    """Estimate the error of a reference that is the average of two independent halves.

    With independent, equally converged halves A and B (variance s^2 per pixel each) the
    reference R = (A + B) / 2 has variance s^2 / 2, while E[(A - B)^2] = 2 s^2. So
    E[(R - truth)^2] = E[(A - B)^2] / 4: the reference's MSE (and, treating the
    denominators r^2 + eps as fixed, its relMSE) is a quarter of the half-vs-half value.
    Returned: ``halves_relmse`` (A vs B, denominators from R), ``ref_relmse`` (= / 4),
    and the same for MSE.
    """
    a, b = validate_pair(half_a, half_b, names)
    r = 0.5 * (a + b)
    sq = (a - b) ** 2
    halves_rel = float((sq / (r * r + EPS)).mean())
    halves_mse = float(sq.mean())
    return {
        "halves_relmse": halves_rel,
        "ref_relmse": halves_rel / 4.0,
        "halves_mse": halves_mse,
        "ref_mse": halves_mse / 4.0,
    }


# --- errors with the reference's own error removed ---------------------------------------------
#
# The reference R = (A + B) / 2 averages two independent, unbiased halves. For a test image x
# (independent of them) and the unknown truth T, per value
#
#     (x - A)(x - B) = (x - T)^2 - (x - T)(a + b) + a b,     a = A - T, b = B - T,
#
# whose expectation over the halves is (x - T)^2: the product of the errors against the two
# halves is an unbiased estimate of the squared error against the truth. It equals
# (x - R)^2 - (A - B)^2 / 4, the measured squared error less the reference's own (estimated
# from the halves), so the corrected MSE is the measured MSE less ``ref_mse``. relMSE keeps
# the reference in its denominator, r^2 + eps with r = R: corrected to first order in the
# reference's relative noise. Its uncertainty, given x, comes from the halves alone:
#
#     Var[(x - A)(x - B)] = (x - T)^2 (vA + vB) + vA vB,
#
# the first term this image's own (it falls with the image's error), the second shared by
# every image compared with this reference (the noise of the reference-error estimate).
# vA, vB are the variances of the halves' means per value: measured from each half's passes
# when given, else estimated from the halves' difference alone, (A - B)^2 for vA + vB and
# (A - B)^4 / 12 for vA vB (exact in expectation for Gaussian noise of equal variance; heavier
# tails overstate it). Pixels are independent (box filter, independent samples); the three
# channels of a pixel are not, and are combined as if fully correlated (an upper bound).
#
# Only squared errors decompose so: MAPE, SMAPE, HDR-FLIP and SSIM are shown as measured.

# Metrics whose reference error is removed, and how each is corrected.
CORRECTABLE: tuple[str, ...] = ("mse", "rmse", "relmse", "relmse_trimmed")
# Standard uncertainties in the interval a verdict or a flag uses (about 95 %).
COVERAGE = 2.0
# A corrected error is determined when that interval lies within this fraction of it (the
# workflow's determined_fraction, configs/schema.yaml).
DETERMINED_FRACTION = 0.2


def variance_terms(
    a: np.ndarray, b: np.ndarray, var_a: np.ndarray | None, var_b: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """(vA + vB, vA vB) per value: from the halves' own variances when both are given, else
    estimated from their difference."""
    if var_a is None or var_b is None:
        d2 = (a - b) ** 2
        return d2, d2 * d2 / 12.0
    va, vb = (as_rgb(v, "variance") for v in (var_a, var_b))
    for v in (va, vb):
        if v.shape != a.shape:
            raise ValueError(f"variance image is {v.shape[1]}x{v.shape[0]}, the halves "
                             f"{a.shape[1]}x{a.shape[0]}")  # fmt: skip
        if not np.all(np.isfinite(v)) or (v < 0).any():
            raise ValueError("variance image has negative or non-finite values")
    return va + vb, va * vb


def mean_and_uncertainty(
    product: np.ndarray, own: np.ndarray, shared: np.ndarray, kept: np.ndarray | None = None
) -> tuple[float, float, float]:
    """Mean of ``product`` over pixels and channels, and the standard uncertainties of that
    mean from per-value variances ``own`` and ``shared`` (a pixel's channels taken as fully
    correlated: the standard deviation of their mean is at most the mean of theirs).
    ``kept``: a boolean (H, W) mask of the pixels averaged (all by default)."""
    if kept is not None:
        product, own, shared = product[kept], own[kept], shared[kept]
    n = product.shape[0] * (product.shape[1] if product.ndim == 3 else 1)
    sd_own = np.sqrt(own).mean(axis=-1)
    sd_shared = np.sqrt(shared).mean(axis=-1)
    return (
        float(product.mean()),
        float(np.sqrt((sd_own**2).sum())) / n,
        float(np.sqrt((sd_shared**2).sum())) / n,
    )


def corrected_errors(
    test: np.ndarray,
    half_a: np.ndarray,
    half_b: np.ndarray,
    var_a: np.ndarray | None = None,
    var_b: np.ndarray | None = None,
) -> dict[str, float]:
    """The MSE-type errors of ``test`` with the reference's own error removed, and their
    uncertainties; the reference is the mean of the independent halves ``half_a``, ``half_b``
    (``var_a``, ``var_b``: the variances of their means per value, when known).

    For each metric m of CORRECTABLE: ``m_corrected`` (an estimate of m against the truth;
    it may come out negative when the image is closer to the truth than the reference can
    tell), ``m_u`` (its standard uncertainty from the reference's noise, given the image) and
    ``m_u_shared`` (the part of it shared by every image compared with this reference; the
    rest is this image's own, independent of the shared part). relMSE (trimmed) drops the
    pixels the measured one drops. RMSE is the square root of the corrected MSE (0 when that
    is negative), its uncertainties those of the MSE carried through the square root.
    """
    x, a = validate_pair(test, half_a, ("test image", "reference half 0"))
    _, b = validate_pair(test, half_b, ("test image", "reference half 1"))
    v_sum, v_prod = variance_terms(a, b, var_a, var_b)
    r = 0.5 * (a + b)
    product = (x - a) * (x - b)
    own = np.maximum(product, 0.0) * v_sum  # (x - T)^2 estimated by the product itself
    w = 1.0 / (r * r + EPS)
    out: dict[str, float] = {}

    def put(name: str, value: float, u: float, shared: float) -> None:
        out[f"{name}_corrected"] = value
        out[f"{name}_u"] = math.hypot(u, shared)
        out[f"{name}_u_shared"] = shared

    put("mse", *mean_and_uncertainty(product, own, v_prod))
    mse, mse_u, mse_shared = out["mse_corrected"], out["mse_u"], out["mse_u_shared"]
    out["rmse_corrected"], out["rmse_u"] = _sqrt_interval(mse, mse_u)
    out["rmse_u_shared"] = _sqrt_interval(mse, mse_shared)[1]
    relative = (product * w, own * w * w, v_prod * w * w)
    put("relmse", *mean_and_uncertainty(*relative))
    measured_px = ((x - r) ** 2 * w).mean(axis=2)
    put("relmse_trimmed", *mean_and_uncertainty(*relative, kept=_untrimmed(measured_px)))
    return out


def _sqrt_interval(value: float, u: float) -> tuple[float, float]:
    """sqrt of a corrected MSE (0 below 0), and the half-width of the interval value +- u
    carried through sqrt: the uncertainty of the RMSE."""
    hi, lo = math.sqrt(max(value + u, 0.0)), math.sqrt(max(value - u, 0.0))
    return math.sqrt(max(value, 0.0)), 0.5 * (hi - lo)


def _untrimmed(per_pixel: np.ndarray, fraction: float = TRIM_FRACTION) -> np.ndarray:
    """Mask of the pixels trimmed_mean keeps: all but the floor(fraction * size) largest."""
    v = np.ravel(per_pixel)
    k = int(math.floor(fraction * v.size))
    kept = np.ones(v.size, dtype=bool)
    if k > 0:
        kept[np.argpartition(v, v.size - k)[v.size - k :]] = False
    return kept.reshape(per_pixel.shape)


def determined(value: float, u: float, fraction: float) -> bool:
    """Whether a corrected error is known to within ``fraction`` of itself: positive, and its
    interval of COVERAGE standard uncertainties no wider than that on either side."""
    return bool(value > 0 and COVERAGE * u <= fraction * value)


# Benchmarks' rule of thumb: a measurement is limited by its reference unless the reference's
# own relMSE is this many times below it (the workflow removes the reference's error instead).
REF_QUALITY_FACTOR = 10.0


def reference_ok(relmse: float, ref_relmse: float, factor: float = REF_QUALITY_FACTOR) -> bool:
    """Whether a measured relMSE is ``factor`` times the reference's own or more."""
    return bool(relmse >= factor * ref_relmse)


def average_references(
    a: np.ndarray, b: np.ndarray, names: tuple[str, str] = ("half 0", "half 1")
) -> tuple[np.ndarray, dict[str, float]]:
    """The mean of two independent references and its own error (reference_error)."""
    err = reference_error(a, b, names)
    return 0.5 * (np.asarray(a, np.float64) + np.asarray(b, np.float64)), err
