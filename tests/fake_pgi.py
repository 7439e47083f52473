"""A stand-in for the `pgi` CLI, for workflow tests: same arguments and file outputs, no rendering.

Images are a smooth per-scene pattern plus Gaussian noise whose variance falls as 1/time
(1/spp for references), so the workflow sees converging methods. Writes EXR + JSON sidecars
like `pgi render --snapshots` (contracts.md). Methods: the ``FAKE_PGI_METHODS`` environment
variable (comma separated), default "pt,lt,sppm". Mitsuba's references of the scenes named in
``FAKE_PGI_DEAD_SCENES`` (comma separated) are black, as Mitsuba's are in dense, white media;
references by the ``pgi`` source are never.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import zlib
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

W, H = 24, 16


def truth(scene: str) -> np.ndarray:
    k = zlib.crc32(scene.encode()) % 7
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    base = 0.3 + 0.5 * np.sin(x / (3 + k)) ** 2 + 0.2 * y / H
    img = np.stack([base, base * 0.8, base * 0.6 + 0.1], axis=2)
    img[H // 3 : H // 2, W // 3 : W // 2] = 4.0  # a bright "light"
    return img


def write(path: Path, img: np.ndarray, side: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    spec = oiio.ImageSpec(W, H, 3, oiio.FLOAT)
    out = oiio.ImageOutput.create(str(path))
    assert out is not None and out.open(str(path), spec)
    out.write_image(np.ascontiguousarray(img, dtype=np.float32))
    out.close()
    path.with_suffix(".json").write_text(json.dumps(side, indent=1))


def scene_name(arg: str) -> str:
    p = Path(arg)
    return p.parent.name if p.suffix == ".yaml" else p.name


def tag(t: float) -> str:
    return str(int(t)) if float(t).is_integer() else f"{t:g}"


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="fake-pgi")
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("methods")
    sub.add_parser("fingerprint")
    r = sub.add_parser("render")
    r.add_argument("scene")
    r.add_argument("--method", required=True)
    r.add_argument("--time", type=float)
    r.add_argument("--threads", type=int, default=1)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--snapshots", default="")
    r.add_argument("--set", action="append", default=[])
    r.add_argument("-o", required=True)
    f = sub.add_parser("reference")
    f.add_argument("scene")
    f.add_argument("--spp", type=int, required=True)
    f.add_argument("--seed", type=int, default=0)
    f.add_argument("--threads", type=int, default=1)
    f.add_argument("--set", action="append", default=[])
    f.add_argument("--source", default="mitsuba")
    f.add_argument("--store")
    f.add_argument("--check", type=float, default=10.0)
    f.add_argument("-o", required=True)
    a = ap.parse_args(argv)
    methods = os.environ.get("FAKE_PGI_METHODS", "pt,lt,sppm").split(",")
    if a.cmd == "methods":
        for m in methods:
            print(f"{m}    fake method {m}")
        return 0
    if a.cmd == "fingerprint":  # the code "changes" when the test says so
        code = {"render": os.environ.get("FAKE_PGI_RENDER_CODE", "r0"),
                "reference": os.environ.get("FAKE_PGI_REFERENCE_CODE", "f0")}  # fmt: skip
        print(json.dumps(code))
        return 0
    scene = scene_name(a.scene)
    if not Path(a.scene).exists():
        print(f"pgi: error: no scene {a.scene}", file=sys.stderr)
        return 2
    t = truth(scene)
    out = Path(a.o)
    if a.cmd == "reference":  # noise of variance (0.3 t)^2 / spp; no store is kept
        rng = np.random.default_rng(a.seed + (7919 if a.source == "pgi" else 0))
        sd = 0.3 / np.sqrt(a.spp) * t
        img = t + sd * rng.standard_normal(t.shape)
        dead = os.environ.get("FAKE_PGI_DEAD_SCENES", "").split(",")
        if a.source == "mitsuba" and scene in dead:
            img = np.zeros_like(img)
        side = {"method": "mitsuba-reference", "spp": a.spp, "seed": a.seed, "scene": scene,
                "renderer": f"fake {a.source}", "source": a.source, "passes": 8,
                "seconds_per_spp": 0.001, "render_seconds": 0.001 * a.spp,
                "variance": f"{out.stem}.var.exr"}  # fmt: skip
        write(out, np.maximum(img, 0), side)
        write(out.with_name(f"{out.stem}.var.exr"), sd * sd, {})
        out.with_name(f"{out.stem}.var.json").unlink()  # a variance has no sidecar
        return 0
    if a.method not in methods:
        print(f"pgi: error: unknown method {a.method}", file=sys.stderr)
        return 2
    snaps = [float(s) for s in a.snapshots.split(",") if s]
    tmax = a.time or (max(snaps) if snaps else 1.0)
    quality = 1.0 + methods.index(a.method)  # later methods are noisier
    noise = np.random.default_rng(a.seed * 1000 + methods.index(a.method)).standard_normal(t.shape)
    for budget in [*snaps, None]:
        secs = tmax if budget is None else budget
        img = np.maximum(t + 0.2 * quality / np.sqrt(8 * secs) * t * noise, 0)
        side = {
            "method": a.method,
            "params": {
                kv.split("=", 1)[0][len("method.") :]: kv.split("=", 1)[1]
                for kv in a.set
                if kv.startswith("method.")
            },
            "iterations": int(10 * secs),
            "spp": int(10 * secs),
            "render_seconds": secs * 1.01,
            "load_seconds": 0.05,
            "rays": int(1e5 * secs),
            "nonfinite": 0,
            "seed": a.seed,
            "threads": a.threads,
            "version": "fake",
            "overrides": [kv for kv in a.set if not kv.startswith("method.")],
            "scene": scene,
        }
        dest = out if budget is None else out.with_name(f"{out.stem}.t{tag(budget)}.exr")
        write(dest, img, side)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
