# References, rendered as two independent halves (different seeds); their difference
# estimates the reference's own error (compare.metrics.reference_error), which the analysis
# removes from every MSE-type error.
#
# A scene's reference is either fixed (reference.spp or the scene's reference_spp: a number)
# or sized to the study ("auto"): a pilot of each half, then a plan (compare.sizing: how many
# samples bring the reference's relMSE to a fraction of the best method's at the largest
# budget, within a time cap), then the halves at that count. Each half keeps its passes in a
# store (`pgi reference --store`) that the pilot starts and the half extends: a reference that
# needs more samples later is extended, not rendered again. The plan is also where a check of
# the pilot, or another source of references, would come in: it names the source
# (`pgi reference --source`) that renders the halves.

import json


def reference_folder(scene):
    return f"{R}/reference/{scene}"


def reference_store(wildcards):
    return f"{reference_folder(wildcards.scene)}/store/half{wildcards.half}.npz"


def sized(scene):
    return PLAN.scenes[scene].reference_sized


rule reference_pilot:
    output:
        exr=f"{R}/reference/{{scene}}/pilot{{half}}.exr",
        json=f"{R}/reference/{{scene}}/pilot{{half}}.json",
    params:
        scene=scene_arg,
        sets=set_args,
        spp=PLAN.ref_pilot_spp,
        seed=lambda w: PLAN.ref_seed + int(w.half),
        source=PLAN.ref_source,
        store=reference_store,
        # `pgi fingerprint`: a change of the code `pgi reference` runs (scene loading, the
        # Mitsuba export) or of Mitsuba reruns the references; other renderer code does not
        code=PLAN.code.get("reference", ""),
        scene_digest=scene_digest,
    threads: PLAN.ref_threads
    log:
        f"{R}/logs/reference/{{scene}}/pilot{{half}}.log",
    benchmark:
        f"{R}/benchmarks/reference/{{scene}}/pilot{{half}}.tsv"
    shell:
        "{PGI} reference {params.scene:q} --spp {params.spp} --seed {params.seed}"
        " --source {params.source} --threads {threads} {params.sets}"
        " --store {params.store:q} -o {output.exr:q} > {log:q} 2>&1"


def plan_inputs(wildcards):
    """A sized reference's plan reads the pilot and every method's images at the largest
    budget; a fixed one's reads nothing."""
    if not sized(wildcards.scene):
        return {"code": PLAN_CODE}
    largest = PLAN.budget_tags[-1]
    folder = reference_folder(wildcards.scene)
    return {
        "pilot": [f"{folder}/pilot{h}.exr" for h in (0, 1)],
        "runs": [
            f"{run_prefix(wildcards.scene, m, s)}.t{largest}.exr"
            for m in PLAN.methods
            for s in PLAN.seeds
        ],
        "code": PLAN_CODE,
    }


def plan_spec(wildcards):
    scene = PLAN.scenes[wildcards.scene]
    folder = reference_folder(wildcards.scene)
    spec = {"out": f"{folder}/plan.json", "source": PLAN.ref_source}
    if not scene.reference_sized:
        return json.dumps({**spec, "spp": scene.reference_spp}, sort_keys=True)
    largest = PLAN.budget_tags[-1]
    spec |= {
        "pilot": [f"{folder}/pilot{h}.exr" for h in (0, 1)],
        "runs": {
            m: [f"{run_prefix(wildcards.scene, m, s)}.t{largest}.exr" for s in PLAN.seeds]
            for m in PLAN.methods
        },
        "target": PLAN.ref_target,
        "max_seconds": scene.reference_max_seconds,
    }
    return json.dumps(spec, sort_keys=True)


rule reference_plan:
    input:
        unpack(plan_inputs),
    output:
        f"{R}/reference/{{scene}}/plan.json",
    params:
        spec=plan_spec,
    log:
        f"{R}/logs/reference/{{scene}}/plan.log",
    benchmark:
        f"{R}/benchmarks/reference/{{scene}}/plan.tsv"
    shell:
        "{PY} -m compare.steps reference-plan {params.spec:q} > {log:q} 2>&1"


def half_inputs(wildcards):
    """A sized half renders what its plan asks for; a fixed one needs nothing."""
    if sized(wildcards.scene):
        return {"plan": f"{reference_folder(wildcards.scene)}/plan.json"}
    return {}


def half_samples(wildcards):
    """`pgi reference` options for the samples (and the source): the config's, or (sized)
    the plan's, read when the job runs."""
    scene = PLAN.scenes[wildcards.scene]
    if scene.reference_sized:
        plan = shlex.quote(f"{reference_folder(wildcards.scene)}/plan.json")
        return f"$({PY} -m compare.steps reference-args {plan})"
    return f"--spp {scene.reference_spp}"


def half_source(wildcards):
    return "" if sized(wildcards.scene) else f"--source {PLAN.ref_source}"


rule reference_half:
    input:
        unpack(half_inputs),
    output:
        exr=f"{R}/reference/{{scene}}/half{{half}}.exr",
        json=f"{R}/reference/{{scene}}/half{{half}}.json",
    params:
        scene=scene_arg,
        sets=set_args,
        samples=half_samples,
        source=half_source,
        seed=lambda w: PLAN.ref_seed + int(w.half),
        store=reference_store,
        code=PLAN.code.get("reference", ""),
        scene_digest=scene_digest,
    threads: PLAN.ref_threads
    log:
        f"{R}/logs/reference/{{scene}}/half{{half}}.log",
    benchmark:
        f"{R}/benchmarks/reference/{{scene}}/half{{half}}.tsv"
    shell:
        "{PGI} reference {params.scene:q} {params.samples} --seed {params.seed} {params.source}"
        " --threads {threads} {params.sets} --store {params.store:q}"
        " -o {output.exr:q} > {log:q} 2>&1"


rule reference:
    input:
        a=f"{R}/reference/{{scene}}/half0.exr",
        b=f"{R}/reference/{{scene}}/half1.exr",
        plan=f"{R}/reference/{{scene}}/plan.json",
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
        " {output.exr:q} {output.json:q} --plan {input.plan:q} > {log:q} 2>&1"
