"""End-to-end tests of the Snakemake workflow.

The main study runs against tests/fake_pgi.py (a stand-in with the renderer's CLI and file
contract, no rendering) so it takes seconds; `test_real_renderer_tiny` runs configs/tiny.yaml
with the real `pgi` when its reference renderer is available.
"""

from __future__ import annotations

import html
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
SNAKEFILE = ROOT / "Snakefile"
FAKE = Path(__file__).with_name("fake_pgi.py")

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("snakemake") is None, reason="snakemake not installed"
)


def snakemake(workdir: Path, *args: str, env: dict | None = None, check: bool = True):
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), e.get("PYTHONPATH", "")])
    e.update(env or {})
    cmd = [sys.executable, "-m", "snakemake", "-s", str(SNAKEFILE), "--cores", "2", *args]
    p = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True, env=e, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError(f"snakemake failed ({p.returncode}):\n{p.stdout}\n{p.stderr}")
    return p


def job_counts(output: str) -> dict[str, int]:
    """Parse the 'Job stats' table of a dry run."""
    counts = {}
    m = re.search(r"Job stats:\n.*?\n-+\s+-+\n(.*?)\ntotal", output, re.S)
    if not m:
        return counts
    for line in m.group(1).splitlines():
        parts = line.split()
        if len(parts) == 2:
            counts[parts[0]] = int(parts[1])
    return counts


def write_config(path: Path, scenes_dir: Path, **over) -> Path:
    cfg = {
        "name": "fake",
        "scenes_dir": str(scenes_dir),
        "results_dir": "results",
        "reports_dir": "reports",
        "pgi": f"{sys.executable} {FAKE}",
        "threads": 2,
        "scenes": ["alpha"],
        "methods": ["pt", "lt"],
        "budgets": [0.5, 1, 2],
        "seeds": [1, 2],
        "reference": {"spp": 256},
    }
    cfg.update(over)
    path.write_text(yaml.safe_dump(cfg))
    return path


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    wd = tmp_path_factory.mktemp("study")
    for s in ("alpha", "beta"):
        (wd / "scenes" / s).mkdir(parents=True)
        (wd / "scenes" / s / "scene.yaml").write_text(f"# fake scene {s}\n")
    # alpha reads an included file from another folder and an asset named there
    (wd / "scenes" / "shared").mkdir()
    (wd / "scenes" / "shared" / "box.yaml").write_text("shapes: [{type: mesh, file: box.ply}]\n")
    (wd / "scenes" / "shared" / "box.ply").write_text("fake mesh\n")
    (wd / "scenes" / "alpha" / "scene.yaml").write_text("include: ../shared/box.yaml\n")
    write_config(wd / "cfg.yaml", wd / "scenes")
    snakemake(wd, "--configfile", "cfg.yaml", env={"FAKE_PGI_METHODS": "pt,lt,sppm"})
    return wd


def test_outputs(study: Path) -> None:
    rep = study / "reports"
    for f in ("index.html", "scene-alpha.html", "data/alpha.js", "tables/summary.csv"):
        assert (rep / f).is_file(), f
    runs = pd.read_csv(rep / "tables" / "runs.csv")
    assert len(runs) == 1 * 2 * 2 * 3  # scenes x methods x seeds x budgets
    assert set(runs.method) == {"pt", "lt"}
    assert runs.render_seconds.gt(0).all() and runs.relmse.gt(0).all()
    # every MSE-type error also with the reference's own removed, and its uncertainty
    for m in ("mse", "rmse", "relmse", "relmse_trimmed"):
        assert runs[f"{m}_corrected"].notna().all() and runs[f"{m}_u"].gt(0).all(), m
    summary = pd.read_csv(rep / "tables" / "summary.csv")
    assert summary.determined.all()  # the fake reference is far finer than the fake methods
    assert runs.wall_seconds.notna().all() and runs.max_rss_mb.notna().all()
    # errors fall with time for every run
    for _, d in runs.groupby(["method", "seed"]):
        assert d.sort_values("budget").relmse.is_monotonic_decreasing
    conv = pd.read_csv(rep / "tables" / "convergence.csv")
    slope = conv[(conv.metric == "relmse")].slope
    assert slope.between(-1.2, -0.8).all()  # the fake renderer's noise falls as 1/t
    tte = pd.read_csv(rep / "tables" / "time_to_error.csv")
    assert tte.set_index("method").loc["pt", "speedup_vs_pt"] == pytest.approx(1.0)
    assert (study / "results" / "reference" / "alpha" / "ref.json").is_file()
    assert "alpha" in (rep / "tables" / "overview.md").read_text()


