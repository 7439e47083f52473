"""A slab of fog under a directional light, whose single scattering has a closed form.

The scene (found by rendering scenes no one here wrote): fog 1 unit thick and `width` wide (a
cube scaled to [width / 2, width / 2, 0.5], null boundary, sigma_t 1, albedo 0.8, HG g 0.3),
lit by a directional light of irradiance 1 travelling along (0.5, 0, 0.866), 30 degrees from
the slab's normal, so that it enters through the far face; a camera at (0, 0, 5) looks at the
origin with a 10-degree field of view; max_depth 2 (single scattering only). Along a camera
direction w the radiance is

    L(w) = sigma_s p(cos theta) E integral_0^d exp(-sigma_t s / |w_z|)
                                              exp(-sigma_t (d - s) / cos 30) ds / |w_z|

(s the depth below the near face, d = 1, theta between the light's direction and -w), in
closed form (exp(-b d) - exp(-a d)) / (a - b) / |w_z| with a = sigma_t / |w_z|,
b = sigma_t / cos 30. A pixel is its mean over the pixel (box filter): the mean over 16 x 16
stratified directions per pixel, from the renderer's own camera rays (checked against
Mitsuba's in test_mitsuba_export), within 1e-6 of the pixel's integral. At 32 x 32 the image
mean is 0.045795. The visible part of the slab (under 1 unit across) takes light that
entered it within 0.6 of it: any width from 4 up has the same image.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from renderer.scene import load_scene
from renderer.scene.model import Scene

SIGMA_T, ALBEDO, G, THICKNESS, IRRADIANCE = 1.0, 0.8, 0.3, 1.0, 1.0
LIGHT = np.array([0.5, 0.0, np.sqrt(3) / 2])  # the direction the light travels
IMAGE_MEAN = 0.045795  # the closed form's, at 32 x 32


def slab_scene(folder: Path, width: float = 1000.0, res: int = 32, max_depth: int = 2) -> Scene:
    """The slab `width` units wide, written to `folder` and loaded."""
    half = width / 2
    doc = {
        "name": f"slab-{width:g}",
        "description": "a slab of fog under a directional light (tests/slab.py)",
        "integrator": {"max_depth": max_depth, "rr_depth": 5},
        "camera": {"origin": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 10},
        "film": {"width": res, "height": res},
        "media": {
            "fog": {
                "type": "homogeneous",
                "sigma_t": SIGMA_T,
                "albedo": ALBEDO,
                "phase": {"type": "hg", "g": G},
            }
        },
        "materials": {"boundary": {"type": "null"}},
        "shapes": [
            {
                "name": "slab",
                "type": "cube",
                "material": "boundary",
                "interior": "fog",
                "transform": [{"scale": [half, half, THICKNESS / 2]}],
            }
        ],
        "lights": [{"type": "directional", "direction": LIGHT.tolist(), "irradiance": IRRADIANCE}],
    }
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "scene.yaml").write_text(yaml.safe_dump(doc))
    return load_scene(folder / "scene.yaml")


def henyey_greenstein(cos: np.ndarray) -> np.ndarray:
    return (1 - G * G) / (4 * np.pi * (1 + G * G - 2 * G * cos) ** 1.5)


def closed_form(scene: Scene, sub: int = 16) -> np.ndarray:
    """Per pixel (H, W, 3): the single-scattering radiance, averaged over sub x sub directions
    per pixel (gray: the same in every channel)."""
    from renderer import _core
    from renderer.engine import build_native_scene

    core = build_native_scene(scene).core
    w, h = scene.film.width, scene.film.height
    s = (np.arange(sub) + 0.5) / sub
    fx = (np.arange(w)[:, None] + s[None, :]).ravel()
    fy = (np.arange(h)[:, None] + s[None, :]).ravel()
    x, y = np.meshgrid(fx, fy)
    dirs = _core.camera_directions(core, np.stack([x.ravel(), y.ravel()], 1).astype(np.float64))
    wz = np.abs(dirs[:, 2])
    a, b = SIGMA_T / wz, SIGMA_T / LIGHT[2]
    depth_integral = (np.exp(-b * THICKNESS) - np.exp(-a * THICKNESS)) / (a - b) / wz
    radiance = SIGMA_T * ALBEDO * henyey_greenstein(-(dirs @ LIGHT)) * IRRADIANCE * depth_integral
    pixels = radiance.reshape(h, sub, w, sub).mean(axis=(1, 3))
    return np.repeat(pixels[..., None], 3, axis=-1)
