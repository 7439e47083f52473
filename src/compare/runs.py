"""Per-job steps of the workflow: merge the reference halves, compare one timed run.

Each function is what one Snakemake job does; the rules run ``python -m compare.steps``,
whose thin adaptors parse the job's arguments and call these.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from renderer.imageio import read_exr, read_json, write_exr, write_json

from .metrics import (
    METRICS,
    REF_QUALITY_FACTOR,
    average_references,
    compare_images,
    reference_ok,
)

#: sidecar fields copied into every metrics row (missing ones become NaN)
SIDECAR_FIELDS: tuple[str, ...] = (
    "render_seconds",
    "load_seconds",
    "iterations",
    "spp",
    "rays",
    "nonfinite",
    "threads",
)


def sidecar_path(exr: str | Path) -> Path:
    return Path(exr).with_suffix(".json")


def merge_reference(
    half_a: str | Path, half_b: str | Path, out_exr: str | Path, out_json: str | Path
) -> dict[str, Any]:
    """Average two independent reference halves and record the reference's own error.

    See :func:`compare.metrics.reference_error` for why the reference error is a quarter of
    the half-vs-half error.
    """
    a = read_exr(half_a).astype(np.float64)
    b = read_exr(half_b).astype(np.float64)
    # Also validates shapes and finiteness; messages name the halves' files.
    ref, err = average_references(
        a, b, names=(f"reference half {half_a}", f"reference half {half_b}")
    )
    sides = []
    for h in (half_a, half_b):
        p = sidecar_path(h)
        sides.append(read_json(p) if p.is_file() else {})
    info: dict[str, Any] = {
        **err,
        "halves": [str(half_a), str(half_b)],
        "spp_per_half": [s.get("spp") for s in sides],
        # e.g. "mitsuba 3.9.1 volpath" (one grey render per channel for chromatic extinction)
        "renderer": " / ".join(sorted({str(s["renderer"]) for s in sides if s.get("renderer")})),
        "seeds": [s.get("seed") for s in sides],
        "render_seconds": sum(float(s.get("render_seconds") or 0.0) for s in sides),
        "width": int(ref.shape[1]),
        "height": int(ref.shape[0]),
    }
    write_exr(out_exr, ref, {"reference": info})
    write_json(out_json, info)
    return info


def compare_run(
    snapshots: Sequence[str | Path],
    budgets: Sequence[float],
    ref_exr: str | Path,
    ref_json: str | Path,
    out_csv: str | Path,
    *,
    scene: str,
    method: str,
    seed: int,
    threads: int,
    ref_quality_factor: float = REF_QUALITY_FACTOR,
) -> pd.DataFrame:
    """Compare every snapshot of one timed run against the reference; one CSV row per budget.

    Checks that the run used the configured thread count (sidecar ``threads``).
    """
    if len(snapshots) != len(budgets):
        raise ValueError(f"{len(snapshots)} snapshots but {len(budgets)} budgets")
    ref = read_exr(ref_exr).astype(np.float64)
    ref_info = read_json(ref_json)
    ref_rel = float(ref_info["ref_relmse"])
    ref_mse = float(ref_info["ref_mse"])
    rows = []
    for path, budget in zip(snapshots, budgets, strict=True):
        side = read_json(sidecar_path(path))
        got_threads = side.get("threads")
        if got_threads is not None and int(got_threads) != int(threads):
            raise RuntimeError(
                f"{path}: rendered with {got_threads} threads but the config asks for "
                f"{threads}; timings would not be comparable"
            )
        img = read_exr(path)
        try:
            m = compare_images(img, ref)
        except ValueError as e:
            raise ValueError(f"{path} vs {ref_exr}: {e}") from e
        row: dict[str, Any] = {
            "scene": scene,
            "method": method,
            "seed": int(seed),
            "budget": float(budget),
        }
        for k in SIDECAR_FIELDS:
            v = side.get(k)
            row[k] = float(v) if isinstance(v, int | float) else math.nan
        row.update(m)
        row["ref_relmse"] = ref_rel
        row["ref_mse"] = ref_mse
        # the measured error includes the reference's own error; flag unless it is well below
        row["ref_ok"] = reference_ok(m["relmse"], ref_rel, ref_quality_factor)
        row["image"] = str(path)
        rows.append(row)
    df = pd.DataFrame(rows, columns=[*rows[0].keys()] if rows else None)
    Path(out_csv).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out_csv, index=False)
    return df


__all__ = ["METRICS", "SIDECAR_FIELDS", "compare_run", "merge_reference", "sidecar_path"]
