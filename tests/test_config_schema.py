"""The workflow config schema: shipped configs validate, bad ones fail with a clear message."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

pytest.importorskip("snakemake")
from snakemake.exceptions import WorkflowError  # noqa: E402
from snakemake.utils import validate  # noqa: E402

from compare.plan import PlanError, make_plan, schema_error_message  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = str(ROOT / "configs" / "schema.yaml")
GOOD = {"scenes": ["cbox"], "methods": ["pt"], "budgets": [1, 2], "seeds": [1]}


@pytest.mark.parametrize("name", ["default", "full", "tiny", "media"])
def test_shipped_configs_validate(name: str) -> None:
    cfg = yaml.safe_load((ROOT / "configs" / f"{name}.yaml").read_text())
    validate(cfg, SCHEMA)


def test_defaults_filled_in() -> None:
    cfg = copy.deepcopy(GOOD)
    validate(cfg, SCHEMA)
    assert cfg["threads"] == 2 and cfg["primary_metric"] == "relmse"
    assert cfg["determined_fraction"] == 0.2 and cfg["reports_dir"] == "reports"
    assert cfg["reference"]["spp"] == "auto" and cfg["reference"]["max_seconds"] == 120


@pytest.mark.parametrize(
    ("change", "expect"),
    [
        ({"budgets": [1, -2]}, r"-2 is less than or equal to the minimum of 0"),
        ({"budgets": []}, r"\[\] should be non-empty"),
        ({"seeds": ["one"]}, r"'one' is not of type 'integer'"),
        ({"methods": "some"}, r"'some' is not valid under any of the given schemas"),
        ({"threads": 0}, r"0 is less than the minimum of 1"),
        ({"primary_metric": "psnr"}, r"'psnr' is not one of"),
        ({"budget": [1]}, r"Additional properties are not allowed \('budget' was unexpected\)"),
        ({"scenes": [{"nam": "x"}]}, r"not valid under any of the given schemas"),
        ({"reference": {"spp": 0}}, r"0 is less than the minimum of 1"),
        ({"reference": {"spp": "many"}}, r"'many' does not match '\^auto\$'"),
        ({"reference": {"max_seconds": 0}}, r"0 is less than or equal to the minimum of 0"),
        ({"ref_quality_factor": 10}, r"'ref_quality_factor' was unexpected"),
    ],
)
def test_bad_config_rejected(change: dict, expect: str) -> None:
    cfg = {**copy.deepcopy(GOOD), **change}
    with pytest.raises(WorkflowError, match=expect):
        validate(cfg, SCHEMA)


@pytest.mark.parametrize(
    ("change", "line"),
    [
        (
            {"scenes": [{"nam": "cbox"}]},
            "scenes[0]: Additional properties are not allowed ('nam' was unexpected) "
            "(scenes[0] may also be a string)",
        ),
        (
            {"scenes": [{"name": "cbox", "reference_spp": 0}]},
            "scenes[0].reference_spp: 0 is less than the minimum of 1 "
            "(scenes[0] may also be a string)",
        ),
        (
            {"scenes": ["cb ox"]},
            "scenes[0]: 'cb ox' does not match '^[A-Za-z0-9_.-]+$' "
            "(scenes[0] may also be a mapping)",
        ),
        ({"scenes": [3]}, "scenes[0]: 3 is not a string or a mapping"),
        ({"methods": "some"}, "methods: 'some' is not one of ['all'] (methods may also be a list)"),
        ({"methods": ["p t"]}, "methods[0]: 'p t' does not match"),
        ({"budgets": ["5e-1"]}, "write 0.5)"),
        ({"budgets": ["1e-9"]}, "write 1.0e-09)"),  # 1e-09 is text in YAML 1.1 too
        ({"budgets": ["2e20"]}, "write 2.0e+20)"),
        (
            {"budgets": ["1"]},
            "budgets[0]: '1' is not of type 'number' (it is text: in a config file write 1 "
            "without quotes; snakemake's --config reads list items as text",
        ),
        ({"budget": [1]}, "top level: Additional properties are not allowed ('budget' was"),
    ],
)
def test_schema_error_names_the_form_that_was_meant(change: dict, line: str) -> None:
    """A key that takes one of several forms (oneOf) used to fail with "... is not valid under
    any of the given schemas", naming neither what was wrong nor what would do."""
    cfg = {**copy.deepcopy(GOOD), **change}
    with pytest.raises(WorkflowError) as caught:
        validate(cfg, SCHEMA)
    message = schema_error_message(caught.value.__cause__ or caught.value.__context__)
    assert message.startswith(line) if line.startswith(tuple("tms")) else line in message, message


