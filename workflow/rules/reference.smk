# References, rendered as two independent halves (different seeds); their difference
# estimates the reference's own error (compare.metrics.reference_error), which the analysis
# removes from every MSE-type error.
#
# A scene's reference is either fixed (reference.spp or the scene's reference_spp: a number)
# or sized to the study ("auto"): a pilot of each half, then a plan (compare.sizing: how many
# samples bring the reference's relMSE to a fraction of the best method's at the largest
# budget, within a time cap), then the halves at that count. Each half keeps its passes in a
# store (`pgi reference --store`, one per source and half) that the pilot starts and the half
# extends: a reference that needs more samples later is extended, not rendered again.
#
# Every reference is checked against pgi's pt (`reference_check`: two halves of
# reference.check_spp, compare.trust). The plan checks a sized Mitsuba reference's pilot and,
# where it is not trustworthy, names pgi's pt as the source of the halves, the check's halves
# as their pilot (their stores are extended); the merge checks the finished reference.

import json


def reference_folder(scene):
    return f"{R}/reference/{scene}"


def reference_store(scene, source, half):
    """Where `pgi reference --store` keeps a half's passes: one store per source and half (a
    half rendered by pgi's pt extends the check's)."""
    return f"{reference_folder(scene)}/store/{source}-half{half}.npz"


def sized(scene):
    return PLAN.scenes[scene].reference_sized


def mitsuba_pilot(scene):
    """A sized reference Mitsuba is to render has a pilot (which the plan also checks)."""
    return sized(scene) and PLAN.scenes[scene].reference_source == "mitsuba"


def check_images(scene):
    return [f"{reference_folder(scene)}/check{h}.exr" for h in (0, 1)]


rule reference_pilot:
    output:
        exr=f"{R}/reference/{{scene}}/pilot{{half}}.exr",
        json=f"{R}/reference/{{scene}}/pilot{{half}}.json",
    params:
        scene=scene_arg,
        sets=set_args,
        spp=PLAN.ref_pilot_spp,
        seed=lambda w: PLAN.ref_seed + int(w.half),
        store=lambda w: reference_store(w.scene, "mitsuba", w.half),
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
        " --source mitsuba --check 0 --threads {threads} {params.sets}"
        " --store {params.store:q} -o {output.exr:q} > {log:q} 2>&1"


rule reference_check:
    """pgi's pt in two halves of their own seeds and stores: what the reference is checked
    against, and the pilot of a reference pt renders (which extends these stores)."""
    output:
        exr=f"{R}/reference/{{scene}}/check{{half}}.exr",
        json=f"{R}/reference/{{scene}}/check{{half}}.json",
    params:
        scene=scene_arg,
        sets=set_args,
        spp=PLAN.ref_check_spp,
        seed=lambda w: PLAN.ref_seed + int(w.half),
        store=lambda w: reference_store(w.scene, "pgi", w.half),
        code=PLAN.code.get("render", ""),  # pgi's pt: the whole renderer
        scene_digest=scene_digest,
    threads: PLAN.ref_threads
    log:
        f"{R}/logs/reference/{{scene}}/check{{half}}.log",
    benchmark:
        f"{R}/benchmarks/reference/{{scene}}/check{{half}}.tsv"
    shell:
        "{PGI} reference {params.scene:q} --spp {params.spp} --seed {params.seed}"
        " --source pgi --threads {threads} {params.sets}"
        " --store {params.store:q} -o {output.exr:q} > {log:q} 2>&1"


def plan_inputs(wildcards):
    """Every plan reads the check; a sized one also reads Mitsuba's pilot (where Mitsuba is
    to render) and every method's images at the largest budget."""
    scene = wildcards.scene
    inputs = {"check": check_images(scene), "code": PLAN_CODE}
    if not sized(scene):
        return inputs
    largest = PLAN.budget_tags[-1]
    if mitsuba_pilot(scene):
        inputs["pilot"] = [f"{reference_folder(scene)}/pilot{h}.exr" for h in (0, 1)]
    inputs["runs"] = [
        f"{run_prefix(scene, m, s)}.t{largest}.exr" for m in PLAN.methods for s in PLAN.seeds
    ]
    return inputs


def plan_spec(wildcards):
    scene = PLAN.scenes[wildcards.scene]
    folder = reference_folder(wildcards.scene)
    spec = {
        "out": f"{folder}/plan.json",
        "scene": wildcards.scene,
        "source": scene.reference_source,
        "check": check_images(wildcards.scene),
    }
    if not scene.reference_sized:
        return json.dumps({**spec, "spp": scene.reference_spp}, sort_keys=True)
    largest = PLAN.budget_tags[-1]
    if mitsuba_pilot(wildcards.scene):
        spec["pilot"] = [f"{folder}/pilot{h}.exr" for h in (0, 1)]
    spec |= {
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


def half_samples(wildcards):
    """`pgi reference` options from the plan, read when the job runs: the samples, the source
    (Mitsuba, or pgi's pt where the check found Mitsuba's reference untrustworthy) and its
    store for this half."""
    plan = shlex.quote(f"{reference_folder(wildcards.scene)}/plan.json")
    return f"$({PY} -m compare.steps reference-args {plan} {wildcards.half})"


rule reference_half:
    input:
        plan=f"{R}/reference/{{scene}}/plan.json",
    output:
        exr=f"{R}/reference/{{scene}}/half{{half}}.exr",
        json=f"{R}/reference/{{scene}}/half{{half}}.json",
    params:
        scene=scene_arg,
        sets=set_args,
        samples=half_samples,
        seed=lambda w: PLAN.ref_seed + int(w.half),
        code=PLAN.code.get("reference", ""),
        scene_digest=scene_digest,
    threads: PLAN.ref_threads
    log:
        f"{R}/logs/reference/{{scene}}/half{{half}}.log",
    benchmark:
        f"{R}/benchmarks/reference/{{scene}}/half{{half}}.tsv"
    shell:
        "{PGI} reference {params.scene:q} {params.samples} --seed {params.seed}"
        " --threads {threads} {params.sets} -o {output.exr:q} > {log:q} 2>&1"


rule reference:
    input:
        a=f"{R}/reference/{{scene}}/half0.exr",
        b=f"{R}/reference/{{scene}}/half1.exr",
        plan=f"{R}/reference/{{scene}}/plan.json",
        check=lambda w: check_images(w.scene),
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
        " {output.exr:q} {output.json:q} --plan {input.plan:q} --check {input.check:q}"
        " > {log:q} 2>&1"
