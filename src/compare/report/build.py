"""Build the static HTML report: ``index.html`` plus one ``scene-<name>.html`` per scene.

Pages open from disk with no server and no network: CSS, JavaScript, plots (SVG) and the
equal-time grids (PNG data URIs) are inline; the interactive viewer's linear image data sits
next to the page in ``data/<scene>.js`` (a classic script, which browsers load from file://).
"""

from __future__ import annotations

import html
import json
import math
from datetime import UTC, datetime
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from renderer.imageio import read_exr, read_json
from renderer.scene.yaml_dialect import check_yaml_file

from .. import tables as T
from ..metrics import COVERAGE, DETERMINED_FRACTION, EPS, relmse_map
from . import images as I  # noqa: N812
from .plots import convergence_svg, method_colours

e = html.escape
PLOT_METRICS = ("relmse", "flip", "one_minus_ssim")


def _asset(name: str) -> str:
    return resources.files("compare.report").joinpath("assets", name).read_text()


def _page(title: str, body: str, head_extra: str = "") -> str:
    return (
        "<!doctype html>\n<html lang=en><head><meta charset=utf-8>"
        f"<meta name=viewport content='width=device-width'><title>{e(title)}</title>"
        f"<style>{_asset('style.css')}</style>{head_extra}</head>\n<body>\n{body}\n</body></html>\n"
    )


def _nav(scenes: list[str], current: str | None) -> str:
    links = ['<a href="index.html">overview</a>']
    for s in scenes:
        if s == current:
            links.append(f"<b>{e(s)}</b>")
        else:
            links.append(f'<a href="scene-{e(s)}.html">{e(s)}</a>')
    return "<nav>" + " ".join(links) + "</nav>"


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    tmp.replace(path)


def _read_tables(folder: str | Path, spec: dict[str, Any]) -> dict[str, pd.DataFrame]:
    """The tables, rows in the study's order of scenes and methods."""
    folder = Path(folder)
    names = ("runs", "summary", "convergence", "time_to_error", "stats", "best")
    return {
        n: T.study_order(
            pd.read_csv(folder / f"{n}.csv"),
            spec["scenes"],
            None if n == "best" else spec["methods"],
        )
        for n in names
        if (folder / f"{n}.csv").is_file()
    }


def _names(listed: Any) -> list[str]:
    """The methods of a comma-separated cell (empty, or NaN as a CSV reads an empty one)."""
    return [m for m in str(listed).split(",") if m] if isinstance(listed, str) else []


def _metric_label(m: str) -> str:
    return T.METRIC_LABELS.get(m, m)


def _readable_column(name: str) -> str:
    """A table column as a reader names it: metric labels, units, no identifiers."""
    if name.startswith("speedup_vs_"):
        return f"speed-up vs {name[len('speedup_vs_') :]}"
    if name == "speedup_bound":
        return "speed-up bound"
    if name == "seconds":
        return "time [s]"
    metric, sep, rest = name.partition(" (")
    return _metric_label(metric) + (sep + rest if sep else "")


def _ref_error_for(metric: str, ref: dict[str, Any]) -> float | None:
    key = T.REFERENCE_ERROR.get(metric)
    return ref.get(key) if key else None


_BOUND_SIGN = {"<=": "≤ ", ">=": "≥ ", "?": "?"}


def _slopes_note(reference_error_removed: bool = True) -> str:
    removed = (
        "A noisy reference adds its own error to every measurement, which flattens the curves "
        'of methods that get close to it. "Reference error removed": the fit of (error − '
        "reference error) over the runs with at least twice the reference error. "
    )
    return (
        f'<p class="note">{removed if reference_error_removed else ""}Every slope is left out '
        "unless the runs it fits come from three budgets or more, the largest at least 4x the "
        "smallest (two points always lie on a line). The plots' legends give the slopes as "
        "measured. Under each slope, as (seeds a to b): the smallest and largest "
        "of the slopes fitted to one seed's runs alone (the seeds are independent, the "
        "snapshots of one run are not), left out unless two seeds or more give one. The slope "
        "above is fitted over all runs, so it is not the middle of that range and may lie "
        "outside it when the seeds' render times differ.</p>"
    )


def _fraction(spec: dict[str, Any]) -> float:
    return float(spec.get("determined_fraction", DETERMINED_FRACTION))


def _legend(metric: str, fraction: float, corrected: bool = True) -> str:
    removed = (
        " with the reference's own error removed; under it, the reference's standard "
        "uncertainty of that mean (ref. ±) and the mean as measured"
        if corrected
        else ""
    )
    return (
        f'<p class="note">{e(_metric_label(metric))}{removed}, mean ± standard deviation over '
        "seeds. <b>Bold green</b>: lowest mean error for that scene and budget, and any method "
        f"that Welch's t-test on log errors at {T.TIE_LEVEL:g} cannot tell from it with these "
        "seeds and this reference (a tie). "
        f'<span class="flag">⚠</span>: {e(T.flag_meaning(fraction))}, so the cell says '
        "little about the method (a larger reference would). "
        f'<span class="offbudget">at … s</span>: the snapshot\'s mean render time, more than '
        f"{T.OFF_BUDGET:.0%} off its budget (a snapshot is the image at the iteration end "
        "nearest its budget; a method whose iterations are long cannot come closer), so the "
        "cell is not an equal-time comparison. A cell that ran over its budget so is never "
        "bold and wins nothing: it had more time than the others.</p>"
    )


