"""Light paths shared by the light-side methods (lt, pm, sppm, ppb).

The native tracer is ``cpp/lightpath.h`` (its header documents the records and
their units); this module finds the medium each light emits into and runs the
passes of one iteration: emit, then trace / scatter / next rays until every
path has ended.
"""

from __future__ import annotations

import numpy as np

from .. import _core
from ..engine import NativeScene
from ..errors import PgiError
from ..scene.model import PointLight, Scene, SpotLight
from ..tracer import EmbreeTracer, RayBatch

# Probe directions per emitter: the medium is the majority answer.
_PROBE_DIRECTIONS = 5
# Surfaces a probe may pass on its way to a medium boundary.
_MAX_PROBE_HITS = 64


def _medium_names(scene: Scene) -> dict[str, int]:
    """Medium indices as the native scene numbers them (insertion order)."""
    return {name: i for i, name in enumerate(scene.media)}


def locate_media(
    native: NativeScene,
    tracer: EmbreeTracer,
    scene: Scene,
    points: np.ndarray,
    directions: np.ndarray,
) -> np.ndarray:
    """Medium index (-1 = vacuum) around each point, found along a probe ray per point.

    As in Mitsuba, only shapes that name a medium change it, so the first such
    shape the probe crosses tells the side the point is on: its exterior when
    the probe enters it from the normal side, else its interior.
    """
    n = len(points)
    result = np.full(n, -1, np.int32)
    if n == 0 or not scene.media:
        return result
    ids = _medium_names(scene)
    tri = native.triangles
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    inside, outside, named = _triangle_media(native, scene, ids)
    eps = 1e-5 * float(np.ptp(tri.reshape(-1, 3), axis=0).max())
    batch = RayBatch(n)
    origin = points.astype(np.float64).copy()
    dirs = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    pending = np.arange(n)
    for _ in range(_MAX_PROBE_HITS):
        if len(pending) == 0:
            break
        m = len(pending)
        batch.origins[:m] = origin[pending]
        batch.directions[:m] = dirs[pending]
        batch.tmax[:m] = 1e30
        tfar, prim, _, _ = tracer.intersect(batch, m)
        prim = prim[:m].astype(np.int64)
        hit = prim >= 0
        pending, tfar, prim = pending[hit], tfar[:m][hit], prim[hit]
        is_named = named[prim]
        front = np.einsum("ij,ij->i", dirs[pending], normals[prim]) < 0
        done = pending[is_named]
        result[done] = np.where(front[is_named], outside[prim[is_named]], inside[prim[is_named]])
        pending, tfar = pending[~is_named], tfar[~is_named]
        origin[pending] += dirs[pending] * (tfar[:, None] + eps)
    return result


def _per_triangle(native: NativeScene, scene: Scene, values: list) -> np.ndarray:
    """One value per shape, repeated over the shape's native triangles (the ones
    build_native_scene kept)."""
    pairs = zip(scene.shapes, values, strict=True)
    per = np.concatenate([np.full(len(s.faces), v) for s, v in pairs])
    return per[native.kept]


def _triangle_media(native: NativeScene, scene: Scene, ids: dict[str, int]):
    """Interior, exterior and 'names a medium' per native triangle (same order as the core)."""
    shapes = scene.shapes
    inside = _per_triangle(
        native, scene, [-1 if s.interior is None else ids[s.interior] for s in shapes]
    )
    outside = _per_triangle(
        native, scene, [-1 if s.exterior is None else ids[s.exterior] for s in shapes]
    )
    named = _per_triangle(
        native, scene, [s.interior is not None or s.exterior is not None for s in shapes]
    )
    return inside.astype(np.int32), outside.astype(np.int32), named.astype(bool)


def emission_media(native: NativeScene, tracer: EmbreeTracer, scene: Scene, seed: int = 0):
    """(per triangle, per light) medium each light emits into, in the core's light order.

    Area lights come first in the core (one per emitting shape, in shape order), then
    point, spot and directional lights in the scene's order. Emitting triangles are
    probed from their centroid on the front side; point and spot lights from their
    position; directional lights start on a disk just outside the scene's bounding sphere
    (vacuum). When the camera sits in a medium, lights it reaches without crossing a shape
    that names a medium share it (a fog-filled room has no shape naming its fog; a smoke
    grid with no shape around it lets the sun's paths start in the smoke, outside its box),
    a directional light judged from its disk's centre.
    """
    rng = np.random.default_rng(seed)
    tri = native.triangles
    ntri = len(tri)
    per_triangle = np.full(ntri, -1, np.int32)
    emitting = _emitting_triangles(native, scene)
    lights_area = sum(1 for s in scene.shapes if s.emission is not None)
    point_positions = []
    for light in scene.lights:
        if isinstance(light, (PointLight, SpotLight)):
            point_positions.append(np.asarray(light.position, np.float64))
        else:
            point_positions.append(None)
    if len(emitting):
        t = tri[emitting]
        centroid = t.mean(axis=1)
        normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        extent = float(np.ptp(tri.reshape(-1, 3), axis=0).max())
        start = centroid + normal * 1e-4 * extent
        votes = []
        for _ in range(_PROBE_DIRECTIONS):
            d = rng.normal(size=(len(emitting), 3))
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            # Keep the probe on the emitting side.
            d = np.where((np.einsum("ij,ij->i", d, normal) < 0)[:, None], -d, d)
            votes.append(locate_media(native, tracer, scene, start, d))
        per_triangle[emitting] = _majority(np.stack(votes))
    per_light = np.full(lights_area + len(scene.lights), -1, np.int32)
    for i, pos in enumerate(point_positions):
        if pos is None:
            continue
        d = rng.normal(size=(_PROBE_DIRECTIONS, 3))
        found = locate_media(native, tracer, scene, np.repeat(pos[None], _PROBE_DIRECTIONS, 0), d)
        per_light[lights_area + i] = _majority(found[:, None])[0]
    if scene.camera.medium is not None:
        # A medium no shape names (a room filled with the camera's fog) is invisible to the
        # probes. A light that the camera reaches without crossing a shape naming a medium is
        # in the camera's medium, by the same transition rule.
        camera_medium = _medium_names(scene)[scene.camera.medium]
        if len(emitting):
            same = _reaches_camera_freely(native, tracer, scene, start)
            per_triangle[emitting[same]] = camera_medium
        for i, pos in enumerate(point_positions):
            if pos is None:  # directional: the centre of the disk its paths start on
                pos = _sun_disk_centre(native, scene.lights[i].direction)
            if _reaches_camera_freely(native, tracer, scene, pos[None])[0]:
                per_light[lights_area + i] = camera_medium
    return per_triangle, per_light


