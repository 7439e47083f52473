"""Readers of the ``lights`` section (point, spot and directional lights), and the check that
something in the scene emits."""

from __future__ import annotations

from typing import Any

import numpy as np

from renderer.errors import shorten_repr as _describe
from renderer.scene.document import KeyPath
from renderer.scene.limits import MAX_LIGHT, MIN_LENGTH
from renderer.scene.media import read_stated_medium
from renderer.scene.model import DirectionalLight, Light, PointLight, Shape, SpotLight
from renderer.scene.validation import Validator, or_empty


def read_lights(val: Validator, doc: dict) -> list[Light]:
    """The optional ``lights`` section (absent or empty: no lights). Read after ``media``,
    whose names a light's ``medium`` refers to."""
    lights_doc = or_empty(doc.get("lights"), [])
    if not isinstance(lights_doc, list):
        val.fail(("lights",), f"expected a list of lights, got {_describe(lights_doc)}")
    media = val.table(doc, "media")
    return [_light(val, i, d, media) for i, d in enumerate(lights_doc)]


def check_something_emits(val: Validator, shapes: list[Shape], lights: list[Light]) -> None:
    """A scene without an emitter renders black: refused, naming the emitter written dark."""
    if not any(map(_emits, lights)) and not any(s.emission and any(s.emission) for s in shapes):
        # Point at the emitter written dark (often by an override) rather than at `lights`.
        dark = [("shapes", i, "emission") for i, s in enumerate(shapes) if s.emission]
        dark += [("lights", i) for i in range(len(lights))]
        what = "this emitter is black and no other light emits" if dark else "no light emits"
        val.fail(
            dark[0] if dark else ("lights",),
            f"{what}: add a light or give a shape a non-zero emission",
        )


def _emits(light: Light) -> bool:
    power = light.irradiance if isinstance(light, DirectionalLight) else light.intensity
    return any(c > 0 for c in power)


def _light(val: Validator, i: int, d: Any, media: dict) -> Light:
    p: KeyPath = ("lights", i)
    kind = val.kind(d, p, ("point", "spot", "directional"))
    if kind == "point":
        val.mapping(d, p, required=("type", "position", "intensity"), optional=("medium",))
        return PointLight(
            val.vec3(d["position"], p + ("position",)),
            val.rgb(d["intensity"], p + ("intensity",), hi=MAX_LIGHT),
            read_stated_medium(val, d, p, media),
        )
    if kind == "directional":
        val.mapping(d, p, required=("type", "direction", "irradiance"), optional=("medium",))
        direction = val.vec3(d["direction"], p + ("direction",), nonzero=True)
        return DirectionalLight(
            direction / np.linalg.norm(direction),
            val.rgb(d["irradiance"], p + ("irradiance",), hi=MAX_LIGHT),
            read_stated_medium(val, d, p, media),
        )
    val.mapping(
        d,
        p,
        required=("type", "position", "target", "intensity"),
        optional=("cutoff_angle", "beam_width", "medium"),
    )
    pos, target = val.vec3(d["position"], p + ("position",)), val.vec3(d["target"], p + ("target",))
    if not np.max(np.abs(target - pos)) >= MIN_LENGTH:
        val.fail(p + ("target",), "equals the light's position, so its axis is undefined")
    cutoff = val.number(
        d.get("cutoff_angle", 20.0), p + ("cutoff_angle",), lo=0, hi=90, lo_open=True, float32=True
    )
    beam = val.number(
        d.get("beam_width", cutoff * 0.75),
        p + ("beam_width",),
        lo=0,
        hi=cutoff,
        lo_open=True,
        float32=True,
    )
    intensity = val.rgb(d["intensity"], p + ("intensity",), hi=MAX_LIGHT)
    return SpotLight(pos, target, intensity, cutoff, beam, read_stated_medium(val, d, p, media))