def test_missing_required_key() -> None:
    cfg = copy.deepcopy(GOOD)
    del cfg["seeds"]
    with pytest.raises(WorkflowError, match="'seeds' is a required property"):
        validate(cfg, SCHEMA)


def _scenes(tmp_path: Path) -> Path:
    (tmp_path / "cbox").mkdir()
    (tmp_path / "cbox" / "scene.yaml").write_text("# x\n")
    return tmp_path


def test_plan_unknown_scene(tmp_path: Path) -> None:
    cfg = {**GOOD, "scenes": ["nosuch"], "scenes_dir": str(_scenes(tmp_path))}
    with pytest.raises(PlanError, match="no scene 'nosuch'.*known scenes: cbox"):
        make_plan(cfg, tmp_path, check_methods=False, check_scenes=False)


def test_plan_resolves(tmp_path: Path) -> None:
    cfg = {
        **GOOD,
        "scenes": ["cbox", {"name": "cbox", "reference_spp": 8}][:1],
        "scenes_dir": str(_scenes(tmp_path)),
        "budgets": [4, 0.5, 2],
        "set": ["film.width=8"],
        "pgi": "echo",
    }
    plan = make_plan(cfg, tmp_path, check_methods=False, check_scenes=False)
    assert plan.budget_tags == ["0.5", "2", "4"]
    assert plan.scene_set_args("cbox") == ["--set", "film.width=8"]
    assert plan.pgi == ("echo",)


def _fake_pgi(tmp_path: Path) -> str:
    """A `pgi` whose `methods` lists pt, lt and mitsuba, and announces bdpt and vrl."""
    script = tmp_path / "fake-pgi"
    script.write_text(
        "#!/bin/sh\n"
        'if [ "$1" = fingerprint ]; then echo \'{"render": "r", "reference": "f"}\'; exit 0; fi\n'
        "printf 'pt  path tracing\\nlt  light tracing\\nmitsuba  x\\n"
        "# not yet implemented: bdpt, vrl\\n'\n"
    )
    script.chmod(0o755)
    return str(script)


@pytest.mark.parametrize(
    ("change", "expect"),
    [
        ({"methods": ["pt", "nosuch"]}, r"methods: unknown method\(s\) nosuch; .*pt, lt, mitsuba"),
        ({"exclude_methods": ["ppt"]}, r"exclude_methods: unknown method\(s\) ppt"),
        ({"method_args": {"sppm": ["--x"]}}, r"method_args: unknown method\(s\) sppm"),
        ({"methods": ["pt"], "exclude_methods": ["pt"]}, r"no method left after exclude_methods"),
        ({"methods": ["lt", "mitsuba"]}, r"baseline: 'pt' is not among the methods .*lt, mitsuba"),
        ({"methods": "all", "exclude_methods": ["pt"]}, r"baseline: 'pt' is not among"),
        ({"methods": ["pt", "bdpt"]}, r"methods: unknown method\(s\) bdpt"),  # cannot render
    ],
)
def test_plan_refuses_methods_it_cannot_run(tmp_path: Path, change: dict, expect: str) -> None:
    cfg = {**GOOD, "scenes_dir": str(_scenes(tmp_path)), "pgi": _fake_pgi(tmp_path), **change}
    with pytest.raises(PlanError, match=expect):
        make_plan(cfg, tmp_path, check_scenes=False)


