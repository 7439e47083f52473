"""The study plan: a validated workflow config resolved into scenes, methods, budgets, seeds.

The Snakefile calls :func:`make_plan` once; nothing in the rules names a scene or a method.
Methods come from the config, or from `pgi methods` when the config says ``methods: all``.
A *variant* is a method run with settings of its own under a label of its own (``pt-delta``:
``pt`` with delta tracking); to the rules and the report it is one more method.
"""

from __future__ import annotations

import json
import math
import shlex
import shutil
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from jsonschema.exceptions import best_match

# The comment line with which `pgi methods` announces methods not implemented yet.
from renderer.cli import PLANNED_PREFIX
from renderer.errors import PgiError
from renderer.imageio import check_folder_can_be_made
from renderer.methods import check_method_parameters, check_overrides
from renderer.progressive import snapshot_label
from renderer.scene import load_scene
from renderer.scene.model import format_path

from .metrics import DETERMINED_FRACTION


class PlanError(ValueError):
    """A config that passed the schema but cannot be run (unknown scene or method, ...)."""


def check_config_files(files: list[Path]) -> None:
    """Config files read strictly before the workflow's own reader (YAML 1.1) takes them: a
    key written twice would silently keep its last value, and YAML 1.1 reads some text as
    numbers no one meant (`1:30` is 90, `010` is 8)."""
    import yaml

    from renderer.scene.model import format_path
    from renderer.scene.yaml_dialect import check_yaml_file

    for file in files:
        try:
            read = check_yaml_file(Path(file))
        except PgiError as e:
            raise PlanError(str(e)) from None
        if read is None:
            continue
        strict, text = read
        try:
            loose = yaml.safe_load(text)  # the same text, as YAML 1.1 reads it
        except yaml.YAMLError:
            continue  # the workflow's reader says so itself
        for path, text, value in _values_only_yaml11_sees(strict, loose):
            remedy = (
                "quote it if you mean the text (no config key takes a boolean)"
                if isinstance(value, bool) else "write the number you mean"
            )  # fmt: skip
            raise PlanError(
                f"{file}: {format_path(path)}: {text!r} is read as {value} by the "
                f"workflow's YAML 1.1 reader; {remedy}"
            )


def _values_only_yaml11_sees(
    strict: Any, loose: Any, path: tuple = ()
) -> list[tuple[tuple, str, float | bool]]:
    """Leaves that YAML 1.2 reads as text and YAML 1.1 as a number (sexagesimal, octal) or a
    boolean (yes, no, on, off)."""
    if isinstance(strict, dict) and isinstance(loose, dict):
        return [hit for k in strict if k in loose
                for hit in _values_only_yaml11_sees(strict[k], loose[k], (*path, k))]  # fmt: skip
    if isinstance(strict, list) and isinstance(loose, list) and len(strict) == len(loose):
        return [hit for i, (s, lo) in enumerate(zip(strict, loose, strict=True))
                for hit in _values_only_yaml11_sees(s, lo, (*path, i))]  # fmt: skip
    misread = isinstance(loose, int | float)  # bool is an int too
    return [(path, strict, loose)] if misread and isinstance(strict, str) else []


def number_as_text_hint(value: Any, expected: Any = "number") -> str:
    """For a schema's type error (``expected``: the type it wanted): why a number may have
    arrived as text. The workflow reads configs as YAML 1.1, where 5e-1 and 1.0e3 are strings
    (scene files read them as numbers). No hint where the number would not do either."""
    from renderer.scene.yaml_dialect import parse_yaml_value

    if not isinstance(value, str):
        return ""
    try:
        number = parse_yaml_value(value, "config")
    except PgiError:
        return ""
    if isinstance(number, bool) or not isinstance(number, int | float):
        return ""
    if not math.isfinite(number):
        return ""
    if isinstance(number, float) and number.is_integer() and abs(number) < 2**53:
        number = int(number)  # 1.0e3 -> 1000, which fits an integer key too
    if expected == "integer" and not isinstance(number, int):
        return ""
    spelled = yaml11_spelling(number)
    try:  # text that YAML 1.1 itself reads as a number was quoted
        quoted = not isinstance(yaml.safe_load(value), str)
    except yaml.YAMLError:
        quoted = False
    if quoted:
        # Quoted in a file, or a list item given with snakemake's --config, which reads them
        # all as text: the remedy differs, so both are said.
        return (
            f" (it is text: in a config file write {spelled} without quotes; snakemake's "
            "--config reads list items as text, so give lists in a config file)"
        )
    return (
        f" (the workflow reads configs as YAML 1.1, where {value} is text, not a number: "
        f"write {spelled})"
    )


