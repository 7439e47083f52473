"""How many samples a study's reference needs, from a short pilot and the study's own renders.

The reference's relMSE is a set fraction (``target``) of the best method's relMSE at the
study's largest budget, under a time cap. What it needs follows from a pilot, the first
passes of the two halves: the pilot's own error, which falls as 1/spp, and its seconds per
spp. The best method's error is bounded from below, so that the reference is not made too
coarse:

- from the study's seeds: half the relMSE between two seeds' images of a method estimates
  its variance, which its error (variance plus squared bias) is at least;
- from the pilot: the method's relMSE with the pilot's own error removed
  (compare.metrics.corrected_errors), less COVERAGE of its uncertainty.

The larger of the two bounds a method's error; the smallest over the methods, the best one's.
relMSE's denominators are those of the mean of the pilot and every image compared, which is
far less noisy than the pilot alone. Nothing here renders: the plan says how many samples each
half needs, and the reference step renders those it does not have yet.
"""

from __future__ import annotations

import itertools
import math
import shlex
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .metrics import COVERAGE, EPS, mean_and_uncertainty, variance_terms

# The layout of a plan's JSON (the reference step reads its "source" and "spp").
PLAN_VERSION = 1


def method_error_bounds(
    images: Mapping[str, Sequence[np.ndarray]],
    half_a: np.ndarray,
    half_b: np.ndarray,
    var_a: np.ndarray | None = None,
    var_b: np.ndarray | None = None,
) -> tuple[dict[str, dict[str, float]], float]:
    """Per method (its images at one budget, one per seed): ``from_seeds`` (half the relMSE
    between seeds, averaged over pairs; NaN with one seed), ``from_pilot`` (relMSE with the
    pilot's error removed, less COVERAGE uncertainties) and ``bound`` (the larger; the pilot's
    point estimate when neither is positive). Also the pilot's own relMSE, with the same
    denominators."""
    every = [x for xs in images.values() for x in xs]
    r = 0.5 * (half_a + half_b)
    mean = (np.sum(every, axis=0) + r) / (len(every) + 1)
    w = 1.0 / (mean * mean + EPS)
    v_sum, v_prod = variance_terms(half_a, half_b, var_a, var_b)
    pilot_error = float(((half_a - half_b) ** 2 * w).mean() / 4.0)
    out: dict[str, dict[str, float]] = {}
    for method, xs in images.items():
        pairs = [float(((x - y) ** 2 * w).mean() / 2.0) for x, y in itertools.combinations(xs, 2)]
        corrected, spread = [], []
        for x in xs:
            product = (x - half_a) * (x - half_b)
            own = np.maximum(product, 0.0) * v_sum * w * w
            value, u_own, u_shared = mean_and_uncertainty(product * w, own, v_prod * w * w)
            corrected.append(value)
            spread.append(math.hypot(u_own, u_shared))
        point = float(np.mean(corrected))
        from_pilot = point - COVERAGE * float(np.mean(spread))
        from_seeds = float(np.mean(pairs)) if pairs else math.nan
        bound = max(v for v in (from_seeds, from_pilot, -math.inf) if not math.isnan(v))
        out[method] = {
            "from_seeds": from_seeds,
            "from_pilot": from_pilot,
            "pilot_estimate": point,
            "bound": bound if bound > 0 else point,
        }
    return out, pilot_error


