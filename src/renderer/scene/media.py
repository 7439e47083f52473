"""Readers of the ``media`` section: homogeneous and grid media, their extinction bounds and
placement, and their phase functions (Henyey-Greenstein, Rayleigh, tabulated, Mie)."""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from renderer.errors import not_a_file, one_line
from renderer.errors import shorten_repr as _describe
from renderer.scene.density import read_density, read_npy
from renderer.scene.document import KeyPath
from renderer.scene.limits import (
    MAX_COORDINATE,
    MAX_EXTINCTION,
    MAX_MIE_IOR,
    MAX_MIE_SIZE,
    MAX_MIE_WORK,
    MAX_VOXEL_DEPTH,
)
from renderer.scene.model import VACUUM, Medium, Phase
from renderer.scene.validation import Validator

PHASES = ("isotropic", "hg", "rayleigh", "tabulated", "mie")


def read_media(val: Validator, doc: dict) -> dict[str, Medium]:
    """The ``media`` section: name -> medium (absent or empty: none)."""
    table = val.table(doc, "media")
    if VACUUM in table:
        val.fail(
            ("media", VACUUM),
            f"the name {VACUUM!r} is reserved: a light's `medium: {VACUUM}` says it sits in no "
            "medium; name this medium otherwise",
        )
    return {k: _medium(val, k, v) for k, v in table.items()}


def read_stated_medium(val: Validator, d: dict, p: KeyPath, media: dict) -> str | None:
    """The ``medium`` a light or emitting shape ``d`` (at ``p``) states it emits into: a name
    from ``media``, or VACUUM; None where it states none (absent or null)."""
    v = d.get("medium")
    if v is None:
        return None
    if v == VACUUM:
        return VACUUM
    return val.name_ref(v, p + ("medium",), media, "medium")