def yaml11_spelling(number: int | float) -> str:
    """How to write a number so that YAML 1.1 reads it as one: its float needs a dot in the
    mantissa (1e-09 is text there, 1.0e-09 a number; repr always signs the exponent)."""
    text = repr(number)
    mantissa, e, exponent = text.partition("e")
    if isinstance(number, float) and e and "." not in mantissa:
        text = f"{mantissa}.0e{exponent}"
    return text


# How a schema type reads in a message.
_TYPE_WORDS = {
    "array": "a list",
    "object": "a mapping",
    "string": "a string",
    "integer": "an integer",
    "number": "a number",
    "boolean": "true or false",
}


def _type_words(expected: Any) -> list[str]:
    names = [expected] if isinstance(expected, str) else list(expected)
    return [_TYPE_WORDS.get(n, n) for n in names]


def _key_path(error: Any) -> str:
    return format_path(error.absolute_path) if error.absolute_path else "top level"


def schema_error_message(error: Any) -> str:
    """One line for a config's schema error (a ``jsonschema.ValidationError``): the key path
    and what is wrong there. Where a key may take one of several forms (``oneOf``), the
    schema's own message ("is not valid under any of the given schemas") names neither; this
    reports what is wrong with the form the value has (a mapping missing ``name``, a string
    that is no scene name) and says which other forms the key takes."""
    other_forms = ""
    while error.context:
        # Each form (branch of the oneOf) the value failed, by its index in the oneOf.
        branches: dict[Any, list] = {}
        for e in error.context:
            branches.setdefault(e.relative_schema_path[0], []).append(e)
        # A form that wants another type is not the one meant: drop it, but say it exists.
        wanted: list[str] = []
        meant = []
        for errors in branches.values():
            type_errors = [e for e in errors if e.validator == "type" and not e.relative_path]
            if type_errors:
                wanted += _type_words(type_errors[0].validator_value)
            else:
                meant += errors
        if not meant:
            return f"{_key_path(error)}: {error.instance!r} is not {' or '.join(wanted)}"
        if wanted:
            other_forms = f" ({_key_path(error)} may also be {' or '.join(wanted)})"
        error = best_match(meant)
    message = error.message
    if error.validator == "type":  # a number that arrived as text (YAML 1.1)?
        message += number_as_text_hint(error.instance, error.validator_value)
    elif error.validator == "pattern":  # a key taking a number or a word (reference.spp)
        numeric = [t for t in ("integer", "number") if t in (error.schema.get("type") or ())]
        if numeric:
            message += number_as_text_hint(error.instance, numeric[0])
    return f"{_key_path(error)}: {message}{other_forms}"


@dataclass(frozen=True)
class SceneSpec:
    name: str
    path: Path  # scene folder
    set: tuple[str, ...] = ()
    # samples per reference half; None: sized to the study (compare.sizing) within the cap
    reference_spp: int | None = None
    reference_max_seconds: float = 120.0  # the cap of a sized reference, both halves
    # what renders its reference: "mitsuba" (checked against pgi's pt, which takes over where
    # Mitsuba's is not trustworthy) or "pgi" (pgi's pt from the start)
    reference_source: str = "mitsuba"

    @property
    def reference_sized(self) -> bool:
        return self.reference_spp is None