def test_rerun_does_nothing(study: Path) -> None:
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
    dry = snakemake(study, "--configfile", "cfg.yaml", "-n", env=env)
    assert "Nothing to be done" in dry.stdout + dry.stderr
    outputs = sorted(p for p in study.rglob("*") if p.is_file() and ".snakemake" not in p.parts)
    before = {p: p.stat().st_mtime_ns for p in outputs}
    run = snakemake(study, "--configfile", "cfg.yaml", env=env)
    assert "Nothing to be done" in run.stdout + run.stderr
    assert {p: p.stat().st_mtime_ns for p in outputs} == before  # nothing rewritten


def test_every_table_is_an_output_a_lost_one_is_made_again(study: Path) -> None:
    """tables.md, overview.html and best.csv were written but not declared: deleted, no rule
    made them again (found by a review). Declared, each is a target that reruns the tables
    (Snakemake leaves a lost intermediate file alone while what was made from it is up to
    date, so a plain run does not)."""
    tables = study / "reports" / "tables"
    kept = study / "kept"
    kept.mkdir()
    names = ["tables.md", "overview.html", "best.csv"]
    for name in names:
        shutil.move(tables / name, kept / name)
    try:
        lost = [f"reports/tables/{name}" for name in names]
        env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
        dry = snakemake(study, "--configfile", "cfg.yaml", "-n", *lost, env=env)
        assert re.search(r"^tables\s+1$", dry.stdout, re.M), dry.stdout
    finally:
        for name in names:
            shutil.move(kept / name, tables / name)  # as they were: the next test reruns nothing
        kept.rmdir()


def test_files_a_scene_reads_are_its_inputs(study: Path) -> None:
    """Editing what an included file says, or an asset it names, reruns that scene's renders
    and references (here alpha: 2 methods x 2 seeds, 2 halves); a comment or a new
    description reruns only the scene's report page; rewriting a file unchanged (a newer
    time, the same content) reruns nothing."""
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
    edits = [
        ("shared/box.yaml", "integrator: {max_depth: 3}\n", 4, 2, 1),
        ("shared/box.ply", "# edited\n", 4, 2, 1),
        ("shared/box.yaml", "# a comment\n", 0, 0, 1),
        ("alpha/scene.yaml", "description: a new text for the report\n", 0, 0, 1),
        ("alpha/scene.yaml", "", 0, 0, 0),
    ]
    for name, added, renders, halves, pages in edits:
        f = study / "scenes" / name
        before, text = f.stat(), f.read_text()
        try:
            f.write_text(text + added)
            c = job_counts(snakemake(study, "--configfile", "cfg.yaml", "-n", env=env).stdout)
            assert c.get("render", 0) == renders and c.get("reference_half", 0) == halves, (
                name,
                added,
                c,
            )
            assert c.get("report_scene", 0) == pages, (name, added, c)
        finally:
            f.write_text(text)
            os.utime(f, ns=(before.st_atime_ns, before.st_mtime_ns))
    dry = snakemake(study, "--configfile", "cfg.yaml", "-n", env=env)
    assert "Nothing to be done" in dry.stdout + dry.stderr


def test_renderer_code_changes_rerun_what_they_affect(study: Path) -> None:
    """`pgi fingerprint` changes: new render code reruns every render (2 methods x 2 seeds)
    and pgi's pt check of the reference (2 halves), whose plan then reruns the halves (a
    Mitsuba half finds its passes in its store: nothing is rendered again); new reference
    code reruns the references (2 halves), not the check and no render."""
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
    cases = [
        ({"FAKE_PGI_RENDER_CODE": "r1"}, 4, 2, 2),
        ({"FAKE_PGI_REFERENCE_CODE": "f1"}, 0, 0, 2),
    ]
    for changed, renders, checks, halves in cases:
        c = job_counts(
            snakemake(study, "--configfile", "cfg.yaml", "-n", env={**env, **changed}).stdout
        )
        counts = (c.get("render", 0), c.get("reference_check", 0), c.get("reference_half", 0))
        assert counts == (renders, checks, halves), (changed, c)