def _medium(val: Validator, name: str, d: Any) -> Medium:
    p: KeyPath = ("media", name)
    kind = val.kind(d, p, ("homogeneous", "grid"))
    common = ("albedo", "scale", "phase")
    if kind == "homogeneous":
        val.mapping(d, p, required=("type", "sigma_t", "albedo"), optional=common)
    else:
        val.mapping(
            d, p, required=("type", "density", "albedo"), optional=common + ("sigma_t", "transform")
        )
    if kind == "grid":  # grid extinction is grey: the density carries the variation
        grey = val.number(d.get("sigma_t", 1.0), p + ("sigma_t",), lo=0)
        sigma_t = (grey, grey, grey)
    else:
        sigma_t = val.rgb(d["sigma_t"], p + ("sigma_t",))
    albedo = val.rgb(d["albedo"], p + ("albedo",), hi=1)
    scale = val.number(d.get("scale", 1.0), p + ("scale",), lo=0)
    phase = _phase(val, d["phase"], p + ("phase",)) if "phase" in d else Phase()

    def check_extinction(peak: float, what: str) -> None:
        if max(sigma_t) * scale * peak > MAX_EXTINCTION * (1 + 1e-6):  # float32's rounding
            val.fail(p, f"{what} is {max(sigma_t) * scale * peak:g}, above {MAX_EXTINCTION:g}")

    if kind == "homogeneous":
        check_extinction(1.0, "sigma_t x scale")
        return Medium(name, kind, sigma_t, albedo, scale, phase)
    density, placement, source = read_density(val, d["density"], p + ("density",))
    check_extinction(float(density.max(initial=0.0)), "sigma_t x scale x the densest voxel")
    to_world = val.transform(d.get("transform", []), p + ("transform",))
    if placement is not None:  # an OpenVDB file places its grid; the transform moves it on
        to_world = to_world @ placement
    linear = to_world[:3, :3]
    # Relative to the box's edge lengths: a tiny grid is fine, a flat one is not; nor one
    # so small that the world-to-grid map overflows (subnormal scales).
    # (A box too large for its determinant is left to the bound on its corners below.)
    det = abs(np.linalg.det(linear))
    flat = np.isfinite(det) and det <= 1e-12 * np.prod(np.linalg.norm(linear, axis=0))
    if flat or not np.all(np.isfinite(np.linalg.inv(linear))):
        val.fail(p + ("transform",), "is singular: the grid's box would have no volume")
    if np.any(linear - np.diag(np.diag(linear))):
        # Mitsuba bounds a grid by the axis-aligned box of its transformed cube and extends
        # edge values into the rest of that box: only axis-aligned grids mean the same there.
        val.fail(
            p + ("transform",),
            "rotates the grid; Mitsuba supports only axis-aligned grids (scale and translate)",
        )
    corners = np.array([[x, y, z, 1.0] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    if not np.all(np.abs(corners @ to_world.T)[:, :3] < MAX_COORDINATE):
        val.fail(p + ("transform",), f"places the grid's box beyond +-{MAX_COORDINATE:g}")
    voxel = float((np.abs(np.diag(linear)) / np.array(density.shape)).max())
    voxel_depth = max(sigma_t) * scale * float(density.max(initial=0.0)) * voxel
    if voxel_depth > MAX_VOXEL_DEPTH:
        val.fail(
            p,
            f"the densest voxel is {voxel_depth:.3g} optical depths across (sigma_t x scale x "
            f"density x voxel edge {voxel:.3g}); at most {MAX_VOXEL_DEPTH:g} can be tracked, "
            f"and it is opaque long before: lower scale",
        )
    return Medium(name, kind, sigma_t, albedo, scale, phase, density, to_world, source)


def _phase(val: Validator, d: Any, p: KeyPath) -> Phase:
    kind = val.kind(d, p, PHASES)
    if kind in ("isotropic", "rayleigh"):
        val.mapping(d, p, required=("type",))
        return Phase(kind)
    if kind == "hg":
        val.mapping(d, p, required=("type", "g"))
        g = val.number(d["g"], p + ("g",), lo=-1, hi=1, lo_open=True, hi_open=True, float32=True)
        return Phase("hg", g=g)
    if kind == "tabulated":
        val.mapping(d, p, required=("type",), optional=("values", "file"))
        if ("values" in d) == ("file" in d):
            given = "both" if "values" in d else "neither"
            val.fail(p, f"give either values (a list) or file (.npy or text); {given} given")
        if "values" in d:
            raw = d["values"]
            if not isinstance(raw, list):
                val.fail(p + ("values",), f"expected a list of numbers, got {_describe(raw)}")
            values = np.array([val.number(x, p + ("values", i), lo=0) for i, x in enumerate(raw)])
        else:
            file = val.o.file(p).parent / val.string(d["file"], p + ("file",))
            if file.suffix == ".npy":
                values = read_npy(val, file, p + ("file",))
            else:
                if not file.is_file():
                    val.fail(p + ("file",), f"file {not_a_file(file)}: {file}")
                try:
                    with warnings.catch_warnings():  # an empty file: numpy warns, we say so
                        warnings.simplefilter("ignore", UserWarning)
                        values = np.loadtxt(file, ndmin=1)
                except (OSError, ValueError) as e:
                    why = one_line(str(e))
                    if "number of columns changed" in why:  # numpy's words for ragged rows
                        why = "its lines hold different counts of numbers"
                    val.fail(
                        p + ("file",),
                        f"cannot read {file}: {why}; write one number per line, or all on one",
                    )
                if values.size == 0:
                    val.fail(p + ("file",), f"{file} holds no numbers")
            if values.dtype.kind not in "fiu":
                val.fail(p + ("file",), f"{file}: expected numbers, got {values.dtype}")
            # (squeezed as a plain array: numpy's squeeze of a one-value memory map fails)
            if np.squeeze(np.asarray(values)).ndim > 1:  # e.g. a column of angles beside them
                val.fail(
                    p + ("file",),
                    f"{file}: expected one list of values, got a table of shape "
                    f"{list(values.shape)}",
                )
            values = np.asarray(values, np.float64).ravel()
            if not np.all(np.isfinite(values)) or np.any(values < 0):
                val.fail(p + ("file",), f"{file}: values must be finite and >= 0")
        if len(values) < 2 or not values.max() > 0:
            why = f"a tabulated phase function needs >= 2 values, not all 0, got {len(values)}"
            if "file" in d:  # the file's fault: named, with its key
                val.fail(p + ("file",), f"{file}: {why}")
            val.fail(p, why)
        # Only the shape matters (both renderers normalise); scaled to a peak of 1 it sums
        # without overflow and survives Mitsuba's float32.
        return Phase("tabulated", values=values / values.max())
    # mie: a Lorenz-Mie table for water droplets, computed at load (renderer.volumes)
    keys = ("effective_radius", "effective_variance", "wavelength", "ior", "resolution")
    val.mapping(d, p, required=("type",), optional=keys)
    from renderer.volumes import mie_largest_radius, mie_phase_table

    radius = val.number(d.get("effective_radius", 2.0), p + ("effective_radius",), lo=0.01, hi=50)
    variance = val.number(
        d.get("effective_variance", 0.1), p + ("effective_variance",), lo=0.01, hi=0.5
    )
    wavelength = val.number(d.get("wavelength", 0.55), p + ("wavelength",), lo=0.1, hi=10)
    # Droplets, not gems: the series' recurrence runs |ior| x size parameter terms.
    ior = val.number(d.get("ior", 1.333), p + ("ior",), lo=1.0, lo_open=True, hi=MAX_MIE_IOR)
    resolution = val.integer(d.get("resolution", 2048), p + ("resolution",), 16, 1 << 13)
    # The table's series runs over the largest droplet's size parameter for each of 64 radii,
    # at each of `resolution` angles: both are bounded, and so is their product (measured:
    # 3-4 s at each corner of these bounds).
    size = 2 * np.pi * mie_largest_radius(radius, variance) / wavelength
    if size > MAX_MIE_SIZE or size * resolution > MAX_MIE_WORK:
        val.fail(
            p,
            f"droplets up to {mie_largest_radius(radius, variance):.3g} um at wavelength "
            f"{wavelength:g} um have size parameter {size:.0f}; the table would take minutes "
            f"to compute (size parameter at most {MAX_MIE_SIZE:g}, and times resolution at "
            f"most {MAX_MIE_WORK:.2g})",
        )
    table = mie_phase_table(radius, variance, wavelength, ior, resolution)
    return Phase("tabulated", values=np.array(table))