# The settings a variant may change: they change how an image is estimated, not what it
# shows (ray marching's bias is there to be measured), so every variant is compared with the
# scene's one reference.
VARIANT_SCENE_KEYS = (
    "integrator.estimator",
    "integrator.march_step",
    "integrator.rr_depth",
    "integrator.rr",
)


@dataclass(frozen=True)
class VariantSpec:
    method: str  # the `pgi methods` id it runs
    set: tuple[str, ...] = ()  # `--set` overrides: method.* parameters and VARIANT_SCENE_KEYS

    def describe(self) -> str:
        return f"{self.method} with {', '.join(self.set)}" if self.set else self.method


@dataclass(frozen=True)
class Plan:
    name: str
    root: Path  # folder of the Snakefile; scenes_dir is relative to it
    results: Path  # relative to Snakemake's working directory unless absolute
    reports: Path
    pgi: tuple[str, ...]
    threads: int
    ref_threads: int
    scenes: dict[str, SceneSpec]
    methods: tuple[str, ...]
    budgets: tuple[float, ...]
    seeds: tuple[int, ...]
    ref_seed: int
    # sized references: the pilot's spp per half, and the target (reference relMSE over the
    # best method's at the largest budget)
    ref_pilot_spp: int = 16
    ref_target: float = 1.0
    # spp per half of pgi's pt check of each reference (and the pilot of a reference pt renders)
    ref_check_spp: int = 16
    method_args: dict[str, tuple[str, ...]] = field(default_factory=dict)
    variants: dict[str, VariantSpec] = field(default_factory=dict)
    baseline: str = "pt"
    primary_metric: str = "relmse"
    determined_fraction: float = DETERMINED_FRACTION
    title: str = "pgi comparison"
    viewer_max_size: int = 512
    timed_render_slots: int = 1
    # `pgi fingerprint`: digests of the code behind renders and references (empty when the
    # plan was made without asking pgi)
    code: dict[str, str] = field(default_factory=dict)

    @property
    def budget_tags(self) -> list[str]:
        return [budget_tag(b) for b in self.budgets]

    def snapshot_arg(self) -> str:
        return ",".join(self.budget_tags)

    def scene_set_args(self, scene: str) -> list[str]:
        out: list[str] = []
        for kv in self.scenes[scene].set:
            out += ["--set", kv]
        return out

    def variant(self, label: str) -> VariantSpec:
        """What a study method runs: a variant's spec, or the method itself unchanged."""
        return self.variants.get(label) or VariantSpec(method=label)

    def base_method(self, label: str) -> str:
        """The `pgi methods` id a study method runs (itself, unless it is a variant)."""
        return self.variant(label).method

    def render_args(self, scene: str, label: str) -> list[str]:
        """`pgi render` arguments of one study method on one scene, after the scene: the
        method, the scene's overrides, the variant's settings, then `method_args`."""
        run = self.variant(label)
        out = ["--method", run.method, *self.scene_set_args(scene)]
        for kv in run.set:
            out += ["--set", kv]
        return out + list(self.method_args.get(run.method, ()))


# How a budget appears in file names and in --snapshots: as `pgi render` names snapshots.
budget_tag = snapshot_label


def resolve_pgi(setting: str) -> tuple[str, ...]:
    """The command prefix that runs the renderer CLI."""
    if setting != "auto":
        try:
            return tuple(shlex.split(setting))
        except ValueError as e:  # an unbalanced quote
            raise PlanError(f"pgi: cannot split {setting!r} into a command: {e}") from None
    sibling = Path(sys.executable).parent / "pgi"
    if sibling.is_file():
        return (str(sibling),)
    found = shutil.which("pgi")
    if found:
        return (found,)
    return (sys.executable, "-m", "renderer.cli")


