"""Readers of a grid medium's density: a .npy array, an OpenVDB grid, or a procedural source
(Perlin noise, a step), each checked to be finite, non-negative and within float32 range. Also
the .npy reader the tabulated phase function shares."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from renderer.errors import PgiError, not_a_file, one_line
from renderer.errors import shorten_repr as _describe
from renderer.scene.document import KeyPath
from renderer.scene.limits import MAX_DENSITY, MAX_NOISE_FREQUENCY
from renderer.scene.validation import Validator
from renderer.volumes import MAX_GRID_SIDE, MAX_VDB_COORD

DENSITY_SOURCES = ("npy", "vdb", "perlin", "step")


def read_npy(val: Validator, file: Path, p: KeyPath) -> np.ndarray:
    """One array from a .npy file (no pickles), mapped, not read: its shape can be checked
    before a header that claims terabytes allocates anything."""
    if not file.is_file():
        val.fail(p, f"file {not_a_file(file)}: {file}")
    try:
        a = np.load(file, allow_pickle=False, mmap_mode="r")
    except MemoryError:
        raise
    except Exception as e:  # a garbled header fails in numpy's parser with any error
        lines = str(e).splitlines()
        with open(file, "rb") as f:
            npy = f.read(6) == b"\x93NUMPY"  # numpy says "pickled data" for any other file
        if "pickle" in str(e) or "Python objects" in str(e):
            why = ("it holds Python objects, which pgi does not load; save a numeric array"
                   if npy else "not a numpy .npy file")  # fmt: skip
        elif "greater than file size" in str(e):  # mapping it found the data short
            why = "its header's shape needs more data than the file holds (truncated?)"
        elif "must be positive" in str(e):
            why = "its header gives a negative size"
        else:
            why = one_line(lines[0]) if lines else "not a numpy .npy file"
        val.fail(p, f"cannot read {file} as a .npy array: {why}")
    if not isinstance(a, np.ndarray):
        val.fail(p, f"{file}: expected one array, got {type(a).__name__}")
    extra = file.stat().st_size - (getattr(a, "offset", 0) + a.nbytes)
    if isinstance(a, np.memmap) and extra > 0:  # numpy maps the header's shape, ignores the rest
        val.fail(
            p,
            f"cannot read {file} as a .npy array: it holds {extra} bytes more than its header's "
            f"shape {list(a.shape)} of {a.dtype} needs (written with another shape?)",
        )
    return a


def _load_npy(val: Validator, file: Path, p: KeyPath) -> np.ndarray:
    a = read_npy(val, file, p)
    if a.ndim != 3 or a.dtype.kind not in "fiu" or 0 in a.shape:
        val.fail(
            p,
            f"{file}: expected a 3-D numeric array indexed [x, y, z], got shape "
            f"{list(a.shape)} of {a.dtype}",
        )
    if max(a.shape) > MAX_GRID_SIDE:
        val.fail(p, f"{file}: shape {list(a.shape)}, at most {MAX_GRID_SIDE} voxels per axis")
    return np.array(a)  # read now that its size is known


def _resolution(val: Validator, v: Any, p: KeyPath) -> tuple[int, int, int]:
    if isinstance(v, list):
        if len(v) != 3:
            val.fail(p, f"expected a number or [x, y, z], got {_describe(v)}")
        return tuple(val.integer(n, p + (i,), 1, MAX_GRID_SIDE) for i, n in enumerate(v))  # type: ignore
    n = val.integer(v, p, 1, MAX_GRID_SIDE)
    return (n, n, n)


def read_density(val: Validator, v: Any, p: KeyPath) -> tuple[np.ndarray, np.ndarray | None, Path]:
    """The baked density [x, y, z] of a grid medium, the 4x4 placing its unit cube that the
    source itself defines (an OpenVDB transform; None otherwise), and where it came from.

    ``v`` is a file name (.npy or .vdb) or a mapping with a ``type`` in DENSITY_SOURCES."""
    here = val.o.file(p).parent
    if isinstance(v, str):
        kind = "vdb" if v.lower().endswith(".vdb") else "npy"
        d: dict = {"type": kind, "file": v}
    else:
        d = v
        kind = val.kind(d, p, DENSITY_SOURCES)
    placement = None
    source = val.o.file(p)
    if kind in ("npy", "vdb"):
        optional = ("grid", "bbox") if kind == "vdb" else ()
        val.mapping(d, p, required=("type", "file"), optional=optional)
        file = here / val.string(d["file"], p + ("file",))
        source = file
        if not file.is_file():
            val.fail(p, f"density file {not_a_file(file)}: {file}")
        if kind == "npy":
            a = _load_npy(val, file, p)
        else:
            from renderer.volumes import read_vdb

            bbox = None
            if "bbox" in d:
                b = d["bbox"]
                if not (isinstance(b, list) and len(b) == 2 and
                        all(isinstance(r, list) and len(r) == 3 for r in b)):  # fmt: skip
                    val.fail(p + ("bbox",), "expected [[i0, j0, k0], [i1, j1, k1]] (inclusive)")
                bbox = tuple(
                    tuple(
                        val.integer(x, p + ("bbox", r, c), -MAX_VDB_COORD, MAX_VDB_COORD)
                        for c, x in enumerate(row)
                    )  # fmt: skip
                    for r, row in enumerate(b)
                )
            grid = val.string(d.get("grid", "density"), p + ("grid",))
            try:
                a, placement = read_vdb(file, grid, bbox)
            except PgiError as e:
                val.fail(p, str(e))
    elif kind == "perlin":
        keys = ("octaves", "frequency", "lacunarity", "gain", "offset", "seed")
        val.mapping(d, p, required=("type", "resolution"), optional=keys)
        from renderer.volumes import perlin_density

        octaves = val.integer(d.get("octaves", 4), p + ("octaves",), 1, 16)
        # Upper bounds keep gain^k finite over 16 octaves, and the lattice coordinates of the
        # finest octave in range (they are cast to int64; finer than a voxel is aliasing).
        frequency = val.number(d.get("frequency", 4.0), p + ("frequency",), lo=0, hi=1e4)
        lacunarity = val.number(d.get("lacunarity", 2.0), p + ("lacunarity",), lo=0, hi=16)
        finest = frequency * lacunarity ** (octaves - 1)
        if finest > MAX_NOISE_FREQUENCY:
            val.fail(p, f"the finest octave's frequency, frequency x lacunarity^(octaves - 1), "
                        f"is {finest:g}; at most {MAX_NOISE_FREQUENCY:g}")  # fmt: skip
        a = perlin_density(
            _resolution(val, d["resolution"], p + ("resolution",)),
            octaves=octaves,
            frequency=frequency,
            lacunarity=lacunarity,
            gain=val.number(d.get("gain", 0.5), p + ("gain",), lo=0, hi=16),
            offset=val.number(d.get("offset", 0.0), p + ("offset",), lo=-1e6, hi=1e6),
            seed=val.integer(d.get("seed", 0), p + ("seed",), 0),
        )
    else:  # step
        val.mapping(d, p, required=("type", "resolution", "values"), optional=("axis", "position"))
        from renderer.volumes import step_density

        values = d["values"]
        if not isinstance(values, list) or len(values) != 2:
            val.fail(p + ("values",), f"expected [below, above], got {_describe(values)}")
        axis = val.string(d.get("axis", "x"), p + ("axis",), ("x", "y", "z"))
        a = step_density(
            _resolution(val, d["resolution"], p + ("resolution",)),
            axis="xyz".index(axis),
            position=val.number(d.get("position", 0.5), p + ("position",), lo=0, hi=1),
            values=tuple(
                val.number(x, p + ("values", i), lo=0, hi=MAX_DENSITY) for i, x in enumerate(values)
            ),
        )
    if not np.all(np.isfinite(a)):
        val.fail(p, f"{source}: density has non-finite values")
    if np.abs(a).max() > np.float32(MAX_DENSITY):  # 1e30 itself rounds up in float32
        val.fail(
            p,
            f"{source}: density values must be <= {MAX_DENSITY:g} (float32, with headroom), "
            f"got {np.abs(a).max():g}",
        )
    if a.min() < 0:
        idx = tuple(int(i) for i in np.unravel_index(np.argmin(a), a.shape))
        val.fail(p, f"{source}: density must be >= 0, got {a.min():g} at [x, y, z] = {list(idx)}")
    return np.ascontiguousarray(a, dtype=np.float32), placement, source