@pytest.mark.parametrize(
    ("change", "expect"),
    [
        (
            {"variants": {"pt-delta": {"method": "pt", "set": [
                "integrator.estimator=delta", "integrator.estimator=ratio"]}}},
            r"variants: 'pt-delta': set: integrator.estimator is set twice",
        ),
        ({"set": ["film.width=8", " film.width =16"]}, r"^set: film.width is set twice"),
        (
            {"scenes": [{"name": "cbox", "set": ["film.width=8", "film.width=16"]}]},
            r"scenes: 'cbox': set: film.width is set twice",
        ),
    ],
)  # fmt: skip
def test_plan_refuses_a_key_set_twice_in_one_list(
    tmp_path: Path, change: dict, expect: str
) -> None:
    """The render would take the last value silently: a variant that sets its estimator to
    delta and then back to ratio is plain pt under a misleading label (found by a review)."""
    cfg = {**GOOD, "scenes_dir": str(_scenes(tmp_path)), "pgi": _fake_pgi(tmp_path), **change}
    with pytest.raises(PlanError, match=expect):
        make_plan(cfg, tmp_path, check_scenes=False)
    # A scene's own `set` may override the study's for that scene.
    cfg.update(set=["film.width=8"], scenes=[{"name": "cbox", "set": ["film.width=16"]}])
    cfg.pop("variants", None)
    plan = make_plan(cfg, tmp_path, check_scenes=False)
    assert plan.scene_set_args("cbox") == ["--set", "film.width=8", "--set", "film.width=16"]


def test_plan_accepts_a_baseline_among_its_methods(tmp_path: Path) -> None:
    cfg = {**GOOD, "scenes_dir": str(_scenes(tmp_path)), "pgi": _fake_pgi(tmp_path)}
    plan = make_plan(
        {**cfg, "methods": "all", "exclude_methods": ["pt"], "baseline": "lt"},
        tmp_path,
        check_scenes=False,
    )
    assert plan.methods == ("lt", "mitsuba") and plan.baseline == "lt"
    # methods announced but not implemented may be excluded or configured ahead of time
    cfg.update(methods="all", exclude_methods=["pt", "bdpt"], method_args={"vrl": ["--x"]})
    cfg.update(baseline="lt")
    assert make_plan(cfg, tmp_path, check_scenes=False).methods == ("lt", "mitsuba")


@pytest.mark.parametrize(
    ("change", "expect"),
    [
        ({"set": ["film.widht=8"]}, r"scenes: 'cbox': .*film.widht: unknown key"),
        (
            {"scenes": ["cbox", {"name": "cbox-fog", "set": ["media.fog.sigma_t=-1"]}]},
            r"scenes: 'cbox-fog': .*media.fog.sigma_t",
        ),
    ],
)
def test_plan_loads_each_scene_with_its_overrides(change: dict, expect: str) -> None:
    """A misspelt or out-of-range override stops the plan before any job runs."""
    cfg = {**GOOD, **change}
    with pytest.raises(PlanError, match=expect):
        make_plan(cfg, ROOT, check_methods=False)
    good = {**GOOD, "scenes": ["cbox", "cbox-fog"], "set": ["film.width=8"]}
    assert list(make_plan(good, ROOT, check_methods=False).scenes) == ["cbox", "cbox-fog"]


DELTA = {"pt-delta": {"method": "pt", "set": ["integrator.estimator=delta"]}}