def available_methods(pgi: tuple[str, ...]) -> tuple[list[str], list[str]]:
    """Method ids printed by `pgi methods` (first token of each non-comment line), and the ids
    it announces as not yet implemented."""
    try:
        proc = subprocess.run(
            [*pgi, "methods"], capture_output=True, text=True, timeout=120, check=False
        )
    except (OSError, subprocess.TimeoutExpired) as e:
        raise PlanError(f"pgi: cannot run `{' '.join(pgi)} methods`: {e}") from e
    if proc.returncode != 0:
        raise PlanError(
            f"`{' '.join(pgi)} methods` failed (exit {proc.returncode}): "
            f"{proc.stderr.strip() or proc.stdout.strip()}"
        )
    ids, planned = [], []
    for line in proc.stdout.splitlines():
        if line.startswith(PLANNED_PREFIX):
            planned += [m.strip() for m in line[len(PLANNED_PREFIX) :].split(",") if m.strip()]
            continue
        tok = line.strip().split()
        if tok and not tok[0].startswith("#"):
            ids.append(tok[0])
    return ids, planned


def code_fingerprints(pgi: tuple[str, ...]) -> dict[str, str]:
    """`pgi fingerprint`: {"render": digest, "reference": digest}."""
    try:
        proc = subprocess.run(
            [*pgi, "fingerprint"], capture_output=True, text=True, timeout=120, check=False
        )
    except (OSError, subprocess.TimeoutExpired) as e:
        raise PlanError(f"pgi: cannot run `{' '.join(pgi)} fingerprint`: {e}") from e
    try:
        code = json.loads(proc.stdout) if proc.returncode == 0 else None
    except json.JSONDecodeError:
        code = None
    if not isinstance(code, dict) or not {"render", "reference"} <= set(code):
        raise PlanError(
            f"`{' '.join(pgi)} fingerprint` failed (exit {proc.returncode}): expected JSON "
            f"with render and reference digests, got {(proc.stderr or proc.stdout).strip()!r}"
        )
    return {"render": str(code["render"]), "reference": str(code["reference"])}


# Scenes the plan has loaded, by (scene file, overrides): each is checked, then built with
# every method, from one load.
_Loaded = dict[tuple[Path, tuple[str, ...]], Any]


def _load_once(loaded: _Loaded, path: Path, overrides: tuple[str, ...]) -> Any:
    if (path, overrides) not in loaded:
        loaded[path, overrides] = load_scene(path, overrides)
    return loaded[path, overrides]


def check_scene(
    spec: SceneSpec,
    extra: tuple[str, ...] = (),
    where: str = "scenes",
    loaded: _Loaded | None = None,
) -> None:
    """Load a scene with the study's overrides (and a variant's, ``extra``): a misspelt `set`
    key stops the plan, not the first render (after the references may have run for minutes)."""
    from renderer.engine import march_step  # the native core: only when scenes are checked

    path = spec.path / "scene.yaml"
    try:
        scene = _load_once({} if loaded is None else loaded, path, spec.set + extra)
        for medium in scene.media.values():  # the step is checked when the core is built
            if medium.type == "grid":
                march_step(
                    medium, scene.integrator.march_step, scene.where("integrator", "march_step")
                )
    except PgiError as e:
        raise PlanError(f"{where}: '{spec.name}': {e}") from e


def check_scene_sets(spec: SceneSpec, methods: list[str]) -> None:
    """A study's `set` reaches every render of the scene and its Mitsuba reference: a setting
    one of them would refuse (the transmittance estimator: Mitsuba has its own) stops the
    plan, not the first job to meet it."""
    for method in ["mitsuba", *methods]:
        try:
            check_overrides(method, spec.set)
        except PgiError as e:
            whom = "the Mitsuba reference" if method == "mitsuba" else f"method {method}"
            raise PlanError(
                f"set (scene '{spec.name}'): {e}; `set` reaches {whom} too: put settings of "
                "one method in a variant (variants: {label: {method: ..., set: [...]}})"
            ) from None


