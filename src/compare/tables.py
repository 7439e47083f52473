"""Aggregate per-run metrics into tables: CSV for machines, HTML and Markdown for people.

Tables (all written by :func:`write_tables` into one folder):

- ``runs.csv``           one row per scene x method x seed x budget: metrics, sidecar stats,
                         the reference's own error and the ``ref_ok`` quality flag
- ``summary.csv``        mean, std, min, max over seeds per scene x method x budget
- ``best.csv``           the best method per scene and budget, and the methods tied with it
- ``overview.{md,html}`` primary metric, scene x method rows, one column per budget,
                         mean +- std over seeds, best method per scene and budget marked,
                         cells whose reference is not good enough flagged
- ``convergence.csv``    fitted log-log slope of error vs render time per scene x method x metric,
                         and for MSE and relMSE the slope of the error minus the reference's own
                         error (``slope_ref_removed``, over points at >= 2x that error); for
                         each, the range of the slopes fitted to each seed alone
                         (``*_seed_min``, ``*_seed_max``)
- ``time_to_error.csv``  time each method needs to reach a target error, and its speed-up vs the
                         baseline method (target: the baseline's mean error at its largest
                         budget, else the median final error of all methods); extrapolations
                         further than 4x outside the measured times become bounds (``bound``
                         "<=" / ">=", and ``speedup_bound`` for the speed-up)
- ``stats.csv``          render statistics per run (iterations, rays, load time, memory, wall time)
- ``tables.md``          the convergence, time-to-error and stats tables in Markdown
"""

from __future__ import annotations

import html
import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from .convergence import (
    SlopeFit,
    bounded,
    fit_slope_above_floor,
    fit_slope_over_budgets,
    time_to_error,
)
from .metrics import METRICS

KEYS = ["scene", "method", "budget"]
# Metrics whose reference error is known, and its column in runs.csv (the reference's own
# error adds to theirs: compare.metrics.reference_error).
REFERENCE_ERROR: dict[str, str] = {"mse": "ref_mse", "relmse": "ref_relmse"}

METRIC_LABELS: dict[str, str] = {
    "mse": "MSE",
    "rmse": "RMSE",
    "relmse": "relMSE",
    "relmse_trimmed": "relMSE (trimmed 0.1%)",
    "mape": "MAPE",
    "smape": "SMAPE",
    "flip": "HDR-FLIP",
    "one_minus_ssim": "1 - SSIM",
}


def budget_label(b: float) -> str:
    return f"{b:g} s"


def load_runs(metric_csvs: Iterable[str | Path], benchmarks: dict | None = None) -> pd.DataFrame:
    """Concatenate per-run metric CSVs; join benchmark TSVs keyed by (scene, method, seed)."""
    frames = [pd.read_csv(p) for p in metric_csvs]
    if not frames:
        raise ValueError("no metrics to aggregate")
    df = pd.concat(frames, ignore_index=True)
    df["wall_seconds"] = math.nan
    df["max_rss_mb"] = math.nan
    for (scene, method, seed), tsv in (benchmarks or {}).items():
        try:
            b = pd.read_csv(tsv, sep="\t")
        except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError):
            continue
        if b.empty:
            continue
        sel = (df.scene == scene) & (df.method == method) & (df.seed == int(seed))
        df.loc[sel, "wall_seconds"] = pd.to_numeric(b["s"], errors="coerce").iloc[-1]
        if "max_rss" in b:
            df.loc[sel, "max_rss_mb"] = pd.to_numeric(b["max_rss"], errors="coerce").iloc[-1]
    df["ref_ok"] = df["ref_ok"].astype(bool)
    return df.sort_values(["scene", "method", "seed", "budget"]).reset_index(drop=True)


def listed_first(order: Sequence[str], names: Iterable[str]) -> list[str]:
    """``order`` (the config's), then any other of ``names`` alphabetically."""
    return list(order) + sorted(set(names) - set(order))