def test_a_timed_render_runs_alone_on_more_cores(study: Path) -> None:
    """Given more cores than the config's threads, a timed render claims them all (nothing runs
    beside it), references keep their own count, and pgi still gets the config's threads."""
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
    args = ["--configfile", "cfg.yaml", "-n", "--forceall", "--printshellcmds", "--cores", "6"]
    out = snakemake(study, *args, env=env).stdout
    threads = {
        rule: set(re.findall(r"threads: (\d+)", body))
        for rule, body in re.findall(r"rule (\w+):\n(.*?)(?:\n\n|\Z)", out, re.S)
        if rule in ("render", "reference_half")
    }
    assert threads == {"render": {"6"}, "reference_half": {"2"}}, threads
    assert "--threads 2 " in out and "--threads 6" not in out


def test_more_threads_than_cores_stops_before_any_job(study: Path) -> None:
    too_many = (os.cpu_count() or 1) + 1
    write_config(study / "greedy.yaml", study / "scenes", threads=too_many)
    p = snakemake(study, "--configfile", "greedy.yaml", "-n", check=False)
    assert p.returncode != 0
    assert f"threads: {too_many} is more than this machine's" in p.stdout + p.stderr


def _job_inputs(study: Path) -> list[tuple[str, str]]:
    """(rule, its job's text in a verbose forced dry run) for every job of the fake study."""
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
    args = ["--configfile", "cfg.yaml", "-n", "--forceall", "--printshellcmds"]
    out = snakemake(study, *args, "--verbose", env=env).stdout
    jobs = re.findall(r"rule (\w+):\n(.*?)(?:\n\n|\Z)", out, re.S)
    assert jobs
    return jobs


def test_analysis_code_is_an_input_of_the_analysis(study: Path) -> None:
    """Each analysis step lists the comparison code it runs among its inputs, so editing it
    reruns that step and what follows (renders do not depend on it): the metrics rerun
    comparisons, reference merges (the reference's own error), tables and pages; the tables'
    code the tables and pages; the report's code the pages alone."""
    runs = {
        "src/compare/metrics.py": {
            "compare",
            "reference",
            "reference_plan",
            "tables",
            "report_scene",
            "report_index",
        },
        "src/compare/sizing.py": {"reference_plan", "report_scene", "report_index"},
        "src/compare/tables.py": {"tables", "report_scene", "report_index"},
        "src/compare/report/build.py": {"report_scene", "report_index"},
        "src/compare/report/assets/viewer.js": {"report_scene", "report_index"},
    }
    for rule, body in _job_inputs(study):
        for code, rules in runs.items():
            assert (code in body) == (rule in rules), (rule, code)


def test_analysis_steps_import_only_the_code_they_list(study: Path) -> None:
    """The code a step lists is what its job imports: each analysis job is rerun with Python
    reporting its imports (into the job's log), and every `compare` module imported must be
    among that job's inputs; else an edit of it would not rerun the step."""
    inputs: dict[str, set[str]] = {}
    for rule, body in _job_inputs(study):
        found = re.search(r"input: (.*)", body)
        inputs.setdefault(rule, set()).update(found[1].split(", ") if found else ())
    analysis = ["compare", "reference", "reference_plan", "tables", "report_scene", "report_index"]
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm", "PYTHONPROFILEIMPORTTIME": "1"}
    snakemake(study, "--configfile", "cfg.yaml", "--forcerun", *analysis, env=env)
    logs = {
        "compare": study.glob("results/logs/compare/*/*/*.log"),
        "reference": study.glob("results/logs/reference/*/merge.log"),
        "reference_plan": study.glob("results/logs/reference/*/plan.log"),
        "tables": [study / "results" / "logs" / "tables.log"],
        "report_scene": study.glob("results/logs/report/*.log"),
    }
    for rule, files in logs.items():
        files = list(files)
        assert files, rule
        for log in files:
            modules = re.findall(
                r"import time:.*\|\s+(compare(?:\.\w+)*)\s*$", log.read_text(), re.M
            )
            assert "compare" in modules, (rule, log)  # compare.steps runs as __main__
            for module in modules:
                path = "src/" + module.replace(".", "/")
                files = (f"{path}.py", f"{path}/__init__.py")
                assert any(i.endswith(files) for i in inputs[rule]), (rule, module)


def test_new_method_and_scene_render_only_what_is_new(study: Path) -> None:
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
    write_config(study / "more.yaml", study / "scenes", methods=["pt", "lt", "sppm"])
    c = job_counts(snakemake(study, "--configfile", "more.yaml", "-n", env=env).stdout)
    assert c.get("render") == 2 and c.get("compare") == 2  # one method x 2 seeds
    assert "reference_half" not in c
    write_config(study / "more.yaml", study / "scenes", scenes=["alpha", "beta"])
    c = job_counts(snakemake(study, "--configfile", "more.yaml", "-n", env=env).stdout)
    assert c.get("render") == 4 and c.get("reference_half") == 2  # one scene x 2 x 2


