"""The path tracer's engineering guarantees: determinism, finite output, stopping rules."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_small
from renderer.methods.pt import PathTracing


def _render(scene, threads: int, iterations: int, seed: int = 7) -> np.ndarray:
    method = PathTracing(scene, seed=seed, threads=threads, params={"spp_per_wave": 2})
    for i in range(iterations):
        method.run_iteration(i)
    assert method.stats()["nonfinite"] == 0
    return method.image()


@pytest.mark.parametrize("name", ["cbox-fog", "cbox-grid", "cbox-glass"])
def test_same_seed_same_image_whatever_the_thread_count(name):
    scene = load_small(name, 24, 24)
    one = _render(scene, threads=1, iterations=3)
    two = _render(scene, threads=2, iterations=3)
    assert np.array_equal(one, two)
    assert np.all(np.isfinite(one)) and one.max() > 0


def test_same_samples_same_image_whatever_the_wave_size():
    """Sample s of pixel p is keyed by (seed, s, p), and the film adds a pixel's samples in
    sample order: 8 spp in waves of 1, 2 or 4 spp give the very same image."""
    scene = load_small("cbox-fog", 16, 16)
    images = []
    for spp_per_wave in (1, 2, 4):
        method = PathTracing(scene, seed=5, threads=2, params={"spp_per_wave": spp_per_wave})
        for i in range(8 // spp_per_wave):
            method.run_iteration(i)
        images.append(method.image())
    assert np.array_equal(images[0], images[1]) and np.array_equal(images[0], images[2])


def test_same_image_whatever_the_lanes_and_their_slots():
    """A wave streams through its lanes, each keeping slots_per_lane paths in flight and
    refilling a slot as soon as its path ends: a slot, a few, more than the wave has paths,
    on one lane or two, give the very same image and counts."""
    scene = load_small("cbox-grid", 16, 16)
    runs = []
    for threads, slots in ((1, 1), (2, 1), (2, 7), (1, 300), (2, 4096)):
        method = PathTracing(
            scene, seed=3, threads=threads, params={"spp_per_wave": 2, "slots_per_lane": slots}
        )
        for i in range(2):
            method.run_iteration(i)
        stats = method.stats()
        runs.append((method.image(), stats["rays"], stats["density_lookups"]))
    assert runs[0][0].max() > 0 and runs[0][2] > 0
    for image, rays, lookups in runs[1:]:
        assert np.array_equal(image, runs[0][0]) and (rays, lookups) == runs[0][1:]


def test_other_seed_other_image():
    scene = load_small("cbox-fog", 16, 16)
    assert not np.array_equal(_render(scene, 1, 1, seed=1), _render(scene, 1, 1, seed=2))


def test_iterations_are_independent_of_order_of_runs():
    # Iteration i depends only on (seed, i): running 0..3 or just 2..3 then 0..1 gives one image.
    scene = load_small("cbox", 16, 16)
    a = PathTracing(scene, seed=3, threads=1, params={})
    b = PathTracing(scene, seed=3, threads=1, params={})
    for i in range(4):
        a.run_iteration(i)
    for i in (2, 3, 0, 1):
        b.run_iteration(i)
    assert np.allclose(a.image(), b.image(), rtol=1e-12, atol=0)


def test_max_depth_one_sees_only_emitters():
    scene = load_small("cbox", 32, 32, ("integrator.max_depth=1",))
    image = _render(scene, 1, 2)
    lit = image.max(axis=2) > 0
    # Only the light's pixels: a small patch near the top centre.
    ys, xs = np.nonzero(lit)
    assert 0 < lit.sum() < 0.05 * lit.size
    assert ys.max() < 32 * 0.25 and abs(xs.mean() - 15.5) < 3


def test_unknown_parameter_is_a_clear_error():
    from renderer.errors import PgiError

    with pytest.raises(PgiError, match="unknown parameter"):
        PathTracing(load_small("cbox", 8, 8), seed=0, threads=1, params={"bogus": 1})


class _ClosestHitShadows:
    """A pt kernel that resolves its shadow rays from closest hits, as with null boundaries."""

    shadows_any_hit = False

    def __init__(self, kernel) -> None:
        self._kernel = kernel

    def __getattr__(self, name: str):
        return getattr(self._kernel, name)


class _CountingOcclusion:
    """Wraps a tracer's occlusion query and counts the rays it answers."""

    def __init__(self, tracer) -> None:
        self.rays = 0
        self._occluded = tracer.occluded

    def __call__(self, batch, n):
        self.rays += n
        return self._occluded(batch, n)


