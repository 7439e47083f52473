"""Default kernel radii of pm, sppm and ppb, derived from what the photons see (docs/methods.md,
"Default radii").

A radius that neither ``{name}_world`` nor ``{name}_relative`` gives is measured by a *pilot*
in the first iteration run, between its light paths and its camera paths: the method's own
kernels run once on that iteration's light paths and on a regular sample of about
PILOT_QUERIES of its camera paths, and estimate nothing (reusing the light paths costs the
pilot a camera pass of a few thousand paths, not an iteration's photons; the first iteration's
radii then depend on its own photons, as the later iterations' do not). Where an estimate
would be made (a camera-path vertex on a diffuse surface; in a medium, a camera-path segment up
to a free flight along it), they record how far the k nearest photons (ppb: beams) that
estimate would gather lie, k being ``{name}_neighbours``. Each kernel (the surfaces, and each
medium on its own) takes the median of its queries' distances, so that a typical query gathers
k photons an iteration, but at most EXTENT_FRACTION of the bounding radius of the photons it
could gather (a medium's: its own photons'), so that a kernel stays small against the medium
it estimates, and in a grid medium at most FREE_PATHS mean free paths where the flights ended (pm
and sppm; not ppb's beams).
pm's and sppm's kernels, and ppb's beams in grid media, are also at most their *scene's cap*,
the radius the old rule gave them (the fallback, a fraction of the scene's radius): where
photons are few, a kernel that gathers k of them each iteration costs more in bias and time
than it saves in variance at the study's budgets (crepuscular's fog 0.17 against 0.046), and
the cap only ever narrows a kernel.
The radii then depend on the photons around the places the camera sees wherever the scene's
bounding box would make them too wide: a backdrop 20 times as large leaves the radii in a
medium as they were.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene.model import Film, Scene

# Camera paths the pilot samples (every n-th path of an iteration of one sample per pixel):
# 4096 took every path at 64 x 64, the pilot then costing about an iteration of ppb.
PILOT_QUERIES = 1024
# A derived radius is at most this fraction of the bounding radius of its kernel's photons.
EXTENT_FRACTION = 0.1
# A grid medium's derived radius is at most this many of its typical mean free paths (the median
# of 1 / sigma_t where the pilot's flights ended): where density varies inside a medium, a kernel
# wider than that reaches from a camera ray still in thin or empty parts to the photons of dense
# ones. Not in homogeneous media: their only edges are their boundaries, which the boundary
# kernels follow, and a laterally uniform slab needs kernels of many free paths to gather photons.
# Not ppb's beams either (methods/ppb.py): their estimate weighs them by sigma_s at the camera.
FREE_PATHS = 1.0


@dataclass(frozen=True)
class DerivedRadius:
    """A kernel's radius in world units and how it was set (for the sidecar)."""

    world: float
    rule: str

    def record(self) -> dict:
        return {"world": self.world, "rule": self.rule}


def pilot_stride(film: Film, spp: int) -> int:
    """Every how many camera paths of an iteration (``spp`` per pixel, path i through pixel
    i mod pixels) the pilot samples one: about PILOT_QUERIES in all, and a stride prime to the
    number of pixels, so that its paths go through every pixel in turn."""
    pixels = film.width * film.height
    stride = max(1, -(-pixels * spp // PILOT_QUERIES))
    while math.gcd(stride, pixels) != 1:
        stride += 1
    return stride


def run_pilot(method, surface_neighbours: int, medium_neighbours: int, iteration: int) -> None:
    """Run ``method``'s camera paths of ``iteration`` as the pilot: its kernel (pm's photon
    gathering or ppb's beam gathering) records the k nearest neighbours of each query point, and
    is set back to gathering alone afterwards, whatever happens."""
    kernel = method.camera_paths.kernel
    kernel.set_pilot(
        surface_neighbours,
        medium_neighbours,
        EXTENT_FRACTION,
        pilot_stride(method.scene.film, method.spp_per_iteration),
    )
    try:
        method.camera_paths.run(iteration)
    finally:
        kernel.set_pilot(0, 0, EXTENT_FRACTION, 1)


def given(world: float, key: str) -> DerivedRadius:
    return DerivedRadius(world, f"given ({key})")


def is_grid(scene: Scene, medium_ids: dict[str, int], index: int) -> bool:
    """Whether kernel ``index`` is a grid medium's (-1, the surfaces', is not)."""
    names = {i: name for name, i in medium_ids.items()}
    return index in names and scene.media[names[index]].type == "grid"


def from_pilot(
    distances: np.ndarray,
    extent: float,
    neighbours: int,
    what: str,
    fallback_world: float,
    fallback_rule: str,
    minimum: float,
    free_paths: np.ndarray | None = None,
    scene_cap: bool = True,
) -> DerivedRadius:
    """The radius of one kernel from its pilot queries (``distances`` to the k-th nearest
    photon or beam of each, inf where fewer than k lie within the cap) and the bounding radius
    ``extent`` of what it could gather; ``fallback_world`` when the pilot saw nothing to go by.
    ``what`` names the queries in the rule, e.g. "camera-path vertices on diffuse surfaces".
    ``free_paths`` (a grid medium's queries; None elsewhere): the mean free path where each
    one's flight ended; the radius is at most FREE_PATHS times their median. ``scene_cap``: the
    radius is also at most ``fallback_world``, the rule from the scene's radius."""
    if extent <= 0:
        return DerivedRadius(fallback_world, f"{fallback_rule}: the pilot found nothing to gather")
    if len(distances) == 0:
        return DerivedRadius(fallback_world, f"{fallback_rule}: no pilot query reached {what}")
    median = float(np.median(distances))
    rule = f"median distance to the {neighbours} nearest over {len(distances)} {what}"
    bounds = [(EXTENT_FRACTION * extent, f"{EXTENT_FRACTION:g} of the extent of what it gathers "
               f"({extent:.4g})")]  # fmt: skip
    if free_paths is not None and len(free_paths):
        free_path = float(np.median(free_paths))
        bounds.append((FREE_PATHS * free_path, f"{FREE_PATHS:g} x the median mean free path "
                       f"where its flights ended ({free_path:.4g})"))  # fmt: skip
    if scene_cap:
        bounds.append((fallback_world, f"{fallback_rule} (the scene's cap)"))
    cap, cap_rule = min(bounds)
    if not median < cap:
        return DerivedRadius(max(cap, minimum), f"{cap_rule}: {rule} lies beyond it")
    return DerivedRadius(max(median, minimum), rule)