def test_methods_all_picks_up_new_methods(study: Path) -> None:
    write_config(study / "all.yaml", study / "scenes", methods="all")
    c = job_counts(
        snakemake(
            study, "--configfile", "all.yaml", "-n", env={"FAKE_PGI_METHODS": "pt,lt,sppm,vrl"}
        ).stdout
    )
    assert c.get("render") == 4  # sppm and vrl, 2 seeds each


def test_bad_config_fails_clearly(study: Path) -> None:
    """One line naming the config file and the key: not the schema (an unknown key printed
    303 lines of it), not a traceback."""
    for over, line in [
        ({"budgets": [1, -2]}, "budgets[1]: -2 is less than or equal to the minimum of 0"),
        ({"budget": [1]}, "top level: Additional properties are not allowed ('budget' was"),
        ({"scenes": []}, "scenes: [] should be non-empty"),
        ({"methods": ["pt", "nosuch"]}, "methods: unknown method(s) nosuch"),
        ({"methods": "pt"}, "methods: 'pt' is not one of ['all'] (methods may also be a list)"),
    ]:
        write_config(study / "bad.yaml", study / "scenes", **over)
        p = snakemake(study, "--configfile", "bad.yaml", "-n", check=False)
        out = (p.stdout + p.stderr).strip().splitlines()
        assert p.returncode != 0 and len(out) == 1, out
        assert out[0].startswith("config (") and "bad.yaml): " + line in out[0], out
    # A key given by --config is in no file: the line says where it came from.
    write_config(study / "bad.yaml", study / "scenes")
    p = snakemake(study, "--configfile", "bad.yaml", "--config", "threads=0", "-n", check=False)
    line = "bad.yaml and --config): threads: 0 is less than the minimum of 1"
    assert p.returncode != 0 and line in p.stdout + p.stderr, p.stdout + p.stderr


def test_config_numbers_as_text_and_repeated_keys_are_explained(study: Path) -> None:
    """The workflow reads configs as YAML 1.1: 5e-1 and 1.0e3 arrive as text, which scene files
    read as numbers, and a key written twice keeps its last value silently. Both stop the plan
    with a line that says so (found by a review)."""
    path = write_config(study / "bad.yaml", study / "scenes", budgets=[0.5, 1])
    text = path.read_text()
    for edited, line in [
        (text.replace("- 0.5", "- 5e-1"), "budgets[0]: '5e-1' is not of type 'number' (the "
         "workflow reads configs as YAML 1.1, where 5e-1 is text, not a number: write 0.5)"),
        (text.replace("spp: 256", "spp: 1.0e3"), "write 1000)"),
        (text + "methods: [pt]\n", "bad.yaml:"),
    ]:  # fmt: skip
        path.write_text(edited)
        p = snakemake(study, "--configfile", "bad.yaml", "-n", check=False)
        out = (p.stdout + p.stderr).strip().splitlines()
        assert p.returncode != 0 and len(out) == 1 and line in out[0], out
    assert "duplicate key 'methods'" in out[0]


def test_the_default_config_is_read_strictly_too(tmp_path: Path) -> None:
    """With no --configfile the Snakefile reads configs/default.yaml; that file gets the same
    strict reading as a config given (found by a review: a repeated key passed unseen)."""
    shutil.copy(SNAKEFILE, tmp_path / "Snakefile")
    shutil.copytree(ROOT / "workflow", tmp_path / "workflow")
    shutil.copytree(ROOT / "configs", tmp_path / "configs")
    (tmp_path / "src").symlink_to(ROOT / "src")  # the packages it imports are this checkout's
    default = tmp_path / "configs" / "default.yaml"
    default.write_text(default.read_text() + "seeds: [1]\n")
    cmd = [sys.executable, "-m", "snakemake", "-s", str(tmp_path / "Snakefile"), "-n", "-c1"]
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    p = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600)
    out = (p.stdout + p.stderr).strip().splitlines()
    assert p.returncode != 0 and len(out) == 1 and "duplicate key 'seeds'" in out[0], out


@pytest.mark.parametrize(
    "over,key",
    [
        ({"budgets": [1, float("inf")]}, "budgets"),
        ({"seeds": [1, 2**64]}, "seeds"),
        ({"reference": {"spp": 16, "seed": 2**63 - 1}}, "reference.seed"),
    ],
    ids=["infinite-budget", "seed-too-large", "reference-seed-too-large"],
)
def test_plan_rejects_values_pgi_would_refuse(study: Path, over: dict, key: str) -> None:
    write_config(study / "bad.yaml", study / "scenes", **over)
    p = snakemake(study, "--configfile", "bad.yaml", "-n", check=False)
    out = p.stdout + p.stderr
    assert p.returncode != 0 and f"bad.yaml): {key}: expected" in out, out


