"""Scenes: the YAML scene format, its loader, and the resolved scene both renderers receive."""

from renderer.scene.loader import find_scene_file, load_scene
from renderer.scene.model import (
    Camera,
    DirectionalLight,
    Film,
    Integrator,
    Light,
    Material,
    Medium,
    Phase,
    PointLight,
    Scene,
    Shape,
    SpotLight,
)

__all__ = [
    "Camera",
    "DirectionalLight",
    "Film",
    "Integrator",
    "Light",
    "Material",
    "Medium",
    "Phase",
    "PointLight",
    "Scene",
    "Shape",
    "SpotLight",
    "find_scene_file",
    "load_scene",
]
