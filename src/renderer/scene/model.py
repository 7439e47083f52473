"""The resolved scene: what both renderers receive after a scene file is loaded.

Everything here is in world space and already validated. Shapes are plain
triangle lists (generated primitives and mesh files alike), so our renderer
and Mitsuba see the same triangles. Colours are linear RGB triples.

Conventions (each matches Mitsuba 3 and has a parity test):
- A triangle's geometric normal is cross(v1 - v0, v2 - v0) normalised. The
  *exterior* medium lies on the side the normal points to, the *interior*
  medium on the other side. After a surface event at a shape that names an
  interior or exterior medium, the path continues in the medium on the side
  its new direction points to; a shape that names neither leaves the path in
  the medium it was in (walls inside fog reflect back into the fog).
- Area emission is one-sided: radiance leaves the front (normal) side only.
- The medium a light emits into is the one it states (``medium``; ``VACUUM`` for none), an
  emitter that names media emits into its exterior, and otherwise the scene's rule decides
  (docs/scene-format.md, "Where lights emit"; renderer.engine computes it).
- Density grids are indexed ``density[x, y, z]`` (as OpenVDB's copyToArray
  gives them); voxel (i, j, k) has its centre at ((i, j, k) + 0.5) / res in
  the unit cube, which ``to_world`` places in the scene. Values are
  interpolated trilinearly, as Mitsuba's ``gridvolume`` does.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

RGB = tuple[float, float, float]

# The name a light states for no medium; no medium of the `media` table may take it.
VACUUM = "vacuum"


@dataclass(frozen=True)
class Camera:
    origin: np.ndarray  # (3,)
    target: np.ndarray  # (3,)
    up: np.ndarray  # (3,)
    fov: float  # degrees, measured along fov_axis
    fov_axis: str  # "x", "y", "diagonal", "smaller" or "larger"
    medium: str | None = None  # name of the medium the camera sits in


@dataclass(frozen=True)
class Film:
    width: int
    height: int


@dataclass(frozen=True)
class Integrator:
    max_depth: int = -1  # Mitsuba's meaning: 1 = emitters only, 2 = direct light; -1 = unlimited
    rr_depth: int = 5  # Russian roulette starts at this depth, as in Mitsuba
    # Its rule: "throughput" (survive with probability min(1, throughput), as pbrt-v4; weights
    # stay bounded in white, dense media) or "mitsuba" (capped at 0.95, as Mitsuba's volpath;
    # ours only: Mitsuba always plays its own).
    rr: str = "throughput"
    # Transmittance estimator in density grids: "delta", "ratio", "residual" or "raymarch"
    # (ours only; Mitsuba's volpath always uses its own). march_step: raymarch step length in
    # world units, 0 = half the grid's smallest voxel.
    estimator: str = "ratio"
    march_step: float = 0.0


@dataclass(frozen=True)
class Material:
    name: str
    type: str  # "diffuse", "mirror", "dielectric", "null"
    reflectance: RGB = (0.5, 0.5, 0.5)  # diffuse only
    ior: float = 1.5  # dielectric only: interior IOR over exterior IOR


@dataclass(frozen=True)
class Phase:
    type: str = "isotropic"  # "isotropic", "hg", "rayleigh" or "tabulated"
    g: float = 0.0  # HG asymmetry; g > 0 scatters forward
    # tabulated only: values at cos(theta) = linspace(-1, 1, n) (+1 forward), linearly
    # interpolated and normalised (Mitsuba's tabphase)
    values: np.ndarray | None = None


@dataclass(frozen=True)
class Medium:
    name: str
    type: str  # "homogeneous" or "grid"
    sigma_t: RGB  # extinction per unit length before ``scale`` (grid: multiplies density)
    albedo: RGB
    scale: float = 1.0
    phase: Phase = field(default_factory=Phase)
    density: np.ndarray | None = None  # grid only: float32 [x, y, z], values >= 0
    to_world: np.ndarray | None = None  # grid only: 4x4, maps the unit cube into the scene
    source: Path | None = None  # grid only: file the density came from (for messages)


@dataclass(frozen=True)
class Shape:
    name: str
    vertices: np.ndarray  # (V, 3) float64, world space
    faces: np.ndarray  # (F, 3) int32
    material: str  # key into Scene.materials
    emission: RGB | None = None  # area light radiance, one-sided
    # Medium names. A shape naming neither leaves a path's medium unchanged; one naming only
    # one side has vacuum on the other.
    interior: str | None = None
    exterior: str | None = None
    # Emitters naming neither: the medium stated to emit into (a name from media, or VACUUM);
    # None: the scene's rule decides.
    medium: str | None = None


@dataclass(frozen=True)
class PointLight:
    position: np.ndarray
    intensity: RGB  # W/sr
    medium: str | None = None  # stated: a name from media, or VACUUM; None: the rule's


@dataclass(frozen=True)
class SpotLight:
    position: np.ndarray
    target: np.ndarray
    intensity: RGB  # W/sr on the axis
    cutoff_angle: float = 20.0  # degrees: no light outside
    beam_width: float = 15.0  # degrees: full intensity inside; linear falloff in angle between
    medium: str | None = None  # stated: a name from media, or VACUUM; None: the rule's


@dataclass(frozen=True)
class DirectionalLight:
    direction: np.ndarray  # direction the light travels, normalised
    irradiance: RGB  # W/m^2 on a surface facing the light
    medium: str | None = None  # stated: a name from media, or VACUUM; None: the rule's


Light = PointLight | SpotLight | DirectionalLight


def format_path(path: Sequence[str | int]) -> str:
    """A key path as messages write it: media.fog.phase.g, shapes[3].file."""
    out = ""
    for k in path:
        out += f"[{k}]" if isinstance(k, int) else (f".{k}" if out else str(k))
    return out or "(top level)"


@dataclass(frozen=True)
class Scene:
    name: str
    path: Path  # the scene file
    camera: Camera
    film: Film
    integrator: Integrator
    materials: dict[str, Material]
    media: dict[str, Medium]
    shapes: list[Shape]
    lights: list[Light]
    description: str = ""
    stresses: list[str] = field(default_factory=list)  # light paths this scene exists to test
    expected_winners: list[str] = field(default_factory=list)  # methods that should win here
    # Where any key path is written, for checks made after loading (the loader's: the file,
    # an include or an override, and the key path there); None: the scene file itself.
    locate_key: Callable[[tuple[str | int, ...]], str] | None = field(
        default=None, compare=False, repr=False
    )

    def where(self, *key: str | int) -> str:
        """Where the value at key path ``key`` is written, as loading errors name it
        ("scene.yaml (override 'media.fog.phase.g=0.9995'): media.fog.phase.g")."""
        if self.locate_key is not None:
            return self.locate_key(key)
        return f"{self.path}: {format_path(key)}"

    def where_shape(self, index: int) -> str:
        """Where shape ``index`` is written, and its name: for an error message."""
        name = self.shapes[index].name
        where = self.where("shapes", index)
        return f"{where} ({name})" if name else where

    @property
    def has_media(self) -> bool:
        return bool(self.media)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds of all triangles."""
        lo = np.min([s.vertices.min(axis=0) for s in self.shapes], axis=0)
        hi = np.max([s.vertices.max(axis=0) for s in self.shapes], axis=0)
        return lo, hi