def test_own_config_takes_schema_defaults_not_the_default_study(study: Path) -> None:
    """Keys a config leaves out get the schema's defaults; configs/default.yaml (its results
    folder, its film-size overrides) applies only when no config is given."""
    cfg = {
        "scenes_dir": str(study / "scenes"),
        "pgi": f"{sys.executable} {FAKE}",
        "scenes": ["beta"],
        "methods": ["pt"],
        "budgets": [1],
        "seeds": [1],
    }
    (study / "min.yaml").write_text(yaml.safe_dump(cfg))
    # As in a checkout: the default study's config where the Snakefile looks for it.
    (study / "configs").mkdir()
    shutil.copy(ROOT / "configs" / "default.yaml", study / "configs" / "default.yaml")
    try:
        args = ["--configfile", "min.yaml", "-n", "--forceall", "--printshellcmds"]
        out = snakemake(study, *args, env={"FAKE_PGI_METHODS": "pt"}).stdout
    finally:
        shutil.rmtree(study / "configs")
    assert "results/reference/beta/half0.exr" in out and "reports/index.html" in out
    assert "results/default" not in out and "film.width" not in out


def test_slurm_profile_dry_run_parses(study: Path) -> None:
    profile = ROOT / "configs" / "profiles" / "slurm"
    args = ["--configfile", "cfg.yaml", "--profile", str(profile), "-n", "--forceall"]
    if importlib.util.find_spec("snakemake_executor_plugin_slurm") is None:
        args += ["--executor", "local"]  # profile still parsed; the plugin is not installed
    p = snakemake(study, *args, env={"FAKE_PGI_METHODS": "pt,lt,sppm"})
    c = job_counts(p.stdout)
    assert c.get("render") == 4


def test_variant_renders_with_its_own_settings(study: Path) -> None:
    """A variant renders its own method with its own overrides, under its own label, against
    the scene's one reference; the report says what it is."""
    variant = {"pt-delta": {"method": "pt", "set": ["integrator.estimator=delta"]}}
    write_config(
        study / "var.yaml",
        study / "scenes",
        results_dir="results",
        reports_dir="reports-var",
        variants=variant,
    )
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
    c = job_counts(snakemake(study, "--configfile", "var.yaml", "-n", env=env).stdout)
    assert c.get("render") == 2 and "reference_half" not in c  # the variant's two seeds only
    snakemake(study, "--configfile", "var.yaml", env=env)
    side = json.loads((study / "results/render/alpha/pt-delta/s1/run.t1.json").read_text())
    assert side["method"] == "pt" and side["overrides"] == ["integrator.estimator=delta"]
    plain = json.loads((study / "results/render/alpha/pt/s1/run.t1.json").read_text())
    assert plain["overrides"] == []
    runs = pd.read_csv(study / "reports-var" / "tables" / "runs.csv")
    assert set(runs.method) == {"pt", "lt", "pt-delta"}
    index = (study / "reports-var" / "index.html").read_text()
    assert "<b>pt-delta</b>: pt with integrator.estimator=delta" in index


def test_thread_mismatch_is_an_error(tmp_path: Path, study: Path) -> None:
    from compare.runs import compare_run

    snap = study / "results" / "render" / "alpha" / "pt" / "s1"
    ref = study / "results" / "reference" / "alpha"
    with pytest.raises(RuntimeError, match="rendered with 2 threads but the config asks for 4"):
        compare_run(
            [snap / "run.t1.exr"],
            [1.0],
            ref / "ref.exr",
            ref / "ref.json",
            tmp_path / "m.csv",
            scene="alpha",
            method="pt",
            seed=1,
            threads=4,
        )


def _real_renderer_ready() -> bool:
    pgi = shutil.which("pgi") or str(Path(sys.executable).with_name("pgi"))
    if not Path(pgi).exists():
        return False
    for mod in ("renderer.cli", "renderer.reference", "renderer.methods.mitsuba"):
        if importlib.util.find_spec(mod) is None:
            return False
    return True


