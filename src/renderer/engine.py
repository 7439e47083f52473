"""Hands a loaded scene to the native core and to Embree: the same triangles for both."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from . import _core
from .errors import PgiError
from .scene.model import (
    VACUUM,
    Camera,
    DirectionalLight,
    Film,
    Medium,
    PointLight,
    Scene,
    SpotLight,
)
from .scene.triangles import kept_faces

# Voxels per majorant cell: small enough to follow a plume's shape, large
# enough that the DDA does not dominate. (bench/bench_media.py sweeps it: the
# tighter the majorants, the closer delta tracking gets to ratio tracking.)
MAJORANT_CELL = 4
# Ray-marching steps shorter than this fraction of a voxel refine nothing and cost hours.
_MIN_MARCH_STEP = 1e-3


# How far off an emitting triangle, on its front side, the walk from the camera ends, relative
# to the scene's size: beyond the surface offsets of rays, well within any medium's boundary.
_EMITTER_LIFT = 1e-4
# A triangle's corners, pulled this fraction of the way towards its centroid, are walked to as
# well: a medium's boundary that cuts across the triangle ends their walks in another medium.
_CORNER_PULL = 0.01


@dataclass(frozen=True)
class SplitEmitter:
    """An emitter whose parts end their walks from the camera in different media: a boundary
    of a medium cuts it, and light paths, which start in one medium per triangle, would start
    some of its light in the wrong one."""

    where: str  # the shape, as messages name it
    media: tuple[str, str]  # two of the media its parts lie in

    def describe(self) -> str:
        return (
            f"{self.where}: a boundary of a medium crosses this emitter (part of it lies in "
            f"{self.media[0]}, part in {self.media[1]})"
        )


@dataclass
class EmissionMedia:
    """The medium each light emits into, by the scene's rule (docs/scene-format.md, "Where
    lights emit"), as the core holds them (-1: vacuum); and what the rule found amiss."""

    per_light: np.ndarray  # per core light (area lights' entries unused)
    per_triangle: np.ndarray  # per triangle (-1 where none emits)
    split_emitters: list[SplitEmitter]
    # One line per light or emitting shape that states a medium where its walk ends in another.
    stated_elsewhere: list[str]


@dataclass
class NativeScene:
    core: _core.Scene
    triangles: np.ndarray  # (T, 3, 3) float64, the triangles both Embree and the core use
    kept: np.ndarray  # per face of every shape, in shape order: whether it is in `triangles`
    # As the core was given them: the index of each named medium; per triangle the medium
    # inside and outside (-1: none named) and whether its shape names a medium at all; the
    # core's light index of each of the scene's lights (area lights come first); and the
    # medium each light emits into.
    medium_ids: dict[str, int]
    interior: np.ndarray
    exterior: np.ndarray
    transition: np.ndarray
    light_ids: list[int]
    emission: EmissionMedia

    @cached_property
    def normals(self) -> np.ndarray:
        """(T, 3) unit normals of the triangles, oriented as the core's."""
        t = self.triangles
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    @property
    def dropped_triangles(self) -> int:
        return int((~self.kept).sum())

    def per_triangle(self, scene: Scene, values: list) -> np.ndarray:
        """One value per shape of ``scene``, repeated over the shape's triangles that were
        kept (the core's and Embree's triangle order)."""
        pairs = zip(scene.shapes, values, strict=True)
        return np.concatenate([np.full(len(s.faces), v) for s, v in pairs])[self.kept]


def camera_basis(camera: Camera, film: Film) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """forward, right, up: right/up scaled to the film's half-extent at unit distance.

    Follows Mitsuba's look_at and perspective conventions (fov along ``fov_axis``).
    """
    forward = camera.target - camera.origin
    forward = forward / np.linalg.norm(forward)
    left = np.cross(camera.up, forward)
    left = left / np.linalg.norm(left)
    up = np.cross(forward, left)
    aspect = film.width / film.height
    half = math.tan(math.radians(camera.fov) / 2)
    axis = camera.fov_axis
    if axis == "smaller":
        axis = "x" if film.width < film.height else "y"
    elif axis == "larger":
        axis = "x" if film.width >= film.height else "y"
    if axis == "x":
        tan_x, tan_y = half, half / aspect
    elif axis == "y":
        tan_x, tan_y = half * aspect, half
    elif axis == "diagonal":
        diag = math.hypot(film.width, film.height)
        tan_x, tan_y = half * film.width / diag, half * film.height / diag
    else:
        raise PgiError(f"camera.fov_axis: unknown axis {camera.fov_axis!r}")
    return forward, -left * tan_x, up * tan_y


