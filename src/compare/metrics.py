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


# A comparison is limited by its reference unless the reference's own relMSE is this many
# times below the image's (the workflow's ref_quality_factor, configs/schema.yaml).
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