def study_order(
    df: pd.DataFrame, scenes: Sequence[str] = (), methods: Sequence[str] | None = ()
) -> pd.DataFrame:
    """df with its rows in the study's order: scenes, then methods, as the config lists them
    (any not listed after those, alphabetically), other columns' order kept. Every table and
    every section of the report then lists methods in one order. ``methods=None``: scenes,
    then budgets (a table with one method per scene and budget). Rows are taken by position,
    whatever df's index."""
    if df.empty or "scene" not in df or ("method" not in df and methods is not None):
        return df

    def rank(column: pd.Series, order: Sequence[str]) -> np.ndarray:
        position = {name: i for i, name in enumerate(listed_first(order, column))}
        return column.map(position).to_numpy()

    second = df["budget"].to_numpy() if methods is None else rank(df["method"], methods)
    rows = np.lexsort((second, rank(df["scene"], scenes)))  # stable: last key sorts first
    return df.iloc[rows].reset_index(drop=True)


def summarize(runs: pd.DataFrame) -> pd.DataFrame:
    """Mean/std/min/max over seeds of every metric (flat columns ``<metric>_<stat>``)."""
    metrics = [m for m in METRICS if m in runs]
    g = runs.groupby(KEYS, sort=True)
    agg = g[metrics + ["render_seconds"]].agg(["mean", "std", "min", "max"])
    agg.columns = [f"{a}_{b}" for a, b in agg.columns]
    agg["n_seeds"] = g["seed"].nunique()
    agg["ref_relmse"] = g["ref_relmse"].first()
    agg["ref_ok"] = g["ref_ok"].all()
    return agg.reset_index()


def render_time(d: pd.DataFrame, column: str = "render_seconds") -> pd.Series:
    """Measured render seconds, or the budget where a run did not record them."""
    return d[column].where(d[column] > 0, d["budget"])


def one_row_per_image(d: pd.DataFrame) -> pd.DataFrame:
    """The runs of one scene and method with one row per image. A method whose iteration
    outlasts the gap between budgets hands several budgets the same snapshot (same seed, same
    iteration count): one measurement, which a fit must count once (Mitsuba at 3 s per
    iteration gave its 0.5, 1 and 2 s budgets one image, and three budgets "spanning 4x" a
    slope of seed noise). Of each such group the row kept is the budget nearest the image's
    render time."""
    key = next((k for k in ("iterations", "render_seconds") if k in d and d[k].notna().all()), None)
    if key is None or "seed" not in d:
        return d
    distance = np.abs(np.log(render_time(d) / d["budget"]))
    nearest_first = d.loc[distance.sort_values(kind="stable").index]
    return nearest_first.drop_duplicates(subset=["seed", key]).sort_index()


# A snapshot is the image at the iteration end nearest its budget: a method whose iterations
# are long misses the budget by up to half an iteration either way. Beyond this fraction of
# its budget a cell is marked as not equal-time.
OFF_BUDGET = 0.1


def off_budget(render_seconds: float, budget: float) -> bool:
    """True if a cell's mean render time is more than OFF_BUDGET of its budget away from it."""
    return bool(abs(render_seconds - budget) > OFF_BUDGET * budget)


def over_budget(render_seconds: float, budget: float) -> bool:
    """True if a cell took more than OFF_BUDGET longer than its budget: it had more time than
    the cells it would be ranked against."""
    return off_budget(render_seconds, budget) and render_seconds > budget


# Two cells are a tie when Welch's t-test at this two-sided level cannot tell their errors
# apart. Errors are compared as logarithms (their ratio is what matters, and methods whose
# errors differ 40x must not tie because one of them varies between seeds); the spreads come
# from a few seeds, so the critical value is Student's (4.3 for two seeds a side with equal
# spreads, up to 12.7 when one spread dominates), not the normal 1.96.
TIE_LEVEL = 0.05


def tied(a_mean: float, a_std: float, a_n: int, b_mean: float, b_std: float, b_n: int) -> bool:
    """Whether Welch's t-test on log errors (Welch-Satterthwaite degrees of freedom; the
    spread of a log as std / mean) cannot reject equal errors at TIE_LEVEL. Never with fewer
    than two seeds on either side (no spread is known) or a non-positive mean."""
    if min(a_n, b_n) < 2 or not (math.isfinite(a_std) and math.isfinite(b_std)):
        return False
    if not (a_mean > 0 and b_mean > 0):
        return a_mean == b_mean
    va, vb = (a_std / a_mean) ** 2 / a_n, (b_std / b_mean) ** 2 / b_n
    if va + vb == 0:
        return a_mean == b_mean
    dof = (va + vb) ** 2 / (va**2 / (a_n - 1) + vb**2 / (b_n - 1))
    critical = float(stats.t.ppf(1 - TIE_LEVEL / 2, dof))
    return abs(math.log(a_mean / b_mean)) < critical * math.sqrt(va + vb)


