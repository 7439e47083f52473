"""Convergence plots: log-log error vs render time, one line per method, as inline SVG."""

from __future__ import annotations

import io
import math
import re

import matplotlib
import numpy as np
import pandas as pd

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import NullLocator  # noqa: E402

from ..convergence import fit_slope_of_corrected, fit_slope_over_budgets  # noqa: E402
from ..metrics import COVERAGE  # noqa: E402
from ..tables import (  # noqa: E402
    METRIC_LABELS,
    listed_first,
    one_row_per_image,
    render_time,
    value_column,
)

plt.rcParams["svg.fonttype"] = "none"  # keep text as text: smaller, searchable
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h")


def method_colours(methods: list[str]) -> dict[str, str]:
    cmap = plt.get_cmap("tab10" if len(methods) <= 10 else "tab20")
    return {m: matplotlib.colors.to_hex(cmap(i % cmap.N)) for i, m in enumerate(methods)}


def convergence_svg(
    runs: pd.DataFrame,
    metric: str,
    title: str,
    colours: dict[str, str],
    ref_error: float | None = None,
) -> str:
    """Mean error over seeds vs mean render time per method, min-max band over seeds,
    fitted slope in the legend, and the reference's own error as a dashed line. Where the
    runs have ``metric`` with the reference's error removed, that is drawn, with error bars
    of COVERAGE times the reference's uncertainty of the mean and the measured mean dotted.
    Runs whose error is undefined (NaN, e.g. 1 - SSIM of images under 11 pixels) are left
    out; an error of exactly 0 counts in the means, and only means above 0 are drawn (log
    axis). With nothing to draw the figure says so."""
    column = value_column(runs, metric)
    corrected = column != metric
    values = pd.to_numeric(runs[column], errors="coerce")
    runs = runs[np.isfinite(values)]
    if not (runs[column] > 0).any():
        return _no_data_svg(title, "no finite positive values to plot on a log scale")
    fig, ax = plt.subplots(figsize=(7.6, 4.2), dpi=100)
    # A marker per method as well as a colour: curves that coincide (pm and sppm) stay apart.
    order = listed_first(list(colours), runs["method"])
    markers = {m: MARKERS[i % len(MARKERS)] for i, m in enumerate(order)}
    for method, d in runs.groupby("method", sort=False):  # the legend in the study's order
        t_all = render_time(d)
        d = d.assign(t=t_all)
        g = d.groupby("budget")
        t_all, measured = g["t"].mean(), g[metric].mean()
        mean, lo, hi = g[column].mean(), g[column].min(), g[column].max()
        drawn = mean > 0
        t, mean, lo, hi = t_all[drawn], mean[drawn], lo[drawn].where(lo[drawn] > 0), hi[drawn]
        one = one_row_per_image(d)
        if corrected:
            fit = fit_slope_of_corrected(
                one["t"], one[column], one[f"{metric}_u"], budgets=one["budget"]
            )
        else:
            fit = fit_slope_over_budgets(one["t"].to_numpy(), one[column].to_numpy(), one["budget"])
        slope = f"{fit.slope:+.2f}" if math.isfinite(fit.slope) else "n/a"
        c = colours.get(method, None)
        ax.plot(t, mean, "-", marker=markers[method], color=c, lw=1.6, ms=5, mfc="none",
                mew=1.3, label=f"{method} (slope {slope})")  # fmt: skip
        if corrected:
            u = g[f"{metric}_u"].mean()[drawn]
            ax.errorbar(t, mean, yerr=[np.minimum(COVERAGE * u, 0.999 * mean), COVERAGE * u],
                        fmt="none", ecolor=c, elinewidth=1, capsize=2)  # fmt: skip
            shown = measured > 0
            ax.plot(t_all[shown], measured[shown], ":", color=c, lw=1)
        if d["seed"].nunique() > 1:
            ax.fill_between(t, lo, hi, color=c, alpha=0.18, lw=0)
    if ref_error is not None and math.isfinite(ref_error) and ref_error > 0:
        ax.axhline(ref_error, color="0.3", ls="--", lw=1, label="reference's own error")
    if corrected:
        ax.plot([], [], ":", color="0.3", lw=1, label="as measured")
    ax.set_xscale("log")
    ax.set_yscale("log")
    # Sizes for the page, which shows the figure at about 560 of its 760 pixels.
    ax.set_xlabel("render time [s]", fontsize=12)
    removed = " (reference error removed)" if corrected else ""
    ax.set_ylabel(METRIC_LABELS.get(metric, metric) + removed, fontsize=12)
    ax.tick_params(labelsize=11)
    ax.set_title(title, fontsize=13)
    ax.grid(True, which="both", alpha=0.25)
    # Beside the axes, where it cannot cover a curve.
    ax.legend(
        fontsize=11, loc="upper left", bbox_to_anchor=(1.02, 1), borderaxespad=0, frameon=False
    )
    budgets = np.sort(runs["budget"].unique())
    if budgets.size:
        ax.set_xticks(budgets)
        ax.set_xticklabels([f"{b:g}" for b in budgets])
        ax.xaxis.set_minor_locator(NullLocator())
    fig.tight_layout()
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight")  # the legend beside the axes too
    plt.close(fig)
    svg = buf.getvalue()
    svg = svg[svg.find("<svg") :]  # drop the XML prolog for inlining
    return re.sub(r"<metadata>.*?</metadata>\s*", "", svg, flags=re.S)


def _no_data_svg(title: str, why: str) -> str:
    """A small inline SVG in place of a plot that has nothing to draw."""
    from html import escape

    return (
        '<svg xmlns="http://www.w3.org/2000/svg" width="460" height="60">'
        f'<text x="8" y="22" font-size="14">{escape(title)}</text>'
        f'<text x="8" y="44" font-size="12" fill="#666">{escape(why)}</text></svg>'
    )
