"""Translate a resolved :class:`Scene` into a Mitsuba 3 scene dict (for ``mi.load_dict``).

Both renderers must see the same scene, so every shape goes to Mitsuba as a triangle mesh
built from our own numpy triangles (flat face normals, no vertex normals), and every default
Mitsuba would otherwise pick is set explicitly (box film filter, HG g, dielectric ext_ior,
near clip). The dict contains already-built Mitsuba objects (meshes, media, BSDFs) so that one
medium instance is shared by the sensor and the shapes that bound it; build it with the
variant :func:`renderer.mitsuba_env.import_mitsuba` selects, and load it in the same variant.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import Any

import numpy as np

from renderer.errors import PgiError
from renderer.mitsuba_env import import_mitsuba
from renderer.scene.model import (
    RGB,
    DirectionalLight,
    Light,
    Material,
    Medium,
    Phase,
    PointLight,
    Scene,
    Shape,
    SpotLight,
)
from renderer.scene.triangles import kept_faces

# Mitsuba starts camera rays at a near plane (default 0.01) and ends them at a far plane, both
# in scene units: the segment before the near plane and its medium attenuation are skipped,
# everything past the far plane is missed. Ours start at the camera and never end, so both
# planes are set relative to the scene's reach from the camera, the near one far below what
# float32 resolves there (Mitsuba rounds the ray origin to float32 anyway; its directions were
# measured within 1.2e-7 of ours for far / near ratios up to 1e18), so that a small medium
# around the camera in a scene of large reach loses no more than 1e-9 of that reach.
NEAR_CLIP = 1e-9  # x reach
FAR_CLIP = 1e6  # x reach


# Mitsuba moves a ray's origin off a surface by (1 + the point's largest |coordinate|) x
# 2^-24 x 1500 (Interaction::offset_p): a fixed length, not one relative to the scene.
MITSUBA_RAY_EPSILON = 2.0**-24 * 1500
# Largest ratio of that offset to the scene's extent without a warning. cbox-fog scaled
# down, its fog scaled up (pt unchanged at every scale): Mitsuba's image mean was right at a
# ratio of 2.6e-3 (scale 1e-2), 22 % dark at 5.2e-3, 11 % dark at 2.6e-2, 43 % bright at 0.26
# and black at 2.6 (the extent of the shapes and grid boxes, where rays leave surfaces; not
# of a distant camera or light). The shipped scenes have 5-8e-5.
MAX_MITSUBA_OFFSET_RATIO = 1e-3


def _scene_points(scene: Scene, lights_and_camera: bool = True) -> np.ndarray:
    """Every triangle vertex and grid-box corner; with ``lights_and_camera``, also every light
    position and the camera's origin."""
    cube = np.array([[x, y, z, 1.0] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    points = [s.vertices for s in scene.shapes]
    points += [(cube @ m.to_world.T)[:, :3] for m in scene.media.values() if m.to_world is not None]
    if lights_and_camera:
        placed = [li for li in scene.lights if hasattr(li, "position")]
        points += [np.reshape(li.position, (1, 3)) for li in placed]
        points.append(np.reshape(scene.camera.origin, (1, 3)))
    return np.concatenate(points)


def camera_reach(scene: Scene) -> float:
    """Distance from the camera to the farthest triangle vertex, grid-box corner or light."""
    offsets = _scene_points(scene) - scene.camera.origin
    return max(float(np.linalg.norm(offsets, axis=1).max()), 1e-30)


def check_mitsuba_scale(scene: Scene) -> None:
    """Warn (on stderr) about a scene so small, or so far from the origin, that Mitsuba's
    fixed ray offset is not small against it: its image may be wrong with no error of its
    own. A warning, not a refusal: a small absorber seen through null boundaries alone
    renders right (test_camera_rays_in_a_medium_reach_any_scale)."""
    points = _scene_points(scene, lights_and_camera=False)  # where rays leave surfaces
    extent = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    reach = float(np.abs(points).max())
    offset = (1 + reach) * MITSUBA_RAY_EPSILON
    if offset > MAX_MITSUBA_OFFSET_RATIO * extent:
        print(
            f"pgi: warning: {scene.path}: the scene spans {extent:.3g} units and reaches "
            f"{reach:.3g} from the origin, and Mitsuba offsets its rays from surfaces by "
            f"{offset:.2g} units, over {MAX_MITSUBA_OFFSET_RATIO:g} of the scene's size: a "
            "scaled-down cbox-fog came out 11-43 % wrong from 5x that; scale the scene up (and "
            "sigma_t down by the same factor) or move it towards the origin",
            file=sys.stderr,
        )


def _rgb(c: RGB) -> dict[str, Any]:
    return {"type": "rgb", "value": [float(x) for x in c]}


def _const_volume(c: RGB) -> dict[str, Any]:
    # constvolume parses its rgb without the [0, 1] reflectance check, so sigma_t may exceed 1
    return {"type": "constvolume", "value": _rgb(c)}


def _bsdf(m: Material) -> dict[str, Any]:
    if m.type == "diffuse":
        return {"type": "diffuse", "reflectance": _rgb(m.reflectance)}
    if m.type == "mirror":  # conductor with material "none": reflectance exactly 1
        return {"type": "conductor", "material": "none"}
    if m.type == "dielectric":
        return {"type": "dielectric", "int_ior": float(m.ior), "ext_ior": 1.0}
    if m.type == "null":
        return {"type": "null"}
    raise PgiError(f"material {m.name!r}: type {m.type!r} has no Mitsuba equivalent")


def phase_dict(p: Phase) -> dict[str, Any]:
    if p.type == "isotropic":
        return {"type": "isotropic"}
    if p.type == "hg":
        return {"type": "hg", "g": float(p.g)}
    if p.type == "rayleigh":
        return {"type": "rayleigh"}
    if p.type == "tabulated":
        assert p.values is not None
        return {"type": "tabphase", "values": ", ".join(repr(float(v)) for v in p.values)}
    raise PgiError(f"phase function {p.type!r} has no Mitsuba equivalent here")


def grid_data(m: Medium) -> np.ndarray:
    """sigma_t * density as Mitsuba's gridvolume wants it: float32 (Z, Y, X, C), C = 1 or 3."""
    assert m.density is not None
    zyx = np.transpose(m.density, (2, 1, 0)).astype(np.float32)
    sigma_t = np.asarray(m.sigma_t, dtype=np.float32)
    if np.all(sigma_t == sigma_t[0]):
        return np.ascontiguousarray((zyx * sigma_t[0])[..., None])
    return np.ascontiguousarray(zyx[..., None] * sigma_t)


def _medium(mi: Any, m: Medium) -> dict[str, Any]:
    common = {
        "albedo": _const_volume(m.albedo),
        "scale": float(m.scale),
        "phase": phase_dict(m.phase),
    }
    if m.type == "homogeneous":
        return {"type": "homogeneous", "sigma_t": _const_volume(m.sigma_t), **common}
    if m.type != "grid":
        raise PgiError(f"medium {m.name!r}: type {m.type!r} has no Mitsuba equivalent")
    assert m.to_world is not None
    lin = m.to_world[:3, :3]
    if np.any(lin - np.diag(np.diag(lin))):
        # Mitsuba bounds a grid by the axis-aligned box of its transformed cube and extends
        # edge values into the part of that box outside the cube: only axis-aligned grids match.
        raise PgiError(
            f"{m.source}: medium {m.name!r}: Mitsuba supports only axis-aligned grids "
            "(transform with scale and translate, no rotation)"
        )
    grid = {
        "type": "gridvolume",
        "grid": mi.VolumeGrid(grid_data(m)),
        "to_world": mi.ScalarTransform4f(m.to_world.tolist()),
        "filter_type": "trilinear",
        "wrap_mode": "clamp",
    }
    # Grid extinction is grey. Mitsuba's default (spectral extinction) weights a path by tr / pdf
    # of the whole segment to the next surface at the majorant: both underflow float32 past an
    # optical depth of ~87, and paths through a shape reaching far beyond its grid went black.
    return {"type": "heterogeneous", "sigma_t": grid, "has_spectral_extinction": False, **common}


def _mesh(
    mi: Any, s: Shape, faces: np.ndarray, bsdfs: dict[str, Any], media: dict[str, Any]
) -> Any:
    props = mi.Properties()
    props["bsdf"] = bsdfs[s.material]
    if s.emission is not None:
        props["emitter"] = mi.load_dict({"type": "area", "radiance": _rgb(s.emission)})
    if s.interior is not None:
        props["interior"] = media[s.interior]
    if s.exterior is not None:
        props["exterior"] = media[s.exterior]
    mesh = mi.Mesh(
        s.name,
        vertex_count=len(s.vertices),
        face_count=len(faces),
        props=props,
        has_vertex_normals=False,
        has_vertex_texcoords=False,
    )
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.ravel(s.vertices.astype(np.float32))
    params["faces"] = np.ravel(faces.astype(np.uint32))
    params.update()
    return mesh


def _look_at(mi: Any, origin: np.ndarray, target: np.ndarray, up: np.ndarray) -> Any:
    # Mitsuba takes target - origin in float32: a target within float32 spacing of the
    # origin (valid in our float64) would give no direction and a black image. The same
    # direction from a target at least as far as the origin is from 0 survives the rounding.
    origin = np.asarray(origin, np.float64)
    offset = np.asarray(target, np.float64) - origin
    length = float(np.linalg.norm(offset))
    target = origin + offset / length * max(length, float(np.abs(origin).max()), 1.0)
    return mi.ScalarTransform4f().look_at(
        origin=[float(x) for x in origin],
        target=[float(x) for x in target],
        up=[float(x) for x in up],
    )


def _light(mi: Any, light: Light) -> dict[str, Any]:
    if isinstance(light, PointLight):
        return {
            "type": "point",
            "position": [float(x) for x in light.position],
            "intensity": _rgb(light.intensity),
        }
    if isinstance(light, SpotLight):
        axis = light.target - light.position
        up = np.eye(3)[np.argmin(np.abs(axis))]  # any vector not parallel to the axis
        return {
            "type": "spot",
            "to_world": _look_at(mi, light.position, light.target, up),
            "intensity": _rgb(light.intensity),
            "cutoff_angle": float(light.cutoff_angle),
            "beam_width": float(light.beam_width),
        }
    if isinstance(light, DirectionalLight):
        return {
            "type": "directional",
            "direction": [float(x) for x in light.direction],
            "irradiance": _rgb(light.irradiance),
        }
    raise PgiError(f"light type {type(light).__name__} has no Mitsuba equivalent")


def has_chromatic_extinction(scene: Scene) -> bool:
    """Whether some medium's extinction differs between colour channels."""
    return any(len(set(m.sigma_t)) > 1 for m in scene.media.values())


def grey_channel_scenes(scene: Scene) -> list[Scene]:
    """Three scenes whose channel c is channel c of ``scene``: every medium's extinction and
    albedo set to their channel-c values. RGB transport never mixes channels, so this is exact,
    and each render needs no spectral MIS.

    Mitsuba 3.9's ``volpath`` samples distances by one channel's extinction and weights the
    others by that channel's pdf alone, an estimator whose tail grows with the ratio between
    channels: on cbox-fog with sigma_t [0.2, 1, 3] its mean at 40 x 96 spp was 4 % low in red
    and 5 % in blue against pt. ``volpathmis`` (spectral MIS) fixed that case but on sigma_t
    [0.2, 2, 8] its blue was still 2.8 % below the same channel rendered grey (two 8192-spp
    references against one), where pt agreed with the grey render to 0.1 %."""
    scenes = []
    for c in range(3):
        media = {
            name: replace(m, sigma_t=(m.sigma_t[c],) * 3, albedo=(m.albedo[c],) * 3)
            for name, m in scene.media.items()
        }
        scenes.append(replace(scene, media=media))
    return scenes


# Mitsuba samples HG in single precision: on cbox-fog (HG media only scatter forward as g
# nears 1, so the image tends to that of the fog with albedo 0) it was right at g = 0.999,
# and its image 36 % dark at 0.9999 (40 % in the light's shadow; 66 % there at 0.99999),
# where pt stays right.
MAX_MITSUBA_HG_G = 0.999


def to_mitsuba_dict(scene: Scene, integrator: str = "volpath") -> dict[str, Any]:
    """A dict for ``mi.load_dict`` describing ``scene`` for Mitsuba's ``integrator`` (volpath,
    or volpathmis: the two take the same parameters)."""
    mi = import_mitsuba()
    check_mitsuba_scale(scene)
    for name, m in scene.media.items():
        if m.phase.type == "hg" and abs(m.phase.g) > MAX_MITSUBA_HG_G:
            raise PgiError(
                f"{scene.where('media', name, 'phase', 'g')} = {m.phase.g:g}: Mitsuba's HG "
                f"sampling is biased beyond |g| = {MAX_MITSUBA_HG_G:g} (cbox-fog at g = 0.9999 "
                "came out 36 % dark), so its image would be no reference; pgi's own methods "
                "render it"
            )
        if 0 in m.sigma_t and any(m.sigma_t):
            # Measured on cbox-fog with sigma_t [0, 1, 3]: volpath returns NaN everywhere, and
            # volpathmis 49 % of our green and 14 % of our blue (with 1e-7 for 0 it agrees).
            raise PgiError(
                f"{scene.where('media', name, 'sigma_t')} = {list(m.sigma_t)}: Mitsuba cannot "
                "render extinction that is zero in some channels but not all; give those "
                "channels a small positive value (e.g. 1e-7)"
            )
    media = {name: mi.load_dict(_medium(mi, m)) for name, m in scene.media.items()}
    bsdfs = {name: mi.load_dict(_bsdf(m)) for name, m in scene.materials.items()}
    cam = scene.camera
    reach = camera_reach(scene)
    sensor: dict[str, Any] = {
        "type": "perspective",
        "fov": float(cam.fov),
        "fov_axis": cam.fov_axis,
        "to_world": _look_at(mi, cam.origin, cam.target, cam.up),
        "near_clip": NEAR_CLIP * reach,
        "far_clip": FAR_CLIP * reach,
        "film": {
            "type": "hdrfilm",
            "width": scene.film.width,
            "height": scene.film.height,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
        "sampler": {"type": "independent", "sample_count": 1},
    }
    if cam.medium is not None:
        sensor["medium"] = media[cam.medium]
    d: dict[str, Any] = {
        "type": "scene",
        "integrator": {
            "type": integrator,
            "max_depth": scene.integrator.max_depth,
            "rr_depth": scene.integrator.rr_depth,
        },
        "sensor": sensor,
    }
    # The triangles our renderer keeps: degenerate ones are dropped for both.
    for i, (s, keep) in enumerate(zip(scene.shapes, kept_faces(scene), strict=True)):
        if keep.any():
            d[f"shape_{i:03d}"] = _mesh(mi, s, s.faces[keep], bsdfs, media)
    for i, (light, medium) in enumerate(zip(scene.lights, _light_media(scene), strict=True)):
        d[f"light_{i:03d}"] = _light(mi, light)
        if medium is not None:  # where the light sits, as ours has it (emitter.get_medium())
            d[f"light_{i:03d}"]["medium"] = media[medium]
    return d


def _light_media(scene: Scene) -> list[str | None]:
    """The medium each of the scene's lights emits into (None: vacuum), by the scene's rule
    (docs/scene-format.md, "Where lights emit"), which the native scene computes."""
    if not scene.media:
        return [None] * len(scene.lights)
    from renderer.engine import build_native_scene

    native = build_native_scene(scene)
    names = list(native.medium_ids)
    per_light = native.emission.per_light[native.light_ids]
    return [names[m] if m >= 0 else None for m in per_light]


def load_mitsuba_scene(scene: Scene, integrator: str = "volpath") -> Any:
    """The ``mi.Scene`` for ``scene``, rendered by ``integrator``."""
    mi = import_mitsuba()
    try:
        return mi.load_dict(to_mitsuba_dict(scene, integrator))
    except RuntimeError as e:
        raise PgiError(f"{scene.path}: Mitsuba cannot load this scene: {e}") from e