# `pgi render` options the workflow gives every render itself.
_WORKFLOW_OPTIONS = {
    "method": "--method",
    "time": "--time",
    "spp": "--spp",
    "snapshots": "--snapshots",
    "seed": "--seed",
    "threads": "--threads",
    "output": "-o/--output",
}


_UNSET = object()


def _render_parser_for_method_args() -> Any:
    """`pgi render`'s own parser, with _WORKFLOW_OPTIONS optional and defaulting to _UNSET: a
    parse of ``method_args`` alone then shows which of them they give, also at their default
    value (``--seed 0``) or abbreviated (``--thr 1``)."""
    import argparse

    from renderer.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    render = sub.choices["render"]
    for action in render._actions:
        if action.dest in _WORKFLOW_OPTIONS:
            action.required, action.default = False, _UNSET
    return render


def check_method_args(method: str, args: tuple[str, ...]) -> list[str]:
    """``method_args`` as `pgi render` would read them, before any job runs: options it knows,
    none that are the workflow's to give (``--spp`` would stop a run before its last snapshot), and
    ``--set`` only for method parameters (a scene value would change what the reference
    shows). Returns the parameters they set (``method.KEY``)."""
    import contextlib
    import io

    from renderer.methods import method_ids

    where = f"method_args: {method}"
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr):
            parsed = _render_parser_for_method_args().parse_args(["scene", *args])
    except SystemExit:
        why = stderr.getvalue().strip().splitlines()
        raise PlanError(
            f"{where}: {why[-1] if why else 'not valid `pgi render` arguments'}"
        ) from None
    given = [o for dest, o in _WORKFLOW_OPTIONS.items() if getattr(parsed, dest) is not _UNSET]
    if given:
        raise PlanError(
            f"{where}: {', '.join(given)}: the workflow gives this itself (a run's budgets are "
            "its snapshots)"
        )
    keys = []
    for kv in parsed.set:
        key = kv.split("=", 1)[0]
        if not key.startswith("method.") or "=" not in kv:
            raise PlanError(
                f"{where}: --set {kv}: method_args may set method.KEY=VALUE only; a scene "
                "value belongs in `set`, where the reference sees it too"
            )
        keys.append(key[len("method.") :])
    if method in method_ids():  # else announced, not implemented: parameters not known yet
        try:
            check_method_parameters(method, keys)
        except PgiError as e:
            raise PlanError(f"{where}: {e}") from None
    return [f"method.{key}" for key in keys]


def check_one_value_per_key(overrides: Sequence[str], where: str) -> tuple[str, ...]:
    """A list of `key=value` overrides that sets one key twice keeps the last value silently (a
    variant `pt-delta` setting the estimator to delta and then to ratio is plain pt under a
    misleading label): refused, naming the key."""
    seen: set[str] = set()
    for kv in overrides:
        key = str(kv).split("=", 1)[0].strip()
        if key in seen:
            raise PlanError(f"{where}: {key} is set twice; the render would take the last value")
        seen.add(key)
    return tuple(overrides)


def check_scene_overrides_only(overrides: Sequence[str], where: str) -> tuple[str, ...]:
    """A study's or a scene's `set` reaches every method and the reference, so it may change
    the scene only: a method parameter there would be reported as a key the scene does not
    have, naming a scene file the user never touched."""
    for kv in overrides:
        key = str(kv).split("=", 1)[0].strip()
        if key == "method" or key.startswith("method."):
            raise PlanError(
                f"{where}: {key}: method parameters cannot go in a study's or a scene's set (it "
                "reaches every method and the reference); use method_args or a variant"
            )
    return tuple(overrides)


