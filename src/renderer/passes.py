"""Pass sequences shared by methods whose native kernels follow the camera-path protocol.

A camera-path kernel offers ``begin_wave``, ``shade``, ``shadow_rays``, ``resolve_shadows``,
``next_rays`` and ``end_wave`` (see cpp/camera_path.h); ``trace_camera_wave`` is the one
Python loop that drives them (ppb's gathering), bounce by bounce, with Embree tracing every
batch in between. ``resolve_shadow_rays`` serves every kernel or lane with a shadow-ray
queue: pt's lanes (methods/pt.py), ppb and lt.
"""

from __future__ import annotations

from typing import Any

from .tracer import EmbreeTracer, RayBatch


def resolve_shadow_rays(kernel: Any, tracer: EmbreeTracer, shadows: RayBatch) -> None:
    """Trace the queued shadow rays segment by segment until each is blocked or arrives.
    Without null boundaries in the scene a ray has one segment, and whether anything
    blocks it is all it needs: Embree's occlusion query answers that for less."""
    any_hit = kernel.shadows_any_hit
    while queued := kernel.shadow_rays(*shadows.buffers):
        if any_hit:
            kernel.resolve_occlusion(tracer.occluded(shadows, queued))
        else:
            tfar, prim, _, _ = tracer.intersect(shadows, queued)
            kernel.resolve_shadows(tfar, prim)


def trace_camera_wave(
    kernel: Any, tracer: EmbreeTracer, paths: RayBatch, shadows: RayBatch, iteration: int
) -> None:
    """One wave of camera paths: camera rays, then trace / shade / shadows / extend per bounce."""
    active = kernel.begin_wave(iteration, *paths.buffers)
    while active:
        if kernel.shade(*tracer.intersect(paths, active)):
            resolve_shadow_rays(kernel, tracer, shadows)
        active = kernel.next_rays(*paths.buffers)
    kernel.end_wave()
