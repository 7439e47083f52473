"""The timed, progressive render loop shared by every method.

The clock counts only what a method does to produce its image (iterations,
including any photon or light-path generation inside them); scene loading
and BVH builds happen in the method's constructor and are reported
separately, and writing snapshots pauses the clock.

An image for a time (a snapshot, or the end of a --time budget) is taken at the
iteration end nearest that time, judged by the last iteration's length: a method
whose iterations are long then misses a budget by at most about half an
iteration either way, instead of always overrunning it by up to a whole one
(which handed it extra time in every equal-time comparison).
"""

from __future__ import annotations

import os
import platform
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .errors import PgiError
from .fingerprint import render_fingerprint
from .imageio import write_exr, write_image_and_sidecar
from .methods import get_method
from .scene.model import Scene


@dataclass
class RenderSettings:
    method: str
    seed: int = 0
    threads: int = 1
    time_budget: float | None = None  # seconds of render time
    spp: int | None = None  # stop after this many samples per pixel
    snapshots: Sequence[float] = ()  # render times at which to write intermediate images
    params: dict = field(default_factory=dict)
    overrides: Sequence[str] = ()  # scene overrides the scene was loaded with (for the record)


def snapshot_label(seconds: float) -> str:
    """How a time appears in a snapshot's file name: 4 -> "4", 0.5 -> "0.5", 1e6 -> "1e+06"
    (six significant digits; the workflow names its budgets' files with this too)."""
    return f"{float(seconds):g}"


def extra_image_path(out: Path, name: str) -> Path:
    """out.exr -> out.s2t3.exr for a method's extra image named s2t3."""
    return out.with_name(f"{out.stem}.{name}{out.suffix}")


def snapshot_path(out: Path, seconds: float) -> Path:
    """out.exr -> out.t4.exr for a 4 s snapshot (out.t0.5.exr for half a second)."""
    return out.with_name(f"{out.stem}.t{snapshot_label(seconds)}{out.suffix}")


def reached(target: float, render_seconds: float, last_iteration: float) -> bool:
    """Whether the image for `target` seconds is the one at hand: the next iteration end,
    expected `last_iteration` later, would lie further from it than this one."""
    return render_seconds + 0.5 * last_iteration >= target


def timed_iterations(
    method: Any, clock: Callable[[], float] | None = None
) -> Iterator[tuple[float, float]]:
    """Runs ``method``'s iterations one after another, yielding after each the render seconds
    so far and that iteration's own; what the caller does between them is not counted.
    ``clock``: wall-clock seconds (time.perf_counter) unless another is given, such as the
    process's CPU seconds for benchmarks on a shared machine (bench/)."""
    clock = clock or time.perf_counter
    elapsed = 0.0
    iteration = 0
    while True:
        start = clock()
        method.run_iteration(iteration)
        last = clock() - start
        elapsed += last
        iteration += 1
        yield elapsed, last


def iterate_to(
    method: Any, times: Sequence[float], clock: Callable[[], float] | None = None
) -> Iterator[tuple[float, float]]:
    """Runs ``method``'s iterations and yields (time, render seconds) at the iteration end
    nearest each of ``times``, as ``render`` takes its snapshots, for measurements that write
    no files (bench/); it stops after the last. One iteration end may serve several times.
    ``clock`` as timed_iterations'."""
    pending = sorted(float(t) for t in times)
    if not pending:
        return
    for elapsed, last in timed_iterations(method, clock):
        while pending and reached(pending[0], elapsed, last):
            yield pending.pop(0), elapsed
        if not pending:
            return


def run_for(method: Any, seconds: float, clock: Callable[[], float] | None = None) -> float:
    """``method``'s iterations up to the end nearest ``seconds`` of render time (at least
    one); returns the render seconds they took. ``clock`` as timed_iterations'."""
    return [elapsed for _, elapsed in iterate_to(method, [seconds], clock)][-1]


def available_cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def check_threads(threads: int | None) -> None:
    """More threads than cores would only make timings unfair: refused."""
    if threads is not None and threads > available_cores():
        raise PgiError(
            f"--threads {threads} asked for, but only {available_cores()} core(s) are "
            "available to this process"
        )


# Whether a progress bar has drawn on stderr's current line: a message printed while it
# has (an error, an interrupt) must start a line of its own.
_bar_line_open = False


def end_progress_line() -> None:
    """Ends a line a progress bar left open on the terminal."""
    global _bar_line_open
    if _bar_line_open:
        sys.stderr.write("\n")
        sys.stderr.flush()
        _bar_line_open = False


class Progress:
    """A bar on a terminal, plain lines otherwise (one every few seconds)."""

    def __init__(self, total_seconds: float | None, total_spp: int | None, enabled: bool) -> None:
        self.total_seconds, self.total_spp = total_seconds, total_spp
        self.enabled = enabled
        self.tty = sys.stderr.isatty()
        self._last = 0.0
        self._printed: tuple[float, int] | None = None  # the last plain line's time and spp

    def update(self, seconds: float, spp: int, force: bool = False, finished: bool = False) -> None:
        """Draws the bar (``force``: now, ending its line); ``finished``: the render is done,
        whatever the clock says (it may stop half an iteration short of its budget)."""
        global _bar_line_open
        if not self.enabled:
            return
        frac = 0.0
        if self.total_seconds:
            frac = seconds / self.total_seconds
        if self.total_spp:
            frac = max(frac, spp / self.total_spp)
        frac = 1.0 if finished else min(frac, 1.0)
        if self.tty:
            bar = "#" * int(frac * 30)
            sys.stderr.write(f"\r[{bar:<30}] {frac:6.1%}  {seconds:7.1f} s  {spp} spp")
            _bar_line_open = True
            if force:
                end_progress_line()
            sys.stderr.flush()
        elif (force or seconds - self._last >= 5) and self._printed != (seconds, spp):
            self._last, self._printed = seconds, (seconds, spp)
            print(f"progress {frac:6.1%} {seconds:.1f} s {spp} spp", file=sys.stderr, flush=True)