def _reading_note() -> str:
    """What the errors are, in the page itself: a reader assumes the usual meanings."""
    return (
        '<p class="note"><b>Reading the errors.</b> x is a method\'s image, r the reference, '
        "both linear RGB; means run over pixels and channels. relMSE = mean((x − r)² / "
        f"(r² + {EPS:g})): where the reference is darker than about {math.sqrt(EPS):g} it "
        f"weighs squared errors by 1/{EPS:g}, like MSE scaled up, not relative to the pixel. "
        "MSE = mean((x − r)²), RMSE = √MSE. relMSE (trimmed 0.1 %): relMSE without the "
        "0.1 % of pixels with the largest per-pixel relMSE (fireflies). MAPE = mean(|x − r| / "
        f"(|r| + {EPS:g})); SMAPE = mean(|x − r| / (|x| + |r| + {EPS:g})), at most 1. "
        "1 − SSIM compares the images tonemapped to display sRGB "
        "(exposure 0, clipped to [0, 1]); FLIP is HDR-FLIP over its own range of exposures. "
        "Every error is measured against the reference, so it includes the reference's own "
        "error. MSE, RMSE and relMSE (also trimmed) are shown with it removed: the reference "
        "is the mean of two independent halves A and B, and mean((x − A)(x − B)), the measured "
        "error less the reference's own estimated from the halves, is an unbiased estimate of "
        "the error against the truth (for relMSE to first order: its denominator is the "
        "reference's). It can come out below zero where the reference cannot resolve the "
        "error; each such figure comes with its standard uncertainty (ref. ±) from the "
        "reference's noise, and the measured figure beside it. MAPE, SMAPE, HDR-FLIP and "
        "1 − SSIM are not squared errors, so they cannot be corrected this way: they are "
        "shown as measured, the reference's error included. Slopes marked <i>reference error "
        "removed</i> are fitted to the corrected errors.</p>"
    )


def _methods_note(methods: list[str], bases: dict[str, str]) -> str:
    """What each method of the study is (`pgi methods`' descriptions), and what comparing
    Mitsuba with a Mitsuba reference means."""
    from renderer.methods import describe

    seen = dict.fromkeys(bases.get(m, m) for m in methods)
    items = []
    for m in seen:
        try:
            items.append(f"<b>{e(m)}</b>: {e(describe(m))}")
        except KeyError:  # a method this version no longer has: name it only
            items.append(f"<b>{e(m)}</b>")
    text = f'<p class="note"><b>Methods.</b> {"; ".join(items)}.'
    if "mitsuba" in seen:
        text += (
            " The reference is Mitsuba's too (volpath, one grey render per channel "
            "where a medium's extinction differs between colour channels; each scene page "
            "names it): mitsuba "
            "shares its conventions, and on most scenes its integrator, while the pgi methods "
            "are measured across two renderers, so a systematic difference between them (the "
            "parity tests bound it within their noise) would count against the pgi methods only."
        )
    return text + "</p>"


# --- the reference ----------------------------------------------------------------------------


def _sizing_sentence(ref: dict[str, Any]) -> str:
    """How the reference's samples were chosen (its plan), in words; "" without a plan."""
    plan = ref.get("plan") or {}
    if plan.get("how") == "fixed":
        return "Its samples are fixed by the config."
    if plan.get("how") != "sized":
        return ""
    text = (
        f"Sized from a pilot of {plan.get('pilot_spp')} spp a half (its relMSE "
        f"{T.fmt(plan.get('pilot_relmse'))}, {T.fmt(plan.get('seconds_per_spp'))} s per spp): "
    )
    if plan.get("best_method"):
        text += (
            f"target relMSE {T.fmt(plan.get('target_error'))}, {T.fmt(plan.get('target'))} x "
            f"the best method's error at the largest budget ({e(str(plan['best_method']))}, "
            f"at least {T.fmt(plan.get('best_error_bound'))}), which takes "
            f"{plan.get('spp_needed')} spp a half"
        )
    else:
        text += "no method's error could be bounded, so the reference takes what the cap allows"
    cap = f"the cap of {T.fmt(plan.get('max_seconds'))} s for both halves"
    if plan.get("cap_bound"):
        text += (
            f'; <span class="flag">{cap} bound it</span> at {plan.get("spp_cap")} spp a half, '
            "so the reference is coarser than the target asks"
        )
    else:
        text += f", within {cap}"
    return text + "."


