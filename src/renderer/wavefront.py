"""The one driver of the native kernels: it runs a kernel's passes, the iteration protocol of
``cpp/passes.h``, with Embree tracing every batch of rays in between.

An iteration of a method is a short sequence of kernels; each is wrapped in a ``Wavefront``
and run with ``Wavefront.run(iteration)``:

    kernel.begin(iteration)
    on each lane (several lanes: each on a thread of its own):
        resolve the shadow rays begin queued
        while n := lane.next_rays(rays):
            if lane.shade(*trace(rays, n)): resolve the shadow rays
    kernel.end()

A kernel of several lanes (pt) traces each lane's batches on the lane's own thread; a kernel of
one lane (every other) runs its passes on all the method's threads and has its batches split
across them. Every lane has ended when ``run`` returns or raises: if one fails, or a signal
arrives (Ctrl-C, SIGTERM), the others stop at their next pass, and a pass that is tracking
through dense media stops at once (``_core.request_interrupt``).
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Any

from . import _core
from .tracer import EmbreeTracer, RayBatch


class Wavefront:
    """One native kernel with its ray buffers, run pass by pass (module docstring)."""

    def __init__(self, kernel: Any, tracer: EmbreeTracer) -> None:
        self.kernel = kernel
        self.lanes = [kernel.lane(i) for i in range(kernel.lanes)]
        # Several lanes each trace on their own thread: the tracer must not split their batches.
        self.tracer = tracer if len(self.lanes) == 1 else tracer.single_threaded()
        self.rays = [RayBatch(lane.capacity) for lane in self.lanes]
        self.shadows = [RayBatch(lane.shadow_slots) for lane in self.lanes]
        self._pool = ThreadPoolExecutor(len(self.lanes) - 1) if len(self.lanes) > 1 else None

    def run(self, iteration: int) -> None:
        """One iteration of the kernel: begin, every lane's passes, end."""
        self.kernel.begin(iteration)
        if self._pool is None:
            self.trace_lane(0, threading.Event())
        else:
            self._trace_lanes()
        self.kernel.end()

    def trace_lane(self, index: int, stop: threading.Event) -> None:
        """Lane `index`'s passes until it has no ray left, or until `stop` is set. A lane that
        fails sets `stop`: the others end at their next pass instead of finishing first."""
        lane, rays, tracer = self.lanes[index], self.rays[index], self.tracer
        try:
            self.resolve_shadow_rays(index)
            while not stop.is_set() and (active := lane.next_rays(*rays.buffers)):
                if lane.shade(*tracer.intersect(rays, active)):
                    self.resolve_shadow_rays(index)
        except BaseException:
            stop.set()
            raise

    def resolve_shadow_rays(self, index: int) -> None:
        """Trace lane `index`'s queued shadow rays segment by segment until each is blocked or
        arrives. Without null boundaries in the scene a ray has one segment, and whether
        anything blocks it is all it needs: Embree's occlusion query answers that for less."""
        lane = self.lanes[index]
        slots = lane.shadow_slots
        if slots > len(self.shadows[index].tmax):
            self.shadows[index] = RayBatch(max(slots, 2 * len(self.shadows[index].tmax)))
        shadows = self.shadows[index]
        any_hit = lane.shadows_any_hit
        while queued := lane.shadow_rays(*shadows.buffers):
            if any_hit:
                lane.resolve_occlusion(self.tracer.occluded(shadows, queued))
            else:
                tfar, prim, _, _ = self.tracer.intersect(shadows, queued)
                lane.resolve_shadows(tfar, prim)

    def _trace_lanes(self) -> None:
        """Every lane at once: the first on this thread, the others on the pool's. Raises this
        thread's error (a signal's exception, say), or else the first lane's that is not an
        interrupt, once every lane has ended."""
        stop = threading.Event()
        others = [self._pool.submit(self.trace_lane, i, stop) for i in range(1, len(self.lanes))]
        error, cut_short = None, False
        try:
            self.trace_lane(0, stop)
        except BaseException as e:
            error = e
        while True:  # until every lane has ended, whatever arrives meanwhile
            if error is not None and not cut_short:
                stop.set()
                _core.request_interrupt()  # a pass through dense media ends now, too
                cut_short = True
            try:
                # In short waits: a signal that arrives just before this thread blocks is
                # handled within one of them, not once the other lanes end (seconds later).
                if not wait(others, timeout=0.05).not_done:
                    break
            except BaseException as e:  # a signal's handler raised while this thread waited
                error = error or e
        failures = [f.exception() for f in others if f.exception() is not None]
        if cut_short or failures:
            _core.clear_interrupt()  # every lane has ended: the flag stops nothing more
        if error is not None:
            raise error
        if failures:
            real = [e for e in failures if not isinstance(e, KeyboardInterrupt)]
            raise (real or failures)[0]