def ranked_cells(summary: pd.DataFrame, metric: str) -> pd.DataFrame:
    """The cells that have a mean ``metric``: the ones a budget's winner is chosen among."""
    return summary.dropna(subset=[f"{metric}_mean"])


def best_methods(summary: pd.DataFrame, metric: str) -> pd.DataFrame:
    """The method with the lowest mean ``metric`` per scene and budget, and in ``tied_with``
    the other methods (comma-separated) that seeds cannot tell from it. A cell that overran
    its budget (over_budget) neither wins nor ties: it is not an equal-time result. One that
    stopped short of it may, having had less time; a budget whose cells all overran has no
    winner."""
    col, std = f"{metric}_mean", f"{metric}_std"
    valid = ranked_cells(summary, metric)
    if "render_seconds_mean" in valid:
        in_time = [
            not over_budget(t, b)
            for t, b in zip(valid.render_seconds_mean, valid.budget, strict=True)
        ]
        valid = valid[in_time]
    idx = valid.groupby(["scene", "budget"])[col].idxmin()
    cols = ["scene", "budget", "method", col, "render_seconds_mean"]
    best = valid.loc[idx, [c for c in cols if c in valid]].reset_index(drop=True)
    ties = []
    for i in idx:
        b = valid.loc[i]
        rivals = valid[
            (valid.scene == b.scene) & (valid.budget == b.budget) & (valid.method != b.method)
        ]
        ties.append(
            ",".join(
                str(r["method"])
                for _, r in rivals.iterrows()
                if std in valid and tied(b[col], b[std], b["n_seeds"], r[col], r[std], r["n_seeds"])
            )
        )
    best["tied_with"] = ties
    return best


def _slope_fits(
    t: pd.Series, d: pd.DataFrame, metric: str, floor: float | None
) -> tuple[SlopeFit, float, float]:
    """(fit over all of d's runs, min and max of the slopes over each seed's runs alone);
    with a floor, of the error less the floor (fit_slope_above_floor). The range is NaN
    unless two seeds or more give a slope."""
    times, errors, budgets = t.to_numpy(), d[metric].to_numpy(), d["budget"].to_numpy()

    def fit(rows: np.ndarray) -> SlopeFit:  # rows by position
        if floor is None:
            return fit_slope_over_budgets(times[rows], errors[rows], budgets[rows])
        return fit_slope_above_floor(times[rows], errors[rows], floor, budgets=budgets[rows])

    seeds = d.groupby("seed").indices.values() if "seed" in d else []
    per_seed = [f.slope for f in map(fit, seeds) if math.isfinite(f.slope)]
    lo, hi = (min(per_seed), max(per_seed)) if len(per_seed) >= 2 else (math.nan, math.nan)
    return fit(np.arange(len(d))), lo, hi


def convergence_table(runs: pd.DataFrame, metrics: Sequence[str] = METRICS) -> pd.DataFrame:
    """One row per scene x method x metric: the slope fitted over all runs, and the range of
    the slopes fitted to each seed's runs alone. The seeds' curves are independent, so their
    spread shows how much a slope is worth; the points of one curve are not (each snapshot
    continues the run before it), so a regression's own standard error would understate it."""
    rows = []
    for (scene, method), d in runs.groupby(["scene", "method"], sort=True):
        d = one_row_per_image(d)
        t = render_time(d)
        for m in metrics:
            if m not in d:
                continue
            f, lo, hi = _slope_fits(t, d, m, None)
            floor = REFERENCE_ERROR.get(m)
            g, g_lo, g_hi = (
                _slope_fits(t, d, m, float(d[floor].median()))
                if floor in d
                else (None, np.nan, np.nan)
            )
            rows.append(
                {
                    "scene": scene,
                    "method": method,
                    "metric": m,
                    "slope": f.slope,
                    "slope_seed_min": lo,
                    "slope_seed_max": hi,
                    "intercept_log10": f.intercept,
                    "r2": f.r2,
                    "points": f.n,
                    # The same fit on error minus the reference's own error (see convergence.py).
                    "slope_ref_removed": g.slope if g else np.nan,
                    "slope_ref_removed_seed_min": g_lo,
                    "slope_ref_removed_seed_max": g_hi,
                    "points_ref_removed": g.n if g else 0,
                }
            )
    return pd.DataFrame(rows)


