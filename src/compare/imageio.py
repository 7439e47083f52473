"""EXR reading/writing for the comparison side.

Uses ``renderer.imageio`` (the project's one image I/O module) when the renderer package is
importable, and OpenImageIO directly otherwise, so ``compare`` also works on machines that
only have result files.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np


def read_exr(path: str | Path) -> np.ndarray:
    """Read an image as float32 (H, W, 3)."""
    try:
        from renderer.imageio import read_exr as _read
    except ImportError:
        _read = None
    if _read is not None:
        return _read(path)
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise OSError(f"{path}: cannot read image: {buf.geterror()}")
    px = np.asarray(buf.get_pixels(oiio.FLOAT))
    if px.shape[2] == 1:
        px = np.repeat(px, 3, axis=2)
    return np.ascontiguousarray(px[:, :, :3], dtype=np.float32)


def write_exr(path: str | Path, image: np.ndarray, metadata: dict | None = None) -> None:
    """Write (H, W, 3) linear RGB as a float EXR (atomically)."""
    try:
        from renderer.imageio import write_exr as _write
    except ImportError:
        _write = None
    if _write is not None:
        _write(path, image, metadata)
        return
    import OpenImageIO as oiio

    path = Path(path)
    img = np.ascontiguousarray(image, dtype=np.float32)
    path.parent.mkdir(parents=True, exist_ok=True)
    spec = oiio.ImageSpec(img.shape[1], img.shape[0], 3, oiio.FLOAT)
    spec.attribute("compression", "zip")
    if metadata:
        spec.attribute("pgi", json.dumps(metadata, default=str))
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}.exr")
    out = oiio.ImageOutput.create(str(tmp))
    if out is None or not out.open(str(tmp), spec) or not out.write_image(img):
        raise OSError(f"{path}: cannot write image: {oiio.geterror()}")
    out.close()
    os.replace(tmp, path)


def write_json(path: str | Path, data: dict) -> None:
    """Write JSON atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True, default=str) + "\n")
    os.replace(tmp, path)


def read_json(path: str | Path) -> dict:
    return json.loads(Path(path).read_text())
