"""Images for the report: tonemapped PNGs, false-colour error maps, compact linear data.

The interactive viewer needs linear HDR data for its exposure control; it gets RGBE (Ward's
shared-exponent format, 4 bytes per pixel, ~1% relative precision) encoded as base64 and
decodes it in JavaScript. Static grids use tonemapped PNGs embedded as data URIs.
"""

from __future__ import annotations

import base64
import io
import math

import numpy as np

from ..metrics import tonemap_srgb


def downsample(img: np.ndarray, max_size: int) -> np.ndarray:
    """Box-filter ``img`` by an integer factor so that neither side exceeds ``max_size``."""
    h, w = img.shape[:2]
    f = max(1, math.ceil(max(h, w) / max_size))
    if f == 1:
        return img
    hh, ww = h // f, w // f
    a = img[: hh * f, : ww * f].astype(np.float64)
    return a.reshape(hh, f, ww, f, *img.shape[2:]).mean(axis=(1, 3))


def encode_rgbe(img: np.ndarray) -> bytes:
    """Linear RGB (H, W, 3) -> RGBE bytes (H*W*4), row-major, top row first."""
    a = np.maximum(np.asarray(img, dtype=np.float64), 0.0)
    m = a.max(axis=2)
    out = np.zeros(a.shape[:2] + (4,), dtype=np.uint8)
    ok = m > 1e-32
    mant, exp = np.frexp(m[ok])  # m = mant * 2^exp, mant in [0.5, 1)
    scale = mant * 256.0 / m[ok]
    out[ok, :3] = np.clip(np.floor(a[ok] * scale[:, None]), 0, 255).astype(np.uint8)
    out[ok, 3] = np.clip(exp + 128, 0, 255).astype(np.uint8)
    return out.tobytes()


def decode_rgbe(data: bytes, h: int, w: int) -> np.ndarray:
    """Inverse of :func:`encode_rgbe` (as the viewer's JavaScript does it)."""
    b = np.frombuffer(data, dtype=np.uint8).reshape(h, w, 4).astype(np.float64)
    e = b[..., 3]
    f = np.where(e > 0, np.ldexp(1.0, (e - 136).astype(int)), 0.0)
    return (b[..., :3] + 0.5) * f[..., None] * (e[..., None] > 0)


def b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def auto_exposure(ref: np.ndarray) -> float:
    """Exposure (EV) that maps the reference's log-average luminance to mid grey 0.18."""
    lum = 0.2126 * ref[..., 0] + 0.7152 * ref[..., 1] + 0.0722 * ref[..., 2]
    lum = lum[lum > 0]
    if lum.size == 0:
        return 0.0
    key = float(np.exp(np.mean(np.log(lum + 1e-6))))
    return float(np.clip(round(math.log2(0.18 / key) * 2) / 2, -12, 12)) if key > 0 else 0.0


def png_bytes(rgb01: np.ndarray) -> bytes:
    """(H, W, 3) display values in [0, 1] -> PNG bytes."""
    from matplotlib.image import imsave

    buf = io.BytesIO()
    imsave(buf, np.clip(rgb01, 0, 1), format="png")
    return buf.getvalue()


def data_uri_png(data: bytes) -> str:
    return "data:image/png;base64," + b64(data)


def tonemapped_png(img: np.ndarray, exposure: float) -> bytes:
    return png_bytes(tonemap_srgb(img, exposure))


def false_colour(values: np.ndarray, lo: float, hi: float, cmap: str = "inferno") -> np.ndarray:
    """Map values to colours on a log10 scale between ``lo`` and ``hi`` (both > 0)."""
    from matplotlib import colormaps

    v = np.log10(np.maximum(values, lo))
    t = np.clip((v - math.log10(lo)) / (math.log10(hi) - math.log10(lo)), 0, 1)
    return colormaps[cmap](t)[..., :3]


def error_range(maps: list[np.ndarray]) -> tuple[float, float]:
    """A shared log-scale range for several per-pixel error maps (robust percentiles)."""
    vals = np.concatenate([m.ravel() for m in maps]) if maps else np.array([1.0])
    vals = vals[vals > 0]
    if vals.size == 0:
        return 1e-4, 1.0
    hi = float(np.percentile(vals, 99.5))
    lo = max(float(np.percentile(vals, 5)), hi * 1e-4)
    if not hi > lo:
        hi = lo * 10
    return lo, hi


def colorbar_png(lo: float, hi: float, cmap: str = "inferno", width: int = 256) -> bytes:
    t = np.logspace(math.log10(lo), math.log10(hi), width)[None, :].repeat(12, axis=0)
    return png_bytes(false_colour(t, lo, hi, cmap))
