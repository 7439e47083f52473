"""The study plan: a validated workflow config resolved into scenes, methods, budgets, seeds.

The Snakefile calls :func:`make_plan` once; nothing in the rules names a scene or a method.
Methods come from the config, or from `pgi methods` when the config says ``methods: all``.
"""

from __future__ import annotations

import math
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

# The comment line with which `pgi methods` announces methods not implemented yet.
from renderer.cli import PLANNED_PREFIX
from renderer.errors import PgiError
from renderer.scene import load_scene


class PlanError(ValueError):
    """A config that passed the schema but cannot be run (unknown scene or method, ...)."""


@dataclass(frozen=True)
class SceneSpec:
    name: str
    path: Path  # scene folder
    set: tuple[str, ...] = ()
    reference_spp: int = 1024


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
    method_args: dict[str, tuple[str, ...]] = field(default_factory=dict)
    baseline: str = "pt"
    primary_metric: str = "relmse"
    ref_quality_factor: float = 10.0
    title: str = "pgi comparison"
    viewer_max_size: int = 512
    timed_render_slots: int = 1

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


def budget_tag(seconds: float) -> str:
    """How a budget appears in file names: 2 -> "2", 0.5 -> "0.5" (as `pgi render` writes)."""
    f = float(seconds)
    return str(int(f)) if f.is_integer() else f"{f:g}"


def resolve_pgi(setting: str) -> tuple[str, ...]:
    """The command prefix that runs the renderer CLI."""
    if setting != "auto":
        return tuple(shlex.split(setting))
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
    except OSError as e:
        raise PlanError(f"cannot run `{' '.join(pgi)} methods`: {e}") from e
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


def check_scene(spec: SceneSpec) -> None:
    """Load a scene with the study's overrides: a misspelt `set` key stops the plan, not the
    first render (after the references may have run for minutes)."""
    try:
        load_scene(spec.path / "scene.yaml", spec.set)
    except PgiError as e:
        raise PlanError(f"scenes: '{spec.name}': {e}") from e


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
    pgi = resolve_pgi(str(config.get("pgi", "auto")))
    scenes_dir = root / config.get("scenes_dir", "scenes")
    ref = dict(config.get("reference") or {})
    global_set = tuple(config.get("set") or ())
    default_spp = int(ref.get("spp", 1024))

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
            set=global_set + tuple(entry.get("set") or ()),
            reference_spp=int(entry.get("reference_spp", default_spp)),
        )
        if check_scenes and str(config.get("pgi", "auto")) == "auto":
            check_scene(scenes[name])

    wanted = config["methods"]
    exclude = set(config.get("exclude_methods") or ())
    if wanted == "all" or check_methods:
        avail, planned = available_methods(pgi)
    else:
        avail, planned = [], []
    if wanted == "all":
        methods = [m for m in avail if m not in exclude]
        if not methods:
            raise PlanError("methods: 'all' but `pgi methods` lists no method")
    else:
        methods = [m for m in wanted if m not in exclude]
        if not methods:
            raise PlanError("methods: no method left after exclude_methods")
    if check_methods or wanted == "all":
        # A misspelt id would silently drop a method, its arguments or an exclusion. A method
        # announced but not implemented may be excluded or configured ahead of its arrival.
        for key, names, known in (
            ("methods", [] if wanted == "all" else wanted, avail),
            ("exclude_methods", sorted(exclude), avail + planned),
            ("method_args", list(config.get("method_args") or {}), avail + planned),
        ):
            unknown = [m for m in names if m not in known]
            if unknown:
                raise PlanError(
                    f"{key}: unknown method(s) {', '.join(unknown)}; "
                    f"`pgi methods` lists: {', '.join(avail) or 'none'}"
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
    report = dict(config.get("report") or {})
    threads = int(config.get("threads", 2))
    return Plan(
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
        method_args={k: tuple(v) for k, v in (config.get("method_args") or {}).items()},
        baseline=baseline,
        primary_metric=str(config.get("primary_metric", "relmse")),
        ref_quality_factor=float(config.get("ref_quality_factor", 10.0)),
        title=str(report.get("title", "pgi comparison")),
        viewer_max_size=int(report.get("viewer_max_size", 512)),
        timed_render_slots=int(config.get("timed_render_slots", 1)),
    )
