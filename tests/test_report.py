"""Tables, convergence fits and the HTML report (checked in a real headless Chromium)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from compare import tables as T
from compare.convergence import bounded, fit_slope, fit_slope_above_floor, time_to_error
from compare.report import images as I  # noqa: N812
from compare.report.browser_check import check_page, find_chromium
from compare.report.build import build_index, build_scene_page
from compare.runs import compare_run, merge_reference
from renderer.imageio import read_exr, write_exr, write_json
from renderer.known_methods import NOT_YET_IMPLEMENTED

needs_chromium = pytest.mark.skipif(find_chromium() is None, reason="no chromium")


def test_fit_slope_exact_power_law() -> None:
    t = np.array([1.0, 2, 4, 8])
    f = fit_slope(t, 0.3 * t**-0.8)
    assert f.slope == pytest.approx(-0.8)
    assert f.intercept == pytest.approx(math.log10(0.3))
    assert f.r2 == pytest.approx(1.0)
    assert f.predict(16) == pytest.approx(0.3 * 16**-0.8)
    assert math.isnan(fit_slope([1.0], [1.0]).slope)


def test_fit_slope_above_floor_removes_the_reference_error() -> None:
    t = np.array([1.0, 2, 4, 8, 16])
    floor = 0.05
    measured = 0.4 / t + floor  # an unbiased method's error plus the reference's own error
    assert fit_slope(t, measured).slope > -0.8  # the floor flattens the raw fit
    f = fit_slope_above_floor(t, measured, floor)
    assert f.slope == pytest.approx(-1.0)
    assert f.n == 4  # at 16 s the error is below 2x the floor: dropped
    assert math.isnan(fit_slope_above_floor(t, measured, math.nan).slope)
    assert math.isnan(fit_slope_above_floor(t, measured, 1.0).slope)  # nothing above 2x


def test_fit_slope_above_floor_needs_three_budgets_spanning_four_times() -> None:
    """What the points above the floor must show before their slope is reported: two seeds at
    the first budget (a "slope" of seed noise), or budgets 1 and 2 only, are not enough."""
    floor = 0.05
    two_seeds_one_budget = fit_slope_above_floor([1.02, 1.11], [0.4, 0.3], floor)
    assert math.isnan(two_seeds_one_budget.slope) and two_seeds_one_budget.n == 2
    t = np.array([1.0, 1.1, 2.0, 2.2, 4.0, 4.4])
    budgets = np.array([1, 1, 2, 2, 4, 4])
    measured = 0.4 / t + floor
    f = fit_slope_above_floor(t, measured, floor, budgets=budgets)
    assert f.slope == pytest.approx(-1.0) and f.n == 6
    assert math.isnan(fit_slope_above_floor(t[:4], measured[:4], floor, budgets=budgets[:4]).slope)
    # three budgets, but spanning less than 4x
    close = fit_slope_above_floor([1.0, 1.5, 2.0], [0.45, 0.32, 0.25], floor)
    assert math.isnan(close.slope) and close.n == 3
    # budgets 1, 2 and 4 span 4x even when the first snapshot came late (3.995x in time:
    # lt on cbox-fog lost its slope to that)
    late = fit_slope_above_floor([1.0013, 2.0, 4.0], [0.45, 0.25, 0.15], floor, budgets=[1, 2, 4])
    assert math.isfinite(late.slope) and late.n == 3


def test_time_to_error() -> None:
    t = [1.0, 2.0, 4.0]
    e = [1.0, 0.5, 0.25]
    assert time_to_error(t, e, 0.5) == (pytest.approx(2.0), False)
    got, extrap = time_to_error(t, e, math.sqrt(0.5))  # halfway in log-log between 1 and 2 s
    assert got == pytest.approx(math.sqrt(2)) and not extrap
    got, extrap = time_to_error(t, e, 0.125)  # beyond the data: fitted slope -1
    assert got == pytest.approx(8.0) and extrap
    assert math.isnan(time_to_error(t, [1, 1, 1], 0.1)[0])


def test_time_to_error_extrapolates_only_from_enough_budgets() -> None:
    """Two budgets (the tiny study's) give a line whatever their noise: no extrapolation,
    so the table says what was measured (a bound) instead of a time from that line."""
    t, e = np.array([0.5, 1.0]), np.array([0.1, 0.05])
    assert math.isnan(time_to_error(t, e, 0.01)[0])
    assert bounded(time_to_error(t, e, 0.04), t, e, 0.04) == (1.0, False, ">=")
    assert time_to_error(t, e, 0.005**0.5) == (pytest.approx(2**0.5 / 2), False)  # measured
    # budgets 1, 2 and 4 whose first snapshot came late (3.995x in time) still extrapolate
    late = np.array([1.0013, 2.0, 4.0])
    got, extrap = time_to_error(late, [0.1, 0.05, 0.025], 0.02, budgets=[1, 2, 4])
    assert extrap and got > 4.0
    assert math.isnan(time_to_error(late, [0.1, 0.05, 0.025], 0.02)[0])


def test_time_to_error_never_contradicts_the_measurements() -> None:
    t = [1.0, 2.0, 4.0, 8.0]
    # never reached: extrapolated from the last point, so after it (the fit through all the
    # points would have put it at 1.3 s)
    got, extrap = time_to_error(t, [4.0, 2.0, 1.5, 1.1], 1.0)
    assert extrap and got >= 8.0
    # below the target at the first point: extrapolated back from it, so before it
    got, extrap = time_to_error(t, [0.99, 0.98, 0.3, 0.05], 1.0)
    assert extrap and got <= 1.0
    # a later rise above the target and fall below it again is not "first reached"
    got, extrap = time_to_error(t, [0.9, 1.1, 0.8, 0.7], 1.0)
    assert extrap and got <= 1.0
    # the first crossing from above is interpolated
    got, extrap = time_to_error(t, [4.0, 2.0, 0.5, 2.0], 1.0)
    assert not extrap and 2.0 < got < 4.0


def test_time_to_error_far_outside_the_budgets_becomes_a_bound() -> None:
    t = np.array([1.0, 2.0, 4.0])
    e = np.array([0.1, 0.05, 0.025])  # slope -1
    # within 4x of the measured times: the extrapolation stands
    assert bounded(time_to_error(t, e, 0.01), t, e, 0.01) == (pytest.approx(10.0), True, "")
    # 0.001 would need 100 s: only "not reached by 4 s" is measured
    assert bounded(time_to_error(t, e, 0.001), t, e, 0.001) == (4.0, False, ">=")
    # 10 would be reached at 0.01 s: only "reached by 1 s" is measured
    assert bounded(time_to_error(t, e, 10.0), t, e, 10.0) == (1.0, False, "<=")
    flat = np.array([0.1, 0.1, 0.1])  # no slope to extrapolate with
    assert bounded(time_to_error(t, flat, 0.01), t, flat, 0.01) == (4.0, False, ">=")
    assert bounded(time_to_error(t, flat, 1.0), t, flat, 1.0) == (1.0, False, "<=")
    assert bounded((2.0, False), t, e, 0.05) == (2.0, False, "")  # interpolated: unchanged
    assert T._speedup_bound("", "<=") == ">=" and T._speedup_bound(">=", "") == ">="
    assert T._speedup_bound(">=", ">=") == "?"


def test_rgbe_roundtrip() -> None:
    rng = np.random.default_rng(0)
    a = rng.random((6, 5, 3)) * 50
    d = I.decode_rgbe(I.encode_rgbe(a), 6, 5)
    assert np.all(np.abs(d - a) <= a.max(axis=2, keepdims=True) / 128)


def _runs() -> pd.DataFrame:
    rows = []
    for method, k in (("pt", 1.0), ("lt", 3.0)):
        for seed in (1, 2):
            for b in (1.0, 2.0, 4.0):
                err = k / b * (1 + 0.1 * seed)
                rows.append(
                    {
                        "scene": "s",
                        "method": method,
                        "seed": seed,
                        "budget": b,
                        "render_seconds": b,
                        "relmse": err,
                        "mse": err,
                        "flip": err / 10,
                        "ref_relmse": 0.2 if b == 4.0 else 1e-4,
                        "ref_ok": not (b == 4.0),
                        "rays": 1e6 * b,
                        "iterations": 10 * b,
                    }
                )
    return pd.DataFrame(rows)


def test_tables_best_flags_and_speedup(tmp_path: Path) -> None:
    tabs = T.write_tables(_runs(), tmp_path, metric="relmse", baseline="pt")
    best = tabs["best"]
    assert (best.method == "pt").all() and len(best) == 3
    s = tabs["summary"].set_index(["method", "budget"])
    assert s.loc[("pt", 1.0), "relmse_mean"] == pytest.approx(1.15)
    assert s.loc[("pt", 1.0), "relmse_std"] == pytest.approx(np.std([1.1, 1.2], ddof=1))
    tte = tabs["time_to_error"].set_index("method")
    # lt has 3x the error of pt at every time and slope -1: needs 3x the time
    assert tte.loc["lt", "speedup_vs_pt"] == pytest.approx(1 / 3)
    md = (tmp_path / "overview.md").read_text()
    assert "**1.15 ± 0.071**" in md and "⚠" in md
    html = (tmp_path / "overview.html").read_text()
    assert 'class="best"' in html and "refbad" in html and "offbudget" not in html
    for name in ("runs", "summary", "convergence", "time_to_error", "stats"):
        assert (tmp_path / f"{name}.csv").is_file()
    conv = tabs["convergence"].set_index(["method", "metric"])
    # errors fall as 1/t; the reference's error (median 1e-4) is removed before the fit
    assert conv.loc[("pt", "relmse"), "slope_ref_removed"] == pytest.approx(-1.0, abs=0.01)
    assert conv.loc[("pt", "relmse"), "points_ref_removed"] == 6
    assert np.isnan(conv.loc[("pt", "flip"), "slope_ref_removed"])  # no reference error known


def test_slope_ranges_come_from_each_seed_alone(tmp_path: Path) -> None:
    """Seed 1's error falls as 1/t, seed 2's as 1/sqrt(t): the table keeps the fit over all
    runs and gives the per-seed slopes as its range; the report prints both."""
    runs = _runs()
    second = runs.seed == 2
    runs.loc[second, "relmse"] = runs.loc[second, "relmse"] * runs.loc[second, "budget"] ** 0.5
    conv = T.write_tables(runs, tmp_path, metric="relmse", baseline="pt")["convergence"]
    pt = conv.set_index(["method", "metric"]).loc[("pt", "relmse")]
    assert pt["slope_seed_min"] == pytest.approx(-1.0) and pt["slope_seed_max"] == pytest.approx(
        -0.5
    )
    assert -1.0 < pt["slope"] < -0.5
    assert pt["slope_ref_removed_seed_min"] == pytest.approx(-1.0, abs=0.01)
    assert pt["slope_ref_removed_seed_max"] == pytest.approx(-0.5, abs=0.01)
    cell = T.slope_cells(conv[(conv.method == "pt") & (conv.metric == "relmse")]).iloc[0]
    assert cell == f"{pt['slope']:.2f}<br><small>(seeds -1.00 to -0.50)</small>"
    text = T.fmt_slope(pt["slope"], pt["slope_seed_min"], pt["slope_seed_max"])
    assert text == f"{pt['slope']:.2f} (seeds -1.00 to -0.50)"
    assert "<br><small>(seeds -1.00 to -0.50)</small>" in T.frame_html(pd.DataFrame({"c": [cell]}))
    one_seed = T.write_tables(runs[~second], tmp_path, metric="relmse", baseline="pt")
    lone = one_seed["convergence"].iloc[0]
    assert np.isnan(lone["slope_seed_min"])  # a range needs two seeds
    assert T.fmt_slope(lone["slope"], lone["slope_seed_min"], lone["slope_seed_max"]) == "-1.00"


def test_tables_list_methods_in_the_study_order(tmp_path: Path) -> None:
    """The config lists pt before lt: every table and the overview keep that order (they
    used to sort alphabetically while the report's other sections followed the config)."""
    tabs = T.write_tables(_runs(), tmp_path, metric="relmse", baseline="pt", methods=["pt", "lt"])
    for name in ("runs", "summary", "convergence", "time_to_error", "stats"):
        assert list(tabs[name].method.unique()) == ["pt", "lt"], name
        assert list(pd.read_csv(tmp_path / f"{name}.csv").method.unique()) == ["pt", "lt"]
    html = T.overview_html(tabs["summary"], "relmse")
    assert html.index(">pt<") < html.index(">lt<")
    runs = _runs()
    runs.loc[(runs.method == "lt") & (runs.budget == 1.0), "relmse"] = 0.01  # lt wins at 1 s
    best = T.write_tables(runs, tmp_path, metric="relmse", baseline="pt", methods=["pt", "lt"])
    assert list(best["best"].budget) == [1.0, 2.0, 4.0]  # the winners by budget, not method
    assert list(best["best"].method) == ["lt", "pt", "pt"]
    plain = T.write_tables(_runs(), tmp_path, metric="relmse", baseline="pt")
    assert list(plain["summary"].method.unique()) == ["lt", "pt"]  # none given: alphabetical
    # Rows are taken by position: runs concatenated without a fresh index (labels repeat)
    # keep their count, and the per-seed slopes their seeds.
    halves = [r.reset_index(drop=True) for _, r in _runs().groupby("seed")]
    repeated = T.write_tables(pd.concat(halves), tmp_path, metric="relmse", baseline="pt")
    assert len(repeated["runs"]) == len(_runs())
    assert repeated["summary"].equals(plain["summary"])
    assert repeated["convergence"].equals(plain["convergence"])


def test_baseline_against_itself_is_exactly_one_whatever_its_bound(tmp_path: Path) -> None:
    """pt identical to the reference (target 0, met from its first budget on): its own
    time is a bound ("<="), and its speed-up against itself is 1 with no bound, not "?"."""
    runs = _runs()
    runs.loc[runs.method == "pt", "relmse"] = 0.0
    tte = T.write_tables(runs, tmp_path, metric="relmse", baseline="pt")["time_to_error"]
    own = tte.set_index("method").loc["pt"]
    assert own["bound"] == "<=" and own["speedup_vs_pt"] == 1.0 and own["speedup_bound"] == ""


def test_convergence_plot_leaves_out_what_a_log_axis_cannot_show() -> None:
    """1 - SSIM is NaN on images under 11 pixels: such runs are left out of the plot, and a
    metric with nothing left gives a placeholder, not an exception."""
    from compare.report.plots import convergence_svg

    runs = _runs()
    runs["one_minus_ssim"] = math.nan
    svg = convergence_svg(runs, "one_minus_ssim", "s: 1 - SSIM", {})
    assert svg.startswith("<svg") and "no finite positive values" in svg
    runs.loc[runs.method == "lt", "one_minus_ssim"] = 0.5  # pt has none: lt alone is drawn
    svg = convergence_svg(runs, "one_minus_ssim", "s: 1 - SSIM", {})
    assert "lt (slope" in svg and "pt (slope" not in svg


def test_reference_halves_that_differ_in_size_are_named(tmp_path: Path) -> None:
    write_exr(tmp_path / "a.exr", np.ones((8, 8, 3)))
    write_exr(tmp_path / "b.exr", np.ones((8, 9, 3)))
    with pytest.raises(
        ValueError, match=r"reference half .*a\.exr is 8x8 but reference half .*b\.exr is 9x8"
    ):
        merge_reference(
            tmp_path / "a.exr", tmp_path / "b.exr", tmp_path / "r.exr", tmp_path / "r.json"
        )
    assert not (tmp_path / "r.exr").exists()


@pytest.mark.parametrize("factor", [1.5, 0.6])
def test_snapshots_off_budget_are_marked(tmp_path: Path, factor: float) -> None:
    """A cell whose snapshot came over 10 % after or before its budget is not equal time:
    marked; one within 10 % is not."""
    runs = _runs()
    runs["render_seconds"] *= 1.09 if factor > 1 else 0.91  # within the allowance: unmarked
    runs.loc[(runs.method == "lt") & (runs.budget == 1.0), "render_seconds"] = factor
    T.write_tables(runs, tmp_path, metric="relmse", baseline="pt")
    md = (tmp_path / "overview.md").read_text()
    off = [line for line in md.splitlines() if line.startswith("|") and "(at " in line]
    assert len(off) == 1 and off[0].startswith("| s | lt |") and f"(at {factor:g} s)" in off[0]
    html = (tmp_path / "overview.html").read_text()
    assert html.count('class="offbudget"') == 1 and f"snapshot at {factor:g} s on average" in html


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small report built through the library (reference merge -> compare -> tables -> html)."""
    wd = tmp_path_factory.mktemp("report")
    rng = np.random.default_rng(5)
    h, w = 24, 32
    y, x = np.mgrid[0:h, 0:w]
    truth = np.stack([0.2 + x / w, 0.3 + y / h, 0.5 + 0 * x], axis=2).astype(np.float64)
    truth[8:12, 10:16] = 5.0
    for k in (0, 1):
        write_exr(wd / f"half{k}.exr", truth * (1 + 0.01 * rng.standard_normal(truth.shape)))
        write_json(wd / f"half{k}.json", {"renderer": "mitsuba 3.9.1 volpathmis", "spp": 4})
    merge_reference(wd / "half0.exr", wd / "half1.exr", wd / "ref.exr", wd / "ref.json")
    methods, budgets = ["pt", "lt"], ["1", "2"]
    csvs, snaps = [], {}
    for mi, m in enumerate(methods):
        for seed in (1, 2):
            paths = []
            for b in budgets:
                img = truth * (1 + (mi + 1) * 0.3 / float(b) * rng.standard_normal(truth.shape))
                p = wd / m / f"s{seed}" / f"run.t{b}.exr"
                write_exr(p, np.maximum(img, 0))
                # pt's first snapshot comes 30 % late: the winners table must say so
                late = 1.3 if (m, b) == ("pt", "1") else 1.0
                write_json(
                    p.with_suffix(".json"),
                    {"render_seconds": late * float(b), "threads": 2, "iterations": 3},
                )
                paths.append(str(p))
            if seed == 1:
                snaps[m] = paths
            out = wd / "metrics" / f"{m}-{seed}.csv"
            compare_run(
                paths,
                [float(b) for b in budgets],
                wd / "ref.exr",
                wd / "ref.json",
                out,
                scene="toy",
                method=m,
                seed=seed,
                threads=2,
            )
            csvs.append(out)
    rep = wd / "reports"
    T.write_tables(T.load_runs(csvs), rep / "tables")
    common = {
        "reports": str(rep),
        "tables": str(rep / "tables"),
        "metric": "relmse",
        "baseline": "pt",
        "factor": 10,
        "title": "test report",
        "study": "t",
        "methods": methods,
        "scenes": ["toy"],
    }
    scene_file = wd / "scene.yaml"  # only its self-description is read
    scene_file.write_text(
        "description: A toy scene for the report test.\n"
        "stresses: [direct light]\nexpected_winners: [pt, sppm, upbp]\n"
    )
    # every method of the study's table is implemented: a planned one stands in for the next
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(NOT_YET_IMPLEMENTED, "upbp", "unified points, beams and paths")
        build_scene_page(
            {
                **common,
                "scene": "toy",
                "scene_file": str(scene_file),
                "ref": str(wd / "ref.exr"),
                "ref_json": str(wd / "ref.json"),
                "seed": 1,
                "budgets": budgets,
                "snapshots": snaps,
                "viewer_max_size": 512,
            }
        )
    build_index({**common, "refs": {"toy": str(wd / "ref.json")}})
    return rep


def test_a_time_to_error_never_reached_is_a_dash(report: Path, tmp_path: Path) -> None:
    """No finite time (no finite error, as SSIM on films under 11 px): a dash, not "– s*",
    which read as an extrapolated time."""
    tables = tmp_path / "tables"
    tables.mkdir()
    for csv in (report / "tables").glob("*.csv"):
        (tables / csv.name).write_bytes(csv.read_bytes())
    tte = pd.read_csv(tables / "time_to_error.csv")
    tte.loc[tte.method == "lt", "seconds"] = math.nan
    tte.to_csv(tables / "time_to_error.csv", index=False)
    build_index(
        {
            "reports": str(tmp_path / "out"), "tables": str(tables), "metric": "relmse",
            "baseline": "pt", "factor": 10, "title": "t", "study": "t", "methods": ["pt", "lt"],
            "scenes": ["toy"], "refs": {"toy": str(report.parent / "ref.json")},
        }
    )  # fmt: skip
    index = (tmp_path / "out" / "index.html").read_text()
    assert 'title="no finite error to reach the target with">–</td>' in index
    assert "– s" not in index  # the old cell: "– s*"


def test_index_lists_scenes_and_variants_in_the_config_order(report: Path, tmp_path: Path) -> None:
    """The spec's JSON arrives with its keys sorted (refs, variants): the reference-quality
    table and the variants note still follow the config's order, as every other section."""
    tables = tmp_path / "tables"
    tables.mkdir()
    for csv in (report / "tables").glob("*.csv"):
        df = pd.read_csv(csv)
        if "scene" in df:  # a second scene, "abc", after "toy" in the config
            df = pd.concat([df, df.assign(scene="abc")], ignore_index=True)
        df.to_csv(tables / csv.name, index=False)
    ref = str(report.parent / "ref.json")
    build_index(
        {
            "reports": str(tmp_path / "out"), "tables": str(tables), "metric": "relmse",
            "baseline": "pt", "factor": 10, "title": "t", "study": "t", "methods": ["pt", "lt"],
            "scenes": ["toy", "abc"], "refs": {"abc": ref, "toy": ref},
            "variants": {"lt": "lt with settings", "pt": "pt with settings"},
        }
    )  # fmt: skip
    index = (tmp_path / "out" / "index.html").read_text()
    quality = index[index.index("<h2>Reference quality</h2>") :]
    assert quality.index("<td>toy</td>") < quality.index("<td>abc</td>")
    assert index.index("<b>pt</b>: pt with settings") < index.index("<b>lt</b>: lt with settings")


def test_report_files(report: Path) -> None:
    index = (report / "index.html").read_text()
    page = (report / "scene-toy.html").read_text()
    assert "<svg" in index and 'href="scene-toy.html"' in index
    assert "Reference error removed" in index and "ref. error removed" in page
    assert 'id="viewer"' in page and 'src="data/toy.js"' in page
    assert "A toy scene for the report test." in page and "upbp (not implemented yet)" in page
    # tables name their columns as a reader would: no identifiers
    assert "<th>speed-up vs pt</th>" in page and "<th>time [s]</th>" in page
    assert "speedup_vs" not in page and "<th>one_minus_ssim</th>" not in page
    # pt's late first snapshot is marked under its image too, and nothing else is
    grid = page[page.index("Equal-time images") :]
    assert grid.count('class="offbudget"') == 1 and "pt · relMSE" in grid and ">at 1.3 s<" in grid
    assert "Mitsuba 3.9.1 volpathmis, two independent halves of 4 spp each" in page
    assert re.search(r"<b>Won</b> at [^:]+: (pt \(as expected|lt \(not among the expected)", page)
    winners = index[index.index("Best method per scene") : index.index("Overview:")]
    # pt at 1 s ran 1.3 s: over its budget, it cannot win it (lt does, in time)
    assert 'class="offbudget"' not in winners and "<td>lt (" in winners
    assert "not an equal-time comparison" in index
    for text in (index, page):  # nothing fetched from the network
        assert not re.search(r"(src|href)=[\"']?(https?:)?//", text)
    data = (report / "data" / "toy.js").read_text()
    d = json.loads(data[len("window.PGI_DATA = ") : -2])
    assert d["width"] == 32 and d["height"] == 24 and set(d["images"]) == {"pt", "lt"}


@pytest.fixture(scope="module")
def downsampled_page(report: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The report's scene page again with viewer_max_size 16: its 32x24 film is shown at 16x12."""
    out = tmp_path_factory.mktemp("downsampled")
    wd = report.parent
    snaps = {m: [str(wd / m / "s1" / f"run.t{b}.exr") for b in ("1", "2")] for m in ("pt", "lt")}
    build_scene_page(
        {
            "reports": str(out), "tables": str(report / "tables"), "metric": "relmse",
            "baseline": "pt", "factor": 10, "title": "t", "study": "t", "methods": ["pt", "lt"],
            "scenes": ["toy"], "scene": "toy", "scene_file": str(wd / "scene.yaml"),
            "ref": str(wd / "ref.exr"), "ref_json": str(wd / "ref.json"), "seed": 1,
            "budgets": ["1", "2"], "snapshots": snaps, "viewer_max_size": 16,
        }
    )  # fmt: skip
    return out


def _viewer_data(reports: Path) -> dict:
    data = (reports / "data" / "toy.js").read_text()
    return json.loads(data[len("window.PGI_DATA = ") : -2])


def test_the_viewers_mean_error_is_the_full_size_images(report: Path, downsampled_page: Path):
    """With the film larger than viewer_max_size the viewer shows downsampled images; the
    mean relMSE it is given is still the full-size image's, the one the tables have."""
    from compare.metrics import compare_images

    d = _viewer_data(downsampled_page)
    assert (d["width"], d["height"], d["film"]) == (16, 12, [32, 24])
    wd = report.parent
    ref = read_exr(wd / "ref.exr")
    for m in ("pt", "lt"):
        for b in ("1", "2"):
            image = read_exr(wd / m / "s1" / f"run.t{b}.exr")
            assert d["relmse"][m][b] == pytest.approx(
                compare_images(image, ref)["relmse"], rel=1e-12
            )


@needs_chromium
def test_the_viewer_states_the_full_size_mean_in_the_browser(downsampled_page: Path) -> None:
    caption = (
        "(function () { var v = window.PGI_VIEWER; v.select(1); v.state.budget = 1; v.draw();"
        " return document.querySelectorAll('#viewer figcaption')[2].textContent; })()"
    )
    (shown,) = check_page(downsampled_page / "scene-toy.html", evaluate=(caption,)).values
    said = re.search(r"\(mean ([-+.0-9e]+) of the 32×24 image; map shown at 16×12;", shown)
    full = _viewer_data(downsampled_page)["relmse"]["pt"]["2"]
    assert said and float(said[1]) == pytest.approx(full, rel=5e-3), shown


def test_a_variant_counts_as_its_method_among_the_expected_winners(
    report: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A study of pt-delta (a variant of pt) and lt: pt is in the study, and a win of
    pt-delta is a win of pt."""
    from compare.report.build import _about_scene

    summary = pd.read_csv(report / "tables" / "summary.csv")
    summary["method"] = summary.method.replace({"pt": "pt-delta"})
    monkeypatch.setitem(NOT_YET_IMPLEMENTED, "upbp", "unified points, beams and paths")
    scene_file = report.parent / "scene.yaml"
    text = _about_scene(
        str(scene_file), "toy", summary, "relmse", ["pt-delta", "lt"], {"pt-delta": "pt"}
    )
    expected = "pt, sppm (not in this study), upbp (not implemented yet)"
    assert f"<b>Expected to win:</b> {expected}." in text
    won = r"<b>Won</b> at [^:]+: (pt-delta \(as expected|lt \(not among the expected)"
    assert re.search(won, text)


@needs_chromium
def test_report_in_headless_chromium(report: Path, tmp_path: Path) -> None:
    for page in ("index.html", "scene-toy.html"):
        r = check_page(report / page, screenshot=tmp_path / f"{page}.png")
        assert not r.errors, r.errors
        assert not r.broken_images, r.broken_images
        assert r.screenshot_std > 2.0  # not blank
        narrow = check_page(report / page, width=800)
        assert narrow.overflow_px == 0, narrow.overflowing  # no page-wide scrolling
    # pt's 1 s snapshot of seed 1 came at 1.3 s: the viewer says so, as the grid does
    caption = (
        "(function (m) { var v = window.PGI_VIEWER; v.select(m); v.state.budget = 0; v.draw();"
        " return document.querySelector('#viewer figcaption').textContent; })"
    )
    r = check_page(report / "scene-toy.html", evaluate=(f"{caption}(1)", f"{caption}(2)"))
    assert r.values == ["pt @ 1 s (this image's snapshot at 1.30 s: not equal time)", "lt @ 1 s"], (
        r.values
    )
    assert r.viewer and r.viewer_key_ok  # key "0" switched the viewer to the reference
    # Keys act on the viewer only while it is on screen: scrolled away, "1" leaves it alone.
    press_one = (
        "(function () { var v = document.getElementById('viewer'); window.PGI_VIEWER.select(0);"
        " window.dispatchEvent(new KeyboardEvent('keydown', {key: '1'}));"
        " return [v.getBoundingClientRect().top < window.innerHeight, v.dataset.method]; })"
    )
    r = check_page(
        report / "scene-toy.html",
        evaluate=(
            "document.getElementById('viewer').scrollIntoView()", f"{press_one}()",
            "window.scrollTo(0, 0)", f"{press_one}()",
        ),
    )  # fmt: skip
    assert r.values[1] == [True, "pt"] and r.values[3] == [False, "reference"], r.values
    assert r.images >= 9  # colour bar, reference, 2 methods x 2 budgets x (image + error)


@needs_chromium
def test_wide_tables_scroll_on_their_own_in_a_narrow_window(tmp_path: Path) -> None:
    """A table of 16 budgets in an 800-pixel window: the report's tables scroll inside their
    own box and the page stays as wide as the window. Control: the same table without the
    report's table class widens the whole page, and the check sees it."""
    from compare.report.build import _page

    wide = pd.DataFrame({f"{2**i} s": ["0.00123 ± 4.5e-05"] for i in range(16)})
    table = T.frame_html(wide)
    page = tmp_path / "wide.html"
    page.write_text(_page("wide", table))
    r = check_page(page, width=800)
    assert r.ok and r.overflow_px == 0, r.overflowing
    page.write_text(_page("wide", table.replace('class="data"', "")))
    r = check_page(page, width=800)
    assert not r.ok and r.overflow_px > 400 and "TABLE." in r.overflowing


@needs_chromium
def test_browser_check_catches_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.html"
    bad.write_text(
        "<!doctype html><body><p>x</p><img alt=missing src=nothere.png>"
        "<script>console.error('boom'); undefinedFunction();</script></body>"
    )
    r = check_page(bad)
    assert not r.ok
    assert any("boom" in e for e in r.errors)
    assert any("undefinedFunction" in e for e in r.errors)
    assert "missing" in r.broken_images


def test_methods_welchs_test_on_log_errors_cannot_separate_from_the_best_are_tied() -> None:
    """Errors compared as logs, 10 % seed-to-seed spread over 2 seeds a side: the log
    difference's standard error is 0.1 and Welch's 2 degrees of freedom put the 5 % limit at
    4.30 of it, a ratio of e^0.43 = 1.54. pt 1.00 and mitsuba 1.05 tie; lt at 1.6 does not;
    with one seed no spread is known and nothing ties."""
    rows = [
        ("pt", 1.00, 0.1, 2),
        ("mitsuba", 1.05, 0.105, 2),
        ("lt", 1.60, 0.16, 2),
        ("pm", 1.01, np.nan, 1),
    ]
    summary = pd.DataFrame(
        [
            {
                "scene": "s",
                "budget": 1.0,
                "method": m,
                "relmse_mean": mean,
                "relmse_std": std,
                "n_seeds": n,
                "render_seconds_mean": 1.0,
                "ref_ok": True,
            }
            for m, mean, std, n in rows
        ]
    )
    best = T.best_methods(summary, "relmse")
    assert best.method.tolist() == ["pt"] and best.tied_with.tolist() == ["mitsuba"]
    marked = {r["method"] for r in T.overview_cells(summary, "relmse") if r["cells"][1.0]["best"]}
    assert marked == {"pt", "mitsuba"}
    assert T.tied(1.0, 0.1, 2, 1.53, 0.153, 2) and not T.tied(1.0, 0.1, 2, 1.55, 0.155, 2)
    # More seeds, a smaller limit: 8 a side with 20 % spreads give 14 degrees of freedom and
    # a log limit of 2.14 x 0.1, a ratio of 1.239.
    assert T.tied(1.0, 0.2, 8, 1.23, 0.246, 8) and not T.tied(1.0, 0.2, 8, 1.25, 0.25, 8)
    # One method varying between seeds does not tie it with one 40x better (default study,
    # cbox-fog at 1 s: pt against sppm), though the difference of the means would.
    assert not T.tied(0.192, 0.027, 2, 0.00498, 8.1e-5, 2)
    assert T.tied(1.0, 0.0, 2, 1.0, 0.0, 2) and not T.tied(1.0, 0.0, 2, 1.001, 0.0, 2)


# --------------------------------------------------------------------------- wiring of the tables
# Each of these caught a bug injected into a copy of the code that the tests above let pass.


def test_compare_run_removes_the_reference_error_of_the_halves_ref_json_names(
    tmp_path: Path,
) -> None:
    """Each row has the MSE-type errors measured and corrected: the corrected MSE and relMSE
    are the measured ones less the reference's own (the estimator's identity), with
    uncertainties from the halves named in ref.json, relative to its folder, so that a
    results folder read from elsewhere still finds them."""
    rng = np.random.default_rng(2)
    truth = rng.uniform(0.2, 2.0, (16, 16, 3))
    for h in (0, 1):
        write_exr(
            tmp_path / "ref" / f"half{h}.exr", truth + 0.05 * rng.standard_normal(truth.shape)
        )
    ref = tmp_path / "ref"
    merge_reference(ref / "half0.exr", ref / "half1.exr", ref / "ref.exr", ref / "ref.json")
    write_exr(tmp_path / "run.t1.exr", truth * 1.1)
    write_json(tmp_path / "run.t1.json", {"render_seconds": 1.0, "threads": 2})
    args = ([tmp_path / "run.t1.exr"], [1.0], ref / "ref.exr", ref / "ref.json")
    row = compare_run(*args, tmp_path / "a.csv", scene="s", method="pt", seed=1, threads=2)
    row = row.iloc[0]
    assert row.mse_corrected == pytest.approx(row.mse - row.ref_mse, rel=1e-6)  # ref.exr is float32
    assert row.relmse_corrected == pytest.approx(row.relmse - row.ref_relmse, rel=1e-6)
    assert row.rmse_corrected == pytest.approx(row.mse_corrected**0.5)
    assert 0 < row.relmse_u_shared < row.relmse_u < 0.1 * row.relmse_corrected
    assert "mape_corrected" not in row and "flip_corrected" not in row  # not squared errors


def _summary(rows: list[tuple[str, float, float, int]]) -> pd.DataFrame:
    return pd.DataFrame(
        [
            {"scene": "s", "budget": 1.0, "method": m, "relmse_mean": mean, "relmse_std": std,
             "n_seeds": n, "render_seconds_mean": 1.0, "ref_ok": True}
            for m, mean, std, n in rows
        ]
    )  # fmt: skip


def test_a_method_with_one_seed_can_win() -> None:
    best = T.best_methods(_summary([("pt", 1.0, 0.1, 2), ("pm", 0.5, np.nan, 1)]), "relmse")
    assert best.method.tolist() == ["pm"] and best.tied_with.tolist() == [""]


def test_a_cell_is_flagged_unless_the_reference_determines_its_corrected_mean() -> None:
    """A cell's flag is its corrected mean's: determined when that mean is positive and its
    reference uncertainty (2 standard uncertainties: each seed's own part averaged, the
    shared part once) is within the fraction of it."""
    runs = _runs()
    runs["relmse_corrected"] = runs.relmse
    runs["relmse_u"] = 0.05 * runs.relmse  # 2u = 10 % of the error: determined within 20 %
    runs["relmse_u_shared"] = 0.03 * runs.relmse
    pt1 = (runs.method == "pt") & (runs.budget == 1.0)
    runs.loc[pt1 & (runs.seed == 1), "relmse_u"] = 0.5  # one seed's own part dominates
    s = T.summarize(runs).set_index(["method", "budget"])
    cell = runs[pt1]
    own = np.sqrt(cell.relmse_u**2 - cell.relmse_u_shared**2).mean()
    assert s.loc[("pt", 1.0), "relmse_u"] == pytest.approx(
        np.hypot(own, cell.relmse_u_shared.mean())
    )
    assert not s.loc[("pt", 1.0), "determined"] and s.loc[("pt", 2.0), "determined"]
    assert (
        not T.summarize(runs, determined_fraction=0.05)
        .set_index(["method", "budget"])
        .loc[("pt", 2.0), "determined"]
    )
    runs.loc[pt1, "relmse_corrected"] = -0.01  # below what the reference resolves
    assert not T.summarize(runs).set_index(["method", "budget"]).loc[("pt", 1.0), "determined"]
    md = T.overview_markdown(s.reset_index(), "relmse")
    assert "⚠ (ref. ±" in md and "measured 1.15" in md


def test_slopes_are_fitted_on_render_time_not_on_the_budget() -> None:
    runs = _runs()
    runs["render_seconds"] = runs.budget.map({1.0: 1.5, 2.0: 2.0, 4.0: 4.0})
    runs["relmse"] = runs.seed / runs.render_seconds  # exactly 1 / t per seed
    conv = T.convergence_table(runs, ["relmse"]).set_index("method")
    assert conv.loc["pt", "slope"] == pytest.approx(-1.0)


def test_the_error_target_is_the_baselines_at_its_largest_budget(tmp_path: Path) -> None:
    tte = T.write_tables(_runs(), tmp_path, metric="relmse", baseline="pt")["time_to_error"]
    assert tte.target.tolist() == pytest.approx([1.15 / 4] * 2)
    assert (tte.target_from == "pt at 4 s").all()


def test_an_error_target_off_its_budget_says_when_its_image_was_taken(tmp_path: Path) -> None:
    """Every speed-up in a row is measured against the target's time: "mitsuba at 2 s" for an
    image taken at 3.23 s misled (found by a review)."""
    runs = _runs()
    runs.loc[(runs.method == "pt") & (runs.budget == 4.0), "render_seconds"] = 5.0
    tte = T.write_tables(runs, tmp_path, metric="relmse", baseline="pt")["time_to_error"]
    assert (tte.target_from == "pt at 4 s (its image at 5 s)").all()


def test_budget_columns_sit_over_their_own_cells(tmp_path: Path) -> None:
    runs = _runs()
    runs["budget"] = runs.budget.replace({4.0: 16.0})  # "16 s" sorts before "2 s" as text
    runs["render_seconds"] = runs.budget
    T.write_tables(runs, tmp_path, metric="relmse", baseline="pt", methods=["pt", "lt"])
    md = (tmp_path / "overview.md").read_text().splitlines()
    assert (
        next(row for row in md if row.startswith("| scene"))
        == "| scene | method | 1 s | 2 s | 16 s |"
    )
    pt = next(row for row in md if row.startswith("| s | pt |"))
    assert pt.split(" | ")[2] == "**1.15 ± 0.071**"  # the 1 s cell under the 1 s header
    html = (tmp_path / "overview.html").read_text()
    assert re.findall(r"<th>([\d.]+ s)</th>", html) == ["1 s", "2 s", "16 s"]


def test_benchmarks_join_the_run_of_their_own_seed(tmp_path: Path) -> None:
    csv = tmp_path / "m.csv"
    _runs().assign(ref_ok=True).to_csv(csv, index=False)
    bench = {}
    for seed, seconds in ((1, 10.0), (2, 20.0)):
        tsv = tmp_path / f"s{seed}.tsv"
        tsv.write_text(f"s\tmax_rss\n{seconds}\t{seconds * 10}\n")
        bench[("s", "pt", seed)] = tsv
    runs = T.load_runs([csv], bench)
    pt = runs[runs.method == "pt"].groupby("seed").wall_seconds.first()
    assert pt.to_dict() == {1: 10.0, 2: 20.0}


def test_method_stats_are_those_of_the_largest_budget() -> None:
    st = T.stats_table(_runs())
    assert (st.budget == 4.0).all() and (st.iterations == 40.0).all()


def test_auto_exposure_maps_the_mean_to_middle_grey() -> None:
    assert I.auto_exposure(np.full((4, 4, 3), 0.72)) == -2.0
    assert I.auto_exposure(np.full((4, 4, 3), 0.045)) == 2.0


def test_an_extrapolation_within_four_times_before_the_first_budget_stands() -> None:
    t, e = np.array([1.0, 2.0, 4.0]), np.array([0.1, 0.05, 0.025])
    assert bounded(time_to_error(t, e, 0.2), t, e, 0.2) == (pytest.approx(0.5), True, "")


def test_the_winner_named_is_the_one_at_the_largest_budget(tmp_path: Path) -> None:
    from compare.report.build import _about_scene

    runs = _runs()
    runs.loc[(runs.method == "lt") & (runs.budget == 1.0), "relmse"] = 0.01  # lt wins at 1 s
    scene = tmp_path / "scene.yaml"
    scene.write_text("expected_winners: [pt]\n")
    text = _about_scene(str(scene), "s", T.summarize(runs), "relmse", ["pt", "lt"], {})
    assert "<b>Won</b> at 4 s: pt (as expected" in text


def test_each_image_is_shown_under_its_own_budget(report: Path) -> None:
    page = (report / "scene-toy.html").read_text()
    runs = pd.read_csv(report / "tables" / "runs.csv")
    grid = page[page.index("Equal-time images") :]
    sections = re.split(r"<h3>([\d.]+) s</h3>", grid)[1:]
    assert sections
    for b, html in zip(sections[::2], sections[1::2], strict=True):
        for m in ("pt", "lt"):
            r = runs[(runs.method == m) & (runs.seed == 1) & (runs.budget == float(b))]
            assert f"{m} · relMSE {T.fmt(r.relmse.iloc[0])}" in html, (m, b)


def test_index_and_scene_pages_colour_methods_alike(report: Path, tmp_path: Path, monkeypatch):
    from compare.report import build

    seen = []
    real = build.convergence_svg

    def recording(*args, **kwargs):
        seen.append(dict(args[3]))
        return real(*args, **kwargs)

    monkeypatch.setattr(build, "convergence_svg", recording)
    spec = {
        "reports": str(tmp_path / "out"), "tables": str(report / "tables"), "metric": "relmse",
        "baseline": "pt", "factor": 10, "title": "t", "study": "t", "methods": ["pt", "lt"],
        "scenes": ["toy"], "refs": {"toy": str(report.parent / "ref.json")},
    }  # fmt: skip
    build.build_index(spec)
    # the scene pages' colours: by the study's order of methods, not sorted
    assert seen and all(c == build.method_colours(["pt", "lt"]) for c in seen)


def test_budgets_that_share_one_image_count_once() -> None:
    """A method whose iteration outlasts the budgets (Mitsuba at 3 s per iteration against
    budgets of 1, 2 and 4 s) hands each budget the same image: one point per seed, no slope,
    where the fit used to take each seed's image three times and print a slope of seed noise
    (found by a review: +1.05 beside a single point)."""
    from compare.report.plots import convergence_svg

    runs = _runs()
    slow = runs.method == "lt"
    runs.loc[slow, "iterations"] = 1.0
    runs.loc[slow, "render_seconds"] = 3.0 + 0.1 * runs.seed[slow]
    runs.loc[slow, "relmse"] = 0.5 * runs.seed[slow]  # one image per seed
    conv = T.convergence_table(runs, ["relmse"]).set_index("method")
    assert math.isnan(conv.loc["lt", "slope"]) and conv.loc["lt", "points"] == 2
    assert conv.loc["pt", "slope"] == pytest.approx(-1.0) and conv.loc["pt", "points"] == 6
    svg = convergence_svg(runs, "relmse", "one image", {"pt": "#000", "lt": "#f00"})
    assert "lt (slope n/a)" in svg and "pt (slope -1.00)" in svg
    # Two budgets of three share an image: two distinct images span 1 to 4 s, still no slope.
    runs = _runs()
    runs.loc[runs.budget == 2.0, "iterations"] = 10.0
    runs.loc[runs.budget == 2.0, "render_seconds"] = 1.0
    shared = T.one_row_per_image(runs[runs.method == "pt"])
    assert sorted(shared.budget) == [1.0, 1.0, 4.0, 4.0]


def test_a_slope_needs_three_budgets_spanning_four_times() -> None:
    """Two budgets give two points, which a line always fits: no slope, as measured or with
    the reference error removed, in the table and in the plots' legends."""
    from compare.convergence import fit_slope_over_budgets
    from compare.report.plots import convergence_svg

    runs = _runs()
    two = runs[runs.budget < 4.0]
    conv = T.convergence_table(two, ["relmse"]).set_index("method")
    assert conv.slope.isna().all() and conv.slope_seed_min.isna().all()
    assert T.convergence_table(runs, ["relmse"]).slope.notna().all()  # control: 1, 2 and 4 s
    assert math.isnan(fit_slope_over_budgets([1.0, 2.0, 3.0], [1.0, 0.5, 0.33], [1, 2, 3]).slope)
    svg = convergence_svg(two, "relmse", "two budgets", {"pt": "#000", "lt": "#f00"})
    assert "pt (slope n/a)" in svg and "slope -" not in svg


def test_the_winner_tied_with_an_expected_method_says_so(tmp_path: Path) -> None:
    from compare.report.build import _about_scene

    scene_file = tmp_path / "scene.yaml"
    scene_file.write_text("expected_winners: [pt]\n")
    summary = _summary([("lt", 1.0, 0.1, 2), ("pt", 1.02, 0.1, 2), ("pm", 9.0, 0.1, 2)])
    text = _about_scene(str(scene_file), "s", summary, "relmse", ["lt", "pt", "pm"], {})
    assert "lt (not among the expected, but tied with pt, which is)" in text
    assert "; tied with" not in text  # the tie is said once


def test_a_budget_every_method_overran_has_no_winner(report: Path, tmp_path: Path) -> None:
    """When every cell of a budget overran it, the winners table says none won there, and
    the scene page says so beside the winner at the largest budget that has one; a budget
    with no value at all (every cell NaN) stays blank instead."""
    from compare.report.build import _about_scene

    scene_file = tmp_path / "scene.yaml"
    scene_file.write_text("expected_winners: [pt]\n")
    summary = pd.concat(
        [_summary([("lt", 1.0, 0.1, 2), ("pt", 0.5, 0.1, 2)])] * 2, ignore_index=True
    )
    summary["budget"] = [1.0, 1.0, 2.0, 2.0]
    summary["render_seconds_mean"] = [1.0, 1.0, 2.5, 2.5]
    text = _about_scene(str(scene_file), "s", summary, "relmse", ["lt", "pt"], {})
    won = re.search(r"<b>Won</b> at ([^:]+):", text)
    assert won and won[1] == T.budget_label(1.0), text
    assert f"At {T.budget_label(2.0)} no method stayed within its budget: none won." in text
    summary["render_seconds_mean"] = [2.0, 2.0, 2.5, 2.5]
    text = _about_scene(str(scene_file), "s", summary, "relmse", ["lt", "pt"], {})
    assert "<b>Won</b>" not in text and "No method stayed within any budget: none won." in text
    summary["render_seconds_mean"] = [1.0, 1.0, 2.0, 2.0]
    assert "none won" not in _about_scene(str(scene_file), "s", summary, "relmse", ["pt"], {})
    summary.loc[summary.budget == 2.0, "relmse_mean"] = np.nan  # no value at 2 s: nothing to say
    summary.loc[summary.budget == 2.0, "render_seconds_mean"] = 2.5
    assert "none won" not in _about_scene(str(scene_file), "s", summary, "relmse", ["pt"], {})

    tables = tmp_path / "tables"
    tables.mkdir()
    for csv in (report / "tables").glob("*.csv"):
        (tables / csv.name).write_bytes(csv.read_bytes())
    summary = pd.read_csv(tables / "summary.csv")
    largest = summary.budget == summary.budget.max()
    spec = {
        "reports": str(tmp_path / "out"), "tables": str(tables), "metric": "relmse",
        "baseline": "pt", "factor": 10, "title": "t", "study": "t", "methods": ["pt", "lt"],
        "scenes": ["toy"], "refs": {"toy": str(report.parent / "ref.json")},
    }  # fmt: skip

    def winners() -> str:
        build_index(spec)
        index = (tmp_path / "out" / "index.html").read_text()
        return index[index.index("Best method per scene") : index.index("Overview:")]

    assert "none within budget" not in winners()
    summary.loc[largest, "render_seconds_mean"] = 2 * summary.loc[largest, "budget"]
    summary.to_csv(tables / "summary.csv", index=False)
    assert winners().count("none within budget") == 1
    summary.loc[largest, "relmse_mean"] = np.nan
    summary.to_csv(tables / "summary.csv", index=False)
    assert "none within budget" not in winners()


def test_index_says_what_the_methods_are_and_flags_a_target_near_the_reference(
    report: Path, tmp_path: Path
) -> None:
    """The index names each method by `pgi methods`' description; with mitsuba in the study
    it says the reference is Mitsuba's too. A time-to-error target taken from a flagged
    cell carries the flag."""
    from compare.report.build import _methods_note

    note = _methods_note(["pt", "pt-ratio", "mitsuba"], {"pt-ratio": "pt"})
    assert note.count("<b>pt</b>: volumetric path tracing") == 1 and "pt-ratio" not in note
    assert "<b>mitsuba</b>: Mitsuba 3 volpath" in note and "against the pgi methods" in note
    assert "grey render per channel" in note and "Mitsuba's too" not in _methods_note(["pt"], {})
    tables = tmp_path / "tables"
    tables.mkdir()
    for csv in (report / "tables").glob("*.csv"):
        (tables / csv.name).write_bytes(csv.read_bytes())
    summary = pd.read_csv(tables / "summary.csv")
    spec = {
        "reports": str(tmp_path / "out"), "tables": str(tables), "metric": "relmse",
        "baseline": "pt", "factor": 10, "title": "t", "study": "t", "methods": ["pt", "lt"],
        "scenes": ["toy"], "refs": {"toy": str(report.parent / "ref.json")},
    }  # fmt: skip
    flag = '<th class="scene">toy <span class="flag" title="the target is a flagged cell'
    for flagged in (False, True):
        last = (summary.method == "pt") & (summary.budget == summary.budget.max())
        summary.loc[last, "determined"] = not flagged
        summary.to_csv(tables / "summary.csv", index=False)
        build_index(spec)
        index = (tmp_path / "out" / "index.html").read_text()
        assert "<b>lt</b>: light tracing" in index
        assert (flag in index) == flagged


def test_a_cell_that_overran_its_budget_wins_nothing() -> None:
    """lt's first iteration always runs whole: at a 0.25-s budget it took 0.84 s and, with
    that extra time, had the lowest error. It is not an equal-time result, so it is neither
    best nor tied; a cell that stopped short of its budget may still win."""
    summary = _summary([("lt", 0.01, 0.001, 2), ("pt", 0.02, 0.002, 2), ("pm", 0.0101, 0.001, 2)])
    summary["budget"] = 0.25
    summary["render_seconds_mean"] = [0.84, 0.26, 0.84]
    best = T.best_methods(summary, "relmse")
    assert best.method.tolist() == ["pt"] and best.tied_with.tolist() == [""]
    marked = {r["method"] for r in T.overview_cells(summary, "relmse") if r["cells"][0.25]["best"]}
    assert marked == {"pt"}
    summary["render_seconds_mean"] = [0.84, 0.1, 0.84]  # short of the budget: still ranked
    assert T.best_methods(summary, "relmse").method.tolist() == ["pt"]
    summary["render_seconds_mean"] = 0.84  # all overran: no winner
    assert T.best_methods(summary, "relmse").empty


# --------------------------------------------------------------- verdicts on corrected errors


def _corrected_summary(rows: list[tuple[str, float, float, int, float, float]]) -> pd.DataFrame:
    """Cells of one scene and budget: (method, corrected mean, seed std, seeds, reference
    uncertainty of the mean, its shared part)."""
    return pd.DataFrame(
        [
            {"scene": "s", "budget": 1.0, "method": m, "relmse_mean": mean + 2e-3,
             "relmse_std": std, "relmse_corrected_mean": mean, "relmse_corrected_std": std,
             "relmse_u": u, "relmse_u_shared": shared, "n_seeds": n,
             "render_seconds_mean": 1.0, "determined": True}
            for m, mean, std, n, u, shared in rows
        ]
    )  # fmt: skip


def test_the_references_uncertainty_ties_methods_it_cannot_tell_apart() -> None:
    """pm and sppm 30 % apart, seed spreads of 2-3 %: the seeds tell them apart. Give each
    corrected mean a reference uncertainty of 20 % and they tie, and the tie is the
    reference's: the report says so rather than naming a winner. The part shared by both
    moves them alike: it hardly widens the ratio, and cancels in a difference."""
    apart = _corrected_summary(
        [("pm", 1.0e-3, 2e-5, 3, 1e-5, 5e-6), ("sppm", 1.3e-3, 3e-5, 3, 1e-5, 5e-6)]
    )
    best = T.best_methods(apart, "relmse")
    assert best.method.tolist() == ["pm"] and best.tied_with.tolist() == [""]
    uncertain = _corrected_summary(
        [("pm", 1.0e-3, 2e-5, 3, 2e-4, 1e-5), ("sppm", 1.3e-3, 3e-5, 3, 2.6e-4, 1e-5)]
    )
    best = T.best_methods(uncertain, "relmse")
    assert best.tied_with.tolist() == ["sppm"] and best.reference_ties.tolist() == ["sppm"]
    # the same uncertainty shared by both: the ratio barely moves, no tie
    assert not T.tied(1.0e-3, 2e-5, 3, 1.3e-3, 3e-5, 3, a_u=0, b_u=0, shared_u=2e-4)
    assert T.tied(1.0e-3, 2e-5, 3, 1.3e-3, 3e-5, 3, a_u=2e-4, b_u=2.6e-4, shared_u=0)
    # errors at or below what the reference resolves are compared by their difference, where
    # the shared part cancels and each one's own part counts
    assert T.tied(-1e-4, 1e-5, 3, 5e-5, 1e-5, 3, a_u=1e-4, b_u=1e-4, shared_u=1e-3)
    assert not T.tied(-1e-4, 1e-5, 3, 1e-3, 1e-5, 3, a_u=1e-4, b_u=1e-4, shared_u=1e-3)
    # with one seed a side the seeds say nothing, the reference's uncertainty still does
    assert T.tied(1.0e-3, math.nan, 1, 1.3e-3, math.nan, 1, a_u=2e-4, b_u=2.6e-4)
    assert not T.tied(1.0e-3, math.nan, 1, 1.3e-3, math.nan, 1)
    cells = T.overview_cells(uncertain, "relmse")
    assert all(c["cells"][1.0]["best"] for c in cells)  # both bold: a tie
    assert cells[0]["cells"][1.0]["detail"] == "ref. ±2.0e-04 · measured 0.003"


def _images_of(truth: np.ndarray, sd: float, rng: np.random.Generator) -> np.ndarray:
    return truth * (1 + sd * rng.standard_normal(truth.shape[:2] + (1,)))


@pytest.mark.parametrize("reference_noise", [0.005, 0.5], ids=["fine", "coarse"])
def test_a_winner_is_named_only_where_the_reference_can_rank_the_methods(
    tmp_path: Path, reference_noise: float
) -> None:
    """Synthetic renders of a known truth, end to end through compare_run and the tables:
    "a" (noise 5 %) against "b" (6 %, 1.44x a's error), three seeds each. A fine reference
    names a the winner; with a coarse one (its own error 50x the methods') the cells are not
    determined, and the reference's uncertainty, not the seeds, ties b with a, which the
    index says instead of naming a winner."""
    rng = np.random.default_rng(9)
    truth = np.exp(rng.uniform(-2, 1, (32, 32, 1))) * np.array([1.0, 0.8, 0.6])
    ref = tmp_path / "reference"
    for h in (0, 1):
        write_exr(ref / f"half{h}.exr", _images_of(truth, reference_noise, rng))
    merge_reference(ref / "half0.exr", ref / "half1.exr", ref / "ref.exr", ref / "ref.json")
    csvs = []
    for method, sd in (("a", 0.05), ("b", 0.06)):
        for seed in (1, 2, 3):
            snap = tmp_path / method / f"s{seed}" / "run.t1.exr"
            write_exr(snap, _images_of(truth, sd, rng))
            write_json(snap.with_suffix(".json"), {"render_seconds": 1.0, "threads": 2})
            csvs.append(tmp_path / f"{method}{seed}.csv")
            compare_run([snap], [1.0], ref / "ref.exr", ref / "ref.json", csvs[-1],
                        scene="toy", method=method, seed=seed, threads=2)  # fmt: skip
    tabs = T.write_tables(T.load_runs(csvs), tmp_path / "tables", methods=["a", "b"])
    best = tabs["best"].iloc[0]
    fine = reference_noise < 0.1
    assert tabs["summary"].determined.all() == fine and tabs["summary"].determined.any() == fine
    if fine:
        assert best.method == "a" and best.tied_with == "" and best.reference_ties == ""
    else:  # either may have the lower mean; the other is tied with it, by the reference
        other = {"a": "b", "b": "a"}[best.method]
        assert best.tied_with == other and best.reference_ties == other
    build_index(
        {
            "reports": str(tmp_path / "out"), "tables": str(tmp_path / "tables"),
            "metric": "relmse", "baseline": "a", "title": "t", "study": "t",
            "methods": ["a", "b"], "scenes": ["toy"], "refs": {"toy": str(ref / "ref.json")},
        }
    )  # fmt: skip
    index = (tmp_path / "out" / "index.html").read_text()
    winners = index[index.index("Best method per scene") : index.index("Overview:")]
    assert ("undecided: " in winners) != fine and ("<td>a (" in winners) == fine


# ------------------------------------------------------------------- references sized to a study


def _sizing_case(rng: np.random.Generator, pilot_sd: float, bias: float = 1.0):
    """A truth, a pilot (two halves of noise ``pilot_sd`` per value, their variances known),
    and three seeds of two methods at the largest budget: "good" (noise 4 %, times ``bias``)
    and "poor" (noise 10 %)."""
    truth = np.exp(rng.uniform(-2, 1, (64, 64, 1))) * np.array([1.0, 0.8, 0.6])
    pilot = [_images_of(truth, pilot_sd, rng) for _ in range(2)]
    variances = [(pilot_sd * truth) ** 2] * 2
    images = {
        "good": [bias * _images_of(truth, 0.04, rng) for _ in range(3)],
        "poor": [_images_of(truth, 0.10, rng) for _ in range(3)],
    }
    return truth, pilot, variances, images


def test_a_reference_is_sized_to_a_fraction_of_the_best_methods_error() -> None:
    """The plan bounds the best method's error from below (from its seeds, or its error with
    the pilot's removed), and asks for the samples that bring the reference's error to the
    target fraction of it: the pilot's error falls as 1/spp. A biased best method's seeds
    see its noise only, and its bound stays below its true error."""
    from compare.metrics import relmse_map
    from compare.sizing import plan_reference

    rng = np.random.default_rng(21)
    truth, pilot, variances, images = _sizing_case(rng, pilot_sd=0.3)
    plan = plan_reference(images, pilot, variances, pilot_spp=16, seconds_per_spp=0.01,
                          target=0.5, max_seconds=1000)  # fmt: skip
    true_error = np.mean([relmse_map(x, truth).mean() for x in images["good"]])
    assert plan["best_method"] == "good" and not plan["cap_bound"]
    assert plan["best_error_bound"] == pytest.approx(true_error, rel=0.1)
    pilot_error = float((0.3**2 / 2 * truth**2 / (truth**2 + 0.01)).mean())  # (vA+vB)/4
    assert plan["pilot_relmse"] == pytest.approx(pilot_error, rel=0.1)
    assert (
        plan["spp"]
        == plan["spp_needed"]
        == math.ceil(16 * plan["pilot_relmse"] / (0.5 * plan["best_error_bound"]))
    )
    assert plan["expected_relmse"] == pytest.approx(0.5 * plan["best_error_bound"], rel=0.01)
    assert plan["expected_seconds"] == pytest.approx(2 * plan["spp"] * 0.01)
    _, pilot, variances, images = _sizing_case(np.random.default_rng(21), 0.3, bias=0.9)
    biased = plan_reference(images, pilot, variances, pilot_spp=16, seconds_per_spp=0.01,
                            target=0.5, max_seconds=1000)  # fmt: skip
    true_biased = np.mean([relmse_map(x, truth).mean() for x in images["good"]])
    good = biased["methods"]["good"]
    assert good["from_seeds"] < 0.2 * true_biased  # the seeds see the noise only
    assert good["from_seeds"] <= biased["best_error_bound"] < true_biased


def test_the_cap_bounds_a_reference_and_a_pilot_is_never_undone() -> None:
    from compare.sizing import fixed_plan, plan_reference

    _, pilot, variances, images = _sizing_case(np.random.default_rng(22), pilot_sd=0.3)
    kw = dict(pilot_spp=16, seconds_per_spp=0.01, target=0.5)
    capped = plan_reference(images, pilot, variances, max_seconds=2.0, **kw)
    assert capped["cap_bound"] and capped["spp"] == capped["spp_cap"] == 100
    assert capped["spp_needed"] > 100 and capped["expected_seconds"] == pytest.approx(2.0)
    tiny = plan_reference(images, pilot, variances, max_seconds=0.1, **kw)
    assert tiny["cap_bound"] and tiny["spp"] == 16  # what the pilot rendered is kept
    loose = plan_reference(images, pilot, variances, max_seconds=1000, **{**kw, "target": 1e3})
    assert not loose["cap_bound"] and loose["spp"] == 16  # the pilot is already enough
    assert fixed_plan(256) == {"version": 1, "source": "mitsuba", "how": "fixed", "spp": 256}
