"""Which triangles both renderers get: degenerate ones are dropped for each alike."""

from __future__ import annotations

import numpy as np

from ..errors import PgiError
from .model import Scene

# A triangle whose area is below this fraction of the squared magnitude of its own coordinates
# has no normal at the precision its vertices are stored with (float32 in Embree and Mitsuba),
# and no ray can hit it. The bound is the triangle's own: a small triangle near the origin of
# a large scene is kept.
DEGENERATE_AREA = 1e-14


def kept_faces(scene: Scene) -> list[np.ndarray]:
    """Per shape, the mask of its faces that are not degenerate. An emitter with none left is
    an error: it would emit nothing."""
    masks = []
    for index, shape in enumerate(scene.shapes):
        t = shape.vertices[shape.faces].astype(np.float64)
        area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        size = np.abs(t).max(axis=(1, 2), initial=0.0)
        keep = area > DEGENERATE_AREA * size**2
        if shape.emission is not None and not keep.any():
            raise PgiError(
                f"{scene.where_shape(index)}: every triangle of this "
                f"emitter is degenerate (area below {DEGENERATE_AREA:g} of its squared "
                "coordinates): it would emit nothing"
            )
        masks.append(keep)
    return masks