def march_step(
    medium: Medium, integrator_step: float, where: str = "the scene: integrator.march_step"
) -> float:
    """Ray-marching step in world units: the scene's, or half the grid's smallest voxel.
    ``where``: where the step is written, for the message."""
    assert medium.density is not None and medium.to_world is not None
    voxel = float(
        (np.linalg.norm(medium.to_world[:3, :3], axis=0) / np.array(medium.density.shape)).min()
    )
    if integrator_step <= 0:
        return 0.5 * voxel
    if integrator_step < _MIN_MARCH_STEP * voxel:
        raise PgiError(
            f"{where}: {integrator_step:g} is below "
            f"{_MIN_MARCH_STEP:g} of medium {medium.name}'s smallest voxel ({voxel:g}): "
            "ray marching would take hours"
        )
    return integrator_step


def _add_medium(core: _core.Scene, m: Medium, scene: Scene, majorant_cell: int) -> int:
    """Describe one medium to the core; returns its id."""
    phase, g = _core.PhaseType[m.phase.type], float(m.phase.g)
    if m.type == "homogeneous":
        sigma_t = tuple(float(s) * m.scale for s in m.sigma_t)
        medium_id = core.add_homogeneous_medium(sigma_t, tuple(m.albedo), phase, g)
    else:
        density_zyx = np.ascontiguousarray(np.transpose(m.density, (2, 1, 0)), np.float32)
        world_to_local = np.linalg.inv(np.asarray(m.to_world, np.float64))
        medium_id = core.add_grid_medium(
            density_zyx,
            np.ascontiguousarray(world_to_local[:3]),
            float(m.sigma_t[0]) * m.scale,
            tuple(m.albedo),
            phase,
            g,
            majorant_cell,
        )
        estimator = scene.integrator.estimator
        step = march_step(m, scene.integrator.march_step, scene.where("integrator", "march_step"))
        _core.configure_medium(core, medium_id, _core.Estimator[estimator], step)
    if m.phase.type == "tabulated":
        _core.set_phase_table(core, medium_id, np.ascontiguousarray(m.phase.values, np.float64))
    return medium_id


def build_native_scene(scene: Scene, majorant_cell: int = MAJORANT_CELL) -> NativeScene:
    """Flatten shapes into one triangle list and describe everything else to the core.
    ``majorant_cell``: voxels per majorant-grid cell along each axis (benchmarks vary it)."""
    core = _core.Scene()
    core.roulette = _core.Roulette[scene.integrator.rr]
    material_ids = {}
    for name, m in scene.materials.items():
        material_ids[name] = core.add_material(
            _core.MaterialType[m.type], tuple(map(float, m.reflectance)), float(m.ior)
        )
    medium_ids = {
        name: _add_medium(core, m, scene, majorant_cell) for name, m in scene.media.items()
    }

    def medium(name: str | None) -> int:
        return -1 if name is None else medium_ids[name]

    tris, mats, inside, outside, transition, owner = [], [], [], [], [], []
    for index, shape in enumerate(scene.shapes):
        t = shape.vertices[shape.faces]
        tris.append(t)
        n = len(t)
        mats.append(np.full(n, material_ids[shape.material], np.int32))
        inside.append(np.full(n, medium(shape.interior), np.int32))
        outside.append(np.full(n, medium(shape.exterior), np.int32))
        # As in Mitsuba, a shape that names no medium leaves the current one unchanged.
        named = shape.interior is not None or shape.exterior is not None
        transition.append(np.full(n, named, np.uint8))
        owner.append(np.full(n, index, np.int32))
    triangles = np.concatenate(tris).astype(np.float64)
    owner = np.concatenate(owner)
    keep = np.concatenate(kept_faces(scene))  # Mitsuba drops the same ones
    triangles = np.ascontiguousarray(triangles[keep])
    owner = owner[keep]
    mats, inside, outside, transition = (
        np.concatenate(a)[keep] for a in (mats, inside, outside, transition)
    )

    emitter = np.full(len(triangles), -1, np.int32)
    for index, shape in enumerate(scene.shapes):
        if shape.emission is not None:  # kept_faces refused emitters with no triangle left
            members = np.flatnonzero(owner == index).astype(np.int32)
            emitter[members] = core.add_area_light(tuple(map(float, shape.emission)), members)
    core.set_triangles(triangles, mats, emitter, inside, outside, transition)

    light_ids = []  # the core's index of each of scene.lights
    for light in scene.lights:
        if isinstance(light, PointLight):
            added = core.add_point_light(tuple(light.position), tuple(light.intensity))
        elif isinstance(light, SpotLight):
            added = core.add_spot_light(
                tuple(light.position),
                tuple(light.target - light.position),
                tuple(light.intensity),
                math.radians(light.cutoff_angle),
                math.radians(light.beam_width),
            )
        elif isinstance(light, DirectionalLight):
            added = core.add_directional_light(tuple(light.direction), tuple(light.irradiance))
        else:
            raise TypeError(f"no native light for {type(light).__name__}")
        light_ids.append(added)

    forward, right, up = camera_basis(scene.camera, scene.film)
    core.set_camera(
        tuple(scene.camera.origin),
        tuple(forward),
        tuple(right),
        tuple(up),
        scene.film.width,
        scene.film.height,
        medium(scene.camera.medium),
    )
    core.finalize()
    native = NativeScene(
        core, triangles, keep, medium_ids, inside, outside, transition.astype(bool), light_ids,
        _emission_media(scene, core, triangles, owner, medium_ids, light_ids),
    )  # fmt: skip
    core.set_emission_media(native.emission.per_triangle, native.emission.per_light)
    return native