def test_variants_are_study_methods(tmp_path: Path) -> None:
    """A variant is one more method of the study: its label names its runs, and its render
    runs its own method with the scene's overrides, then its own, then method_args."""
    cfg = {
        **GOOD,
        "scenes_dir": str(_scenes(tmp_path)),
        "pgi": _fake_pgi(tmp_path),
        "set": ["film.width=8"],
        "variants": {**DELTA, "lt-short": {"method": "lt", "set": ["method.x=1"]}},
        "method_args": {"pt": ["--set", "method.spp_per_wave=4"]},
        "baseline": "pt-delta",
    }
    validate(cfg, SCHEMA)
    plan = make_plan(cfg, tmp_path, check_scenes=False)
    assert plan.methods == ("pt", "pt-delta", "lt-short")
    assert plan.base_method("pt-delta") == "pt" and plan.base_method("pt") == "pt"
    assert plan.render_args("cbox", "pt-delta") == [
        "--method", "pt", "--set", "film.width=8",
        "--set", "integrator.estimator=delta", "--set", "method.spp_per_wave=4",
    ]  # fmt: skip
    plain = ["--method", "pt", "--set", "film.width=8", "--set", "method.spp_per_wave=4"]
    assert plan.render_args("cbox", "pt") == plain
    assert plan.variants["pt-delta"].describe() == "pt with integrator.estimator=delta"
    excluded = make_plan({**cfg, "exclude_methods": ["lt-short"]}, tmp_path, check_scenes=False)
    assert excluded.methods == ("pt", "pt-delta") and "lt-short" not in excluded.variants


@pytest.mark.parametrize(
    ("variants", "expect"),
    [
        ({"lt": {"method": "pt"}}, r"variants: 'lt': the label is a method id"),
        ({"pt-x": {"method": "ptt"}}, r"variants: 'pt-x': unknown method 'ptt'; .*pt, lt"),
        (
            {"pt-big": {"method": "pt", "set": ["film.width=64"]}},
            r"variants: 'pt-big': set 'film.width=64' would change the scene its reference",
        ),
        (
            {"pt-d": {"method": "pt", "set": ["integrator.max_depth=2"]}},
            r"would change the scene its reference shows",
        ),
    ],
)
def test_plan_refuses_bad_variants(tmp_path: Path, variants: dict, expect: str) -> None:
    cfg = {**GOOD, "scenes_dir": str(_scenes(tmp_path)), "pgi": _fake_pgi(tmp_path)}
    with pytest.raises(PlanError, match=expect):
        make_plan({**cfg, "variants": variants}, tmp_path, check_scenes=False)


def test_plan_loads_each_scene_with_each_variant() -> None:
    bad = {"pt-x": {"method": "pt", "set": ["integrator.estimator=woodcock"]}}
    with pytest.raises(PlanError, match=r"variants: 'pt-x' on scene: 'cbox': .*estimator"):
        make_plan({**GOOD, "variants": bad}, ROOT)
    # as `pgi render` does: Mitsuba has no estimator of ours, the variant would repeat it
    unread = {"mi-delta": {"method": "mitsuba", "set": ["integrator.estimator=delta"]}}
    with pytest.raises(PlanError, match=r"variants: 'mi-delta': --set integrator.estimator="):
        make_plan({**GOOD, "variants": unread}, ROOT)
    assert make_plan({**GOOD, "variants": DELTA}, ROOT).methods == ("pt", "pt-delta")


@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["--bogus-flag"], r"method_args: pt: .*unrecognized arguments: --bogus-flag"),
        (["--spp", "64"], r"method_args: pt: --spp: the workflow gives this itself"),
        (["--meth", "lt"], r"method_args: pt: --method: the workflow gives this itself"),
        # at their defaults, or the workflow's own values, they used to pass (a review)
        (["--seed", "0"], r"method_args: pt: --seed: the workflow gives this itself"),
        (["--thr", "1"], r"method_args: pt: --threads: the workflow gives this itself"),
        (["--method", "pt"], r"method_args: pt: --method: the workflow gives this itself"),
        (["-o", "<workflow>.exr"], r"method_args: pt: -o/--output: the workflow gives this"),
        (["--set", "film.width=8"], r"method_args: pt: --set film.width=8: .*method.KEY=VALUE"),
        (["--set", "method.nosuch=1"], r"method_args: pt: method pt: unknown parameter"),
    ],
)
def test_plan_reads_method_args_as_pgi_render_would(args: list, expect: str) -> None:
    """Refused before any job: each of these failed the render jobs (or, --spp, stopped the
    runs before their last snapshot) after the references had run."""
    with pytest.raises(PlanError, match=expect):
        make_plan({**GOOD, "method_args": {"pt": args}}, ROOT)
    good = {"pt": ["-q", "--set", "method.spp_per_wave=2"]}
    assert make_plan({**GOOD, "method_args": good}, ROOT).method_args == {
        "pt": ("-q", "--set", "method.spp_per_wave=2")
    }


