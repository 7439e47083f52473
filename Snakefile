# pgi comparison workflow: render every scene x method x seed (a snapshot per time budget),
# render Mitsuba references as two independent halves, compare, tabulate, write the report.
#
#   snakemake --cores 2                                  # default config (configs/default.yaml)
#   snakemake --cores 2 --configfile configs/tiny.yaml   # seconds-long smoke run
#   snakemake --profile configs/profiles/slurm --configfile configs/full.yaml   # cluster
#
# See docs/workflow.md. Nothing below names a scene or a method: they come from the config
# (methods: all = whatever `pgi methods` lists).

import importlib.util
import os
import shlex
import sys

import jsonschema

from snakemake.exceptions import WorkflowError
from snakemake.utils import min_version, validate

min_version("8.0")

SRC = os.path.join(workflow.basedir, "src")
if SRC not in sys.path:
    sys.path.insert(0, SRC)
# jobs (shell and script) import the in-tree `compare` and `renderer` packages
os.environ["PYTHONPATH"] = os.pathsep.join(
    [SRC] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p and p != SRC]
)

# An editable install of another checkout in the same environment would be imported before
# this one's src (its import hook comes first): stop rather than run that checkout's code.
for _package in ("compare", "renderer"):
    _spec = importlib.util.find_spec(_package)
    _found = os.path.dirname(os.path.realpath(_spec.origin)) if _spec and _spec.origin else None
    if _found != os.path.realpath(os.path.join(SRC, _package)):
        sys.exit(
            f"pgi: this Python ({sys.executable}) imports `{_package}` from {_found or 'nowhere'}, "
            f"not from this checkout's {SRC}: set this checkout up (./setup.sh --no-run) and "
            "run the snakemake of its own .venv"
        )

from compare.plan import (  # noqa: E402
    PlanError,
    check_config_files,
    make_plan,
    schema_error_message,
)


# The default study, unless a config is given: a config of one's own must not inherit the
# default study's folders and overrides (missing keys get the schema's defaults instead).
DEFAULT_CONFIG = os.path.join(workflow.basedir, "configs", "default.yaml")
if not workflow.overwrite_configfiles:

    configfile: DEFAULT_CONFIG



# A config that cannot run stops here, before any job: one line naming the config file(s)
# and the key (not the schema, not a traceback), non-zero exit.
CONFIG_FILES = ", ".join(str(f) for f in workflow.overwrite_configfiles) or "configs/default.yaml"
if getattr(getattr(workflow, "config_settings", None), "config", None):
    CONFIG_FILES += " and --config"  # a key given there is in none of the files
try:
    check_config_files(workflow.overwrite_configfiles or [DEFAULT_CONFIG])  # the default too
except PlanError as e:
    sys.exit(f"config: {e}")
try:
    validate(config, "configs/schema.yaml")
except WorkflowError as e:
    why = e.__cause__ or e.__context__  # the schema's own error
    if not isinstance(why, jsonschema.ValidationError):
        raise
    sys.exit(f"config ({CONFIG_FILES}): {schema_error_message(why)}")

try:
    PLAN = make_plan(config, workflow.basedir)
except PlanError as e:
    sys.exit(f"config ({CONFIG_FILES}): {e}")

R = str(PLAN.results)
REP = str(PLAN.reports)
PY = shlex.quote(sys.executable)
PGI = shlex.join(PLAN.pgi)

# Timed renders never run concurrently with each other (unless a profile raises the limit).
if "timed_render" not in workflow.global_resources:
    workflow.register_resource("timed_render", PLAN.timed_render_slots)


wildcard_constraints:
    scene=r"[A-Za-z0-9_.-]+",
    method=r"[A-Za-z0-9_-]+",
    seed=r"\d+",
    half=r"[01]",


include: "workflow/rules/common.smk"
include: "workflow/rules/reference.smk"
include: "workflow/rules/render.smk"
include: "workflow/rules/compare.smk"
include: "workflow/rules/report.smk"


rule all:
    input:
        f"{REP}/index.html",
        f"{REP}/tables/summary.csv",
    default_target: True
