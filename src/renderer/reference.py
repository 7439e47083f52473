"""Ground truth: Mitsuba 3 renders of a scene (box filter, same triangles) by ``volpath``;
where a medium's extinction differs between channels, one grey render per channel (see
``grey_channel_scenes``).

A reference is rendered in passes, each an independent estimate with a seed of its own, and
kept as an :class:`Accumulation`: the sample-weighted mean of the passes and their spread per
value, from which the variance of the mean follows (the workflow's uncertainties use it). An
accumulation can be stored and extended later: more samples add passes, and none already
rendered is thrown away. Passes hold at most 256 spp, which bounds memory in the LLVM variant
(one lane per sample), and are averaged in float64. Nothing is replaced silently: a
non-finite pixel value is an error.

Where the passes come from is a *source* (:data:`SOURCES`): Mitsuba, or pgi's own path
tracer (``pgi``: for scenes where Mitsuba's image cannot be trusted, and for the short check
that finds them, :func:`render_check`). Both give passes of their own seeds, so the
accumulation, the store and the reference's own error work alike for either.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

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
# Passes a workflow reference is split into at least: the spread between passes estimates
# the variance of their mean, 7 degrees of freedom per value with 8.
MIN_PASSES_FOR_VARIANCE = 8
# Passes a check (render_check) aims at.
CHECK_PASSES = 32


def derive_seed(tag: str, seed: int, index: int) -> int:
    """A 32-bit Mitsuba seed for pass/iteration ``index`` of a run with ``seed``. ``tag`` keeps
    streams apart (a reference and a timed Mitsuba run with the same seed are independent)."""
    digest = hashlib.blake2b(f"{tag}/{seed}/{index}".encode(), digest_size=4).digest()
    return int.from_bytes(digest, "little")


def spp_per_pass(scene: Scene, spp: int) -> int:
    """The largest pass of a reference of ``spp`` samples per pixel."""
    pixels = scene.film.width * scene.film.height
    return max(1, min(spp, MAX_SPP_PER_PASS, MAX_SAMPLES_PER_PASS // pixels))


def pass_sizes(scene: Scene, spp: int, min_passes: int = 1) -> list[int]:
    """``spp`` samples split into passes of near-equal size: as few as the largest pass allows,
    and at least ``min_passes`` (never below one sample a pass)."""
    if spp <= 0:
        return []
    count = max(math.ceil(spp / spp_per_pass(scene, spp)), min(min_passes, spp))
    base, extra = divmod(spp, count)
    return [base + 1] * extra + [base] * (count - extra)


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


# --- sources --------------------------------------------------------------------------------


class ReferenceSource(Protocol):
    """What renders a reference's passes."""

    def identity(self) -> dict[str, Any]:
        """What makes its images differ (renderer, version, variant): part of a store's key,
        and of the sidecar."""

    def render_pass(self, spp: int, seed: int) -> np.ndarray:
        """One independent estimate of the image at ``spp`` samples per pixel: (H, W, 3)."""

    def threads(self) -> int:
        """Threads it renders with."""


class MitsubaSource:
    """Mitsuba 3's volpath (one grey render per channel for chromatic media), box filter,
    independent sampler."""

    def __init__(self, scene: Scene, threads: int | None = None) -> None:
        self.mi = import_mitsuba()
        if threads is not None:
            set_threads(threads)
        self.scenes = load_reference_scenes(scene)

    def identity(self) -> dict[str, Any]:
        return {
            "renderer": f"mitsuba {self.mi.__version__} volpath"
            + (" (one grey render per channel)" if len(self.scenes) > 1 else ""),
            "variant": self.mi.variant(),
        }

    def render_pass(self, spp: int, seed: int) -> np.ndarray:
        return mitsuba_pass(self.mi, self.scenes, spp, seed)

    def threads(self) -> int:
        import drjit as dr

        return int(dr.thread_count())


class PgiSource:
    """pgi's unbiased path tracer (``pt``): a pass is a pt render of ``spp`` samples per pixel
    with a seed of its own. Its pixels are independent (a camera path adds to its own pixel
    only), as a reference's variance estimate assumes."""

    method = "pt"

    def __init__(self, scene: Scene, threads: int | None = None) -> None:
        # imported here: Mitsuba references do not depend on the renderer's own methods
        # (`pgi fingerprint`'s reference digest lists the modules `pgi reference` loads)
        from renderer import __version__
        from renderer.methods import get_method
        from renderer.progressive import available_cores

        self.scene = scene
        self.version = __version__
        self.method_class = get_method(self.method)
        self.thread_count = threads or available_cores()

    def identity(self) -> dict[str, Any]:
        return {"renderer": f"pgi {self.version} {self.method}", "variant": "cpu"}

    def render_pass(self, spp: int, seed: int) -> np.ndarray:
        method = self.method_class(
            self.scene, seed=seed, threads=self.thread_count, params={}, spp_budget=spp
        )
        while method.stats()["spp"] < spp:
            method.run_iteration(method.iterations)
        stats = method.stats()
        if stats["nonfinite"]:  # dropped samples would bias the reference
            raise PgiError(f"{self.scene.path}: pt dropped {stats['nonfinite']} non-finite samples")
        return np.asarray(method.image(), dtype=np.float64)

    def threads(self) -> int:
        return self.thread_count