def time_to_error_table(summary: pd.DataFrame, metric: str, baseline: str) -> pd.DataFrame:
    col = f"{metric}_mean"
    rows = []
    for scene, d in summary.groupby("scene", sort=True):
        base = d[d.method == baseline]
        if not base.empty and np.isfinite(base[col]).any():
            last = base.dropna(subset=[col]).sort_values("budget").iloc[-1]
            target = float(last[col])
            target_from = f"{baseline} at {last.budget:g} s"
            seconds = float(last.get("render_seconds_mean", math.nan))
            if math.isfinite(seconds) and off_budget(seconds, float(last.budget)):
                target_from += f" (its image at {seconds:.3g} s)"
        else:
            finals = d.sort_values("budget").groupby("method")[col].last()
            target = float(finals.median())
            target_from = "median final error"
        times: dict[str, tuple[float, bool, str]] = {}
        for method, dm in d.groupby("method", sort=True):
            t_col = render_time(dm, "render_seconds_mean")
            t, e = t_col.to_numpy(), dm[col].to_numpy()
            estimate = time_to_error(t, e, target, budgets=dm.budget.to_numpy())
            times[method] = bounded(estimate, t, e, target)
        t_base, _, base_bound = times.get(baseline, (math.nan, True, ""))
        for method, (t, extrap, bound) in times.items():
            rows.append(
                {
                    "scene": scene,
                    "method": method,
                    "metric": metric,
                    "target": target,
                    "target_from": target_from,
                    "seconds": t,
                    "extrapolated": extrap,
                    "bound": bound,
                    f"speedup_vs_{baseline}": t_base / t if t > 0 else math.nan,
                    # The baseline against itself is 1 exactly, whatever bounds its time.
                    "speedup_bound": ""
                    if method == baseline
                    else _speedup_bound(base_bound, bound),
                }
            )
    return pd.DataFrame(rows)


def _speedup_bound(base: str, method: str) -> str:
    """Direction of the speed-up t_base / t_method when either time is only a bound."""
    lower = {"<=": ">=", ">=": "<=", "": ""}[method]  # speed-up bound from the method's time
    upper = {"<=": "<=", ">=": ">=", "": ""}[base]  # and from the baseline's
    if lower and upper and lower != upper:
        return "?"
    return lower or upper


def stats_table(runs: pd.DataFrame) -> pd.DataFrame:
    """Render statistics of each run at its largest budget."""
    last = runs.sort_values("budget").groupby(["scene", "method", "seed"], sort=True).tail(1)
    cols = [
        "scene",
        "method",
        "seed",
        "budget",
        "render_seconds",
        "load_seconds",
        "iterations",
        "spp",
        "rays",
        "nonfinite",
        "threads",
        "wall_seconds",
        "max_rss_mb",
    ]
    out = last[[c for c in cols if c in last]].copy()
    if "rays" in out:
        out["mrays_per_s"] = out["rays"] / out["render_seconds"] / 1e6
    return out.sort_values(["scene", "method", "seed"]).reset_index(drop=True)


# --- formatting ---------------------------------------------------------------------------


