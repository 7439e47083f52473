# Compare every snapshot of a run with the reference; aggregate all runs into tables.


rule compare:
    input:
        snapshots=lambda w: snapshot_files(w.scene, w.method, w.seed),
        ref=f"{R}/reference/{{scene}}/ref.exr",
        ref_json=f"{R}/reference/{{scene}}/ref.json",
        # the halves whose difference removes the reference's own error (ref.json names them)
        halves=[f"{R}/reference/{{scene}}/half{h}.exr" for h in (0, 1)],
        code=MERGE_CODE,
    output:
        f"{R}/metrics/{{scene}}/{{method}}/s{{seed}}.csv",
    params:
        budgets=",".join(PLAN.budget_tags),
        threads=PLAN.threads,
    log:
        f"{R}/logs/compare/{{scene}}/{{method}}/s{{seed}}.log",
    benchmark:
        f"{R}/benchmarks/compare/{{scene}}/{{method}}/s{{seed}}.tsv"
    shell:
        "{PY} -m compare.steps compare-run --scene {wildcards.scene} --method {wildcards.method}"
        " --seed {wildcards.seed} --threads {params.threads} --budgets {params.budgets}"
        " --ref {input.ref:q} --ref-json {input.ref_json:q}"
        " -o {output:q} {input.snapshots:q} > {log:q} 2>&1"


rule tables:
    input:
        metrics=[metrics_file(*r) for r in all_runs()],
        benchmarks=[bench_file(*r) for r in all_runs()],
        code=TABLE_CODE,
    output:
        summary=f"{REP}/tables/summary.csv",
        runs=f"{REP}/tables/runs.csv",
        convergence=f"{REP}/tables/convergence.csv",
        tte=f"{REP}/tables/time_to_error.csv",
        stats=f"{REP}/tables/stats.csv",
        best=f"{REP}/tables/best.csv",
        overview=f"{REP}/tables/overview.md",
        overview_html=f"{REP}/tables/overview.html",
        tables_md=f"{REP}/tables/tables.md",
    params:
        out=f"{REP}/tables",
        metric=PLAN.primary_metric,
        baseline=PLAN.baseline,
        results=R,
        scenes=",".join(PLAN.scenes),
        methods=",".join(PLAN.methods),
        fraction=PLAN.determined_fraction,
    log:
        f"{R}/logs/tables.log",
    benchmark:
        f"{R}/benchmarks/tables.tsv"
    shell:
        "{PY} -m compare.steps tables --results {params.results:q} --metric {params.metric}"
        " --baseline {params.baseline} --scenes {params.scenes:q} --methods {params.methods:q}"
        " --determined-fraction {params.fraction}"
        " -o {params.out:q} {input.metrics:q} > {log:q} 2>&1"
