"""Aggregate per-run metrics into tables: CSV for machines, HTML and Markdown for people.

Tables (all written by :func:`write_tables` into one folder):

- ``runs.csv``           one row per scene x method x seed x budget: metrics as measured,
                         sidecar stats, the reference's own error, what rendered it
                         (``reference``: Mitsuba, or pgi's pt where Mitsuba's failed its
                         check) and whether it passed (``reference_trusted``); for the MSE-type
                         metrics the error with the reference's own removed
                         (``<metric>_corrected``) and its uncertainties (``<metric>_u``, of
                         which ``<metric>_u_shared`` is shared by every image of the scene)
- ``summary.csv``        mean, std, min, max over seeds per scene x method x budget, measured
                         and corrected; the reference's uncertainty of each corrected mean
                         (``<metric>_u``) and whether that mean is determined (``determined``)
- ``best.csv``           the best method per scene and budget by corrected error, the methods
                         tied with it, those of them tied only by the reference's
                         uncertainty (``reference_ties``), and the reference's source; none
                         for a scene whose reference failed its check (compare.trust)
- ``overview.{md,html}`` primary metric, scene x method rows, one column per budget,
                         mean +- std over seeds (corrected, the measured value beside it),
                         best method per scene and budget marked, cells whose corrected
                         error is not determined flagged
- ``convergence.csv``    fitted log-log slope of error vs render time per scene x method x metric,
                         and for the MSE-type metrics the slope of the corrected error
                         (``slope_ref_removed``, over points at >= 4x its uncertainty); for
                         each, the range of the slopes fitted to each seed alone
                         (``*_seed_min``, ``*_seed_max``)
- ``time_to_error.csv``  time each method needs to reach a target error (corrected errors where
                         the runs have them), and its speed-up vs the
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
    fit_slope_of_corrected,
    fit_slope_over_budgets,
    time_to_error,
)
from .metrics import (
    CORRECTABLE,
    COVERAGE,
    DETERMINED_FRACTION,
    METRICS,
    determined,
)

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


def is_corrected(frame: pd.DataFrame, metric: str) -> bool:
    """Whether a runs or summary table has ``metric`` with the reference's error removed
    (tables made from runs that carry no such column are read as measured)."""
    return f"{metric}_corrected" in frame or f"{metric}_corrected_mean" in frame


def value_column(frame: pd.DataFrame, metric: str) -> str:
    """The column of a runs table that verdicts, fits and plots use for ``metric``."""
    return f"{metric}_corrected" if f"{metric}_corrected" in frame else metric


# The metric whose determination flags a cell in every table (the one relMSE's eps and the
# reference's sizing are about).
FLAG_METRIC = "relmse"


def summarize(runs: pd.DataFrame, determined_fraction: float = DETERMINED_FRACTION) -> pd.DataFrame:
    """Mean/std/min/max over seeds of every metric (flat columns ``<metric>_<stat>``), measured
    and, where the runs have them, corrected (``<metric>_corrected_<stat>``). For those, the
    reference's standard uncertainty of the cell's corrected mean (``<metric>_u``; its part
    shared by every cell of the scene, ``<metric>_u_shared``; each image's own part is averaged
    over the seeds as if they were fully correlated, an upper bound) and whether that mean is
    determined to within ``determined_fraction`` (``<metric>_determined``; ``determined`` is
    FLAG_METRIC's)."""
    metrics = [m for m in METRICS if m in runs]
    corrected = [f"{m}_corrected" for m in CORRECTABLE if f"{m}_corrected" in runs]
    g = runs.groupby(KEYS, sort=True)
    agg = g[metrics + corrected + ["render_seconds"]].agg(["mean", "std", "min", "max"])
    agg.columns = [f"{a}_{b}" for a, b in agg.columns]
    agg["n_seeds"] = g["seed"].nunique()
    agg["ref_relmse"] = g["ref_relmse"].first()
    for column in ("reference", "reference_trusted"):  # what rendered the reference, and
        if column in runs:  # whether verdicts may be drawn against it (compare.trust)
            agg[column] = g[column].first()
    for m in (c[: -len("_corrected")] for c in corrected):
        total, shared = runs[f"{m}_u"], runs[f"{m}_u_shared"]
        own = np.sqrt(np.maximum(total**2 - shared**2, 0.0)).groupby([runs[k] for k in KEYS])
        agg[f"{m}_u_shared"] = shared.groupby([runs[k] for k in KEYS]).mean()
        agg[f"{m}_u"] = np.hypot(own.mean(), agg[f"{m}_u_shared"])
        agg[f"{m}_determined"] = [
            determined(v, u, determined_fraction)
            for v, u in zip(agg[f"{m}_corrected_mean"], agg[f"{m}_u"], strict=True)
        ]
    if f"{FLAG_METRIC}_determined" in agg:
        agg["determined"] = agg[f"{FLAG_METRIC}_determined"]
    return agg.reset_index()


def error_columns(summary: pd.DataFrame, metric: str) -> tuple[str, str, str | None, str | None]:
    """The summary's columns for ``metric``'s verdicts: mean, std over seeds, and the
    reference's uncertainty of the mean with its shared part (None for a measured metric)."""
    if f"{metric}_corrected_mean" in summary:
        c = f"{metric}_corrected"
        return f"{c}_mean", f"{c}_std", f"{metric}_u", f"{metric}_u_shared"
    return f"{metric}_mean", f"{metric}_std", None, None


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
# spreads, up to 12.7 when one spread dominates), not the normal 1.96. The reference's
# uncertainty of corrected errors adds to the seeds' spreads, as a term known exactly.
TIE_LEVEL = 0.05


def tied(
    a_mean: float,
    a_std: float,
    a_n: int,
    b_mean: float,
    b_std: float,
    b_n: int,
    a_u: float = 0.0,
    b_u: float = 0.0,
    shared_u: float = 0.0,
) -> bool:
    """Whether Welch's t-test (Welch-Satterthwaite degrees of freedom) cannot reject equal
    errors at TIE_LEVEL. Means over seeds with seed spreads ``*_std`` (unknown with fewer
    than two seeds) and, for corrected errors, the reference's uncertainty of each mean: the
    part of each its own (``a_u``, ``b_u``) and the part shared by both (``shared_u``, which
    moves both alike). On logarithms (the spread of a log as std / mean) when both means are
    positive; else on the difference, where the shared part cancels. With no spread and no
    uncertainty, only equal errors tie."""
    seeds_known = min(a_n, b_n) >= 2 and math.isfinite(a_std) and math.isfinite(b_std)
    logs = a_mean > 0 and b_mean > 0
    if logs:
        distance = abs(math.log(a_mean / b_mean))
        va, vb = (a_std / a_mean) ** 2 / a_n, (b_std / b_mean) ** 2 / b_n
        known = (a_u / a_mean) ** 2 + (b_u / b_mean) ** 2
        known += (shared_u * (1 / a_mean - 1 / b_mean)) ** 2
    else:
        distance = abs(a_mean - b_mean)
        va, vb = a_std**2 / a_n, b_std**2 / b_n
        known = a_u**2 + b_u**2
    if not seeds_known:
        va = vb = 0.0
    if not math.isfinite(distance) or va + vb + known == 0:
        return a_mean == b_mean
    if va + vb > 0:  # the reference's term is known exactly: infinite degrees of freedom
        dof = (va + vb + known) ** 2 / (va**2 / (a_n - 1) + vb**2 / (b_n - 1))
        critical = float(stats.t.ppf(1 - TIE_LEVEL / 2, dof))
    else:
        critical = float(stats.norm.ppf(1 - TIE_LEVEL / 2))
    return distance < critical * math.sqrt(va + vb + known)


def ranked_cells(summary: pd.DataFrame, metric: str) -> pd.DataFrame:
    """The cells that have a mean ``metric`` (measured, and corrected where the summary has
    it): the ones a budget's winner is chosen among."""
    columns = {error_columns(summary, metric)[0], f"{metric}_mean"}
    return summary.dropna(subset=[c for c in columns if c in summary])


def _less(spread: float, part: float) -> float:
    """A standard deviation without an independent part of it (never below zero)."""
    return math.sqrt(max(spread**2 - part**2, 0.0)) if math.isfinite(spread) else spread


def best_methods(summary: pd.DataFrame, metric: str) -> pd.DataFrame:
    """The method with the lowest mean ``metric`` (corrected where the summary has it) per
    scene and budget; in ``tied_with`` the other methods (comma-separated) that seeds and the
    reference's uncertainty cannot tell from it, and in ``reference_ties`` those of them that
    the seeds alone would have told apart (the seeds' spread less the part the reference's
    noise adds to it). A cell that overran its budget (over_budget)
    neither wins nor ties: it is not an equal-time result. One that stopped short of it may,
    having had less time; a budget whose cells all overran has no winner."""
    col, std, u, shared = error_columns(summary, metric)
    valid = ranked_cells(summary, metric)
    if "reference_trusted" in valid:  # no verdict against a reference that failed its check
        valid = valid[valid.reference_trusted.astype(bool)]
    if "render_seconds_mean" in valid:
        in_time = [
            not over_budget(t, b)
            for t, b in zip(valid.render_seconds_mean, valid.budget, strict=True)
        ]
        valid = valid[np.array(in_time, dtype=bool)]  # (an empty list would pick columns)
    idx = valid.groupby(["scene", "budget"])[col].idxmin()
    cols = ["scene", "budget", "method", col, "render_seconds_mean", "reference"]
    best = valid.loc[idx, [c for c in cols if c in valid]].reset_index(drop=True)

    def uncertainty(row: pd.Series) -> tuple[float, float]:
        """(own, shared) reference uncertainty of a cell's mean; zero for a measured metric."""
        if u is None:
            return 0.0, 0.0
        total, common = float(row[u]), float(row[shared])
        return math.sqrt(max(total**2 - common**2, 0.0)), common

    ties, by_reference = [], []
    for i in idx:
        b = valid.loc[i]
        b_own, common = uncertainty(b)
        rivals = valid[
            (valid.scene == b.scene) & (valid.budget == b.budget) & (valid.method != b.method)
        ]
        tie, reference = [], []
        for _, r in rivals.iterrows():
            if std not in valid:
                continue
            r_own, _ = uncertainty(r)
            seeds = (b[col], b[std], b["n_seeds"], r[col], r[std], r["n_seeds"])
            if tied(*seeds, b_own, r_own, common):
                tie.append(str(r["method"]))
                # The reference's noise also spreads each seed's corrected error (its own
                # part): what the seeds would show without it is the rest of their spread.
                alone = (b[col], _less(b[std], b_own), b["n_seeds"])
                alone += (r[col], _less(r[std], r_own), r["n_seeds"])
                if not tied(*alone):
                    reference.append(str(r["method"]))
        ties.append(",".join(tie))
        by_reference.append(",".join(reference))
    best["tied_with"] = ties
    best["reference_ties"] = by_reference
    return best


def _slope_fits(
    t: pd.Series, d: pd.DataFrame, metric: str, ref_removed: bool
) -> tuple[SlopeFit, float, float]:
    """(fit over all of d's runs, min and max of the slopes over each seed's runs alone), of
    the errors as measured or, with ``ref_removed``, with the reference's error removed: the
    runs' corrected errors where they have them (fit_slope_of_corrected), else the measured
    ones less the median reference error (fit_slope_above_floor). The range is NaN unless two
    seeds or more give a slope; the fit is NaN when the reference's error is unknown."""
    times, budgets = t.to_numpy(), d["budget"].to_numpy()
    errors = d[metric].to_numpy()
    floor_column = REFERENCE_ERROR.get(metric)

    def fit(rows: np.ndarray) -> SlopeFit:  # rows by position
        if not ref_removed:
            return fit_slope_over_budgets(times[rows], errors[rows], budgets[rows])
        if f"{metric}_corrected" in d:
            corrected, u = d[f"{metric}_corrected"].to_numpy(), d[f"{metric}_u"].to_numpy()
            return fit_slope_of_corrected(times[rows], corrected[rows], u[rows], budgets[rows])
        if floor_column in d:
            floor = float(d[floor_column].median())
            return fit_slope_above_floor(times[rows], errors[rows], floor, budgets=budgets[rows])
        return SlopeFit(math.nan, math.nan, math.nan, 0)

    seeds = d.groupby("seed").indices.values() if "seed" in d else []
    per_seed = [f.slope for f in map(fit, seeds) if math.isfinite(f.slope)]
    lo, hi = (min(per_seed), max(per_seed)) if len(per_seed) >= 2 else (math.nan, math.nan)
    return fit(np.arange(len(d))), lo, hi


def convergence_table(runs: pd.DataFrame, metrics: Sequence[str] = METRICS) -> pd.DataFrame:
    """One row per scene x method x metric: the slope fitted over all runs, and the range of
    the slopes fitted to each seed's runs alone, as measured and (MSE-type metrics) with the
    reference's error removed. The seeds' curves are independent, so their spread shows how
    much a slope is worth; the points of one curve are not (each snapshot continues the run
    before it), so a regression's own standard error would understate it."""
    rows = []
    for (scene, method), d in runs.groupby(["scene", "method"], sort=True):
        d = one_row_per_image(d)
        t = render_time(d)
        for m in metrics:
            if m not in d:
                continue
            f, lo, hi = _slope_fits(t, d, m, False)
            removable = m in REFERENCE_ERROR or f"{m}_corrected" in d
            g, g_lo, g_hi = _slope_fits(t, d, m, True) if removable else (None, np.nan, np.nan)
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
                    # The same fit on the errors with the reference's own error removed.
                    "slope_ref_removed": g.slope if g else np.nan,
                    "slope_ref_removed_seed_min": g_lo,
                    "slope_ref_removed_seed_max": g_hi,
                    "points_ref_removed": g.n if g else 0,
                }
            )
    return pd.DataFrame(rows)


