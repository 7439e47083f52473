# Timed renders: one run per scene x method x seed writes a snapshot at every time budget.
# Budgets come from the renderer's own clock (sidecar render_seconds); `benchmark:` records
# wall time and memory. Every run holds the `timed_render` resource, so timed renders never
# share the machine with each other, and locally it claims every core Snakemake may use, so
# no reference or comparison runs beside it either (pgi still gets the config's threads).


# `pgi render` would refuse a thread count above the machine's cores (its own check): say so
# before any job runs.
if workflow.local_exec:
    try:
        check_threads(PLAN.threads)
    except PgiError:
        sys.exit(
            f"config ({CONFIG_FILES}): threads: {PLAN.threads} is more than this machine's "
            f"{available_cores()} cores; every render would fail (use --config threads=N)"
        )


def render_cores(wildcards):
    if not workflow.local_exec:
        return PLAN.threads
    return max(PLAN.threads, workflow.cores)



rule render:
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
        # `pgi fingerprint`: a change of the renderer's code reruns the renders
        code=PLAN.code.get("render", ""),
        # the scene's content (its files as parsed, less the report-only keys, and assets)
        scene_digest=scene_digest,
    threads: render_cores
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
