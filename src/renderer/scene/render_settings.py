"""Readers of the sections that say how the scene is imaged: ``camera`` (where from),
``film`` (the image's size) and ``integrator`` (path depths and the media estimator)."""

from __future__ import annotations

import numpy as np

from renderer.ranges import INT32_MAX
from renderer.scene.document import KeyPath
from renderer.scene.limits import MAX_FILM_SIDE, MAX_UNROULETTED_DEPTH, MIN_LENGTH
from renderer.scene.model import Camera, Film, Integrator, Medium
from renderer.scene.validation import Validator, or_empty

FOV_AXES = ("x", "y", "diagonal", "smaller", "larger")
ESTIMATORS = ("delta", "ratio", "residual", "raymarch")


def read_camera(val: Validator, doc: dict, media: dict[str, Medium]) -> Camera:
    """The ``camera`` section; the medium it sits in, if any, is one of ``media``."""
    p: KeyPath = ("camera",)
    d = val.mapping(
        doc["camera"],
        p,
        required=("origin", "target", "up", "fov"),
        optional=("fov_axis", "medium"),
    )
    origin, target = val.vec3(d["origin"], p + ("origin",)), val.vec3(d["target"], p + ("target",))
    up = val.vec3(d["up"], p + ("up",), nonzero=True)
    view = target - origin
    if not np.max(np.abs(view)) >= MIN_LENGTH:
        val.fail(p + ("target",), "equals camera.origin, so the view direction is undefined")
    view, up = view / np.max(np.abs(view)), up / np.max(np.abs(up))  # no underflow below
    if np.linalg.norm(np.cross(view, up)) <= 1e-9 * np.linalg.norm(view) * np.linalg.norm(up):
        val.fail(p + ("up",), "is parallel to the view direction (target - origin)")
    camera = Camera(
        origin=origin, target=target, up=up,
        fov=val.number(
            d["fov"], p + ("fov",), lo=0, hi=180, lo_open=True, hi_open=True, float32=True
        ),
        fov_axis=val.string(d.get("fov_axis", "x"), p + ("fov_axis",), FOV_AXES),
        medium=d.get("medium"),
    )  # fmt: skip
    if camera.medium is not None:
        val.name_ref(camera.medium, p + ("medium",), media, "medium")
    return camera


def read_film(val: Validator, doc: dict) -> Film:
    """The ``film`` section: the image's width and height in pixels."""
    film_doc = val.mapping(doc["film"], ("film",), required=("width", "height"))
    return Film(val.integer(film_doc["width"], ("film", "width"), 1, MAX_FILM_SIDE),
                val.integer(film_doc["height"], ("film", "height"), 1, MAX_FILM_SIDE))  # fmt: skip


# Russian roulette rules (cpp/wavefront.h, survive_roulette): survival from the throughput
# (pbrt-v4's rule, the default) or Mitsuba's, capped at 0.95.
ROULETTES = ("throughput", "mitsuba")


def read_integrator(val: Validator, doc: dict) -> Integrator:
    """The optional ``integrator`` section, with its defaults."""
    integ = val.mapping(
        or_empty(doc.get("integrator"), {}),
        ("integrator",),
        optional=("max_depth", "rr_depth", "rr", "estimator", "march_step"),
    )
    integrator = Integrator(
        # Depths reach the native core and Mitsuba as 32-bit ints.
        max_depth=val.integer(
            integ.get("max_depth", -1), ("integrator", "max_depth"), -1, INT32_MAX
        ),
        rr_depth=val.integer(integ.get("rr_depth", 5), ("integrator", "rr_depth"), 1, INT32_MAX),
        rr=val.string(integ.get("rr", "throughput"), ("integrator", "rr"), ROULETTES),
        estimator=val.string(
            integ.get("estimator", "ratio"), ("integrator", "estimator"), ESTIMATORS
        ),
        march_step=val.number(integ.get("march_step", 0.0), ("integrator", "march_step"), lo=0),
    )
    # Before rr_depth nothing but max_depth ends a path: in a closed scene that loses no
    # energy, an iteration would not end (and no time budget is checked inside one).
    unrouletted = min(integrator.rr_depth, integrator.max_depth % (INT32_MAX + 1))
    if unrouletted > MAX_UNROULETTED_DEPTH:
        val.fail(
            ("integrator", "rr_depth"),
            f"{integrator.rr_depth} with max_depth {integrator.max_depth}: paths could run "
            f"{unrouletted} bounces before Russian roulette or the depth limit may end them; "
            f"lower rr_depth or max_depth to at most {MAX_UNROULETTED_DEPTH}",
        )
    return integrator