def _trust_sentence(ref: dict[str, Any]) -> str:
    """Whether the reference can be trusted (its check against pgi's pt, compare.trust) and,
    where Mitsuba's could not, what rendered it instead; in HTML."""
    trust, source = ref.get("trust") or {}, ref.get("source", "mitsuba")
    findings = "; ".join(str(f) for f in trust.get("findings") or ())
    if source == "pgi" and trust and not trust.get("trustworthy", True):
        return (
            f'<p><span class="flag">⚠ No trustworthy Mitsuba reference: {e(findings)}; '
            "reference rendered by pgi's pt</span> (in two independent halves of their own "
            "seeds, its own error estimated and removed as Mitsuba's would be; a Mitsuba pilot "
            "failed the check, so the reference is unbiased by pt's construction, not "
            "confirmed by a second renderer).</p>"
        )
    if source == "pgi":
        return "<p>Reference rendered by pgi's pt, as the config asks (reference_source).</p>"
    if trust and not trust.get("trustworthy", True):
        return (
            f'<p><span class="flag">⚠ No trustworthy Mitsuba reference: {e(findings)}.</span> '
            "Methods are not ranked against it (set the scene's <code>reference_source: "
            "pgi</code> to have pgi's pt render it).</p>"
        )
    if trust:
        spp = (trust.get("check") or {}).get("spp_per_half") or []
        of = f" (two halves of {e(str(spp[0]))} spp)" if spp and spp[0] else ""
        return (
            f"<p>Checked against pgi's pt{of}: no dead pixels where pt sees light, its image "
            "mean within pt's confidence interval, its halves agreeing within their noise.</p>"
        )
    return ""


def _reference_paragraph(ref: dict[str, Any]) -> str:
    spp = ref.get("spp_per_half") or []
    passes = ref.get("passes_per_half") or []
    renderer = ref.get("renderer") or "Mitsuba 3"
    variances = (
        "the variance of each half's mean from the spread of its passes"
        if ref.get("variances")
        else "the variances of the halves estimated from their difference alone"
    )
    return _trust_sentence(ref) + (
        f"<p>{e(renderer[:1].upper() + renderer[1:])}, two independent halves"
        + (f" of {e(str(spp[0]))} spp each" if spp and spp[0] else "")
        + (f" ({e(str(passes[0]))} passes)" if passes and passes[0] else "")
        + f", {T.fmt(ref.get('render_seconds'))} s of rendering. Half-vs-half relMSE "
        f"{T.fmt(ref.get('halves_relmse'))}; estimated relMSE of the reference (their average) "
        f"<b>{T.fmt(ref.get('ref_relmse'))}</b> (a quarter of the half-vs-half value: each half "
        "has error s², their difference 2s², the average s²/2). MSE-type errors are shown "
        f"with it removed; their uncertainties use {variances}. "
        f"{_sizing_sentence(ref)}</p>"
    )


def _trust_word(ref: dict[str, Any]) -> str:
    """The index's word for a reference's check: "yes", "no: Mitsuba's failed, pt's used",
    "no" (not ranked), or "–" (not checked)."""
    trust = ref.get("trust") or {}
    if not trust:
        return "–"
    if trust.get("trustworthy"):
        return "yes"
    return "Mitsuba's: no (pt's used)" if ref.get("source") == "pgi" else "no (not ranked)"


def _reference_row(scene: str, ref: dict[str, Any], cells: pd.DataFrame) -> dict[str, Any]:
    """A scene's row of the index's reference-quality table."""
    plan = ref.get("plan") or {}
    sized = plan.get("how") == "sized"
    row = {
        "scene": scene,
        "spp per half": (ref.get("spp_per_half") or [None])[0],
        "source": ref.get("source_label") or "Mitsuba",
        "trustworthy": _trust_word(ref),
        "sized": "to the study" if sized else ("fixed" if plan else "–"),
        "target relMSE": plan.get("target_error") if sized else math.nan,
        "spp needed": plan.get("spp_needed") if sized else math.nan,
        "cap [s]": plan.get("max_seconds") if sized else math.nan,
        "cap bound": ("yes" if plan.get("cap_bound") else "no") if sized else "–",
        "render time [s]": ref.get("render_seconds"),
        "half-vs-half relMSE": ref.get("halves_relmse"),
        "reference relMSE (est.)": ref.get("ref_relmse"),
    }
    if "determined" in cells:
        row["cells determined"] = f"{int(cells.determined.astype(bool).sum())} of {len(cells)}"
    return row


# --- scene page -------------------------------------------------------------------------------


def _corrected_note(corrected: pd.Series, method: str, budget: str) -> str:
    """Under an image of the grid, beside its measured relMSE: the corrected one."""
    value = corrected.get((method, float(budget)), math.nan)
    return f" ({T.fmt(value)} without the reference's error)" if math.isfinite(value) else ""


def _why_absent(method: str) -> str:
    """Why an expected winner has no results: left out of the study, or not a method yet
    (the brief's bdpt, vpl, vrl and vbl)."""
    from renderer.known_methods import NOT_YET_IMPLEMENTED

    return "not implemented yet" if method in NOT_YET_IMPLEMENTED else "not in this study"