def make_variants(
    config: dict[str, Any], avail: list[str], planned: list[str], check: bool
) -> dict[str, VariantSpec]:
    """The config's ``variants``, checked: a label of its own, a method `pgi methods` lists,
    and only settings that leave the expected image unchanged (ray marching's bias aside)."""
    variants: dict[str, VariantSpec] = {}
    listed = [] if config["methods"] == "all" else list(config["methods"])
    for label, entry in (config.get("variants") or {}).items():
        where = f"variants: '{label}'"
        spec = VariantSpec(
            method=str(entry["method"]),
            set=check_one_value_per_key(entry.get("set") or (), f"{where}: set"),
        )
        if label in listed or (check and label in avail + planned):
            raise PlanError(f"{where}: the label is a method id of `pgi methods`; pick another")
        if check and spec.method not in avail:
            raise PlanError(
                f"{where}: unknown method '{spec.method}'; "
                f"`pgi methods` lists: {', '.join(avail) or 'none'}"
            )
        for kv in spec.set:
            key = kv.split("=", 1)[0]
            if not key.startswith("method.") and key not in VARIANT_SCENE_KEYS:
                raise PlanError(
                    f"{where}: set '{kv}' would change the scene its reference shows; a "
                    f"variant may set method.KEY or {', '.join(VARIANT_SCENE_KEYS)}"
                )
        variants[label] = spec
    return variants


def _check_labels(config: dict[str, Any]) -> None:
    """Variant labels and method_args keys are text: YAML reads `1:` or `yes:` as a number or
    a boolean, which no file name or method id is."""
    for key in ("variants", "method_args"):
        for label in config.get(key) or {}:
            if not isinstance(label, str):
                raise PlanError(
                    f"{key}: {label!r} is read as a {type(label).__name__}, not a label: "
                    f"quote it ('{label}')"
                )