def time_to_error_table(summary: pd.DataFrame, metric: str, baseline: str) -> pd.DataFrame:
    """Time each method's mean error curve (corrected where the summary has it) needs to
    reach the baseline's error at its largest budget, and the speed-up against it."""
    col = error_columns(summary, metric)[0]
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
                    "error": "corrected" if is_corrected(summary, metric) else "measured",
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
    """One dict per scene x method: cells per budget with text (corrected mean +- std where
    the summary has it), ``detail`` (the reference's uncertainty of that mean and the
    measured mean beside it), best and flag marks."""
    best = best_methods(summary, metric)
    best_set = {(r.scene, r.budget, r.method) for r in best.itertuples()}
    best_set |= {
        (r.scene, r.budget, m) for r in best.itertuples() for m in r.tied_with.split(",") if m
    }
    col, std, u, _ = error_columns(summary, metric)
    out = []
    # In the summary's own order (study_order), not alphabetically.
    for (scene, method), d in summary.groupby(["scene", "method"], sort=False):
        cells = {}
        for _, r in d.iterrows():
            detail = ""
            if u is not None:
                detail = f"ref. ±{fmt(r[u], 2)} · measured {fmt(r[f'{metric}_mean'])}"
            cells[r.budget] = {
                "text": fmt_pm(r[col], r[std] if std in r else math.nan),
                "detail": detail,
                "mean": r[col],
                "best": (scene, r.budget, method) in best_set,
                "determined": bool(r.get("determined", True)),
                "seconds": r.render_seconds_mean,
                "off_budget": off_budget(r.render_seconds_mean, r.budget),
            }
        out.append({"scene": scene, "method": method, "cells": cells, "note": reference_note(d)})
    return out