def _sun_disk_centre(native: NativeScene, direction: np.ndarray) -> np.ndarray:
    """Centre of the disk a directional light's paths start on (cpp/lightpath.cpp): the
    core's scene centre, 1.01 scene radii against the direction of travel."""
    core = native.core
    return np.asarray(core.scene_center) - np.asarray(direction, np.float64) * (
        1.01 * core.scene_radius
    )


def _reaches_camera_freely(
    native: NativeScene, tracer: EmbreeTracer, scene: Scene, points: np.ndarray
) -> np.ndarray:
    """True where the segment from a point to the camera crosses no shape naming a medium."""
    n = len(points)
    free = np.ones(n, bool)
    if n == 0:
        return free
    _, _, named = _triangle_media(native, scene, _medium_names(scene))
    eps = 1e-5 * float(np.ptp(native.triangles.reshape(-1, 3), axis=0).max())
    camera = np.asarray(scene.camera.origin, np.float64)
    origin = points.astype(np.float64).copy()
    batch = RayBatch(n)
    pending = np.arange(n)
    for _ in range(_MAX_PROBE_HITS):
        if len(pending) == 0:
            break
        to = camera - origin[pending]
        dist = np.linalg.norm(to, axis=1)
        d = to / np.maximum(dist, 1e-300)[:, None]
        m = len(pending)
        batch.origins[:m], batch.directions[:m], batch.tmax[:m] = origin[pending], d, dist
        tfar, prim, _, _ = tracer.intersect(batch, m)
        prim = prim[:m].astype(np.int64)
        hit = prim >= 0
        crossed = np.zeros(m, bool)
        crossed[hit] = named[prim[hit]]
        free[pending[crossed]] = False
        onward = hit & ~crossed
        origin[pending[onward]] += d[onward] * (tfar[:m][onward, None] + eps)
        pending = pending[onward]
    return free


def _majority(votes: np.ndarray) -> np.ndarray:
    """Most frequent value along axis 0 (ties: the smallest)."""
    out = np.empty(votes.shape[1], np.int32)
    for j in range(votes.shape[1]):
        values, counts = np.unique(votes[:, j], return_counts=True)
        out[j] = values[np.argmax(counts)]
    return out


def _emitting_triangles(native: NativeScene, scene: Scene) -> np.ndarray:
    emits = [s.emission is not None for s in scene.shapes]
    return np.flatnonzero(_per_triangle(native, scene, emits))


class LightPaths:
    """N light paths per iteration, traced pass by pass (see cpp/lightpath.h)."""

    def __init__(
        self,
        native: NativeScene,
        tracer: EmbreeTracer,
        scene: Scene,
        *,
        seed: int,
        threads: int,
        paths: int,
        paths_param: str,
        max_records: int,
        vertices: bool = True,
        segments: bool = True,
    ) -> None:
        self.tracer = tracer
        self.kernel = _core.LightPathTracer(
            native.core,
            scene.integrator.max_depth,
            scene.integrator.rr_depth,
            seed,
            paths,
            threads,
            max_records,
        )
        self.kernel.set_recording(vertices, segments)
        per_triangle, per_light = emission_media(native, tracer, scene, seed)
        self.kernel.set_emission_media(per_triangle.tolist(), per_light.tolist())
        self.rays = RayBatch(paths)
        self.paths = paths
        self.paths_param = paths_param  # the method parameter that sets `paths`, for errors

    def trace(self, iteration: int) -> None:
        """Emit, then trace and scatter until every path of this iteration has ended.

        Raises PgiError when the records exceed ``max_records`` (the memory bound).
        """
        kernel, rays = self.kernel, self.rays
        try:
            active = kernel.begin_iteration(iteration, *rays.buffers)
            while active:
                kernel.scatter(*self.tracer.intersect(rays, active))
                active = kernel.next_rays(*rays.buffers)
        except ValueError as e:
            raise PgiError(
                f"{e} (lower method.{self.paths_param} or raise method.max_records)"
            ) from e