def _emission_media(
    scene: Scene,
    core: _core.Scene,
    triangles: np.ndarray,
    owner: np.ndarray,
    medium_ids: dict[str, int],
    light_ids: list[int],
) -> EmissionMedia:
    """The medium each light emits into (docs/scene-format.md, "Where lights emit"): the one
    it states; an emitter's exterior where it names media; otherwise where the straight walk
    from the camera to the light ends (Scene::walk_medium), and for a directional light the
    camera's medium where no shape names it (a fog that fills the scene), else vacuum.
    ``owner``: the shape of each of ``triangles``; the rest as the core was given them."""
    names = [VACUUM, *medium_ids]  # by core index + 1

    def medium(name: str | None) -> int:
        return -1 if name is None or name == VACUUM else medium_ids[name]

    per_light = np.full(core.light_count, -1, np.int32)
    per_triangle = np.full(len(triangles), -1, np.int32)
    splits: list[SplitEmitter] = []
    stated_elsewhere: list[str] = []

    def check_stated(where: str, stated: str | None, walked: int) -> None:
        if stated is not None and medium(stated) != walked:
            stated_elsewhere.append(
                f"{where}: states medium {stated}, but the straight walk from the camera to it "
                f"ends in {names[walked + 1]}; its light paths start in {stated}, as stated"
            )

    lift = _EMITTER_LIFT * float(np.ptp(triangles.reshape(-1, 3), axis=0).max())
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for index, shape in enumerate(scene.shapes):
        members = np.flatnonzero(owner == index)
        if shape.emission is None or not len(members):
            continue
        if shape.interior is not None or shape.exterior is not None:
            per_triangle[members] = medium(shape.exterior)  # its front side
            continue
        tri = triangles[members]
        centroid = tri.mean(axis=1)
        off = normals[members] * lift
        walked = core.walk_media(centroid + off)
        corners = [
            core.walk_media(tri[:, k] + _CORNER_PULL * (centroid - tri[:, k]) + off)
            for k in range(3)
        ]
        found = np.concatenate([walked, *corners])
        if np.any(found != walked[0]):
            other = found[found != walked[0]][0]
            media = names[walked[0] + 1], names[other + 1]
            splits.append(SplitEmitter(scene.where_shape(index), media))
        elif shape.medium is not None:
            check_stated(scene.where_shape(index), shape.medium, int(walked[0]))
        per_triangle[members] = walked if shape.medium is None else medium(shape.medium)

    fills_scene = scene.camera.medium is not None and not any(
        scene.camera.medium in (s.interior, s.exterior) for s in scene.shapes
    )
    for i, light in enumerate(scene.lights):
        if isinstance(light, DirectionalLight):
            rule = medium(scene.camera.medium) if fills_scene else -1
        else:
            position = np.asarray(light.position, np.float64)[None]
            rule = int(core.walk_media(position)[0])
            check_stated(scene.where("lights", i), light.medium, rule)
        per_light[light_ids[i]] = rule if light.medium is None else medium(light.medium)
    return EmissionMedia(per_light, per_triangle, splits, stated_elsewhere)
