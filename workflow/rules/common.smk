# Helpers shared by the rules: file layout and per-job parameters, all derived from PLAN.

import shlex


def scene_arg(wildcards):
    return str(PLAN.scenes[wildcards.scene].path)


def scene_file(wildcards):
    return str(PLAN.scenes[wildcards.scene].path / "scene.yaml")


def set_args(wildcards):
    return " ".join(shlex.quote(a) for a in PLAN.scene_set_args(wildcards.scene))


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
