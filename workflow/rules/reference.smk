# Mitsuba references, rendered as two independent halves (different seeds); their difference
# estimates the reference's own error (compare.metrics.reference_error).


rule reference_half:
    output:
        exr=f"{R}/reference/{{scene}}/half{{half}}.exr",
        json=f"{R}/reference/{{scene}}/half{{half}}.json",
    params:
        scene=scene_arg,
        sets=set_args,
        spp=lambda w: PLAN.scenes[w.scene].reference_spp,
        seed=lambda w: PLAN.ref_seed + int(w.half),
        # `pgi fingerprint`: a change of the code `pgi reference` runs (scene loading, the
        # Mitsuba export) or of Mitsuba reruns the references; other renderer code does not
        code=PLAN.code.get("reference", ""),
        scene_digest=scene_digest,
    threads: PLAN.ref_threads
    log:
        f"{R}/logs/reference/{{scene}}/half{{half}}.log",
    benchmark:
        f"{R}/benchmarks/reference/{{scene}}/half{{half}}.tsv"
    shell:
        "{PGI} reference {params.scene:q} --spp {params.spp} --seed {params.seed}"
        " --threads {threads} {params.sets} -o {output.exr:q} > {log:q} 2>&1"


rule reference:
    input:
        a=f"{R}/reference/{{scene}}/half0.exr",
        b=f"{R}/reference/{{scene}}/half1.exr",
        # the reference's own error (ref.json) is computed by the analysis code
        code=MERGE_CODE,
    output:
        exr=f"{R}/reference/{{scene}}/ref.exr",
        json=f"{R}/reference/{{scene}}/ref.json",
    log:
        f"{R}/logs/reference/{{scene}}/merge.log",
    benchmark:
        f"{R}/benchmarks/reference/{{scene}}/merge.tsv"
    shell:
        "{PY} -m compare.steps merge-reference {input.a:q} {input.b:q}"
        " {output.exr:q} {output.json:q} > {log:q} 2>&1"
