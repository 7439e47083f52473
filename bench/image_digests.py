"""Digests of every shipped scene rendered by every method of ours at a tiny size: for changes
that must leave images bit for bit as they were (refactors). Run it before and after, and
compare the two outputs (`--save DIR` also keeps the images, to see where two runs differ).

    python bench/image_digests.py > before.txt   # ... change ...
    python bench/image_digests.py > after.txt && diff before.txt after.txt
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

from benchlib import at_least
from renderer.methods import get_method, method_ids
from renderer.scene import load_scene
from renderer.scene.loader import find_scene_file

SCENES = sorted(p.parent.name for p in find_scene_file("cbox").parents[1].glob("*/scene.yaml"))
OURS = [m for m in method_ids() if m != "mitsuba"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=SCENES)
    parser.add_argument("--methods", nargs="+", default=OURS)
    parser.add_argument("--size", type=at_least(1), default=12)
    parser.add_argument("--iterations", type=at_least(1), default=2)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--threads", type=at_least(1), default=2)
    parser.add_argument("--set", action="append", default=[], help="method.KEY=VALUE for all")
    parser.add_argument(
        "--override", action="append", default=[], help="a scene override KEY=VALUE for all"
    )
    parser.add_argument("--save", type=Path, help="also write each image as DIR/scene.method.npy")
    args = parser.parse_args(argv)
    params = {}
    for kv in args.set:
        key, _, value = kv.partition("=")
        params[key.removeprefix("method.")] = int(value) if value.isdigit() else value
    for name in args.scenes:
        size = f"film.width={args.size}", f"film.height={args.size}", *args.override
        for method in args.methods:
            scene = load_scene(name, size)
            cls = get_method(method)
            known = {k: v for k, v in params.items() if k in cls.parameters}
            renderer = cls(scene, seed=args.seed, threads=args.threads, params=known)
            for i in range(args.iterations):
                renderer.run_iteration(i)
            image = np.ascontiguousarray(renderer.image(), np.float64)
            digest = hashlib.sha256(image.tobytes()).hexdigest()[:16]
            print(f"{name:12s} {method:5s} {digest} mean {image.mean():.9g}", flush=True)
            if args.save:
                args.save.mkdir(parents=True, exist_ok=True)
                np.save(args.save / f"{name}.{method}.npy", image)
    return 0


if __name__ == "__main__":
    sys.exit(main())
