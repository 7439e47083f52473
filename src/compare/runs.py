"""Per-job steps of the workflow: merge the reference halves, compare one timed run.

Each function is what one Snakemake job does; the rules run ``python -m compare.steps``,
whose thin adaptors parse the job's arguments and call these.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from renderer.imageio import read_exr, read_json, write_exr, write_json

from .metrics import METRICS, average_references, compare_images, corrected_errors
from .trust import Estimate, check_reference, combined, verdict_record

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


def source_label(source: str) -> str:
    """How a reference's source is named to a reader: "Mitsuba", "pgi's pt"."""
    return {"mitsuba": "Mitsuba", "pgi": "pgi's pt"}.get(source, source)


def read_halves(
    halves: Sequence[str | Path],
) -> tuple[list[np.ndarray], list[np.ndarray] | None]:
    """The two halves of a reference (float64), and the variances of their means when both
    have them beside them (``<half>.var.exr``; else None: estimated from their difference)."""
    images = [read_exr(h).astype(np.float64) for h in halves]
    if all(variance_path(h).is_file() for h in halves):
        return images, [read_exr(variance_path(h)).astype(np.float64) for h in halves]
    return images, None


def half_estimates(halves: Sequence[str | Path]) -> list[Estimate]:
    """Two independent halves (a reference's, or a check's) as compare.trust estimates: each
    image with the variance of its mean and its passes (from its sidecar)."""
    images, variances = read_halves(halves)
    passes = [int(read_json(sidecar_path(h)).get("passes") or 0) for h in halves]
    return [
        Estimate.from_passes(image, variances[i] if variances else None, passes[i])
        for i, image in enumerate(images)
    ]


def check_reference_files(
    halves: Sequence[str | Path], checks: Sequence[str | Path], reference: str
) -> dict[str, Any]:
    """Whether the reference made of ``halves`` can be trusted, judged against pgi's pt check
    (its two halves ``checks``; compare.trust): the verdict as ref.json and plan.json keep it
    (``reference`` names what is judged, e.g. "Mitsuba's reference of cbox-fog")."""
    ref = half_estimates(halves)
    check = half_estimates(checks)
    verdict = check_reference(combined(*ref), combined(*check), (ref[0], ref[1]), "pt")
    record = verdict_record(verdict, reference, "pgi's pt")
    sides = [read_json(sidecar_path(c)) for c in checks]
    record["check"] = {
        "spp_per_half": [s.get("spp") for s in sides],
        "render_seconds": sum(float(s.get("render_seconds") or 0.0) for s in sides),
    }
    return record


def merge_reference(
    half_a: str | Path,
    half_b: str | Path,
    out_exr: str | Path,
    out_json: str | Path,
    plan_json: str | Path | None = None,
    checks: Sequence[str | Path] | None = None,
) -> dict[str, Any]:
    """Average two independent reference halves and record the reference's own error, how it
    was sized (``plan_json``, the reference-plan step's), what rendered it and whether it can
    be trusted: a Mitsuba reference is checked against pgi's pt (``checks``, the check's two
    halves); one pgi's pt rendered carries the plan's verdict on Mitsuba's pilot, which sent
    it there (it is not checked against the check: its first passes are the check's).

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
        # e.g. "mitsuba 3.9.1 volpath" (one grey render per channel for chromatic extinction)
        "renderer": " / ".join(sorted({str(s["renderer"]) for s in sides if s.get("renderer")})),
        "seeds": [s.get("seed") for s in sides],
        # all the halves' passes, those of earlier runs they extend included
        "render_seconds": sum(
            float(s.get("total_render_seconds", s.get("render_seconds")) or 0.0) for s in sides
        ),
        "width": int(ref.shape[1]),
        "height": int(ref.shape[0]),
    }
    plan = read_json(plan_json) if plan_json is not None else {}
    if plan:
        info["plan"] = plan
    sources = {str(s.get("source") or "mitsuba") for s in sides}
    source = sources.pop() if len(sources) == 1 else "mixed"
    info["source"] = source
    info["source_label"] = source_label(source)
    trust = plan.get("trust")
    if source == "mitsuba" and checks:
        scene = sides[0].get("scene") or Path(out_json).parent.name
        trust = check_reference_files([half_a, half_b], checks, f"Mitsuba's reference of {scene}")
    info["trust"] = trust
    # Verdicts are drawn against this reference unless it is Mitsuba's and failed its check.
    info["trusted"] = source != "mitsuba" or not trust or bool(trust["trustworthy"])
    info["warnings"] = [trust["line"]] if trust and not trust["trustworthy"] else []
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
        # what rendered the reference, and whether verdicts may be drawn against it
        row["reference"] = str(ref_info.get("source_label") or "Mitsuba")
        row["reference_trusted"] = bool(ref_info.get("trusted", True))
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