def test_plan_refuses_a_set_a_render_or_the_reference_would_refuse() -> None:
    """`set` reaches the Mitsuba references: the estimator of our tracking belongs in a
    variant (the study used to render every run, then fail at the first reference)."""
    with pytest.raises(PlanError, match=r"set \(scene 'cbox'\): .*the Mitsuba reference too"):
        make_plan({**GOOD, "set": ["integrator.estimator=delta"]}, ROOT)
    scenes = [{"name": "cbox", "set": ["integrator.march_step=0.01"]}]
    with pytest.raises(PlanError, match=r"integrator.march_step=0.01: Mitsuba does not read"):
        make_plan({**GOOD, "scenes": scenes}, ROOT)


def test_plan_refuses_a_variant_parameter_its_method_lacks() -> None:
    bad = {"pt-x": {"method": "pt", "set": ["method.nonexistent=3"]}}
    with pytest.raises(PlanError, match=r"variants: 'pt-x': method pt: unknown parameter"):
        make_plan({**GOOD, "variants": bad}, ROOT)


def test_plan_refuses_a_method_parameter_value_the_render_would_refuse() -> None:
    """Values are read as each render gets them, its method built on its scene: these passed
    the dry run and failed the render jobs after the references had run (found by a review)."""
    bad = {"pt-x": {"method": "pt", "set": ["method.spp_per_wave=0"]}}
    with pytest.raises(PlanError, match=r"pt-x on scene 'cbox': method pt: spp_per_wave must"):
        make_plan({**GOOD, "variants": bad}, ROOT)
    with pytest.raises(PlanError, match=r"pt on scene 'cbox': method pt: spp_per_wave must"):
        make_plan({**GOOD, "method_args": {"pt": ["--set", "method.spp_per_wave=abc"]}}, ROOT)
    # method_args reach the method's variants too
    wave = {"pt-w": {"method": "pt", "set": ["integrator.rr_depth=3"]}}
    args = {"pt": ["--set", "method.spp_per_wave=-1"]}
    with pytest.raises(PlanError, match=r"pt-w on scene 'cbox': .*got -1"):
        make_plan({**GOOD, "methods": ["lt"], "baseline": "lt", "variants": wave,
                   "method_args": args}, ROOT)  # fmt: skip
    assert make_plan({**GOOD, "variants": wave}, ROOT).methods == ("pt", "pt-w")


def test_plan_builds_each_method_on_each_scene(tmp_path: Path, monkeypatch) -> None:
    """A scene a method refuses stops the plan, not that method's renders after the references
    (found by a review): here a lit wall that ground fog reaches through, which the light-path
    methods refuse. Mitsuba only has its parameters read: its warm-up render took up to a
    minute per scene at 256x256."""
    from renderer.methods.mitsuba import MitsubaVolpath

    box = ROOT / "scenes" / "cbox" / "box.yaml"
    (tmp_path / "ground").mkdir()
    (tmp_path / "ground" / "scene.yaml").write_text(
        f"include: {box}\n"
        "media: {fog: {type: homogeneous, sigma_t: 2.0, albedo: 0.8}}\n"
        "materials: {boundary: {type: 'null'}}\n"
        "shapes:\n"
        "  - {name: fog-boundary, type: cube, material: boundary, interior: fog,\n"
        "     transform: [{scale: [0.99, 0.505, 1.0]}, {translate: [0, -0.505, -0.01]}]}\n"
    )
    cfg = {**GOOD, "scenes_dir": str(tmp_path), "scenes": [
        {"name": "ground", "set": ["shapes[2].emission=[1, 1, 1]"]}]}  # fmt: skip
    make_plan(cfg, ROOT)  # pt alone renders it
    with pytest.raises(PlanError, match=r"lt on scene 'ground': .* a boundary of a medium"):
        make_plan({**cfg, "methods": ["pt", "lt"]}, ROOT)

    def no_warm_up(*args, **kwargs):
        raise AssertionError("the plan loaded Mitsuba")

    monkeypatch.setattr(MitsubaVolpath, "__init__", no_warm_up)
    args = {"mitsuba": ["--set", "method.spp_per_iteration=0"]}
    with pytest.raises(PlanError, match=r"mitsuba on scene 'cbox': .*spp_per_iteration must"):
        make_plan({**GOOD, "methods": ["pt", "mitsuba"], "method_args": args}, ROOT)
    args = {"mitsuba": ["--set", "method.spp_per_iteration=4"]}
    make_plan({**GOOD, "methods": ["pt", "mitsuba"], "method_args": args}, ROOT)


