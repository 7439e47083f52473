"""Per-job steps of the workflow: merge the reference halves, compare one timed run.

Each function is what one Snakemake job does; the rules run ``python -m compare.steps``,
whose thin adaptors parse the job's arguments and call these.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from renderer.imageio import read_exr, read_json, write_exr, write_json

from .metrics import METRICS, average_references, compare_images, corrected_errors

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


def variance_path(exr: str | Path) -> Path:
    """The variance of a reference half's mean per value, as `pgi reference` writes it."""
    exr = Path(exr)
    return exr.with_name(f"{exr.stem}.var.exr")


# Checks of a merged reference, each given the halves and the info recorded so far and
# returning what it finds wrong (an empty list: nothing). A check that a reference can be
# trusted (say, no black pixels where a dense medium should glow) goes here; what it finds is
# recorded in ref.json under "warnings".
ReferenceCheck = Callable[[np.ndarray, np.ndarray, dict[str, Any]], list[str]]
REFERENCE_CHECKS: tuple[ReferenceCheck, ...] = ()


def read_halves(
    halves: Sequence[str | Path],
) -> tuple[list[np.ndarray], list[np.ndarray] | None]:
    """The two halves of a reference (float64), and the variances of their means when both
    have them beside them (``<half>.var.exr``; else None: estimated from their difference)."""
    images = [read_exr(h).astype(np.float64) for h in halves]
    if all(variance_path(h).is_file() for h in halves):
        return images, [read_exr(variance_path(h)).astype(np.float64) for h in halves]
    return images, None


def merge_reference(
    half_a: str | Path,
    half_b: str | Path,
    out_exr: str | Path,
    out_json: str | Path,
    plan_json: str | Path | None = None,
) -> dict[str, Any]:
    """Average two independent reference halves and record the reference's own error, how it
    was sized (``plan_json``, the reference-plan step's) and what REFERENCE_CHECKS find.

    See :func:`compare.metrics.reference_error` for why the reference error is a quarter of
    the half-vs-half error.
    """
    (a, b), variances = read_halves([half_a, half_b])
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
        # where the halves are, from ref.json's folder (compare_run reads them)
        "halves": [os.path.relpath(h, Path(out_json).parent) for h in (half_a, half_b)],
        # the halves have their own variances (from their passes) beside them; else they
        # are estimated from the halves' difference
        "variances": bool(variances),
        "spp_per_half": [s.get("spp") for s in sides],
        "passes_per_half": [s.get("passes") for s in sides],
        # e.g. "mitsuba 3.9.1 volpath" (volpathmis for media with chromatic extinction)
        "renderer": " / ".join(sorted({str(s["renderer"]) for s in sides if s.get("renderer")})),
        "seeds": [s.get("seed") for s in sides],
        # all the halves' passes, those of earlier runs they extend included
        "render_seconds": sum(
            float(s.get("total_render_seconds", s.get("render_seconds")) or 0.0) for s in sides
        ),
        "width": int(ref.shape[1]),
        "height": int(ref.shape[0]),
    }
    if plan_json is not None:
        info["plan"] = read_json(plan_json)
    info["warnings"] = [w for check in REFERENCE_CHECKS for w in check(a, b, info)]
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
) -> pd.DataFrame:
    """Compare every snapshot of one timed run against the reference; one CSV row per budget:
    every metric as measured, and the MSE-type ones with the reference's own error removed
    (``<metric>_corrected``, with uncertainties ``<metric>_u`` and ``<metric>_u_shared``;
    compare.metrics.corrected_errors) from the halves that ref.json names.

    Checks that the run used the configured thread count (sidecar ``threads``).
    """
    if len(snapshots) != len(budgets):
        raise ValueError(f"{len(snapshots)} snapshots but {len(budgets)} budgets")
    ref = read_exr(ref_exr).astype(np.float64)
    ref_info = read_json(ref_json)
    ref_rel = float(ref_info["ref_relmse"])
    ref_mse = float(ref_info["ref_mse"])
    if len(ref_info.get("halves") or ()) != 2:
        raise ValueError(f"{ref_json}: names no two halves: the reference error cannot be removed")
    (half_a, half_b), variances = read_halves(
        [Path(ref_json).parent / h for h in ref_info["halves"]]
    )
    var_a, var_b = variances or (None, None)
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
            corrected = corrected_errors(img, half_a, half_b, var_a, var_b)
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
        row.update(corrected)
        row["image"] = str(path)
        rows.append(row)
    df = pd.DataFrame(rows, columns=[*rows[0].keys()] if rows else None)
    Path(out_csv).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out_csv, index=False)
    return df


__all__ = [
    "METRICS",
    "SIDECAR_FIELDS",
    "compare_run",
    "merge_reference",
    "read_halves",
    "sidecar_path",
    "variance_path",
]
