"""Ray casting through embreex: batched, float32, split across threads.

embreex releases the GIL inside ``EmbreeScene.run``, so halves of a batch
traced from two Python threads run in parallel. It has no ``tnear``: the
kernels offset ray origins off surfaces themselves.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

# Below this many rays a batch is not worth splitting across threads.
_MIN_RAYS_PER_THREAD = 4096


class RayBatch:
    """Preallocated float32 buffers the native kernels write rays into."""

    def __init__(self, capacity: int) -> None:
        self.origins = np.zeros((capacity, 3), np.float32)
        self.directions = np.zeros((capacity, 3), np.float32)
        self.tmax = np.zeros(capacity, np.float32)

    @property
    def buffers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.origins, self.directions, self.tmax


class _RayCounter:
    """Rays traced, counted from any thread."""

    def __init__(self) -> None:
        self.rays = 0
        self._lock = threading.Lock()

    def add(self, n: int) -> None:
        with self._lock:
            self.rays += n


class EmbreeTracer:
    """All scene triangles in one Embree mesh; primitive ids index the native triangle list.
    With threads > 1 a large batch is split across threads; with threads == 1 every batch is
    traced on the calling thread, which may be one of several tracing at once (pt's lanes)."""

    def __init__(self, triangles: np.ndarray, threads: int) -> None:
        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self._scene, np.ascontiguousarray(triangles, dtype=np.float32))
        self._counter = _RayCounter()
        self._setup(threads)

    def _setup(self, threads: int) -> None:
        self.threads = max(1, threads)
        # The calling thread traces a chunk itself: the pool holds the other threads.
        self._pool = ThreadPoolExecutor(self.threads - 1) if self.threads > 1 else None

    def single_threaded(self) -> EmbreeTracer:
        """The same scene traced on the calling thread only, its rays counted with this
        tracer's: for callers that trace from several threads at once (pt's lanes)."""
        view = object.__new__(EmbreeTracer)
        view._scene, view._counter = self._scene, self._counter
        view._setup(1)
        return view

    @property
    def rays_traced(self) -> int:
        return self._counter.rays

    def _closest(self, batch: RayBatch, lo: int, hi: int) -> dict:
        return self._scene.run(
            batch.origins[lo:hi], batch.directions[lo:hi], batch.tmax[lo:hi], output=1
        )

    def _any(self, batch: RayBatch, lo: int, hi: int) -> np.ndarray:
        return self._scene.run(
            batch.origins[lo:hi], batch.directions[lo:hi], batch.tmax[lo:hi], query="OCCLUDED"
        )

    def _split(self, run, batch: RayBatch, n: int) -> list:
        """run(batch, lo, hi) over the first n rays, in one chunk per thread when worth it."""
        self._counter.add(n)
        chunks = self.threads if self._pool and n >= 2 * _MIN_RAYS_PER_THREAD else 1
        if chunks == 1:
            return [run(batch, 0, n)]
        bounds = np.linspace(0, n, chunks + 1).astype(int)
        rest = [self._pool.submit(run, batch, bounds[i], bounds[i + 1]) for i in range(1, chunks)]
        return [run(batch, bounds[0], bounds[1])] + [f.result() for f in rest]

    def intersect(
        self, batch: RayBatch, n: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Closest hits of the first n rays: (tfar, primitive id or -1, u, v)."""
        parts = self._split(self._closest, batch, n)
        if len(parts) == 1:
            p = parts[0]
            return p["tfar"], p["primID"], p["u"], p["v"]
        return tuple(np.concatenate([p[k] for p in parts]) for k in ("tfar", "primID", "u", "v"))

    def occluded(self, batch: RayBatch, n: int) -> np.ndarray:
        """Whether anything blocks each of the first n rays within its tmax: an int32 per
        ray, -1 where nothing does. Embree stops at the first hit it finds."""
        parts = self._split(self._any, batch, n)
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def close(self) -> None:
        if self._pool:
            self._pool.shutdown()
