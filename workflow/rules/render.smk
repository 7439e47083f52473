# Timed renders: one run per scene x method x seed writes a snapshot at every time budget.
# Budgets come from the renderer's own clock (sidecar render_seconds); `benchmark:` records
# wall time and memory. Every run declares the same threads and holds the `timed_render`
# resource, so timed renders never share the machine with each other.


rule render:
    input:
        scene=scene_files,
    output:
        snapshots=[f"{R}/render/{{scene}}/{{method}}/s{{seed}}/run.t{t}.exr" for t in PLAN.budget_tags],
        sidecars=[f"{R}/render/{{scene}}/{{method}}/s{{seed}}/run.t{t}.json" for t in PLAN.budget_tags],
        final=f"{R}/render/{{scene}}/{{method}}/s{{seed}}/run.exr",
        final_json=f"{R}/render/{{scene}}/{{method}}/s{{seed}}/run.json",
    params:
        scene=scene_arg,
        # --method (a variant's own method), --set overrides (the scene's, then the
        # variant's) and the config's method_args
        args=render_args,
        snapshots=PLAN.snapshot_arg(),
        # The configured count, whatever Snakemake grants (--cores below it would lower
        # {threads}, and compare refuses runs with other counts); as a param, a change of it
        # reruns the render (Snakemake ignores changes of `threads:`).
        nthreads=PLAN.threads,
    threads: PLAN.threads
    resources:
        timed_render=1,
    log:
        f"{R}/logs/render/{{scene}}/{{method}}/s{{seed}}.log",
    benchmark:
        f"{R}/benchmarks/render/{{scene}}/{{method}}/s{{seed}}.tsv"
    shell:
        "{PGI} render {params.scene:q} {params.args} --seed {wildcards.seed}"
        " --threads {params.nthreads} --snapshots {params.snapshots}"
        " -o {output.final:q} > {log:q} 2>&1"