def _about_scene(
    scene_file: str | None,
    scene: str,
    summary: pd.DataFrame,
    metric: str,
    methods: list[str],
    bases: dict[str, str],
) -> str:
    """What the scene file says it is for, beside the method that actually won. ``bases``
    maps each study method to the `pgi methods` id it runs (a variant to its method)."""
    if not scene_file or not Path(scene_file).is_file():
        return ""
    read = check_yaml_file(Path(scene_file))  # as the renderer reads it (YAML 1.2)
    doc = read[0] if read and isinstance(read[0], dict) else {}
    parts = ["<h2>About this scene</h2>"]
    if doc.get("description"):
        parts.append(f"<p>{e(' '.join(str(doc['description']).split()))}</p>")
    if doc.get("stresses"):
        parts.append(f"<p><b>Stresses:</b> {e(', '.join(map(str, doc['stresses'])))}.</p>")
    expected = [str(m) for m in doc.get("expected_winners") or []]
    if expected:
        present = {bases.get(m, m) for m in methods}
        shown = [m if m in present else f"{m} ({_why_absent(m)})" for m in expected]
        parts.append(f"<p><b>Expected to win:</b> {e(', '.join(shown))}.")
        best = T.best_methods(summary[summary.scene == scene], metric)
        if not best.empty:
            last = best.sort_values("budget").iloc[-1]
            won = str(last.method)
            as_expected = bases.get(won, won) in expected
            tied = [m for m in str(last.tied_with or "").split(",") if m]
            tied_expected = [m for m in tied if bases.get(m, m) in expected]
            by_reference = _names(last.get("reference_ties"))
            verdict = "as expected" if as_expected else "not among the expected"
            if not as_expected and tied_expected:
                which = "which is" if len(tied_expected) == 1 else "which are"
                verdict += f", but tied with {e(', '.join(tied_expected))}, {which}"
            cell = summary[
                (summary.scene == last.scene)
                & (summary.method == won)
                & (summary.budget == last.budget)
            ]
            if not cell.empty and not bool(cell.get("determined", pd.Series([True])).iloc[0]):
                verdict += '; <span class="flag">⚠</span> the reference limits this comparison'
            seconds = float(cell.render_seconds_mean.iloc[0]) if not cell.empty else 0.0
            if T.off_budget(seconds, last.budget):
                verdict += "; not equal time:" + T.off_budget_mark(seconds, last.budget)
            others = [m for m in tied if as_expected or m not in tied_expected]
            if others:
                verdict += f"; tied with {e(', '.join(others))}"
            if by_reference:  # not a winner: the reference cannot rank them
                names = ", ".join([won, *by_reference])
                parts.append(
                    f" <b>Undecided</b> at {e(T.budget_label(last.budget))}: {e(names)} lie "
                    f"within the reference's uncertainty of each other ({verdict}; lowest "
                    f"mean: {e(won)})."
                )
            else:
                parts.append(
                    f" <b>Won</b> at {e(T.budget_label(last.budget))}: {e(won)} ({verdict})."
                )
        ranked = T.ranked_cells(summary[summary.scene == scene], metric)
        trusted = summary[summary.scene == scene].get("reference_trusted", pd.Series([True]))
        if not trusted.astype(bool).all():
            parts.append(" No trustworthy reference: no method is ranked.")
        elif best.empty and not ranked.empty:
            parts.append(" No method stayed within any budget: none won.")
        elif not best.empty and last.budget < ranked.budget.max():
            largest = T.budget_label(ranked.budget.max())
            parts.append(f" At {e(largest)} no method stayed within its budget: none won.")
        parts.append("</p>")
    return "".join(parts)


