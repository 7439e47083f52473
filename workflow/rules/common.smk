# Helpers shared by the rules: file layout and per-job parameters, all derived from PLAN.

import functools
import shlex
from pathlib import Path

from renderer.errors import PgiError
from renderer.progressive import available_cores, check_threads
from renderer.scene.sources import scene_content_digest, scene_sources


def _relative(path):
    """Paths below the working directory are given relative to it, so that a copied or moved
    project (results included) does not look changed to Snakemake."""
    rel = os.path.relpath(path)
    return str(path) if rel.startswith("..") else rel


def scene_arg(wildcards):
    return _relative(PLAN.scenes[wildcards.scene].path)


def scene_yaml(wildcards):
    return _relative(PLAN.scenes[wildcards.scene].path / "scene.yaml")


@functools.cache
def _scene_sources(scene):
    spec = PLAN.scenes[scene]
    return tuple(_relative(p) for p in scene_sources(spec.path, spec.set))


def scene_files(wildcards):
    """The scene file, its includes and its assets (the report pages read them)."""
    return list(_scene_sources(wildcards.scene))


@functools.cache
def _scene_digest(scene):
    spec = PLAN.scenes[scene]  # an asset named by a `set` override counts too
    return scene_content_digest(spec.path, spec.set)


def scene_digest(wildcards):
    """What the scene renders (renderer.scene.sources.scene_content_digest): renders and
    references record it as a param, so an edit that changes it reruns them, and a comment
    or a new description does not. Computed once per scene."""
    return _scene_digest(wildcards.scene)


# The analysis code: editing it reruns the steps that run it and what follows them (cheap
# steps); renderer code does not rerun renders (see docs/workflow.md). Each step lists the
# modules `compare.steps` imports for it (a test checks them against what the jobs import).
def _compare_code(*modules):
    files = ("__init__.py", "steps.py", *modules)
    return sorted(_relative(Path(SRC, "compare", f)) for f in files)


MERGE_CODE = _compare_code("runs.py", "metrics.py", "trust.py")  # compare-run, merge-reference
PLAN_CODE = _compare_code("sizing.py", "runs.py", "metrics.py", "trust.py")  # reference-plan
TABLE_CODE = _compare_code("tables.py", "convergence.py", "metrics.py")
ANALYSIS_CODE = sorted(  # the report pages: all of it
    _relative(p)
    for p in Path(SRC, "compare").rglob("*")
    if p.suffix in (".py", ".css", ".js") and "__pycache__" not in p.parts
)


def set_args(wildcards):
    return " ".join(shlex.quote(a) for a in PLAN.scene_set_args(wildcards.scene))


def render_args(wildcards):
    return " ".join(shlex.quote(a) for a in PLAN.render_args(wildcards.scene, wildcards.method))


def run_prefix(scene, method, seed):
    return f"{R}/render/{scene}/{method}/s{seed}/run"


def snapshot_files(scene, method, seed):
    return [f"{run_prefix(scene, method, seed)}.t{t}.exr" for t in PLAN.budget_tags]


def metrics_file(scene, method, seed):
    return f"{R}/metrics/{scene}/{method}/s{seed}.csv"


def bench_file(scene, method, seed):
    return f"{R}/benchmarks/render/{scene}/{method}/s{seed}.tsv"


def all_runs():
    for scene in PLAN.scenes:
        for method in PLAN.methods:
            for seed in PLAN.seeds:
                yield scene, method, seed