def fmt(x: float, digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    x = float(x)
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e4:
        return f"{x:.{digits}g}"
    return f"{x:.{max(digits - 1, 1)}e}"


def fmt_pm(mean: float, std: float) -> str:
    if std is None or not math.isfinite(float(std)):
        return fmt(mean)
    return f"{fmt(mean)} ± {fmt(std, 2)}"


class Html(str):
    """Text that is already HTML: frame_html puts it in a cell as it is."""


def fmt_slope(slope: float, lo: float, hi: float, html: bool = False) -> str:
    """A fitted slope and, when known, the range of the per-seed slopes:
    "-0.98 (seeds -1.02 to -0.95)"; with ``html``, the range on a line of its own in small
    print. Not an interval around the slope: fitted over all runs, it may lie outside the
    seeds' range when their render times differ."""
    if not math.isfinite(float(slope)):
        return "–"
    if not (math.isfinite(float(lo)) and math.isfinite(float(hi))):
        return f"{slope:.2f}"
    seeds = f"(seeds {lo:.2f} to {hi:.2f})"
    return Html(f"{slope:.2f}<br><small>{seeds}</small>") if html else f"{slope:.2f} {seeds}"


def slope_cells(conv: pd.DataFrame, column: str = "slope") -> pd.Series:
    """fmt_slope (HTML) of each row of a convergence table, for ``slope`` or
    ``slope_ref_removed``."""
    return pd.Series(
        [
            # tables written before the seed ranges existed have no such columns
            fmt_slope(
                r[column],
                r.get(f"{column}_seed_min", math.nan),
                r.get(f"{column}_seed_max", math.nan),
                html=True,
            )
            for _, r in conv.iterrows()
        ],
        index=conv.index,
        dtype=object,
    )


def overview_cells(summary: pd.DataFrame, metric: str) -> list[dict]:
    """One dict per scene x method: cells per budget with text, best and flag marks."""
    best = best_methods(summary, metric)
    best_set = {(r.scene, r.budget, r.method) for r in best.itertuples()}
    best_set |= {
        (r.scene, r.budget, m) for r in best.itertuples() for m in r.tied_with.split(",") if m
    }
    out = []
    # In the summary's own order (study_order), not alphabetically.
    for (scene, method), d in summary.groupby(["scene", "method"], sort=False):
        cells = {}
        for r in d.itertuples():
            cells[r.budget] = {
                "text": fmt_pm(getattr(r, f"{metric}_mean"), getattr(r, f"{metric}_std")),
                "mean": getattr(r, f"{metric}_mean"),
                "best": (scene, r.budget, method) in best_set,
                "ref_ok": bool(r.ref_ok),
                "seconds": r.render_seconds_mean,
                "off_budget": off_budget(r.render_seconds_mean, r.budget),
            }
        out.append({"scene": scene, "method": method, "cells": cells})
    return out


def off_budget_mark(seconds: float, budget: float, averaged: bool = True) -> str:
    """HTML mark of a cell whose snapshot came well before or after its budget (``averaged``:
    the mean time of the cell's seeds; else one image's own)."""
    when = "on average" if averaged else "for this image"
    return (
        f' <span class="offbudget" title="snapshot at {fmt(seconds)} s {when}, budget '
        f'{fmt(budget)} s: not equal time">at {fmt(seconds)} s</span>'
    )


def overview_markdown(summary: pd.DataFrame, metric: str) -> str:
    budgets = sorted(summary.budget.unique())
    head = ["scene", "method", *[budget_label(b) for b in budgets]]
    lines = [
        f"{METRIC_LABELS.get(metric, metric)}, mean ± std over seeds; **bold** = best per "
        f"scene and budget, and any method Welch's t-test on log errors at {TIE_LEVEL:g} "
        "cannot tell from it with these seeds (a tie); ⚠ = reference error not well below "
        "this error; "
        f"(at … s) = the snapshot's mean render time, more than {OFF_BUDGET:.0%} off its "
        "budget (over it, the cell is never bold)",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "|".join(["---"] * len(head)) + "|",
    ]
    for row in overview_cells(summary, metric):
        cells = []
        for b in budgets:
            c = row["cells"].get(b)
            if c is None:
                cells.append("")
                continue
            t = f"**{c['text']}**" if c["best"] else c["text"]
            t = t if c["ref_ok"] else t + " ⚠"
            cells.append(t + f" (at {fmt(c['seconds'])} s)" if c["off_budget"] else t)
        lines.append("| " + " | ".join([row["scene"], row["method"], *cells]) + " |")
    return "\n".join(lines) + "\n"


def overview_html(summary: pd.DataFrame, metric: str, link_scenes: bool = False) -> str:
    """An HTML <table> (no page around it); classes ``best`` and ``refbad`` mark cells."""
    budgets = sorted(summary.budget.unique())
    e = html.escape
    parts = [
        '<table class="overview"><thead><tr><th>scene</th><th>method</th>',
        *[f"<th>{e(budget_label(b))}</th>" for b in budgets],
        "</tr></thead><tbody>",
    ]
    rows = overview_cells(summary, metric)
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["scene"]] = counts.get(r["scene"], 0) + 1
    seen: set[str] = set()
    for r in rows:
        parts.append("<tr>")
        if r["scene"] not in seen:
            seen.add(r["scene"])
            name = e(r["scene"])
            label = f'<a href="scene-{name}.html">{name}</a>' if link_scenes else name
            parts.append(f'<th class="scene" rowspan="{counts[r["scene"]]}">{label}</th>')
        parts.append(f'<th class="method">{e(r["method"])}</th>')
        for b in budgets:
            c = r["cells"].get(b)
            if c is None:
                parts.append("<td></td>")
                continue
            cls = []
            title = ""
            if c["best"]:
                cls.append("best")
            if not c["ref_ok"]:
                cls.append("refbad")
                title = ' title="reference error is not well below this error"'
            mark = ' <span class="flag">⚠</span>' if not c["ref_ok"] else ""
            if c["off_budget"]:
                mark += off_budget_mark(c["seconds"], b)
            parts.append(f'<td class="{" ".join(cls)}"{title}>{e(c["text"])}{mark}</td>')
        parts.append("</tr>")
    parts.append("</tbody></table>")
    return "".join(parts)


