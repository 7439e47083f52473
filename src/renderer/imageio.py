"""Image files through OpenImageIO: linear float EXR in, linear float EXR out."""

from __future__ import annotations

import contextlib
import json
import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from .errors import PgiError, not_a_file, one_line, shorten

FLOAT_TYPES = ("half", "float")  # OpenEXR's pixel types for radiance (the third is uint)


def read_exr(path: str | Path) -> np.ndarray:
    """Read an image as float32 (H, W, 3); a single channel is repeated, alpha is dropped."""
    return read_exr_and_channels(path)[0]


def read_exr_and_channels(path: str | Path) -> tuple[np.ndarray, int]:
    """read_exr's image, and how many colour channels the file stores (1: grey, 3: RGB)."""
    path = Path(path)
    try:
        is_dir = path.is_dir()
    except OSError as e:  # e.g. a file name longer than the file system allows
        raise PgiError(f"{shorten(str(path), 80)}: {e.strerror or e}") from None
    if is_dir:
        raise PgiError(f"{path}: is a folder, expected an image file")
    if not path.is_file():
        reason = not_a_file(path)
        raise PgiError(
            f"{path}: no such image file" if reason == "not found" else f"{path} {reason}"
        )
    with _stderr_captured() as library_said:
        buf = oiio.ImageBuf(str(path))
        unreadable = _first_line(buf.geterror()) if buf.has_error else ""
        exr = not unreadable and buf.file_format_name == "openexr"
        pixels = buf.get_pixels(oiio.FLOAT) if exr else None
    if unreadable:
        with open(path, "rb") as f:  # an EXR's magic number: OpenImageIO's words do not say so
            head = f.read(4)
        if not head:
            raise PgiError(f"{path}: cannot read image: the file is empty")
        if head == b"\x76\x2f\x31\x01":
            raise PgiError(f"{path}: cannot read image: a corrupt or truncated OpenEXR file")
        raise PgiError(f"{path}: cannot read image: {unreadable}")
    if not exr:  # metrics are defined on linear HDR values
        raise PgiError(f"{path}: expected an OpenEXR image, found {buf.file_format_name or '?'}")
    if buf.nsubimages > 1:  # only the first part would be read: which one was meant is unknown
        raise PgiError(
            f"{path}: a multi-part EXR ({buf.nsubimages} parts); expected a single-part image"
        )
    spec = buf.spec()
    window = (spec.x, spec.y, spec.width, spec.height)
    if window != (spec.full_x, spec.full_y, spec.full_width, spec.full_height):
        # pixels outside the data window are undefined, and the pixel grid the metrics see
        # would not be the image's
        raise PgiError(
            f"{path}: its data window (origin {spec.x},{spec.y}, {spec.width}x{spec.height}) "
            f"is not its display window (origin {spec.full_x},{spec.full_y}, "
            f"{spec.full_width}x{spec.full_height}); expected an image that fills its window"
        )
    # A truncated or corrupt file is only noticed while its pixels are decoded.
    if pixels is None or buf.has_error or pixels.ndim != 3:
        why = _first_line(buf.geterror()) or "unexpected layout"
        detail = one_line(_first_line("".join(library_said)).replace(f"{path}: ", ""))
        raise PgiError(f"{path}: cannot read pixels: {why}" + (f" ({detail})" if detail else ""))
    names = tuple(spec.channelnames)
    if names[:3] == ("R", "G", "B"):  # OpenImageIO puts R, G, B first when a file has them
        pixels, channels = pixels[:, :, :3], 3
    elif names in (("Y",), ("Y", "A")):  # grey (OpenEXR's luminance channel), alpha dropped
        pixels, channels = np.repeat(pixels[:, :, :1], 3, axis=2), 1
    else:  # e.g. XYZ, depth, alpha alone or spectral channels: not what the metrics assume
        raise PgiError(
            f"{path}: expected channels R, G, B or one grey channel Y (alpha aside), found "
            f"{', '.join(names)}"
        )
    # An EXR's uint channel holds integers, which OpenImageIO scales to [0, 1] (100 reads
    # as 2.3e-8): not radiance.
    formats = [str(f) for f in spec.channelformats] or [str(spec.format)] * spec.nchannels
    used = zip(names[:channels], formats[:channels], strict=True)
    integers = [f"{name} ({kind})" for name, kind in used if kind not in FLOAT_TYPES]
    if integers:
        raise PgiError(
            f"{path}: channel(s) {', '.join(integers)} hold integers; expected half or float "
            "channels of linear radiance"
        )
    return np.ascontiguousarray(pixels, dtype=np.float32), channels