def build_scene_page(spec: dict[str, Any]) -> None:
    scene = spec["scene"]
    out = Path(spec["reports"])
    tabs = _read_tables(spec["tables"], spec)
    metric = spec["metric"]
    fraction = _fraction(spec)
    methods: list[str] = spec["methods"]
    budgets: list[str] = spec["budgets"]
    colours = method_colours(methods)
    ref_info = read_json(spec["ref_json"])
    ref = read_exr(spec["ref"]).astype(np.float64)
    ev = I.auto_exposure(ref)

    # images at full size for the grid, downsampled for the viewer
    imgs: dict[str, dict[str, np.ndarray]] = {}
    for m in methods:
        imgs[m] = {}
        for b, path in zip(budgets, spec["snapshots"][m], strict=True):
            if Path(path).is_file():
                imgs[m][b] = read_exr(path).astype(np.float64)
    # render time of each image shown (the runs table has every snapshot's)
    shown = tabs["runs"]
    shown = shown[(shown.scene == scene) & (shown.seed == spec["seed"])]
    seconds = shown.set_index(["method", "budget"])["render_seconds"]
    corrected = (
        shown.set_index(["method", "budget"])["relmse_corrected"]
        if "relmse_corrected" in shown
        else pd.Series(dtype=float)
    )
    err = {m: {b: relmse_map(x, ref) for b, x in d.items()} for m, d in imgs.items()}
    lo, hi = I.error_range([x for d in err.values() for x in d.values()])

    body: list[str] = [
        _nav(spec["scenes"], scene),
        f"<h1>{e(scene)}</h1>",
        f'<p class="note">{e(spec["title"])} — study <b>{e(spec["study"])}</b>. '
        f"Images shown are seed {spec['seed']}; tables and plots use every seed.</p>",
    ]

    bases = spec.get("bases") or {}
    about = _about_scene(spec.get("scene_file"), scene, tabs["summary"], metric, methods, bases)
    body.append(about)

    # reference quality
    body.append("<h2>Reference</h2>")
    body.append(_reference_paragraph(ref_info))

    summary = tabs["summary"]
    ss = summary[summary.scene == scene]
    if not ss.empty:
        body.append(f"<h2>Error at each budget ({e(_metric_label(metric))})</h2>")
        body.append(_legend(metric, fraction, T.is_corrected(ss, metric)))
        body.append(T.overview_html(ss, metric, determined_fraction=fraction))

    # convergence
    runs = tabs["runs"]
    rs = runs[runs.scene == scene]
    if not rs.empty:
        body.append("<h2>Convergence</h2>")
        body.append(
            '<p class="note">Log-log error vs render time (the renderer\'s own clock, loading '
            "excluded). Lines: mean over seeds, for MSE-type metrics with the reference's own "
            f"error removed (error bars: ±{COVERAGE:g} of its standard uncertainty; dotted: "
            "as measured; means at or below zero cannot be drawn); bands: min–max over seeds; "
            "slope: least-squares fit over all runs (unbiased methods approach −1 for MSE-type "
            "metrics).</p>"
        )
        body.append('<div class="plots">')
        for pm in dict.fromkeys([metric, *PLOT_METRICS]):
            if pm in rs:
                svg = convergence_svg(
                    rs, pm, f"{scene}: {_metric_label(pm)}", colours, _ref_error_for(pm, ref_info)
                )
                body.append(f"<figure>{svg}</figure>")
        body.append("</div>")
        conv = tabs.get("convergence")
        tte = tabs.get("time_to_error")
        if conv is not None and not conv.empty:
            sc = conv[conv.scene == scene].assign(cell=lambda c: T.slope_cells(c))
            cs = sc.pivot(index="method", columns="metric", values="cell")
            cs = cs.reindex(sc.method.unique())  # pivot sorts; keep the study's order
            cs = cs[[c for c in T.METRICS if c in cs.columns]]
            for m in T.METRICS:
                removed = sc.slope_ref_removed[sc.metric == m] if "slope_ref_removed" in sc else []
                if m in cs.columns and (m in T.REFERENCE_ERROR or pd.notna(removed).any()):
                    ref_removed = sc[sc.metric == m]
                    fixed = T.slope_cells(ref_removed, "slope_ref_removed")
                    fixed.index = ref_removed["method"]
                    cs.insert(list(cs.columns).index(m) + 1, f"{m} (ref. error removed)", fixed)
            body.append("<h3>Fitted slopes (d log error / d log time)</h3>")
            body.append(_slopes_note())
            # One row per metric, one column per method: the bracketed ranges fit the width.
            rows = cs.T.rename(index=_readable_column).rename_axis("metric").reset_index()
            body.append(T.frame_html(rows, 3))
        if tte is not None and not tte.empty:
            ts = tte[tte.scene == scene].drop(columns=["scene"])
            body.append("<h3>Time to reach a target error</h3>")
            if not ts.empty:
                body.append(
                    f'<p class="note">Target: {e(_metric_label(ts.metric.iloc[0]))} = '
                    f"{T.fmt(ts.target.iloc[0])} ({e(str(ts.target_from.iloc[0]))}); "
                    "extrapolated = beyond the measured budgets, from the fitted slope (with three "
                    "budgets or more spanning 4x; at most 4x outside them); bound = only known "
                    "to be reached by the first budget (≤) or not by the last (≥).</p>"
                )
            shown = ts.drop(columns=["metric", "target", "target_from"])
            for col in ("bound", "speedup_bound"):  # as the index writes them
                if col in shown:
                    shown[col] = shown[col].map(lambda v: _BOUND_SIGN.get(str(v), "").strip())
            body.append(T.frame_html(shown.rename(columns=_readable_column), 3))

    # interactive viewer
    vmax = int(spec.get("viewer_max_size", 512))
    ref_v = I.downsample(ref, vmax)
    data = {
        "scene": scene,
        "width": int(ref_v.shape[1]),
        "height": int(ref_v.shape[0]),
        "budgets": budgets,
        "methods": methods,
        "exposure": ev,
        "err_lo": lo,
        "err_hi": hi,
        "colormap": [
            [int(round(255 * c)) for c in row]
            for row in I.false_colour(np.logspace(math.log10(lo), math.log10(hi), 256), lo, hi)
        ],
        "film": [int(ref.shape[1]), int(ref.shape[0])],
        # each image's relMSE at full size, as the tables have it: the viewer's own map (and a
        # mean of it) is of the downsampled, 8-bit-mantissa images
        "relmse": {m: {b: float(np.mean(x)) for b, x in d.items()} for m, d in err.items()},
        "reference": I.b64(I.encode_rgbe(ref_v)),
        # when each image shown was taken: the viewer marks those off budget as the grid does
        "seconds": {
            m: {b: float(seconds[(m, float(b))]) for b in d if (m, float(b)) in seconds.index}
            for m, d in imgs.items()
        },
        "off_budget": T.OFF_BUDGET,
        "images": {
            m: {b: I.b64(I.encode_rgbe(I.downsample(x, vmax))) for b, x in d.items()}
            for m, d in imgs.items()
        },
    }
    _write(
        out / "data" / f"{scene}.js",
        "window.PGI_DATA = " + json.dumps(data, separators=(",", ":")) + ";\n",
    )
    body.append("<h2>Interactive viewer</h2>")
    body.append(
        '<p class="note">Keys: <b>0</b> reference, <b>1–9</b> methods; <b>←/→</b> or '
        "<b>[ ]</b> budget; <b>+/−</b> exposure, <b>e</b> auto exposure; wheel zooms, drag "
        "pans (all panels together), double-click or <b>f</b> fits. The right panel is the "
        "per-pixel relMSE of the selected image (log scale).</p>"
    )
    body.append('<div id="viewer"></div>')
    body.append(f'<script src="data/{e(scene)}.js"></script>')
    body.append(f"<script>{_asset('viewer.js')}</script>")

    # equal-time grids
    body.append("<h2>Equal-time images</h2>")
    body.append(
        f'<p class="note">Tonemapped at {ev:+g} EV (sRGB). Error maps: per-pixel relMSE as '
        "measured (a pixel's own error cannot be told from the reference's), log "
        f"scale from {T.fmt(lo)} (black) to {T.fmt(hi)} (yellow), the same for every image "
        f'on this page: <img alt="colour bar" style="vertical-align:middle;width:200px;height:12px"'
        f' src="{I.data_uri_png(I.colorbar_png(lo, hi))}"></p>'
    )
    ref_png = I.data_uri_png(I.tonemapped_png(ref, ev))
    ncols = len(methods) + 1
    cols = f"grid-template-columns: 5em repeat({ncols}, minmax(60px, 240px))"
    for b in budgets:
        body.append(f"<h3>{e(b)} s</h3>")
        body.append(f'<div class="grid" style="{cols}">')
        body.append('<div class="rowlabel">image</div>')
        body.append(
            f'<figure><img alt="reference" src="{ref_png}"><figcaption>reference</figcaption>'
            "</figure>"
        )
        for m in methods:
            x = imgs[m].get(b)
            if x is None:
                body.append(f"<figure><figcaption>{e(m)}: missing</figcaption></figure>")
                continue
            rel = float(err[m][b].mean())
            uri = I.data_uri_png(I.tonemapped_png(x, ev))
            t = float(seconds.get((m, float(b)), math.nan))  # off budget: say so
            off = (
                T.off_budget_mark(t, float(b), averaged=False) if T.off_budget(t, float(b)) else ""
            )
            body.append(
                f'<figure><img alt="{e(m)} at {e(b)} s" src="{uri}">'
                f"<figcaption>{e(m)} · relMSE {T.fmt(rel)}{_corrected_note(corrected, m, b)}"
                f"{off}</figcaption></figure>"
            )
        body.append('<div class="rowlabel">error</div><div></div>')
        for m in methods:
            em = err[m].get(b)
            if em is None:
                body.append("<div></div>")
                continue
            png = I.data_uri_png(I.png_bytes(I.false_colour(em, lo, hi)))
            body.append(f'<figure><img alt="{e(m)} error at {e(b)} s" src="{png}"></figure>')
        body.append("</div>")

    # statistics
    stats = tabs.get("stats")
    if stats is not None and not stats.empty:
        st = stats[stats.scene == scene].drop(columns=["scene"])
        body.append("<h2>Render statistics</h2>")
        body.append(
            '<p class="note">Per run at its largest budget: render and load seconds from the '
            "renderer's clock, wall time and peak memory (max RSS, MB) from Snakemake's "
            "benchmark of the whole process.</p>"
        )
        body.append(T.frame_html(st, 4))
    if not ss.empty:
        body.append("<details><summary>All metrics (mean over seeds)</summary>")
        cols_all = ["method", "budget"]
        for m in T.METRICS:  # the corrected mean, where there is one, before the measured
            cols_all += [c for c in (f"{m}_corrected_mean", f"{m}_mean") if c in ss]
        body.append(T.frame_html(ss[cols_all], 3))
        body.append("</details>")

    _write(out / f"scene-{scene}.html", _page(f"{scene} — {spec['title']}", "\n".join(body)))


