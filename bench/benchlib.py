"""What the benchmark scripts share: options checked into one-line errors, scenes loaded the
same way, and Mitsuba references cached under a key of everything they depend on, with their
own error measured from two independent halves."""

from __future__ import annotations

import argparse
import hashlib
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from compare.metrics import compare_images, reference_error, reference_ok
from renderer.errors import PgiError
from renderer.fingerprint import reference_fingerprint
from renderer.imageio import read_exr, write_exr
from renderer.progressive import check_threads
from renderer.reference import render_reference
from renderer.scene import load_scene
from renderer.scene.model import Scene
from renderer.scene.sources import scene_content_digest

CACHE = Path(__file__).resolve().parent / ".cache"
REFERENCE_SEEDS = (12345, 54321)  # one per half


def seconds(text: str) -> float:
    """argparse type: a finite time > 0 (a NaN budget is never reached)."""
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds > 0, got {text}")
    return value


def at_least(lowest: int):
    """argparse type: an integer >= lowest."""

    def parse(text: str) -> int:
        value = int(text)
        if value < lowest:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lowest}, got {text}")
        return value

    parse.__name__ = f"integer >= {lowest}"
    return parse


def add_common_options(parser: argparse.ArgumentParser, scenes: Sequence[str]) -> None:
    """--scenes, --size and --threads, as every script takes them."""
    parser.add_argument(
        "--scenes",
        nargs="+",
        default=list(scenes),
        help=f"scene names or files (default: {' '.join(scenes)})",
    )
    parser.add_argument("--size", type=at_least(1), help="film width and height in pixels")
    parser.add_argument(
        "--threads", type=at_least(1), default=2, help="render threads (at most the cores)"
    )


def check_options(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """What argparse cannot check alone: threads against this machine, scenes that load."""
    try:
        check_threads(args.threads)
        for name in args.scenes:
            load_scene(name, ["film.width=8", "film.height=8"])
    except PgiError as e:
        parser.error(str(e))


def scene_at(name: str, size: int, extra: Sequence[str] = ()) -> Scene:
    """Scene `name` on a size x size film."""
    return load_scene(name, [f"film.width={size}", f"film.height={size}", *extra])


def mitsuba_reference(name: str, size: int, spp: int) -> tuple[np.ndarray, float]:
    """Mitsuba's reference of scene `name` at size x size, as two independent halves of
    spp / 2 each, averaged, and its own relMSE estimated from them
    (compare.metrics.reference_error). Cached under bench/.cache with a key of what it
    depends on: the scene's content, the reference code and Mitsuba's version (the
    workflow's fingerprint), the size and the spp."""
    film = [f"film.width={size}", f"film.height={size}"]
    what = f"{scene_content_digest(name, film)}-{reference_fingerprint()}-{size}-{spp}"
    key = hashlib.sha256(what.encode()).hexdigest()[:16]
    CACHE.mkdir(exist_ok=True)
    scene, halves = scene_at(name, size), []
    for half, seed in enumerate(REFERENCE_SEEDS):
        path = CACHE / f"{Path(name).stem}-{key}-{half}.exr"
        if not path.exists():
            print(f"  rendering the reference of {name}, half {half + 1} of 2 ...", flush=True)
            image, _ = render_reference(scene, spp // 2, seed=seed)
            write_exr(path, image)
        halves.append(read_exr(path).astype(np.float64))
    return 0.5 * (halves[0] + halves[1]), reference_error(*halves)["ref_relmse"]


def relmse_less_reference(image: np.ndarray, ref: np.ndarray, ref_err: float) -> tuple[float, bool]:
    """The image's relMSE less the reference's own (their noise is independent), and whether
    the reference is good enough to tell (its error 10x below the image's, as the workflow
    asks); when it is not, the difference is mostly noise and may even be negative."""
    measured = compare_images(image, ref)["relmse"]
    return measured - ref_err, reference_ok(measured, ref_err)


def ratio(numerator: tuple[float, bool], denominator: tuple[float, bool]) -> str:
    """a / b of two relmse_less_reference results, or why there is none."""
    (a, a_ok), (b, b_ok) = numerator, denominator
    if not (a_ok and b_ok and a > 0 and b > 0):
        return "n/a (reference-limited: raise --reference-spp)"
    return f"{a / b:.2f}x"