# File descriptor 2 belongs to the whole process: one capture at a time, or a second one
# would restore the first one's file as stderr.
_STDERR_LOCK = threading.Lock()


@contextlib.contextmanager
def _stderr_captured() -> Iterator[list[str]]:
    """What C libraries write to the process's stderr meanwhile (OpenEXR prints its decoding
    errors there itself), kept out of the terminal and handed over in the list on exit: a
    failed read is one line of ours. Other threads' stderr output meanwhile is caught too;
    no caller reads images while another thread writes there."""
    said: list[str] = []
    with _STDERR_LOCK, tempfile.TemporaryFile() as sink:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(sink.fileno(), 2)
        try:
            yield said
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            said.append(sink.read().decode("utf-8", "replace"))


def _first_line(message: str) -> str:
    return message.strip().splitlines()[0] if message.strip() else ""


def write_exr(path: str | Path, image: np.ndarray, metadata: dict | None = None) -> None:
    """Write (H, W, 3) linear RGB as a float EXR, atomically: a failed write leaves nothing.

    ``metadata`` is stored as a JSON string attribute ``pgi`` in the header.
    """
    path = Path(path)
    _move_into_place([(_exr_to_temporary(path, image, metadata), path)])


def write_json(path: str | Path, data: dict) -> None:
    """Write a JSON sidecar atomically (its folder is created as write_exr's is)."""
    path = Path(path)
    _move_into_place([(_json_to_temporary(path, data), path)])


def _temporary(path: Path, suffix: str = "") -> Path:
    return path.with_name(f".{path.name}.tmp{os.getpid()}{suffix}")


def _make_folder(path: Path) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise PgiError(f"{path}: cannot create its folder: {e.strerror or e}") from None


def _exr_to_temporary(path: Path, image: np.ndarray, metadata: dict | None) -> Path:
    """The EXR written under a temporary name beside ``path``; nothing is left if it fails."""
    given = np.asarray(image)
    with np.errstate(over="ignore"):  # overflow is checked below
        image = given.astype(np.float32)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) image, got shape {image.shape}")
    if not np.all(np.isfinite(image)):
        if np.all(np.isfinite(given)):  # a scene's radiance, not a bug: say so
            raise PgiError(
                f"{path}: pixel values reach {np.abs(given).max():.3g}, beyond what a float "
                f"EXR holds ({np.finfo(np.float32).max:.3g}); make the lights dimmer"
            )
        raise ValueError(f"refusing to write non-finite pixels to {path}")
    _make_folder(path)
    spec = oiio.ImageSpec(image.shape[1], image.shape[0], 3, oiio.FLOAT)
    spec.channelnames = ("R", "G", "B")
    spec.attribute("compression", "zip")
    if metadata:
        spec.attribute("pgi", json.dumps(metadata, default=str))
    tmp = _temporary(path, ".exr")
    out = oiio.ImageOutput.create(str(tmp))
    if out is None:
        raise PgiError(f"{path}: cannot create image writer: {oiio.geterror()}")
    try:
        if not out.open(str(tmp), spec) or not out.write_image(image):
            raise PgiError(f"{path}: cannot write image: {out.geterror()}")
        if not out.close():
            raise PgiError(f"{path}: cannot write image: {out.geterror()}")
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return tmp