def make_plan(
    config: dict[str, Any],
    root: str | Path,
    check_methods: bool = True,
    check_scenes: bool = True,
) -> Plan:
    """Resolve a schema-validated config (defaults filled in) into a :class:`Plan`.

    ``check_methods`` asks `pgi methods` whether the methods exist; ``check_scenes`` loads
    every scene with its overrides, when `pgi` is this package's own (``pgi: auto``): another
    command may read scenes its own way."""
    root = Path(root).resolve()
    _check_labels(config)
    pgi = resolve_pgi(str(config.get("pgi", "auto")))
    scenes_dir = root / config.get("scenes_dir", "scenes")
    ref = dict(config.get("reference") or {})
    global_set = check_scene_overrides_only(
        check_one_value_per_key(config.get("set") or (), "set"), "set"
    )
    # Scenes and arguments are checked here only when `pgi` is this package's own: another
    # command may read them its own way.
    check_here = check_scenes and str(config.get("pgi", "auto")) == "auto"
    fixed_spp = ref.get("spp", "auto")
    default_spp = None if fixed_spp == "auto" else int(fixed_spp)
    default_cap = float(ref.get("max_seconds", 120.0))
    loaded: _Loaded = {}  # each scene read once for all the checks below

    scenes: dict[str, SceneSpec] = {}
    for item in config["scenes"]:
        entry = {"name": item} if isinstance(item, str) else dict(item)
        name = entry["name"]
        if name in scenes:
            raise PlanError(f"scenes: '{name}' is listed twice")
        folder = scenes_dir / name
        if not (folder / "scene.yaml").is_file():
            known = sorted(p.name for p in scenes_dir.glob("*") if (p / "scene.yaml").is_file())
            raise PlanError(
                f"scenes: no scene '{name}' ({folder / 'scene.yaml'} does not exist); "
                f"known scenes: {', '.join(known) or 'none'}"
            )
        scenes[name] = SceneSpec(
            name=name,
            path=folder,
            # A scene's own `set` may override the study's for that scene.
            set=global_set
            + check_scene_overrides_only(
                check_one_value_per_key(entry.get("set") or (), f"scenes: '{name}': set"),
                f"scenes: '{name}': set",
            ),
            reference_spp=(
                int(entry["reference_spp"]) if "reference_spp" in entry else default_spp
            ),
            reference_max_seconds=float(entry.get("reference_max_seconds", default_cap)),
            reference_source=str(entry.get("reference_source", ref.get("source", "mitsuba"))),
        )
        if check_here:
            check_scene(scenes[name], loaded=loaded)

    wanted = config["methods"]
    exclude = set(config.get("exclude_methods") or ())
    if wanted == "all" or check_methods:
        avail, planned = available_methods(pgi)
    else:
        avail, planned = [], []
    variants = make_variants(config, avail, planned, check=check_methods or wanted == "all")
    labels = [v for v in variants if v not in exclude]
    if check_here:
        for label in labels:
            scene_keys = tuple(kv for kv in variants[label].set if not kv.startswith("method."))
            method_keys = [kv.split("=", 1)[0][len("method.") :] for kv in variants[label].set
                           if kv.startswith("method.")]  # fmt: skip
            try:  # as `pgi render` would, before any job runs
                check_overrides(variants[label].method, scene_keys)
                check_method_parameters(variants[label].method, method_keys)
            except PgiError as e:
                raise PlanError(f"variants: '{label}': {e}") from e
            for spec in scenes.values() if scene_keys else ():
                check_scene(spec, scene_keys, f"variants: '{label}' on scene", loaded)
    if wanted == "all":
        methods = [m for m in avail if m not in exclude] + labels
        if not methods:
            raise PlanError("methods: 'all' but `pgi methods` lists no method")
    else:
        methods = [m for m in wanted if m not in exclude] + labels
        if not methods:
            raise PlanError("methods: no method left after exclude_methods")
    if check_methods or wanted == "all":
        # A misspelt id would silently drop a method, its arguments or an exclusion. A method
        # announced but not implemented may be excluded or configured ahead of its arrival.
        for key, names, known in (
            ("methods", [] if wanted == "all" else wanted, avail),
            ("exclude_methods", sorted(exclude), avail + planned + list(variants)),
            ("method_args", list(config.get("method_args") or {}), avail + planned),
        ):
            unknown = [m for m in names if m not in known]
            if unknown:
                raise PlanError(
                    f"{key}: unknown method(s) {', '.join(unknown)}; "
                    f"`pgi methods` lists: {', '.join(avail) or 'none'}"
                )
    method_args = {
        k: tuple(str(a) for a in v) for k, v in (config.get("method_args") or {}).items()
    }
    if check_here:
        args_set = {method: check_method_args(method, args) for method, args in method_args.items()}
        for label in labels:
            run = variants[label]
            # Both reach the render, method_args last: the variant would be its method unchanged.
            clash = [
                k
                for k in (kv.split("=", 1)[0] for kv in run.set)
                if k in args_set.get(run.method, ())
            ]
            if clash:
                raise PlanError(
                    f"variants: '{label}': {clash[0]} is also set by method_args: {run.method}, "
                    "whose value the render would take; set it in one place"
                )
        for spec in scenes.values():
            check_scene_sets(
                spec, sorted({variants[m].method if m in variants else m for m in methods})
            )
    baseline = str(config.get("baseline", "pt"))
    if baseline not in methods:
        raise PlanError(
            f"baseline: '{baseline}' is not among the methods of this study "
            f"({', '.join(methods)}); set `baseline:` to one of them"
        )

    budgets = tuple(sorted(float(b) for b in config["budgets"]))
    if not all(math.isfinite(b) for b in budgets):
        raise PlanError(f"budgets: expected finite seconds, got {list(config['budgets'])}")
    ref_seed = int(ref.get("seed", 1000000))
    # `pgi` takes seeds in [0, 2^63); reference half h renders with ref_seed + h.
    bad = [s for s in config["seeds"] if not 0 <= int(s) < 2**63]
    if bad:
        raise PlanError(f"seeds: expected integers in [0, 2^63), got {bad}")
    if not 0 <= ref_seed < 2**63 - 1:
        raise PlanError(f"reference.seed: expected an integer in [0, 2^63 - 1), got {ref_seed}")
    tags = [budget_tag(b) for b in budgets]
    if len(set(tags)) != len(tags):
        raise PlanError(f"budgets: two budgets have the same file tag: {tags}")
    for b, tag in zip(budgets, tags, strict=True):
        if float(tag) != b:  # --snapshots gets the tag: the render would stop at float(tag)
            raise PlanError(
                f"budgets: {b!r} has more than the 6 significant digits that file names and "
                f"--snapshots carry; write {tag}"
            )
    fraction = float(config.get("determined_fraction", DETERMINED_FRACTION))
    if not math.isfinite(fraction):
        raise PlanError(f"determined_fraction: expected a finite number, got {fraction}")
    target = float(ref.get("target", 1.0))
    for key, value in (("reference.target", target), ("reference.max_seconds", default_cap)):
        if not math.isfinite(value):
            raise PlanError(f"{key}: expected a finite number, got {value}")
    for name, spec in scenes.items():
        if not math.isfinite(spec.reference_max_seconds):
            raise PlanError(
                f"scenes: '{name}': reference_max_seconds: expected a finite number, got "
                f"{spec.reference_max_seconds}"
            )
    # Checked before any job runs, not found by the first job that writes there (or, for the
    # reports, by the last).
    for key, default in (("results_dir", "results"), ("reports_dir", "reports")):
        try:
            check_folder_can_be_made(root / str(config.get(key, default)))
        except PgiError as e:
            raise PlanError(f"{key}: {e}") from None
    report = dict(config.get("report") or {})
    threads = int(config.get("threads", 2))
    plan = Plan(
        name=str(config.get("name", "study")),
        root=root,
        results=Path(config.get("results_dir", "results")),
        reports=Path(config.get("reports_dir", "reports")),
        pgi=pgi,
        threads=threads,
        ref_threads=int(ref.get("threads") or threads),
        scenes=scenes,
        methods=tuple(methods),
        budgets=budgets,
        seeds=tuple(int(s) for s in config["seeds"]),
        ref_seed=ref_seed,
        ref_pilot_spp=int(ref.get("pilot_spp", 16)),
        ref_check_spp=int(ref.get("check_spp", 16)),
        ref_target=target,
        method_args=method_args,
        variants={label: variants[label] for label in labels},
        baseline=baseline,
        primary_metric=str(config.get("primary_metric", "relmse")),
        determined_fraction=fraction,
        title=str(report.get("title", "pgi comparison")),
        viewer_max_size=int(report.get("viewer_max_size", 512)),
        timed_render_slots=int(config.get("timed_render_slots", 1)),
        code=code_fingerprints(pgi) if check_methods else {},
    )
    if check_here:
        check_method_values(plan, loaded)
    return plan