def test_plan_records_the_code_fingerprints_and_refuses_a_pgi_without_them(tmp_path: Path) -> None:
    cfg = {**GOOD, "scenes_dir": str(_scenes(tmp_path)), "pgi": _fake_pgi(tmp_path)}
    plan = make_plan(cfg, tmp_path, check_scenes=False)
    assert plan.code == {"render": "r", "reference": "f"}
    old = tmp_path / "old-pgi"  # a pgi from before `fingerprint`: argparse refuses it
    old.write_text(
        "#!/bin/sh\n"
        'if [ "$1" = methods ]; then echo "pt  path tracing"; exit 0; fi\n'
        "echo 'pgi: error: invalid choice' >&2; exit 2\n"
    )
    old.chmod(0o755)
    with pytest.raises(PlanError, match=r"fingerprint` failed \(exit 2\).*invalid choice"):
        make_plan({**cfg, "pgi": str(old)}, tmp_path, check_methods=True, check_scenes=False)


@pytest.mark.parametrize(
    ("change", "expect"),
    [
        # YAML reads these labels as a number and a boolean: a traceback in the rules before.
        ({"variants": {1: {"method": "pt"}}}, r"variants: 1 is read as a int, not a label"),
        ({"method_args": {True: []}}, r"method_args: True is read as a bool, not a label"),
        ({"pgi": 'pgi "unbalanced'}, r"pgi: cannot split .* into a command: No closing"),
        # pgi names snapshots with 6 significant digits: 1e6 is "1e+06", never "1000000"
        ({"budgets": [1, 0.1234567]}, r"budgets: 0.1234567 has more than the 6 significant"),
        ({"budgets": [1000000, 1000001]}, r"budgets: two budgets have the same file tag"),
        ({"determined_fraction": float("nan")}, r"determined_fraction: expected a finite number"),
        ({"reference": {"target": float("inf")}}, r"reference.target: expected a finite number"),
        (
            {"results_dir": "README.md/r"},
            r"results_dir: .*README.md/r cannot be made: .* is a file",
        ),
        ({"reports_dir": "README.md"}, r"reports_dir: .*README.md is a file, not a folder"),
        ({"reports_dir": "/proc/pgi-reports"}, r"reports_dir: cannot write in /proc"),
    ],
)
def test_plan_refuses_configs_that_failed_late_or_with_a_traceback(
    tmp_path: Path, change: dict, expect: str
) -> None:
    """Found by fuzzing the configs: each passed the plan and failed in a rule, at the first
    job that wrote, or silently."""
    with pytest.raises(PlanError, match=expect):
        make_plan({**GOOD, **change}, ROOT, check_methods=False, check_scenes=False)