def reference_note(cells: pd.DataFrame) -> str:
    """What a scene's rows say of its reference: nothing for a Mitsuba reference that passed
    its check; "reference: pgi's pt" for one rendered by pgi; "no trustworthy reference" for
    a Mitsuba reference that failed it (ranked against nothing)."""
    if "reference_trusted" in cells and not cells.reference_trusted.astype(bool).all():
        return "no trustworthy reference"
    if "reference" in cells:
        source = str(cells.reference.iloc[0])
        return "" if source == "Mitsuba" else f"reference: {source}"
    return ""


def flag_meaning(fraction: float = DETERMINED_FRACTION) -> str:
    """What the ⚠ of a cell says, in words."""
    return (
        f"the corrected error is not determined to within ±{fraction:.0%}: the reference's "
        f"uncertainty of it ({COVERAGE:g} standard uncertainties) is larger, or the error is "
        "not above zero"
    )


def off_budget_mark(seconds: float, budget: float, averaged: bool = True) -> str:
    """HTML mark of a cell whose snapshot came well before or after its budget (``averaged``:
    the mean time of the cell's seeds; else one image's own)."""
    when = "on average" if averaged else "for this image"
    return (
        f' <span class="offbudget" title="snapshot at {fmt(seconds)} s {when}, budget '
        f'{fmt(budget)} s: not equal time">at {fmt(seconds)} s</span>'
    )