@pytest.mark.skipif(not _real_renderer_ready(), reason="real pgi render/reference not available")
def test_real_renderer_tiny(tmp_path: Path) -> None:
    """configs/tiny.yaml with the real renderer and Mitsuba, end to end."""
    snakemake(
        tmp_path,
        "--configfile",
        str(ROOT / "configs" / "tiny.yaml"),
        "--config",
        f"scenes_dir={ROOT / 'scenes'}",
    )
    rep = tmp_path / "reports" / "tiny"
    runs = pd.read_csv(rep / "tables" / "runs.csv")
    assert len(runs) > 0 and (runs.render_seconds > 0).all()
    assert (rep / "index.html").is_file()
    assert runs.threads.eq(2).all()
    # the variant reached the real renderer with its own override
    assert set(runs.method) == {"pt", "mitsuba", "pt-rr1"}
    side = tmp_path / "results" / "tiny" / "render" / "cbox-fog" / "pt-rr1" / "s1" / "run.json"
    overrides = json.loads(side.read_text())["overrides"]
    assert overrides[-1] == "integrator.rr_depth=1" and "film.width=32" in overrides


# ----------------------------------------------------------------------- what the jobs are given
# Each of these caught a bug injected into a copy of the workflow that the tests above let pass.


def test_a_scenes_reference_spp_overrides_the_default(tmp_path: Path) -> None:
    from compare.plan import make_plan

    for s in ("cbox", "fog"):
        (tmp_path / s).mkdir()
        (tmp_path / s / "scene.yaml").write_text("# fake\n")
    cfg = {
        "scenes": ["cbox", {"name": "fog", "reference_spp": 8}], "scenes_dir": str(tmp_path),
        "methods": ["pt"], "budgets": [1], "seeds": [1], "reference": {"spp": 64}, "pgi": "echo",
    }  # fmt: skip
    plan = make_plan(cfg, tmp_path, check_methods=False, check_scenes=False)
    assert plan.scenes["cbox"].reference_spp == 64 and plan.scenes["fog"].reference_spp == 8


@pytest.fixture(scope="module")
def dry_run(tmp_path_factory: pytest.TempPathFactory) -> str:
    """The shell commands of a whole study, not run: seeds 3 and 7, a variant."""
    wd = tmp_path_factory.mktemp("dry")
    (wd / "scenes" / "alpha").mkdir(parents=True)
    (wd / "scenes" / "alpha" / "scene.yaml").write_text("# fake\n")
    write_config(
        wd / "cfg.yaml", wd / "scenes", seeds=[3, 7], reference={"spp": 16, "seed": 100},
        variants={"pt-delta": {"method": "pt", "set": ["integrator.estimator=delta"]}},
    )  # fmt: skip
    p = snakemake(
        wd, "--configfile", "cfg.yaml", "-n", "--forceall", "--printshellcmds",
        env={"FAKE_PGI_METHODS": "pt,lt"},
    )  # fmt: skip
    return p.stdout


def test_reference_halves_have_their_own_seeds(dry_run: str) -> None:
    """Each half, and each half of pt's check, renders with reference.seed + its index."""
    halves = re.findall(r"reference-args \S+ (\d)\) --seed (\d+)", dry_run)
    assert sorted(halves) == [("0", "100"), ("1", "101")]
    checks = re.findall(r" reference \S+ --spp 16 --seed (\d+) --source pgi", dry_run)
    assert sorted(checks) == ["100", "101"]


def test_runs_use_the_configured_seeds(dry_run: str) -> None:
    assert set(re.findall(r" render \S+ .*?--seed (\d+)", dry_run)) == {"3", "7"}


def test_scene_page_gets_each_variants_method_and_one_seeds_images(dry_run: str) -> None:
    spec = json.loads(re.search(r"compare.steps report-scene '(.*?)' >", dry_run).group(1))
    assert spec["bases"] == {"pt": "pt", "lt": "lt", "pt-delta": "pt"}
    assert spec["seed"] == 3
    assert all(f"/s{spec['seed']}/" in p for ps in spec["snapshots"].values() for p in ps)


def test_another_checkouts_installation_is_refused(tmp_path: Path) -> None:
    """A checkout whose environment imports another checkout's packages (an editable
    install's import hook comes before the Snakefile's src) stops with one line, naming both,
    before it runs any of the other checkout's code."""
    for part in ("Snakefile", "workflow", "configs", "scenes"):
        (tmp_path / part).symlink_to(ROOT / part)
    shutil.copytree(ROOT / "src", tmp_path / "src", ignore=shutil.ignore_patterns("__pycache__"))
    cmd = [sys.executable, "-m", "snakemake", "-s", str(tmp_path / "Snakefile"), "-n", "-c1"]
    env = {**os.environ, "PYTHONPATH": ""}
    p = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600)
    out = (p.stdout + p.stderr).strip().splitlines()
    assert p.returncode != 0 and len(out) == 1, out
    assert f"imports `compare` from {ROOT / 'src' / 'compare'}" in out[0], out
    assert str(tmp_path / "src") in out[0], out