SOURCES: dict[str, Callable[[Scene, int | None], ReferenceSource]] = {
    "mitsuba": MitsubaSource,
    "pgi": PgiSource,
}


# --- accumulation ---------------------------------------------------------------------------


@dataclass
class Accumulation:
    """Passes of one reference image: their sample-weighted mean, the weighted sum of squared
    deviations of the passes from it (``m2``, per value; combined by Chan et al.'s update),
    and what made them (``key``: a store is extended only by passes of the same kind)."""

    mean: np.ndarray
    m2: np.ndarray
    spp: int = 0
    passes: int = 0
    key: dict[str, Any] = field(default_factory=dict)
    # (spp, seconds, first pass of its process) of every pass: the source's speed
    pass_log: list[tuple[int, float, bool]] = field(default_factory=list)

    @classmethod
    def empty(cls, height: int, width: int, key: dict[str, Any] | None = None) -> Accumulation:
        zeros = np.zeros((height, width, 3))
        return cls(zeros, zeros.copy(), key=dict(key or {}))

    def add(self, image: np.ndarray, spp: int, seconds: float, first: bool = False) -> None:
        """One pass of ``spp`` samples per pixel. With per-sample variance s^2 a pass has
        variance s^2 / spp, and E[m2] = (passes - 1) s^2."""
        total = self.spp + spp
        delta = image - self.mean
        self.mean = self.mean + delta * (spp / total)
        self.m2 = self.m2 + delta * delta * (self.spp * spp / total)
        self.spp, self.passes = total, self.passes + 1
        self.pass_log.append((int(spp), float(seconds), bool(first)))

    def variance_of_mean(self) -> np.ndarray | None:
        """The variance of ``mean`` per value, estimated from the spread of the passes (None
        below two passes)."""
        if self.passes < 2:
            return None
        return self.m2 / ((self.passes - 1) * self.spp)

    def seconds_per_spp(self) -> float:
        """Render seconds per sample per pixel, leaving out each process's first pass (it
        compiles the kernels) when there are others."""
        steady = [(s, t) for s, t, first in self.pass_log if not first] or [
            (s, t) for s, t, _ in self.pass_log
        ]
        spp = sum(s for s, _ in steady)
        return sum(t for _, t in steady) / spp if spp else math.nan

    def render_seconds(self) -> float:
        return float(sum(t for _, t, _ in self.pass_log))

    def save(self, path: str | Path) -> None:
        """Write the accumulation atomically (a store a later render extends)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {"spp": self.spp, "passes": self.passes, "key": self.key, "log": self.pass_log}
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}.npz")
        try:
            np.savez(tmp, mean=self.mean, m2=self.m2, meta=np.array(json.dumps(meta)))
            tmp.replace(path)
        finally:
            tmp.unlink(missing_ok=True)

    @classmethod
    def load(cls, path: str | Path, key: dict[str, Any], shape: tuple[int, int]) -> Accumulation:
        """The stored accumulation at ``path`` if it was made with ``key`` for an image of
        ``shape`` (height, width); else an empty one with that key (a store of another
        scene, seed or renderer version is replaced, not extended)."""
        try:
            with np.load(path) as data:
                meta = json.loads(str(data["meta"]))
                stored = cls(
                    data["mean"].astype(np.float64),
                    data["m2"].astype(np.float64),
                    int(meta["spp"]),
                    int(meta["passes"]),
                    meta["key"],
                    [(int(s), float(t), bool(f)) for s, t, f in meta["log"]],
                )
        except (OSError, ValueError, KeyError, TypeError):
            return cls.empty(*shape, key)
        # the renderer's identity is added once it has started: checked by the caller
        made_by = {k: v for k, v in stored.key.items() if k != "identity"}
        same = json.loads(json.dumps(key, default=str)) == made_by
        if not same or stored.mean.shape != (*shape, 3) or stored.passes < 1:
            return cls.empty(*shape, key)
        return stored


def render_reference_passes(
    scene: Scene,
    spp: int,
    seed: int = 0,
    threads: int | None = None,
    on_pass: Callable[[float, int], None] | None = None,
    *,
    min_passes: int = 1,
    store: str | Path | None = None,
    key: dict[str, Any] | None = None,
    source: str = "mitsuba",
) -> tuple[Accumulation, dict[str, Any]]:
    """Render ``scene`` to at least ``spp`` samples per pixel, in passes of their own seeds.

    With ``store`` (a file) the passes already stored with the same ``key`` are taken and
    only the samples still missing are rendered, each new pass saved as it ends (an
    interrupted render keeps them); a store holding ``spp`` or more renders nothing and gives
    all it holds. ``min_passes``: the passes rendered now number at least this many (one
    sample each at most). ``on_pass(seconds, spp_done)`` follows the passes. Returns the
    accumulation and an info dict (renderer, variant, passes, load and render seconds,
    threads; spp taken from the store).
    """
    if spp < 1:
        raise PgiError(f"reference: spp must be >= 1, got {spp}")
    if source not in SOURCES:
        raise PgiError(f"reference: unknown source {source!r}; known: {', '.join(SOURCES)}")
    check_reference_fits_in_memory(scene, spp)  # before the renderer's start-up
    shape = (scene.film.height, scene.film.width)
    full_key = {"source": source, "seed": int(seed), **(key or {})}
    acc = Accumulation.empty(*shape, full_key)
    if store is not None and Path(store).is_file():
        acc = Accumulation.load(store, full_key, shape)
    resumed = acc.spp
    sizes = pass_sizes(scene, spp - acc.spp, min_passes)
    t0 = time.perf_counter()
    renderer: ReferenceSource | None = None
    identity = acc.key.get("identity", {})
    if sizes:  # start the renderer only when there is something to render
        renderer = SOURCES[source](scene, threads)
        identity = renderer.identity()
        if acc.passes and acc.key.get("identity") != identity:  # another version or variant
            acc = Accumulation.empty(*shape, full_key)
            resumed, sizes = 0, pass_sizes(scene, spp, min_passes)
        acc.key["identity"] = identity
    t1 = time.perf_counter()
    for i, n in enumerate(sizes):
        start = time.perf_counter()
        image = renderer.render_pass(n, derive_seed("reference", seed, acc.passes))
        bad = int(np.count_nonzero(~np.isfinite(image)))
        if bad:
            raise PgiError(f"{scene.path}: reference has {bad} non-finite pixel values")
        acc.add(image, n, time.perf_counter() - start, first=i == 0)
        if store is not None:
            acc.save(store)
        if on_pass:
            on_pass(time.perf_counter() - t1, acc.spp - resumed)
    info = {
        **identity,
        "source": source,
        "passes": acc.passes,
        "spp_per_pass": max((s for s, _, _ in acc.pass_log), default=0),
        "spp_resumed": resumed,
        "load_seconds": t1 - t0,
        "render_seconds": time.perf_counter() - t1,
        "total_render_seconds": acc.render_seconds(),
        "seconds_per_spp": acc.seconds_per_spp(),
        "threads": renderer.threads() if renderer else threads,
        "nonfinite": 0,
    }
    return acc, info


def render_check(
    scene: Scene, seconds: float, seed: int = 0, threads: int | None = None
) -> tuple[Accumulation, dict[str, Any]]:
    """A short render by the ``pgi`` source to check a reference against: passes for about
    ``seconds`` of render time and at least MIN_PASSES_FOR_VARIANCE of them (their spread
    gives the check's variance), seeded apart from any reference's passes. Passes start at
    1 spp and double while one takes under 1/CHECK_PASSES of ``seconds``: about that many
    passes give the check's variance its degrees of freedom (a t-score from a few is worth
    far less), and passes not much smaller keep the threads busy (a pass lasts as long as
    its longest path: long in dense media)."""
    source = PgiSource(scene, threads)
    acc = Accumulation.empty(scene.film.height, scene.film.width, {"source": "pgi"})
    spp, start = 1, time.perf_counter()
    while acc.passes < MIN_PASSES_FOR_VARIANCE or time.perf_counter() - start < seconds:
        t = time.perf_counter()
        image = source.render_pass(spp, derive_seed("check", seed, acc.passes))
        took = time.perf_counter() - t
        acc.add(image, spp, took, first=acc.passes == 0)
        if took < seconds / CHECK_PASSES and spp < MAX_SPP_PER_PASS:
            spp *= 2
    info = {
        **source.identity(),
        "source": "pgi",
        "spp": acc.spp,
        "passes": acc.passes,
        "render_seconds": acc.render_seconds(),
        "seed": seed,
    }
    return acc, info


def render_reference(
    scene: Scene,
    spp: int,
    seed: int = 0,
    threads: int | None = None,
    on_pass: Callable[[float, int], None] | None = None,
) -> tuple[np.ndarray, dict]:
    """Render ``scene`` with Mitsuba at ``spp`` samples per pixel, in as few passes as memory
    allows. Returns the (H, W, 3) float64 image and an info dict (renderer, variant, passes,
    spp per pass, load and render seconds, threads)."""
    acc, info = render_reference_passes(scene, spp, seed, threads, on_pass)
    return acc.mean, info