@pytest.mark.parametrize("name", ["cbox", "volcaustic"])  # volcaustic: media, no null boundary
def test_occlusion_queries_give_the_image_of_closest_hits(name):
    # Without null boundaries a shadow ray only asks Embree whether anything blocks it;
    # resolving the same rays from closest hits must give the very same image.
    scene = load_small(name, 24, 24)
    any_hit = PathTracing(scene, seed=5, threads=2, params={"spp_per_wave": 2})
    closest = PathTracing(scene, seed=5, threads=2, params={"spp_per_wave": 2})
    assert all(lane.shadows_any_hit for lane in any_hit.camera_paths.lanes)
    counter = any_hit.camera_paths.tracer.occluded = _CountingOcclusion(any_hit.camera_paths.tracer)
    closest.camera_paths.lanes = [_ClosestHitShadows(lane) for lane in closest.camera_paths.lanes]
    for i in range(3):
        any_hit.run_iteration(i)
        closest.run_iteration(i)
    assert counter.rays > 0
    assert any_hit.image().max() > 0
    assert np.array_equal(any_hit.image(), closest.image())


def test_occlusion_query_refused_where_shadow_rays_cross_null_boundaries():
    method = PathTracing(load_small("cbox-fog", 8, 8), seed=0, threads=1, params={})
    lane = method.camera_paths.lanes[0]
    assert not lane.shadows_any_hit
    with pytest.raises(ValueError, match="null boundaries"):
        lane.resolve_occlusion(np.zeros(0, np.int32))


def test_occluded_agrees_with_closest_hits_within_tmax():
    from renderer.engine import build_native_scene
    from renderer.tracer import EmbreeTracer, RayBatch

    native = build_native_scene(load_small("cbox", 8, 8))
    tracer = EmbreeTracer(native.triangles, 2)
    corners = native.triangles.reshape(-1, 3)
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    rng = np.random.default_rng(1)
    n = 20000  # enough for both threads to take a chunk
    start = lo + (hi - lo) * rng.uniform(0.02, 0.98, (n, 3))
    end = lo + (hi - lo) * rng.uniform(0.02, 0.98, (n, 3))
    batch = RayBatch(n)
    batch.origins[:] = start
    span = np.linalg.norm(end - start, axis=1)
    batch.directions[:] = (end - start) / span[:, None]
    batch.tmax[:] = span
    blocked = tracer.occluded(batch, n) >= 0
    _, prim, _, _ = tracer.intersect(batch, n)
    assert 0.05 < blocked.mean() < 0.95
    assert np.array_equal(blocked, prim >= 0)
    # The kernels write tmax >= 0 (a shadow ray within target_eps of its target gets 0):
    # such a ray is blocked by neither query (Embree's occlusion query calls a ray with
    # tmax < 0 blocked, its closest hit does not).
    batch.tmax[:] = 0
    assert not np.any(tracer.occluded(batch, n) >= 0)
    assert not np.any(tracer.intersect(batch, n)[1] >= 0)


class _SignalsItsEnd:
    """Wraps a lane: `done` is set when its next_rays finds nothing left to trace."""

    def __init__(self, lane, done) -> None:
        self._lane, self._done = lane, done

    def next_rays(self, *buffers):
        n = self._lane.next_rays(*buffers)
        if n == 0:
            self._done.set()
        return n

    def __getattr__(self, name: str):
        return getattr(self._lane, name)


@pytest.mark.parametrize("threads", [2, 3])
@pytest.mark.parametrize("failing", ["main", "pool", "pool-after-main"])
def test_an_error_in_one_lane_ends_the_wave_and_the_next_wave_runs(failing, threads):
    """A lane that fails stops the wave with its error: the other lanes end at their next
    step, not at the wave's end, also when the failure comes after the main thread's lane
    has ended; run_iteration returns only once every lane has, and the method renders the
    same waves afterwards (no interrupt left pending, no lane still running)."""
    import threading

    scene = load_small("cbox-fog", 32, 32)  # 2048 paths: eight claims of 256, for 3 lanes
    params = {"spp_per_wave": 2, "slots_per_lane": 16}
    method = PathTracing(scene, seed=2, threads=threads, params=params)
    reference = PathTracing(scene, seed=2, threads=1, params={"spp_per_wave": 2})
    intersect, calls, main_done = method.camera_paths.tracer.intersect, [], threading.Event()
    lanes = method.camera_paths.lanes
    method.camera_paths.lanes = [_SignalsItsEnd(lanes[0], main_done), *lanes[1:]]
    failed_at, failing_thread = [], []  # the number of calls when the lane failed; its thread

    def failing_intersect(batch, n):
        me = threading.current_thread()
        on_main = me is threading.main_thread()
        if not on_main and not failing_thread:
            failing_thread.append(me)  # the first pool lane to trace is the one to fail
        calls.append(me)
        fails = len(calls) > 8 and (on_main if failing == "main" else me in failing_thread)
        if failing == "pool-after-main" and me in failing_thread:
            assert main_done.wait(60)
            fails = True
        if fails and not failed_at:
            failed_at.append(len(calls))
            raise RuntimeError("lane failed")
        return intersect(batch, n)

    method.camera_paths.tracer.intersect = failing_intersect
    with pytest.raises(RuntimeError, match="lane failed"):
        method.run_iteration(0)
    # the wave has hundreds of steps; every other lane ended within its step (an extension
    # ray and a few shadow segments) of the failure
    assert len(failed_at) == 1 and len(calls) <= failed_at[0] + 4 * (threads - 1)
    del method.camera_paths.tracer.intersect
    method.camera_paths.lanes = lanes
    for i in range(2):
        method.run_iteration(i)
        reference.run_iteration(i)
    assert np.array_equal(method.image(), reference.image())