@pytest.fixture(scope="module")
def sized_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The fake study with its reference sized to it ("auto"): a pilot, a plan, the halves."""
    wd = tmp_path_factory.mktemp("sized")
    (wd / "scenes" / "alpha").mkdir(parents=True)
    (wd / "scenes" / "alpha" / "scene.yaml").write_text("# fake scene alpha\n")
    reference = {"spp": "auto", "pilot_spp": 8, "target": 0.5, "max_seconds": 1.0}
    write_config(wd / "cfg.yaml", wd / "scenes", reference=reference)
    snakemake(wd, "--configfile", "cfg.yaml", env={"FAKE_PGI_METHODS": "pt,lt,sppm"})
    return wd


def test_a_sized_reference_follows_its_plan(sized_study: Path) -> None:
    """The plan bounds the best method's error at the largest budget from the pilot and the
    runs, and the halves render the samples it asks for (the fake renders 1 ms per spp, so
    the 1-second cap allows 500 a half); ref.json and the report carry the plan."""
    folder = sized_study / "results" / "reference" / "alpha"
    plan = json.loads((folder / "plan.json").read_text())
    assert plan["how"] == "sized" and plan["best_method"] == "pt" and plan["pilot_spp"] == 8
    assert plan["spp_cap"] == 500 and plan["spp"] == min(plan["spp_needed"], 500) > 8
    for h in (0, 1):
        assert json.loads((folder / f"half{h}.json").read_text())["spp"] == plan["spp"]
        assert json.loads((folder / f"pilot{h}.json").read_text())["spp"] == 8
    ref = json.loads((folder / "ref.json").read_text())
    assert ref["plan"] == plan and ref["variances"] is True
    assert ref["ref_relmse"] < plan["target"] * plan["best_error_bound"] * 1.5
    index = (sized_study / "reports" / "index.html").read_text()
    assert "<td>to the study</td>" in index and "cells determined" in index
    page = (sized_study / "reports" / "scene-alpha.html").read_text()
    assert "Sized from a pilot of 8 spp a half" in page


def test_a_new_method_resizes_the_reference_not_its_pilot(sized_study: Path) -> None:
    """The plan reads every method's runs: a method added reruns the plan and the halves
    (extending their stores), not the pilots; a new cap reruns the plan alone."""
    env = {"FAKE_PGI_METHODS": "pt,lt,sppm"}
    write_config(
        sized_study / "more.yaml",
        sized_study / "scenes",
        methods=["pt", "lt", "sppm"],
        reference={"spp": "auto", "pilot_spp": 8, "target": 0.5, "max_seconds": 1.0},
    )
    c = job_counts(snakemake(sized_study, "--configfile", "more.yaml", "-n", env=env).stdout)
    assert c.get("render") == 2 and c.get("reference_plan") == 1
    assert c.get("reference_half") == 2 and "reference_pilot" not in c
    write_config(
        sized_study / "cap.yaml",
        sized_study / "scenes",
        reference={"spp": "auto", "pilot_spp": 8, "target": 0.5, "max_seconds": 2.0},
    )
    c = job_counts(snakemake(sized_study, "--configfile", "cap.yaml", "-n", env=env).stdout)
    assert c.get("reference_plan") == 1 and "render" not in c and "reference_pilot" not in c


# ------------------------------------------------------------- can the reference be trusted?


@pytest.fixture(scope="module")
def trust_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The fake study on four scenes whose references meet each case of the check against pgi's
    pt: `sound` (Mitsuba's passes), `dense` (Mitsuba's is black: pgi's pt takes over),
    `dark` (black too, but its samples are fixed: nothing can take over) and `ours` (the
    config asks for pgi's pt)."""
    wd = tmp_path_factory.mktemp("trust")
    for s in ("sound", "dense", "dark", "ours"):
        (wd / "scenes" / s).mkdir(parents=True)
        (wd / "scenes" / s / "scene.yaml").write_text(f"# fake scene {s}\n")
    scenes = [
        "sound",
        "dense",
        {"name": "dark", "reference_spp": 64},
        {"name": "ours", "reference_source": "pgi"},
    ]
    reference = {"spp": "auto", "pilot_spp": 8, "check_spp": 8, "target": 0.5, "max_seconds": 1.0}
    write_config(
        wd / "cfg.yaml", wd / "scenes", scenes=scenes, budgets=[0.5, 1], reference=reference
    )
    env = {"FAKE_PGI_METHODS": "pt,lt", "FAKE_PGI_DEAD_SCENES": "dense,dark"}
    snakemake(wd, "--configfile", "cfg.yaml", env=env)
    return wd


