# The HTML report: index (overview tables, convergence plots) and one page per scene
# (equal-time grids, error maps, the interactive viewer, render statistics).

import json


def report_scene_spec(wildcards):
    s = wildcards.scene
    return json.dumps(
        {
            "scene": s,
            "scene_file": scene_yaml(wildcards),
            "reports": REP,
            "tables": f"{REP}/tables",
            "ref": f"{R}/reference/{s}/ref.exr",
            "ref_json": f"{R}/reference/{s}/ref.json",
            "seed": PLAN.seeds[0],
            "methods": list(PLAN.methods),
            "bases": {m: PLAN.base_method(m) for m in PLAN.methods},
            "budgets": PLAN.budget_tags,
            "snapshots": {
                m: snapshot_files(s, m, PLAN.seeds[0]) for m in PLAN.methods
            },
            "metric": PLAN.primary_metric,
            "baseline": PLAN.baseline,
            "determined_fraction": PLAN.determined_fraction,
            "title": PLAN.title,
            "study": PLAN.name,
            "viewer_max_size": PLAN.viewer_max_size,
            "scenes": list(PLAN.scenes),
        },
        sort_keys=True,
    )


rule report_scene:
    input:
        tables=rules.tables.output,
        scene=scene_files,
        code=ANALYSIS_CODE,
        ref=f"{R}/reference/{{scene}}/ref.exr",
        ref_json=f"{R}/reference/{{scene}}/ref.json",
        snapshots=lambda w: [
            f for m in PLAN.methods for f in snapshot_files(w.scene, m, PLAN.seeds[0])
        ],
    output:
        page=f"{REP}/scene-{{scene}}.html",
        data=f"{REP}/data/{{scene}}.js",
    params:
        spec=report_scene_spec,
    log:
        f"{R}/logs/report/{{scene}}.log",
    benchmark:
        f"{R}/benchmarks/report/{{scene}}.tsv"
    shell:
        "{PY} -m compare.steps report-scene {params.spec:q} > {log:q} 2>&1"


rule report_index:
    input:
        tables=rules.tables.output,
        pages=[f"{REP}/scene-{s}.html" for s in PLAN.scenes],
        code=ANALYSIS_CODE,
        refs=[f"{R}/reference/{s}/ref.json" for s in PLAN.scenes],
    output:
        f"{REP}/index.html",
    params:
        spec=json.dumps(
            {
                "reports": REP,
                "tables": f"{REP}/tables",
                "scenes": list(PLAN.scenes),
                "methods": list(PLAN.methods),
                "variants": {k: v.describe() for k, v in PLAN.variants.items()},
                "bases": {m: PLAN.base_method(m) for m in PLAN.methods},
                "metric": PLAN.primary_metric,
                "baseline": PLAN.baseline,
                "determined_fraction": PLAN.determined_fraction,
                "title": PLAN.title,
                "study": PLAN.name,
                "refs": {s: f"{R}/reference/{s}/ref.json" for s in PLAN.scenes},
            },
            sort_keys=True,
        ),
    log:
        f"{R}/logs/report/index.log",
    benchmark:
        f"{R}/benchmarks/report/index.tsv"
    shell:
        "{PY} -m compare.steps report-index {params.spec:q} > {log:q} 2>&1"
