"""Ground truth: Mitsuba 3 renders of a scene (box filter, same triangles) by ``volpath``;
where a medium's extinction differs between channels, one grey render per channel (see
``grey_channel_scenes``).

Large sample counts are split into passes of at most 256 spp, each with its own seed, and
averaged in float64: this bounds memory in the LLVM variant (one lane per sample). Nothing is
replaced silently: a non-finite pixel value is an error.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from renderer.errors import PgiError
from renderer.mitsuba_env import import_mitsuba, set_threads
from renderer.scene.mitsuba_export import (
    grey_channel_scenes,
    has_chromatic_extinction,
    load_mitsuba_scene,
)
from renderer.scene.model import Scene

MAX_SPP_PER_PASS = 256
MAX_SAMPLES_PER_PASS = 1 << 24  # 256 spp at 256x256


def derive_seed(tag: str, seed: int, index: int) -> int:
    """A 32-bit Mitsuba seed for pass/iteration ``index`` of a run with ``seed``. ``tag`` keeps
    streams apart (a reference and a timed Mitsuba run with the same seed are independent)."""
    digest = hashlib.blake2b(f"{tag}/{seed}/{index}".encode(), digest_size=4).digest()
    return int.from_bytes(digest, "little")


def spp_per_pass(scene: Scene, spp: int) -> int:
    pixels = scene.film.width * scene.film.height
    return max(1, min(spp, MAX_SPP_PER_PASS, MAX_SAMPLES_PER_PASS // pixels))


def check_reference_fits_in_memory(scene: Scene, spp: int) -> None:
    """Refuse a reference whose passes would take over half the machine's memory (Mitsuba's
    LLVM variant traces a pass's samples as one wavefront: 16384x16384 crashed it)."""
    from renderer.methods.params import MITSUBA_SAMPLE_BYTES, over_half_memory

    pixels = scene.film.width * scene.film.height
    per_pass = spp_per_pass(scene, spp)
    if too_much := over_half_memory(pixels * (per_pass * MITSUBA_SAMPLE_BYTES + 24)):  # + sum
        raise PgiError(
            f"{scene.path}: a reference of {scene.film.width}x{scene.film.height} pixels at "
            f"{per_pass} spp a pass needs {too_much}: lower the film's size"
        )


def load_reference_scenes(scene: Scene) -> list[Any]:
    """The Mitsuba scenes a reference of ``scene`` renders (with volpath): ``scene`` itself, or
    where a medium's extinction differs between channels, one grey scene per channel."""
    chromatic = has_chromatic_extinction(scene)
    return [load_mitsuba_scene(s) for s in (grey_channel_scenes(scene) if chromatic else [scene])]


def mitsuba_pass(mi: Any, mscenes: list[Any], spp: int, seed: int) -> np.ndarray:
    """One Mitsuba image at ``spp``: of the one scene, or channel c from scene c of three."""
    images = [np.array(mi.render(m, spp=spp, seed=seed), dtype=np.float64) for m in mscenes]
    if len(images) == 1:
        return images[0]
    return np.stack([images[c][..., c] for c in range(3)], axis=-1)


def render_reference(
    scene: Scene,
    spp: int,
    seed: int = 0,
    threads: int | None = None,
    on_pass: Callable[[float, int], None] | None = None,
) -> tuple[np.ndarray, dict]:
    """Render ``scene`` with Mitsuba at ``spp`` samples per pixel.

    Returns the (H, W, 3) float64 image and an info dict (variant, passes, spp per pass,
    load and render seconds, threads). ``on_pass(seconds, spp_done)`` follows the passes.
    """
    if spp < 1:
        raise PgiError(f"reference: spp must be >= 1, got {spp}")
    check_reference_fits_in_memory(scene, spp)  # before Mitsuba's start-up
    mi = import_mitsuba()
    if threads is not None:
        set_threads(threads)
    t0 = time.perf_counter()
    chromatic = has_chromatic_extinction(scene)
    mscenes = [
        load_mitsuba_scene(s) for s in (grey_channel_scenes(scene) if chromatic else [scene])
    ]
    t1 = time.perf_counter()
    per_pass = spp_per_pass(scene, spp)
    total = np.zeros((scene.film.height, scene.film.width, 3))
    done = 0
    for k in range((spp + per_pass - 1) // per_pass):
        n = min(per_pass, spp - done)
        total += n * mitsuba_pass(mi, mscenes, n, derive_seed("reference", seed, k))
        done += n
        if on_pass:
            on_pass(time.perf_counter() - t1, done)
    image = total / spp
    bad = int(np.count_nonzero(~np.isfinite(image)))
    if bad:
        raise PgiError(f"{scene.path}: Mitsuba reference has {bad} non-finite pixel values")
    import drjit as dr

    info = {
        "renderer": f"mitsuba {mi.__version__} volpath"
        + (" (one grey render per channel)" if len(mscenes) > 1 else ""),
        "variant": mi.variant(),
        "passes": k + 1,
        "spp_per_pass": per_pass,
        "load_seconds": t1 - t0,
        "render_seconds": time.perf_counter() - t1,
        "threads": dr.thread_count(),
        "nonfinite": 0,
    }
    return image, info