def check_method_values(plan: Plan, loaded: _Loaded | None = None) -> None:
    """Every render as it will run, before any job: each method is built on its scene with
    the settings it will get (a study's and a scene's `set`, a variant's, then
    `method_args`) and dropped, so that a parameter out of range (`method.spp_per_wave=0`)
    or a scene a method refuses (an emitter a medium's boundary crosses, for the light-path
    methods) stops the plan, not the renders after the references have run. Building takes
    milliseconds (pm's photon buffers a few tenths of a second); Mitsuba, whose warm-up
    render can take a minute, only has its parameters read."""
    from renderer.cli import split_sets
    from renderer.methods import get_method, method_ids

    loaded = {} if loaded is None else loaded
    for name, spec in plan.scenes.items():
        for label in plan.methods:
            args = plan.render_args(name, label)
            method = args[1]
            if method not in method_ids():
                continue
            sets = [args[i + 1] for i, a in enumerate(args) if a == "--set"]
            overrides, params = split_sets(sets)
            cls = get_method(method)
            try:
                scene = _load_once(loaded, spec.path / "scene.yaml", tuple(overrides))
                if hasattr(cls, "check_parameters"):
                    cls.check_parameters(scene, params)
                else:
                    cls(scene, seed=0, threads=1, params=params, spp_budget=None)
            except PgiError as e:
                raise PlanError(f"{label} on scene '{name}': {e}") from None
