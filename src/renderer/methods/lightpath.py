"""Light paths shared by the light-side methods (lt, pm, sppm, ppb).

The native tracer is ``cpp/lightpath.h`` (its header documents the records and
their units); this module finds the medium each light emits into and runs the
passes of one iteration: emit, then trace / scatter / next rays until every
path has ended.
"""

from __future__ import annotations

import sys

import numpy as np

from ..engine import NativeScene
from ..errors import PgiError
from ..scene.model import PointLight, Scene, SpotLight
from ..tracer import EmbreeTracer, RayBatch

# Probe directions per emitter: the medium is the majority answer.
_PROBE_DIRECTIONS = 5


class _ProbeSurfaces:
    """The scene as straight probe rays see it: the shapes that name a medium, and the opaque
    surfaces (neither null nor dielectric) that name none, each in an Embree scene of its own.
    Null and glass surfaces naming no medium change nothing a probe asks, so they are left
    out; and a named shape is found even where it coincides with an unnamed surface (a fog
    box built on the walls), which a walk through the whole scene could step over."""

    def __init__(self, native: NativeScene, scene: Scene) -> None:
        self.inside, self.outside, named = native.interior, native.exterior, native.transition
        passable = native.per_triangle(
            scene,
            [scene.materials[s.material].type in ("null", "dielectric") for s in scene.shapes],
        ).astype(bool)
        self.normals = native.normals
        self.named_ids = np.flatnonzero(named)
        self.opaque_ids = np.flatnonzero(~named & ~passable)
        self.named = self._tracer(native, self.named_ids)
        self.opaque = self._tracer(native, self.opaque_ids)

    @staticmethod
    def _tracer(native: NativeScene, ids: np.ndarray) -> EmbreeTracer | None:
        return EmbreeTracer(native.triangles[ids], 1) if len(ids) else None

    @staticmethod
    def _first_hit(tracer, ids, points, dirs, lengths) -> tuple[np.ndarray, np.ndarray]:
        """Distance (inf: none) and native triangle (-1) of each ray's first hit."""
        n = len(points)
        if tracer is None or n == 0:
            return np.full(n, np.inf), np.full(n, -1, np.int64)
        batch = RayBatch(n)
        batch.origins[:n], batch.directions[:n], batch.tmax[:n] = points, dirs, lengths
        tfar, prim, _, _ = tracer.intersect(batch, n)
        hit = prim[:n] >= 0
        return np.where(hit, tfar[:n], np.inf), np.where(hit, ids[np.maximum(prim[:n], 0)], -1)

    def walk(
        self, points: np.ndarray, directions: np.ndarray, lengths: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Straight rays from `points` (length `lengths`) to the first shape that names a
        medium, passing every surface that names none. Per ray: whether one was reached; the
        medium on the ray's starting side of it (its exterior when the ray enters it from the
        normal side, else its interior; -1 where none was reached); and whether an opaque
        surface naming no medium comes first."""
        dirs = directions / np.linalg.norm(directions, axis=1, keepdims=True)
        lengths = np.asarray(lengths, np.float64)
        t_named, at = self._first_hit(self.named, self.named_ids, points, dirs, lengths)
        t_opaque, _ = self._first_hit(self.opaque, self.opaque_ids, points, dirs, lengths)
        crossed = at >= 0
        side = np.full(len(points), -1, np.int32)
        hit = at[crossed]
        front = np.einsum("ij,ij->i", dirs[crossed], self.normals[hit]) < 0
        side[crossed] = np.where(front, self.outside[hit], self.inside[hit])
        return crossed, side, t_opaque < t_named


def locate_media(
    surfaces: _ProbeSurfaces, points: np.ndarray, directions: np.ndarray
) -> np.ndarray:
    """Medium index (-1 = vacuum) around each point, found along a probe ray per point.

    As in Mitsuba, only shapes that name a medium change it, so the first such
    shape the probe crosses tells the side the point is on: its exterior when
    the probe enters it from the normal side, else its interior.
    """
    _, side, _ = surfaces.walk(points, directions, np.full(len(points), 1e30))
    return side


def emission_media(native: NativeScene, scene: Scene, seed: int = 0):
    """(per triangle, per light) medium each light emits into, in the core's light order
    (NativeScene.light_ids: area lights first). Emitting triangles are
    probed from their centroid on the front side; point and spot lights from their
    position; directional lights start on a disk just outside the scene's bounding sphere
    (vacuum). When the camera sits in a medium, a light shares it if the straight route
    from the light to the camera crosses no shape that names a medium (a fog-filled room
    has no shape naming its fog; a smoke grid with no shape around it lets the sun's paths
    start in the smoke, outside its box). A route that an opaque surface naming no medium
    ends first decides nothing (light cannot pass there, and the medium on its far side is
    not the camera's by any rule): a directional light is judged by the routes from a fixed
    lattice of points over its disk, each deciding route voting for the camera's medium or
    for the medium on its side of the first shape naming one (the sun outside a fog-filled
    room with windows is reached through the windows, whose exterior is vacuum); where no
    route decides, and for the one route of any other light, the route is followed through
    such surfaces.
    """
    rng = np.random.default_rng(seed)
    surfaces = _ProbeSurfaces(native, scene)
    tri = native.triangles
    ntri = len(tri)
    per_triangle = np.full(ntri, -1, np.int32)
    emitting = _emitting_triangles(native, scene)
    point_positions = []
    for light in scene.lights:
        if isinstance(light, (PointLight, SpotLight)):
            point_positions.append(np.asarray(light.position, np.float64))
        else:
            point_positions.append(None)
    camera_medium = None if scene.camera.medium is None else native.medium_ids[scene.camera.medium]
    if len(emitting):
        t = tri[emitting]
        centroid = t.mean(axis=1)
        normal = native.normals[emitting]
        extent = float(np.ptp(tri.reshape(-1, 3), axis=0).max())
        per_triangle[emitting] = _surface_media(
            surfaces, scene, centroid, normal, extent, camera_medium, rng
        )
        # Each triangle starts its paths in one medium: one that a medium's boundary crosses
        # would start some in the wrong one. Its corners (pulled 1 % towards the centroid)
        # and its centroid are compared, for a boundary that cuts across it, each by the
        # medium its route to the camera decides where it does (random probes miss small
        # shapes), with probes of their own, so that the centroid's above stay as they were.
        # An emitter that names media itself is a boundary: its paths take its sides.
        corner_rng = np.random.default_rng([seed, 1])
        checked = ~np.isin(emitting, surfaces.named_ids)
        ref = _surface_media(surfaces, scene, centroid, normal, extent, camera_medium,
                             corner_rng, route_decides=True)  # fmt: skip
        for k in range(3):
            corner = t[:, k] + 0.01 * (centroid - t[:, k])
            found = _surface_media(surfaces, scene, corner, normal, extent, camera_medium,
                                   corner_rng, route_decides=True)  # fmt: skip
            split = np.flatnonzero((found != ref) & checked)
            if len(split):
                first = split[0]
                _refuse_split_emitter(native, scene, emitting[first], (ref[first], found[first]))
    per_light = np.full(native.core.light_count, -1, np.int32)
    for i, pos in enumerate(point_positions):
        if pos is None:
            continue
        d = rng.normal(size=(_PROBE_DIRECTIONS, 3))
        found = locate_media(surfaces, np.repeat(pos[None], _PROBE_DIRECTIONS, 0), d)
        per_light[native.light_ids[i]] = _majority(found[:, None])[0]
    if camera_medium is not None:
        # A medium no shape names (a room filled with the camera's fog) is invisible to the
        # probes. A light that the camera reaches without crossing a shape naming a medium is
        # in the camera's medium, by the same transition rule.
        for i, pos in enumerate(point_positions):
            if pos is None:  # directional: routes from points spread over its disk
                outcome, side = _camera_routes(
                    surfaces, scene, _sun_disk_points(native, scene.lights[i].direction)
                )
                per_light[native.light_ids[i]] = _disk_medium(outcome, side, camera_medium)
            else:
                outcome, _ = _camera_routes(surfaces, scene, pos[None])
                if _route_shares_camera_medium(outcome)[0]:
                    per_light[native.light_ids[i]] = camera_medium
    return per_triangle, per_light


def _surface_media(
    surfaces: _ProbeSurfaces,
    scene: Scene,
    points: np.ndarray,
    normal: np.ndarray,
    extent: float,
    camera_medium: int | None,
    rng: np.random.Generator,
    route_decides: bool = False,
) -> np.ndarray:
    """The medium on the front side of each point of an emitting surface: the majority of
    probes into the front hemisphere, or the camera's medium where the straight route to the
    camera crosses no shape that names a medium. With ``route_decides`` (comparing points of
    one triangle: random probes can miss a small shape), also the medium on the point's side
    of the first shape naming one that this route crosses."""
    start = points + normal * 1e-4 * extent
    votes = []
    for _ in range(_PROBE_DIRECTIONS):
        d = rng.normal(size=(len(points), 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        # Keep the probe on the emitting side.
        d = np.where((np.einsum("ij,ij->i", d, normal) < 0)[:, None], -d, d)
        votes.append(locate_media(surfaces, start, d))
    media = _majority(np.stack(votes))
    if camera_medium is not None:
        outcome, side = _camera_routes(surfaces, scene, start)
        media[_route_shares_camera_medium(outcome)] = camera_medium
        if route_decides:
            crossed = outcome == _CROSSES_NAMED
            media[crossed] = side[crossed]
    return media


def _refuse_split_emitter(
    native: NativeScene, scene: Scene, triangle: int, media: tuple[int, int]
) -> None:
    shape = int(native.per_triangle(scene, list(range(len(scene.shapes))))[triangle])
    names = ["vacuum", *scene.media]
    raise PgiError(
        f"{scene.where_shape(shape)}: a boundary of a "
        f"medium crosses this emitter (part of it lies in {names[media[0] + 1]}, part in "
        f"{names[media[1] + 1]}), but light paths start in one medium per triangle: split the "
        "emitter where the boundary crosses it (pt and mitsuba render it as it is)"
    )


# Points on a directional light's disk whose routes to the camera vote on its medium.
_SUN_PROBES = 1024

# Route outcomes (_camera_routes): which medium the point is in, as far as its straight
# route to the camera tells.
_CROSSES_NAMED, _REACHES_CAMERA, _ENDS_OPAQUE, _ONLY_OPAQUE_TO_CAMERA = 0, 1, 2, 3


def _sun_disk_points(native: NativeScene, direction) -> np.ndarray:
    """Points spread evenly over the disk a directional light's paths start on (the core's
    Scene::directional_disk). A fixed sunflower lattice, the same for every seed; the first
    point is the centre."""
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    centre, radius = native.core.directional_disk(tuple(d))
    centre = np.asarray(centre)
    helper = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
    s = np.cross(d, helper)
    s /= np.linalg.norm(s)
    t = np.cross(d, s)
    k = np.arange(_SUN_PROBES - 1)
    r = radius * np.sqrt((k + 0.5) / (_SUN_PROBES - 1))
    phi = k * np.pi * (3 - np.sqrt(5))  # the golden angle
    ring = centre + (r * np.cos(phi))[:, None] * s + (r * np.sin(phi))[:, None] * t
    return np.vstack([centre[None], ring])


def _route_shares_camera_medium(outcome: np.ndarray) -> np.ndarray:
    """A light judged by its one route: it shares the camera's medium where the route reaches
    the camera, passing only surfaces that name no medium (opaque ones too: with one route
    there is nothing better to go by)."""
    return (outcome == _REACHES_CAMERA) | (outcome == _ONLY_OPAQUE_TO_CAMERA)


def _disk_medium(outcome: np.ndarray, side: np.ndarray, camera_medium: int) -> int:
    """The medium of a directional light's disk from its points' routes (the first one from
    the centre). Routes that decide vote: one reaching the camera for the camera's medium,
    one first crossing a shape that names a medium for the medium on the disk's side of it;
    the majority wins (a tie goes to the smaller index, vacuum first). Routes an opaque
    surface naming no medium ends do not vote; if none votes, the centre's route followed
    through such surfaces decides between the camera's medium and vacuum."""
    votes = np.concatenate(
        [
            np.full((outcome == _REACHES_CAMERA).sum(), camera_medium),
            side[outcome == _CROSSES_NAMED],
        ]
    )
    if votes.size:
        return int(_majority(votes[:, None].astype(np.int32))[0])
    return camera_medium if outcome[0] == _ONLY_OPAQUE_TO_CAMERA else -1