def _json_to_temporary(path: Path, data: dict) -> Path:
    """The JSON written under a temporary name beside ``path``; nothing is left if it fails."""
    _make_folder(path)
    tmp = _temporary(path)
    try:
        tmp.write_text(json.dumps(data, indent=2, sort_keys=True, default=str) + "\n")
    except BaseException as e:
        tmp.unlink(missing_ok=True)
        if isinstance(e, OSError):
            raise PgiError(f"{path}: cannot write: {e.strerror or e}") from None
        raise
    return tmp


def _move_into_place(files: list[tuple[Path, Path]]) -> None:
    """Each (temporary, target) renamed over its target. Should a rename fail (the target a
    folder, say) after an earlier one of the set succeeded, none of the targets is left,
    rather than a pair of which one is stale; a first failure leaves them all as they were."""
    done = 0
    try:
        for tmp, target in files:
            os.replace(tmp, target)
            done += 1
    except OSError as e:
        if done:
            for _, moved in files:
                if moved.is_file():
                    moved.unlink()
        raise PgiError(f"{target}: cannot write: {e.strerror or e}") from None
    finally:
        for tmp, _ in files:
            tmp.unlink(missing_ok=True)


def read_json(path: str | Path) -> dict:
    """A JSON sidecar's contents."""
    return json.loads(Path(path).read_text())


def write_image_and_sidecar(path: str | Path, image: np.ndarray, info: dict) -> None:
    """The EXR (``info`` in its header) and its JSON sidecar: both or neither. Both are
    written under temporary names first, so a failed write (a full disk) leaves an earlier
    pair at that path as it was."""
    path = Path(path)
    sidecar = path.with_suffix(".json")
    json_tmp = _json_to_temporary(sidecar, info)
    try:
        exr_tmp = _exr_to_temporary(path, image, info)
    except BaseException:
        json_tmp.unlink(missing_ok=True)
        raise
    _move_into_place([(exr_tmp, path), (json_tmp, sidecar)])


def check_output_path(path: str | Path) -> Path:
    """An .exr path whose image and sidecar can be written: checked before any work, leaving
    nothing behind (a probe file is created in the nearest existing folder and removed)."""
    out = Path(path)
    if out.suffix.lower() != ".exr":
        raise PgiError(f"-o {path}: the output must be an .exr file")
    for target in (out, out.with_suffix(".json")):
        try:
            is_dir = target.is_dir()
        except OSError as e:  # e.g. a file name longer than the file system allows
            raise PgiError(f"-o {shorten(str(path), 80)}: {e.strerror or e}") from None
        if is_dir:
            raise PgiError(f"-o {path}: {target} is a directory")
    # The image is written to a temporary name first, longer than its own by up to 16 bytes.
    if len(os.fsencode(f".{out.name}.tmp{2**22}.exr")) > 255:
        raise PgiError(f"-o {shorten(str(path), 80)}: file name too long (at most 239 bytes)")
    try:
        check_folder_can_be_made(out.parent)
    except PgiError as e:
        raise PgiError(f"-o {path}: {e}") from None
    return out


def check_folder_can_be_made(folder: Path) -> None:
    """``folder`` exists or can be created, and files can be written in it: checked before any
    work, leaving nothing behind (a probe file is created in the nearest existing folder and
    removed)."""
    if folder.exists() and not folder.is_dir():
        raise PgiError(f"{folder} is a file, not a folder")
    ancestor = folder
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise PgiError(f"{folder} cannot be made: {ancestor} is a file")
    if not os.access(ancestor, os.W_OK):
        raise PgiError(f"cannot write in {ancestor}")
    # Permission bits do not tell everything (a root user, read-only or special file systems).
    try:
        with tempfile.NamedTemporaryFile(dir=ancestor, prefix=".pgi-probe-"):
            pass
    except OSError as e:
        raise PgiError(f"cannot write in {ancestor}: {e.strerror or e}") from None