def frame_html(df: pd.DataFrame, float_digits: int = 3) -> str:
    """A plain HTML table of a DataFrame with compact number formatting."""
    e = html.escape
    parts = ['<table class="data"><thead><tr>']
    parts += [f"<th>{e(str(c))}</th>" for c in df.columns]
    parts.append("</tr></thead><tbody>")
    for row in df.itertuples(index=False):
        parts.append("<tr>")
        for v in row:
            if isinstance(v, bool | np.bool_):
                s = "yes" if v else "no"
            elif isinstance(v, float | np.floating):
                s = fmt(float(v), float_digits)
            else:
                s = str(v)
            parts.append(f"<td>{v if isinstance(v, Html) else e(s)}</td>")
        parts.append("</tr>")
    parts.append("</tbody></table>")
    return "".join(parts)


def frame_markdown(df: pd.DataFrame) -> str:
    head = [str(c) for c in df.columns]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|"]
    for row in df.itertuples(index=False):
        vals = [fmt(float(v)) if isinstance(v, float | np.floating) else str(v) for v in row]
        lines.append("| " + " | ".join(vals) + " |")
    return "\n".join(lines) + "\n"


def write_tables(
    runs: pd.DataFrame,
    out_dir: str | Path,
    *,
    metric: str = "relmse",
    baseline: str = "pt",
    scenes: Sequence[str] = (),
    methods: Sequence[str] = (),
) -> dict[str, pd.DataFrame]:
    """Write every table into ``out_dir``, rows in the order of ``scenes`` and ``methods``
    (study_order); return them by name."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    runs = study_order(runs, scenes, methods)
    summary = study_order(summarize(runs), scenes, methods)
    # The tables derived from these group alphabetically: each is put in the study's order.
    tables = {
        "runs": runs,
        "summary": summary,
        "best": study_order(best_methods(summary, metric), scenes, None),
        "convergence": study_order(convergence_table(runs), scenes, methods),
        "time_to_error": study_order(
            time_to_error_table(summary, metric, baseline), scenes, methods
        ),
        "stats": study_order(stats_table(runs), scenes, methods),
    }
    for name, df in tables.items():
        df.to_csv(out / f"{name}.csv", index=False)
    (out / "overview.md").write_text(overview_markdown(summary, metric))
    style = (
        "<style>body{font-family:sans-serif}td,th{padding:2px 8px;border-bottom:1px solid #ddd}"
        ".best{font-weight:bold;background:#d8f5d0}.refbad{color:#a60}</style>"
    )
    (out / "overview.html").write_text(
        f"<!doctype html><meta charset=utf-8><title>overview</title>{style}"
        f"<p>{html.escape(METRIC_LABELS.get(metric, metric))}, mean ± std over seeds</p>"
        + overview_html(summary, metric)
        + "\n"
    )
    md = ["# Tables", ""]
    for name in ("convergence", "time_to_error", "stats"):
        df = tables[name]
        if name == "convergence":
            df = df[df.metric == metric]
        md += [f"## {name}", "", frame_markdown(df), ""]
    (out / "tables.md").write_text("\n".join(md))
    return tables