def _code_fingerprint() -> str:
    """The digest of the renderer's code and libraries (the workflow's render fingerprint),
    or why it is unknown: `version` alone does not change between commits."""
    try:
        return render_fingerprint()
    except PgiError as e:  # C++ sources edited after the build: a render still runs
        return f"unknown: {e}"


def render(
    scene: Scene,
    settings: RenderSettings,
    out: Path,
    *,
    progress: bool = True,
    on_snapshot: Callable[[Path, dict], None] | None = None,
) -> dict:
    """Render progressively; write snapshots and the final image with JSON sidecars.

    Returns the final sidecar dictionary.
    """
    if settings.time_budget is None and settings.spp is None and not settings.snapshots:
        raise PgiError("give --time, --spp or --snapshots: the render needs a stopping rule")
    check_threads(settings.threads)
    snapshots = sorted(float(s) for s in settings.snapshots)
    budget = settings.time_budget
    if budget is not None and snapshots and snapshots[-1] > budget:
        raise PgiError(
            f"--snapshots {snapshots[-1]:g} lies beyond --time {budget:g}: "
            "it would never be written"
        )
    if budget is None and snapshots:
        budget = snapshots[-1]
    method_cls = get_method(settings.method)

    t0 = time.perf_counter()
    method = method_cls(
        scene,
        seed=settings.seed,
        threads=settings.threads,
        params=settings.params,
        spp_budget=settings.spp,
    )
    load_seconds = time.perf_counter() - t0

    base = {
        "version": __version__,
        "code": _code_fingerprint(),
        "scene": scene.name,
        "scene_file": str(scene.path),
        "method": settings.method,
        "params": settings.params,
        "method_params": method.method_params,
        "overrides": list(settings.overrides),
        "seed": settings.seed,
        "threads": settings.threads,
        "time_budget": budget,
        "spp_budget": settings.spp,
        "load_seconds": load_seconds,
        "resolution": [scene.film.width, scene.film.height],
        "host": platform.node(),
    }

    def sidecar(render_seconds: float, budget_label: float | None) -> dict:
        info = dict(
            base,
            render_seconds=render_seconds,
            last_iteration_seconds=last_iteration,
            **method.stats(),
        )
        if budget_label is not None:
            info["snapshot_budget"] = budget_label
        return info

    def write(path: Path, info: dict) -> None:
        image = method.image()
        if not np.all(np.isfinite(image)):  # the film drops non-finite samples; this is a bug guard
            raise RuntimeError(f"{settings.method} produced non-finite pixels")
        write_image_and_sidecar(path, image, info)
        if on_snapshot:
            on_snapshot(path, info)

    bar = Progress(budget, settings.spp, progress)
    render_seconds = 0.0
    last_iteration = 0.0  # seconds the latest iteration took (none yet: 0)
    iteration = 0
    pending = list(snapshots)
    written: list[Path] = []
    try:
        # Budgets and --spp are at least one iteration away at the start: run, then check.
        for render_seconds, last_iteration in timed_iterations(method):
            iteration += 1
            spp = method.stats().get("spp", iteration)
            bar.update(render_seconds, spp)
            while pending and reached(pending[0], render_seconds, last_iteration):
                label = pending.pop(0)
                path = snapshot_path(out, label)
                write(path, sidecar(render_seconds, label))
                written.append(path)
            if budget is not None and reached(budget, render_seconds, last_iteration):
                break
            if settings.spp is not None and spp >= settings.spp:
                break
    except BaseException:
        # Snapshots already written are whole renders of their budgets (image and sidecar):
        # they stay, and the user is told which; the final image is never written.
        end_progress_line()
        notes = [f"kept {', '.join(str(p) for p in written)}"] if written else []
        # Files there that this run did not write: say so, rather than delete them.
        earlier = [p for p in (snapshot_path(out, s) for s in pending) if p.exists()]
        earlier += [out] if out.exists() else []
        if earlier:
            notes.append(
                f"{', '.join(str(p) for p in earlier)} {'is' if len(earlier) == 1 else 'are'} "
                "from an earlier run"
            )
        if notes:
            print(f"note: no final image; {'; '.join(notes)}", file=sys.stderr)
        raise
    bar.update(render_seconds, method.stats().get("spp", iteration), force=True, finished=True)
    if pending:  # --spp was reached first
        print(
            f"note: reached --spp {settings.spp} after {render_seconds:.2f} s; snapshot(s) at "
            f"{', '.join(f'{p:g}' for p in pending)} s not written",
            file=sys.stderr,
        )
    final = sidecar(render_seconds, None)
    try:
        write(out, final)
        # Images a method makes beside its own (bdpt's per-strategy images): out.NAME.exr.
        extras = method.extra_images() if hasattr(method, "extra_images") else {}
        for name, image in extras.items():
            write_exr(extra_image_path(out, name), image, {"pgi": f"{settings.method} {name}"})
    except BaseException:  # e.g. a full disk: the snapshots written so far stay, and are named
        if written:
            print(
                f"note: no final image; kept {', '.join(str(p) for p in written)}", file=sys.stderr
            )
        raise
    return final