def _camera_routes(
    surfaces: _ProbeSurfaces, scene: Scene, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Outcome of the straight route from each point to the camera, and the medium on the
    point's side of the first shape naming a medium it crosses (-1 if none): _CROSSES_NAMED
    where it crosses such a shape first; _REACHES_CAMERA where it crosses only null or
    dielectric shapes naming none; otherwise an opaque unnamed surface comes first, and the
    route, followed through such surfaces, either crosses a named shape (_ENDS_OPAQUE) or
    not (_ONLY_OPAQUE_TO_CAMERA)."""
    to = np.asarray(scene.camera.origin, np.float64) - points
    dist = np.linalg.norm(to, axis=1)
    directions = to / np.maximum(dist, 1e-300)[:, None]
    directions[dist == 0] = (0, 0, 1)  # a point at the camera: a route of length 0
    crossed, side, opaque_first = surfaces.walk(points, directions, dist)
    outcome = np.where(
        crossed,
        np.where(opaque_first, _ENDS_OPAQUE, _CROSSES_NAMED),
        np.where(opaque_first, _ONLY_OPAQUE_TO_CAMERA, _REACHES_CAMERA),
    ).astype(np.int8)
    return outcome, side


def _majority(votes: np.ndarray) -> np.ndarray:
    """Most frequent value along axis 0 (ties: the smallest)."""
    out = np.empty(votes.shape[1], np.int32)
    for j in range(votes.shape[1]):
        values, counts = np.unique(votes[:, j], return_counts=True)
        out[j] = values[np.argmax(counts)]
    return out


def _emitting_triangles(native: NativeScene, scene: Scene) -> np.ndarray:
    emits = [s.emission is not None for s in scene.shapes]
    return np.flatnonzero(native.per_triangle(scene, emits))


# HG media at least this peaked defeat the light-side estimators (docs/media.md): measured on
# cbox-fog, 10 s runs of lt, pm, sppm and ppb were 50 % low to 22 % high at g = 0.999, and
# about 57 % dark at 0.9999 however long they ran.
PEAKED_HG_G = 0.999


def warn_about_peaked_phase_functions(scene: Scene) -> None:
    """A warning on stderr per medium whose HG phase function is too peaked for methods that
    evaluate it where light and camera paths meet (pt samples it instead)."""
    for name, m in scene.media.items():
        if m.phase.type == "hg" and abs(m.phase.g) >= PEAKED_HG_G:
            print(
                f"pgi: warning: {scene.path}: media.{name}.phase.g = {m.phase.g:g}: lt, pm, sppm "
                "and ppb evaluate the phase function where light and camera paths meet, and a "
                "peak this narrow leaves a few rare, huge samples: expect an image far too dark, "
                "with fireflies, that converges very slowly (pt samples the phase function and "
                "stays right)",
                file=sys.stderr,
            )