def test_a_signal_while_waiting_for_the_other_lanes_stops_them_before_it_is_raised():
    """The main thread's lane has ended and it waits for another, slow one, when a signal's
    handler raises: the slow lane is stopped at its next step and has ended before
    run_iteration raises (a review found it left running on its own for seconds)."""
    import signal
    import threading
    import time

    class Stop(Exception):
        pass

    def handler(signum, frame):
        raise Stop()

    scene = load_small("cbox-fog", 32, 32)
    method = PathTracing(scene, seed=2, threads=2, params={"slots_per_lane": 16})
    intersect, main_done = method.camera_paths.tracer.intersect, threading.Event()
    lanes = method.camera_paths.lanes
    method.camera_paths.lanes = [_SignalsItsEnd(lanes[0], main_done), *lanes[1:]]
    pool_calls, signalled = [], []

    def slow_on_the_pool(batch, n):  # its share of the wave takes seconds
        if threading.current_thread() is not threading.main_thread():
            pool_calls.append(time.monotonic())
            time.sleep(0.02)
        return intersect(batch, n)

    def signal_once_main_is_done():
        if main_done.wait(60):
            signalled.append(time.monotonic())
            signal.pthread_kill(threading.main_thread().ident, signal.SIGUSR1)

    method.camera_paths.tracer.intersect = slow_on_the_pool
    previous = signal.signal(signal.SIGUSR1, handler)
    try:
        threading.Thread(target=signal_once_main_is_done, daemon=True).start()
        with pytest.raises(Stop):
            method.run_iteration(0)
        raised, calls = time.monotonic(), len(pool_calls)
        time.sleep(0.2)
    finally:
        signal.signal(signal.SIGUSR1, previous)
    assert signalled and raised - signalled[0] < 1.0
    assert len(pool_calls) == calls  # nothing traced after run_iteration raised
    assert all(t < raised for t in pool_calls)
    del method.camera_paths.tracer.intersect
    method.camera_paths.lanes = lanes
    method.run_iteration(1)  # no interrupt left pending
    assert method.iterations == 1


_SPOILED_RAY_BUFFERS = {
    "float64-origins": lambda b: (b.origins.astype(np.float64), b.directions, b.tmax),
    "fortran-directions": lambda b: (b.origins, np.asfortranarray(b.directions), b.tmax),
    "float64-tmax": lambda b: (b.origins, b.directions, b.tmax.astype(np.float64)),
}


def _ray_writers(method_id: str) -> list:
    """Every binding through which a method's kernels write rays into the caller's buffers,
    as calls taking those three buffers: each lane's next_rays and shadow_rays."""
    from renderer.methods import get_method

    scene = load_small("cbox-fog", 8, 8)
    method = get_method(method_id)(scene, seed=0, threads=1, params={})
    lanes = [lane for wave in method.wavefronts for lane in wave.lanes]
    return [write for lane in lanes for write in (lane.next_rays, lane.shadow_rays)]


@pytest.mark.parametrize("spoil", list(_SPOILED_RAY_BUFFERS))
@pytest.mark.parametrize("method_id", ["pt", "lt", "pm", "ppb"])
def test_ray_buffers_the_kernels_write_are_never_silently_copied(method_id, spoil):
    """A kernel writes its rays into the caller's buffers: a buffer of another dtype or
    layout must be refused, not converted into a copy that is written and thrown away."""
    from renderer.tracer import RayBatch

    batch = RayBatch(1 << 16)
    for write in _ray_writers(method_id):
        with pytest.raises(TypeError, match="incompatible function arguments"):
            write(*_SPOILED_RAY_BUFFERS[spoil](batch))


def test_a_path_that_carries_nothing_ends():
    """In a box whose every surface is black, each camera path ends where it first lands:
    its throughput is zero, so tracing it on (until rr_depth, as before) would add nothing.
    One camera ray per sample is all that is traced, and the lamp is still seen."""
    black = [f"materials.{m}.reflectance=0" for m in ("white", "red", "green")]
    scene = load_small("cbox", 32, 32, tuple(black))
    method = PathTracing(scene, seed=1, threads=2, params={"spp_per_wave": 1})
    method.run_iteration(0)
    assert method.stats()["rays"] == 32 * 32
    assert method.image().max() > 0