def plan_reference(
    images: Mapping[str, Sequence[np.ndarray]],
    pilot: Sequence[np.ndarray],
    pilot_variances: Sequence[np.ndarray] | None,
    *,
    pilot_spp: int,
    seconds_per_spp: float,
    target: float,
    max_seconds: float,
    source: str = "mitsuba",
) -> dict[str, Any]:
    """The samples per half that bring the reference's relMSE to ``target`` times the best
    method's (``images``: each method's images at the largest budget), at most what
    ``max_seconds`` of rendering (both halves) allow and at least the pilot's ``pilot_spp``.
    ``cap_bound`` says whether the cap decided."""
    var_a, var_b = pilot_variances or (None, None)
    bounds, pilot_error = method_error_bounds(images, pilot[0], pilot[1], var_a, var_b)
    known = {m: b["bound"] for m, b in bounds.items() if b["bound"] > 0}
    best = min(known, key=known.get) if known else None
    rate = seconds_per_spp if seconds_per_spp > 0 else math.nan
    spp_cap = int(max_seconds / (2.0 * rate)) if math.isfinite(rate) else pilot_spp
    if best is not None and pilot_error > 0:
        target_error = target * known[best]
        spp_needed = math.ceil(pilot_spp * pilot_error / target_error)
    else:  # nothing to size by: as much as the cap allows
        target_error, spp_needed = math.nan, spp_cap
    spp = max(pilot_spp, min(spp_needed, spp_cap))
    return {
        "version": PLAN_VERSION,
        "source": source,
        "how": "sized",
        "spp": int(spp),
        "spp_needed": int(spp_needed),
        "spp_cap": int(spp_cap),
        "cap_bound": bool(spp_needed > spp_cap),
        "max_seconds": float(max_seconds),
        "target": float(target),
        "target_error": target_error,
        "best_method": best,
        "best_error_bound": known.get(best, math.nan) if best else math.nan,
        "methods": bounds,
        "pilot_spp": int(pilot_spp),
        "pilot_relmse": pilot_error,
        "seconds_per_spp": seconds_per_spp,
        "expected_seconds": 2.0 * spp * seconds_per_spp,
        "expected_relmse": pilot_error * pilot_spp / spp,
    }


def fixed_plan(spp: int, source: str = "mitsuba") -> dict[str, Any]:
    """The plan of a reference whose samples the config gives."""
    return {"version": PLAN_VERSION, "source": source, "how": "fixed", "spp": int(spp)}


def plan_from_files(spec: dict[str, Any]) -> dict[str, Any]:
    """The reference-plan step: ``spec`` gives ``out`` (the plan's JSON), ``scene``, ``source``
    (the config's: mitsuba or pgi), ``check`` (the two halves of pgi's pt check) and either
    ``spp`` (fixed by the config) or, sized, ``pilot`` (Mitsuba's two pilot halves, where
    Mitsuba is to render; with their sidecars and variances beside them), ``runs`` ({method:
    images at the largest budget}), ``target`` and ``max_seconds``.

    A sized Mitsuba reference's pilot is checked against the check (compare.trust); where it
    is not trustworthy the plan names pgi's pt as the source instead (``fallback``), and the
    check's halves serve as the pilot that sizes it (the halves extend their stores). The
    verdict is kept under ``trust``. Writes the plan and returns it."""
    from renderer.imageio import read_exr, read_json, write_json

    from .runs import check_reference_files, read_halves, sidecar_path

    source = str(spec.get("source", "mitsuba"))
    trust, pilot = None, spec.get("pilot")
    if source == "mitsuba" and pilot and spec.get("check"):
        name = f"Mitsuba's reference of {spec.get('scene', 'this scene')}"
        trust = check_reference_files(pilot, spec["check"], name)
        if not trust["trustworthy"]:
            source = "pgi"
    if source == "pgi":
        pilot = spec.get("check")
    if spec.get("spp"):
        plan = fixed_plan(int(spec["spp"]), source)
    else:
        (a, b), variances = read_halves(pilot)
        sides = [read_json(sidecar_path(h)) for h in pilot]
        images = {
            method: [read_exr(p).astype(np.float64) for p in paths]
            for method, paths in spec["runs"].items()
        }
        rates = [float(s.get("seconds_per_spp") or math.nan) for s in sides]
        plan = plan_reference(
            images,
            [a, b],
            variances,
            pilot_spp=min(int(s["spp"]) for s in sides),
            seconds_per_spp=float(np.nanmean(rates)) if not all(map(math.isnan, rates)) else 0.0,
            target=float(spec["target"]),
            max_seconds=float(spec["max_seconds"]),
            source=source,
        )
    plan["trust"] = trust
    plan["fallback"] = source != spec.get("source", "mitsuba")
    write_json(spec["out"], plan)
    if trust is not None:
        fallback = "; the reference is rendered by pgi's pt" if plan["fallback"] else ""
        print(trust["line"] + fallback)
    return plan


def half_args(plan: dict[str, Any], folder: str | Path, half: int) -> str:
    """The `pgi reference` options of one half of a planned reference: samples, source, and
    the store it extends (``<folder>/store/<source>-half<h>.npz``: a Mitsuba half extends
    its pilot, a pgi one the check). The workflow checks references itself: no check here."""
    source = str(plan.get("source", "mitsuba"))
    store = Path(folder) / "store" / f"{source}-half{half}.npz"
    return f"--spp {int(plan['spp'])} --source {source} --check 0 --store {shlex.quote(str(store))}"