# --- index ------------------------------------------------------------------------------------


def build_index(spec: dict[str, Any]) -> None:
    out = Path(spec["reports"])
    tabs = _read_tables(spec["tables"], spec)
    metric = spec["metric"]
    fraction = _fraction(spec)
    scenes: list[str] = spec["scenes"]
    methods: list[str] = spec["methods"]
    baseline = spec["baseline"]
    colours = method_colours(methods)
    summary, runs = tabs["summary"], tabs["runs"]
    refs = {s: read_json(p) for s, p in spec["refs"].items()}
    now = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")

    body = [
        _nav(scenes, None),
        f"<h1>{e(spec['title'])}</h1>",
        f'<p class="note">Study <b>{e(spec["study"])}</b>: {len(scenes)} scene(s), '
        f"{len(methods)} method(s) ({e(', '.join(methods))}), budgets "
        f"{e(', '.join(T.budget_label(b) for b in sorted(summary.budget.unique())))}, "
        f"{int(runs.seed.nunique())} seed(s). Generated {now}. Tables as CSV and Markdown in "
        '<a href="tables/">tables/</a>.</p>',
    ]
    body.append(_methods_note(methods, spec.get("bases") or {}))
    variants: dict[str, str] = spec.get("variants") or {}
    if variants:
        # in the study's order (the spec's JSON has its keys sorted)
        items = "; ".join(
            f"<b>{e(label)}</b>: {e(variants[label])}" for label in methods if label in variants
        )
        body.append(f'<p class="note">Variants (a method with settings of its own): {items}.</p>')
    body.append(_reading_note())

    # winners
    best = T.best_methods(summary, metric)
    body.append(f"<h2>Best method per scene and budget ({e(_metric_label(metric))})</h2>")
    budgets = sorted(summary.budget.unique())
    ok = summary.set_index(["scene", "method", "budget"]).get("determined", pd.Series(dtype=bool))
    ranked = T.ranked_cells(summary, metric)
    win = ['<table class="overview"><thead><tr><th>scene</th>']
    win += [f"<th>{e(T.budget_label(b))}</th>" for b in budgets]
    win.append("</tr></thead><tbody>")
    for s in scenes:
        win.append(f'<tr><th class="scene"><a href="scene-{e(s)}.html">{e(s)}</a></th>')
        for b in budgets:
            r = best[(best.scene == s) & (best.budget == b)]
            if r.empty and not refs.get(s, {}).get("trusted", True):
                win.append('<td class="note">no trustworthy reference</td>')
                continue
            if r.empty:
                ran = ((ranked.scene == s) & (ranked.budget == b)).any()
                # every cell with a value overran the budget: none is an equal-time result
                win.append('<td class="note">none within budget</td>' if ran else "<td></td>")
                continue
            m = r.method.iloc[0]
            flag = "" if ok.get((s, m, b), True) else ' <span class="flag">⚠</span>'
            seconds = float(r.render_seconds_mean.iloc[0])
            if T.off_budget(seconds, b):
                flag += T.off_budget_mark(seconds, b)
            by_reference = _names(r.reference_ties.iloc[0]) if "reference_ties" in r else []
            seeds = [x for x in _names(r.tied_with.iloc[0]) if x not in by_reference]
            tie = f' <span class="note">tied with {e(", ".join(seeds))}</span>' if seeds else ""
            if by_reference:  # the reference cannot rank them: no winner is named
                names = ", ".join([m, *by_reference])
                win.append(
                    f'<td><span class="undecided">undecided: {e(names)}</span> '
                    '<span class="note">(within the reference\'s uncertainty; lowest '
                    f"{T.fmt(r.iloc[0, 3])})</span>{tie}{flag}</td>"
                )
                continue
            win.append(f"<td>{e(m)} ({T.fmt(r.iloc[0, 3])}){tie}{flag}</td>")
        win.append("</tr>")
    win.append("</tbody></table>")
    body.append("".join(win))

    if "determined" in summary:
        flagged = int((~summary.determined.astype(bool)).sum())
        body.append(
            f'<p class="note">{len(summary) - flagged} of {len(summary)} cells determined '
            f'(<span class="flag">⚠</span> on the other {flagged}: '
            f"{e(T.flag_meaning(fraction))}). Winners are chosen on the errors with the "
            "reference's own removed; where the reference's uncertainty alone leaves methods "
            "unranked, the cell says <i>undecided</i> and names them.</p>"
        )
    body.append(f"<h2>Overview: {e(_metric_label(metric))}</h2>")
    body.append(_legend(metric, fraction, T.is_corrected(summary, metric)))
    body.append(T.overview_html(summary, metric, link_scenes=True, determined_fraction=fraction))
    for m in T.METRICS:
        if m != metric and f"{m}_mean" in summary:
            body.append(f"<details><summary>{e(_metric_label(m))}</summary>")
            body.append(
                '<p class="note">Bold: lowest mean of this metric (and ties). '
                + (
                    "With the reference's own error removed (ref. ±: its uncertainty; the "
                    "measured mean beside it). "
                    if T.is_corrected(summary, m)
                    else "As measured: this metric cannot be corrected for the reference's error. "
                )
                + '<span class="flag">⚠</span> is the flag of the table above, computed from '
                "relMSE in every table.</p>"
            )
            body.append(T.overview_html(summary, m, link_scenes=True, determined_fraction=fraction))
            body.append("</details>")

    # speed-up / time to error
    tte = tabs.get("time_to_error")
    if tte is not None and not tte.empty:
        col = f"speedup_vs_{baseline}"
        body.append(f"<h2>Time to reach the target error, and speed-up vs {e(baseline)}</h2>")
        body.append(
            f'<p class="note">Target per scene: {e(_metric_label(metric))} reached by '
            f"{e(baseline)} at its largest budget"
            + (
                ", all errors with the reference's own removed (⚠ where that cell is not "
                "determined: the target is then uncertain, and the times to reach it say little). "
                if T.is_corrected(summary, metric)
                else " (⚠ where that cell is flagged). "
            )
            + "Seconds of render time, interpolated log-log between budgets; "
            "* = extrapolated from the fitted slope (with three budgets or more spanning 4x; "
            "at most 4x outside the measured times; "
            "beyond that ≤ first budget or ≥ last budget, as measured). "
            "Speed-up = baseline time / method time. A method marked ≤ had beaten the target "
            "at its first snapshot already, and its true time may be far lower: such a bound "
            "does not rank against another method's time; compare their errors at the first "
            "budget in the overview instead.</p>"
        )
        rows = ['<table class="data"><thead><tr><th>scene</th>']
        rows += [f"<th>{e(m)}</th>" for m in methods]
        rows.append("</tr></thead><tbody>")
        last_budget = {
            s: d.budget.max() for s, d in summary[summary.method == baseline].groupby("scene")
        }
        for s in scenes:
            target_ok = bool(ok.get((s, baseline, last_budget.get(s)), True))
            flag = (
                ""
                if target_ok
                else ' <span class="flag" title="the target is a flagged cell: its corrected '
                'error is not determined">⚠</span>'
            )
            rows.append(f'<tr><th class="scene">{e(s)}{flag}</th>')
            for m in methods:
                r = tte[(tte.scene == s) & (tte.method == m)]
                if r.empty:
                    rows.append("<td></td>")
                    continue
                r0 = r.iloc[0]
                if not math.isfinite(float(r0.seconds)):  # e.g. SSIM is NaN on tiny films
                    rows.append('<td title="no finite error to reach the target with">–</td>')
                    continue
                star = "*" if bool(r0.extrapolated) else ""
                sp = r0.get(col, math.nan)
                bound = _BOUND_SIGN.get(str(r0.get("bound", "")), "")
                sp_bound = _BOUND_SIGN.get(str(r0.get("speedup_bound", "")), "")
                speedup = "?" if sp_bound == "?" else f"{sp_bound}×{T.fmt(sp, 2)}"
                rows.append(
                    f"<td>{bound}{T.fmt(r0.seconds)} s{star}<br><small>{speedup}</small></td>"
                )
            rows.append("</tr>")
        rows.append("</tbody></table>")
        body.append("".join(rows))

    conv = tabs.get("convergence")
    if conv is not None and not conv.empty:
        cm = conv[conv.metric == metric]
        body.append(f"<h2>Convergence slopes ({e(_metric_label(metric))} vs time, log-log)</h2>")
        columns = ["slope"]
        removable = metric in T.REFERENCE_ERROR or T.is_corrected(summary, metric)
        if removable and "slope_ref_removed" in cm:
            columns.insert(0, "slope_ref_removed")  # the corrected figure first
        body.append(_slopes_note(len(columns) > 1))
        for col in columns:
            c = cm.assign(cell=T.slope_cells(cm, col)).pivot(
                index="scene", columns="method", values="cell"
            )
            c = c.reindex(
                index=cm.scene.unique(), columns=[m for m in methods if m in c.columns]
            ).reset_index()
            if len(columns) > 1:
                label = "As measured" if col == "slope" else "Reference error removed"
                body.append(f"<h3>{label}</h3>")
            body.append(T.frame_html(c, 3))

    body.append("<h2>Convergence plots</h2>")
    body.append('<div class="plots">')
    for s in scenes:
        rs = runs[runs.scene == s]
        if rs.empty:
            continue
        svg = convergence_svg(rs, metric, s, colours, _ref_error_for(metric, refs.get(s, {})))
        body.append(f'<figure><a href="scene-{e(s)}.html">{svg}</a></figure>')
    body.append("</div>")

    body.append("<h2>Reference quality</h2>")
    rq = pd.DataFrame(
        [_reference_row(s, r, summary[summary.scene == s]) for s, r in refs.items()]
    ).set_index("scene")
    rq = rq.reindex([s for s in scenes if s in refs]).reset_index()  # the study's order
    body.append(
        '<p class="note">The reference is the average of two independent renders (halves); its '
        "relMSE is estimated as a quarter of the relMSE between the halves, and removed from "
        "every MSE-type error. A reference sized by the study aims at its target (a fraction "
        "of the best method's error at the largest budget, bounded from below from the "
        "study's own renders and a pilot) under a cap on its render time: <i>cap bound</i> "
        "says where the cap decided, so that the reference is coarser than its target. Each "
        "scene page says more. Cells determined: those whose corrected relMSE is known to "
        f"within ±{fraction:.0%}.</p>"
    )
    body.append(T.frame_html(rq, 3))

    _write(out / "index.html", _page(spec["title"], "\n".join(body)))