def test_plan_names_large_budgets_as_pgi_names_their_snapshots() -> None:
    from renderer.progressive import snapshot_path

    plan = make_plan({**GOOD, "budgets": [0.5, 1000000]}, ROOT, check_methods=False,
                     check_scenes=False)  # fmt: skip
    assert plan.budget_tags == ["0.5", "1e+06"]
    assert snapshot_path(Path("run.exr"), float(plan.budget_tags[1])).name == "run.t1e+06.exr"


def test_plan_gives_up_on_a_pgi_that_never_answers(tmp_path: Path, monkeypatch) -> None:
    import subprocess

    def never(*args, **kwargs):
        raise subprocess.TimeoutExpired(args[0], 120)

    monkeypatch.setattr(subprocess, "run", never)
    with pytest.raises(PlanError, match=r"pgi: cannot run `.* methods`: .*timed out"):
        make_plan({**GOOD, "pgi": "sleepy-pgi"}, ROOT, check_scenes=False)


def test_plan_refuses_a_variant_setting_that_method_args_would_override() -> None:
    """method_args come last on the render's command line: the variant would silently be
    its method unchanged while the report described it by its own setting."""
    variant = {"pt-w4": {"method": "pt", "set": ["method.spp_per_wave=4"]}}
    args = {"pt": ["--set", "method.spp_per_wave=2"]}
    with pytest.raises(PlanError, match=r"variants: 'pt-w4': method.spp_per_wave is also set"):
        make_plan({**GOOD, "variants": variant, "method_args": args}, ROOT)
    other = {"pt": ["-q"]}
    make_plan({**GOOD, "variants": variant, "method_args": other}, ROOT)


def test_config_text_that_yaml_11_reads_as_a_number_or_boolean_is_refused(tmp_path: Path) -> None:
    """The workflow reads configs as YAML 1.1, where `1:30` is 90 (sexagesimal) and `010` is
    8 (octal): a budget of 90 s and seed 8 nobody wrote (found by fuzzing the configs); `off`
    is False, which the schema would call a wrong type though the text was meant."""
    from compare.plan import check_config_files

    for line, expect in (("budgets: [1, 1:30]", r"budgets\[1\]: '1:30' is read as 90"),
                         ("seeds: [010]", r"seeds\[0\]: '010' is read as 8"),
                         ("methods: [pt, off]", r"methods\[1\]: 'off' is read as False.*quote it"),
                         ):  # fmt: skip
        file = tmp_path / "c.yaml"
        file.write_text(f"scenes: [cbox]\n{line}\n")
        with pytest.raises(PlanError, match=expect):
            check_config_files([file])
    file.write_text("scenes: [cbox]\nbudgets: [1, 90]\nseeds: [8]\nname: '010'\n")
    check_config_files([file])


@pytest.mark.parametrize(
    ("change", "expect"),
    [
        ({"set": ["method.spp_per_wave=2"]}, r"^set: method.spp_per_wave: method parameters"),
        (
            {"scenes": [{"name": "cbox", "set": ["method.light_paths=64"]}]},
            r"^scenes: 'cbox': set: method.light_paths: method parameters .* use method_args",
        ),
    ],
)  # fmt: skip
def test_plan_refuses_method_parameters_in_a_scene_set(
    tmp_path: Path, change: dict, expect: str
) -> None:
    """A study's or a scene's `set` reaches every method and the reference: a method parameter
    there was reported as an unknown key of a scene file the user never touched (found by an
    error-handling probe)."""
    cfg = {**GOOD, "scenes_dir": str(_scenes(tmp_path)), "pgi": _fake_pgi(tmp_path), **change}
    with pytest.raises(PlanError, match=expect):
        make_plan(cfg, tmp_path, check_scenes=False)


@pytest.mark.parametrize("number", [1e-9, 2e20, -3e-5, 1.5e300, 0.5, 123456.0, 1000, 5e-324])
def test_the_spelling_a_hint_suggests_is_a_number_in_yaml_11(number: float) -> None:
    """The remedy a hint gives must itself be read as the number by the workflow's reader."""
    from compare.plan import yaml11_spelling

    assert yaml.safe_load(yaml11_spelling(number)) == number