def _reference_record(study: Path, scene: str, name: str) -> dict:
    return json.loads((study / "results" / "reference" / scene / name).read_text())


def test_a_sound_reference_passes_its_check_and_stays_mitsubas(trust_study: Path) -> None:
    plan = _reference_record(trust_study, "sound", "plan.json")
    assert plan["source"] == "mitsuba" and not plan["fallback"] and plan["trust"]["trustworthy"]
    ref = _reference_record(trust_study, "sound", "ref.json")
    assert ref["source"] == "mitsuba" and ref["trusted"] and ref["trust"]["trustworthy"]
    assert ref["trust"]["checked_against"] == "pgi's pt" and ref["trust"]["findings"] == []
    page = (trust_study / "reports" / "scene-sound.html").read_text()
    assert "Checked against pgi's pt (two halves of 8 spp)" in page
    assert "No trustworthy" not in page


def test_an_untrustworthy_mitsuba_reference_falls_back_to_pt(trust_study: Path) -> None:
    """Mitsuba's black pilot fails the check: the plan sizes the reference from pt's check
    (its pilot) and the halves are pt's, extending the check's stores; the report names the
    finding and the source, and ranks the methods against pt's reference."""
    plan = _reference_record(trust_study, "dense", "plan.json")
    assert plan["source"] == "pgi" and plan["fallback"] and plan["how"] == "sized"
    assert not plan["trust"]["trustworthy"] and plan["pilot_spp"] == 8
    assert any("exactly 0" in f for f in plan["trust"]["findings"]), plan["trust"]
    for h in (0, 1):
        side = _reference_record(trust_study, "dense", f"half{h}.json")
        assert side["source"] == "pgi" and side["spp"] == plan["spp"]
    ref = _reference_record(trust_study, "dense", "ref.json")
    assert ref["source"] == "pgi" and ref["source_label"] == "pgi's pt" and ref["trusted"]
    page = (trust_study / "reports" / "scene-dense.html").read_text()
    finding = html.escape(plan["trust"]["findings"][0])
    assert f"No trustworthy Mitsuba reference: {finding}" in page
    assert "reference rendered by pgi's pt" in page
    tables = trust_study / "reports" / "tables"
    runs = pd.read_csv(tables / "runs.csv")
    assert set(runs[runs.scene == "dense"].reference) == {"pgi's pt"}
    assert set(runs[runs.scene == "sound"].reference) == {"Mitsuba"}
    best = pd.read_csv(tables / "best.csv")
    assert set(best[best.scene == "dense"].reference) == {"pgi's pt"}
    assert "dense (reference: pgi's pt)" in (tables / "overview.md").read_text()


def test_a_fixed_untrustworthy_reference_ranks_nothing(trust_study: Path) -> None:
    """A fixed reference has no pilot to send elsewhere: the finished one is checked, and a
    failure leaves its scene without winners, saying why."""
    ref = _reference_record(trust_study, "dark", "ref.json")
    assert ref["source"] == "mitsuba" and not ref["trusted"]
    assert ref["warnings"] == [ref["trust"]["line"]]
    assert ref["trust"]["line"].startswith("Mitsuba's reference of dark is not trustworthy: ")
    best = pd.read_csv(trust_study / "reports" / "tables" / "best.csv")
    assert "dark" not in set(best.scene) and "sound" in set(best.scene)
    index = (trust_study / "reports" / "index.html").read_text()
    assert "no trustworthy reference" in index
    assert (
        "No trustworthy Mitsuba reference"
        in (trust_study / "reports" / "scene-dark.html").read_text()
    )


def test_a_scene_may_ask_for_pts_reference(trust_study: Path) -> None:
    """`reference_source: pgi`: no Mitsuba pilot; pt's check is the pilot."""
    folder = trust_study / "results" / "reference" / "ours"
    assert not (folder / "pilot0.exr").exists()
    plan = _reference_record(trust_study, "ours", "plan.json")
    assert plan["source"] == "pgi" and not plan["fallback"] and plan["trust"] is None
    ref = _reference_record(trust_study, "ours", "ref.json")
    assert ref["source"] == "pgi" and ref["trusted"] and ref["trust"] is None