def overview_markdown(
    summary: pd.DataFrame, metric: str, determined_fraction: float = DETERMINED_FRACTION
) -> str:
    budgets = sorted(summary.budget.unique())
    head = ["scene", "method", *[budget_label(b) for b in budgets]]
    corrected = (
        " with the reference's own error removed (in brackets: the reference's standard "
        "uncertainty of that mean, and the mean as measured)"
        if is_corrected(summary, metric)
        else ""
    )
    lines = [
        f"{METRIC_LABELS.get(metric, metric)}{corrected}, mean ± std over seeds; **bold** = "
        f"best per scene and budget, and any method Welch's t-test on log errors at "
        f"{TIE_LEVEL:g} cannot tell from it with these seeds and this reference (a tie); "
        f"⚠ = {flag_meaning(determined_fraction)}; "
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
            t = t if c["determined"] else t + " ⚠"
            t = f"{t} ({c['detail']})" if c["detail"] else t
            cells.append(t + f" (at {fmt(c['seconds'])} s)" if c["off_budget"] else t)
        scene = f"{row['scene']} ({row['note']})" if row["note"] else row["scene"]
        lines.append("| " + " | ".join([scene, row["method"], *cells]) + " |")
    return "\n".join(lines) + "\n"


def overview_html(
    summary: pd.DataFrame,
    metric: str,
    link_scenes: bool = False,
    determined_fraction: float = DETERMINED_FRACTION,
) -> str:
    """An HTML <table> (no page around it); classes ``best`` and ``refbad`` (not determined)
    mark cells."""
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
            if r["note"]:
                label += f'<br><small class="note">{e(r["note"])}</small>'
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
            if not c["determined"]:
                cls.append("refbad")
                title = f' title="{e(flag_meaning(determined_fraction))}"'
            mark = ' <span class="flag">⚠</span>' if not c["determined"] else ""
            if c["off_budget"]:
                mark += off_budget_mark(c["seconds"], b)
            if c["detail"]:
                mark += f"<br><small>{e(c['detail'])}</small>"
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
    determined_fraction: float = DETERMINED_FRACTION,
) -> dict[str, pd.DataFrame]:
    """Write every table into ``out_dir``, rows in the order of ``scenes`` and ``methods``
    (study_order); return them by name. Cells whose corrected error is not known to within
    ``determined_fraction`` are flagged."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    runs = study_order(runs, scenes, methods)
    summary = study_order(summarize(runs, determined_fraction), scenes, methods)
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
    (out / "overview.md").write_text(overview_markdown(summary, metric, determined_fraction))
    style = (
        "<style>body{font-family:sans-serif}td,th{padding:2px 8px;border-bottom:1px solid #ddd}"
        ".best{font-weight:bold;background:#d8f5d0}.refbad{color:#a60}</style>"
    )
    (out / "overview.html").write_text(
        f"<!doctype html><meta charset=utf-8><title>overview</title>{style}"
        f"<p>{html.escape(METRIC_LABELS.get(metric, metric))}, mean ± std over seeds</p>"
        + overview_html(summary, metric, determined_fraction=determined_fraction)
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
