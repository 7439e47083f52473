"""The ``pgi`` command: render, reference, compare, methods, validate."""

from __future__ import annotations

import argparse
import errno
import json
import math
import os
import platform
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from . import __version__
from .errors import PgiError, caused_by_interrupt, printable, shorten_repr
from .interrupts import native_passes_interruptible


def _floats(text: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",")]  # an empty item is an error too
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated seconds, got {text!r}"
        ) from None
    if not values or not all(0 < v < math.inf for v in values):
        raise argparse.ArgumentTypeError(f"expected positive, finite seconds, got {text!r}")
    return values


def _positive(kind: type):
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            want = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"expected {want}, got {text!r}") from None
        if not 0 < value < math.inf:
            raise argparse.ArgumentTypeError(f"expected a positive, finite value, got {text!r}")
        return value

    return parse


def _non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 <= value < math.inf:
        raise argparse.ArgumentTypeError(f"expected a finite value >= 0, got {text!r}")
    return value


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"expected an integer in [0, 2^63), got {text!r}")
    return value


def split_sets(items: list[str], command: str = "render") -> tuple[list[str], dict]:
    """--set key=value: ``method.X`` keys are method parameters, the rest edit the scene."""
    overrides, params = [], {}
    for item in items:
        if "=" not in item:
            raise PgiError(f"--set {shorten_repr(item)}: expected key=value")
        key, value = item.split("=", 1)
        if key.startswith("method.") and command != "render":
            raise PgiError(f"--set {key}: method parameters apply to `pgi render` only")
        if key.startswith("method."):
            from .scene.yaml_dialect import parse_yaml_value

            params[key[len("method.") :]] = parse_yaml_value(value, f"--set {key}")
        else:
            overrides.append(item)
    return overrides, params


def _refuse_overwriting_the_scene(
    scene: str, outputs: list[Path], overrides: Sequence[str] = ()
) -> None:
    """No image or sidecar may replace a file the scene reads (its YAML, meshes, grids, and
    what the --set overrides name)."""
    from .scene.sources import resolved, scene_sources

    try:
        sources = set(scene_sources(scene, overrides))
    except PgiError:  # no such scene: loading it says so
        return
    for out in outputs:
        for target in (out, out.with_suffix(".json")):
            if resolved(target) in sources:
                raise PgiError(f"-o {out}: would overwrite {target}, which the scene reads")


def cmd_render(args: argparse.Namespace) -> int:
    from .imageio import check_output_path
    from .methods import check_overrides
    from .progressive import RenderSettings, available_cores, render, snapshot_path
    from .scene import load_scene

    out = check_output_path(args.output)
    snapshot_files = [snapshot_path(out, s) for s in args.snapshots or ()]
    for i, path in enumerate(snapshot_files):
        if path in snapshot_files[:i]:
            first = args.snapshots[snapshot_files.index(path)]
            raise PgiError(f"--snapshots: {first} s and {args.snapshots[i]} s share the file name "
                           f"{path.name}")  # fmt: skip
    for path in snapshot_files:
        check_output_path(path)
    overrides, params = split_sets(args.set)
    _refuse_overwriting_the_scene(args.scene, [out, *snapshot_files], overrides)
    check_overrides(args.method, overrides)
    scene = load_scene(args.scene, overrides)
    settings = RenderSettings(
        method=args.method,
        seed=args.seed,
        threads=args.threads or available_cores(),
        time_budget=args.time,
        spp=args.spp,
        snapshots=args.snapshots or (),
        params=params,
        overrides=overrides,
    )
    info = render(scene, settings, out, progress=not args.quiet)
    print(
        f"{out}: {info['method']} {info['spp']} spp in {info['render_seconds']:.2f} s "
        f"(load {info['load_seconds']:.2f} s), "
        f"{info.get('nonfinite', 0)} non-finite samples dropped"
    )
    for key, why in _BIASED_WHEN_COUNTED.items():
        if info.get(key):
            print(f"note: {info[key]:,} {why}", file=sys.stderr)
    return 0


# Sidecar counts of work a method had to drop; any at all makes the image biased.
_BIASED_WHEN_COUNTED = {
    "beams_truncated": "beams beyond method.max_beams were dropped (beams_truncated): the "
    "image is biased dark; raise method.max_beams",
    "beams_escaped": "beams left the scene inside a medium and were dropped (beams_escaped): "
    "the image is biased dark there",
}


def variance_path(image: str | Path) -> Path:
    """Where `pgi reference` writes the variance of its image's mean per value."""
    image = Path(image)
    return image.with_name(f"{image.stem}.var.exr")


def cmd_reference(args: argparse.Namespace) -> int:
    from .fingerprint import reference_fingerprint, render_fingerprint
    from .imageio import check_output_path, write_exr, write_image_and_sidecar
    from .methods import check_overrides
    from .progressive import Progress, check_threads
    from .reference import CHECK_PASSES, MIN_PASSES_FOR_VARIANCE, render_reference_passes
    from .scene import load_scene
    from .scene.sources import scene_content_digest

    out = check_output_path(args.output)
    check_output_path(variance_path(out))
    overrides, _ = split_sets(args.set, "reference")
    _refuse_overwriting_the_scene(args.scene, [out, variance_path(out)], overrides)
    check_threads(args.threads)
    if args.source == "mitsuba":  # Mitsuba reads neither our estimators nor our roulette
        check_overrides("mitsuba", overrides)
    scene = load_scene(args.scene, overrides)
    key = None
    if args.store:  # passes are taken from it only if they rendered the same image
        key = {
            "scene": scene_content_digest(scene.path, overrides),
            "overrides": list(overrides),
            # pgi's passes depend on the whole renderer, Mitsuba's on what exports to it
            "code": render_fingerprint() if args.source == "pgi" else reference_fingerprint(),
        }
    bar = Progress(None, args.spp, enabled=not args.quiet)
    acc, info = render_reference_passes(
        scene,
        args.spp,
        seed=args.seed,
        threads=args.threads,
        on_pass=bar.update,
        # pt's passes cost little more split finer: more of them give the check's variance
        # more degrees of freedom (compare.trust maps its t-scores to normal ones by them)
        min_passes=CHECK_PASSES if args.source == "pgi" else MIN_PASSES_FOR_VARIANCE,
        store=args.store,
        key=key,
        source=args.source,
    )
    bar.update(info["render_seconds"], acc.spp - info["spp_resumed"], force=True)
    variance = acc.variance_of_mean()
    info = dict(
        info,
        scene=scene.name,
        scene_file=str(scene.path),
        resolution=[scene.film.width, scene.film.height],
        host=platform.node(),
        version=__version__,
        spp=acc.spp,
        seed=args.seed,
        overrides=overrides,
        variance=variance_path(out).name if variance is not None else None,
    )
    trust = None
    if args.source == "mitsuba" and args.check > 0:
        trust = _check_reference(scene, acc, args)
        info["trust"] = trust
    if variance is not None:
        write_exr(variance_path(out), variance, {"variance_of": out.name})
    else:  # a variance file of an earlier render must not pass for this one's
        variance_path(out).unlink(missing_ok=True)
    write_image_and_sidecar(out, acc.mean, info)
    resumed = f" ({info['spp_resumed']} of them from {args.store})" if info["spp_resumed"] else ""
    print(f"{out}: {info['renderer']} reference, {acc.spp} spp in {acc.passes} passes{resumed}")
    if trust is not None:
        print(trust["line"])
    return 0


def _check_reference(scene: Any, acc: Any, args: argparse.Namespace) -> dict[str, Any]:
    """Check a Mitsuba reference against ``args.check`` seconds of pgi's pt (seeds of its own):
    compare.trust's verdict, as the sidecar keeps it (``trust``)."""
    from compare.trust import Estimate, check_reference, verdict_record

    from .reference import render_check

    check, check_info = render_check(scene, args.check, seed=args.seed, threads=args.threads)
    verdict = check_reference(
        Estimate.from_passes(acc.mean, acc.variance_of_mean(), acc.passes),
        Estimate.from_passes(check.mean, check.variance_of_mean(), check.passes),
        check_name="pt",
    )
    record = verdict_record(verdict, f"Mitsuba's reference of {scene.name}", "pgi's pt")
    record["check"] = {k: check_info[k] for k in ("renderer", "spp", "passes", "render_seconds")}
    return record


def _recorded_reference_error(reference: Path, shape: tuple[int, ...]) -> dict[str, float]:
    """The error a reference's sidecar records of it: the workflow's ref.json beside the mean
    of its two halves (halves_relmse, ref_relmse, halves_mse, ref_mse), when it describes an
    image of this size. Empty for any other reference."""
    from compare.metrics import REFERENCE_ERROR_KEYS as keys

    try:
        info = json.loads(reference.with_suffix(".json").read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(info, dict) or (info.get("height"), info.get("width")) != shape[:2]:
        return {}
    values = [info.get(k) for k in keys]
    if not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) and v >= 0
        for v in values
    ):
        return {}
    return {k: float(info[k]) for k in keys}


def cmd_compare(args: argparse.Namespace) -> int:
    import numpy as np

    from compare.metrics import (
        REF_QUALITY_FACTOR,
        average_references,
        compare_images,
        corrected_errors,
        reference_ok,
    )

    from .imageio import read_exr_and_channels

    paths = [args.test, args.reference] + ([args.second_reference] if args.second_reference else [])
    for path in paths:
        if Path(path).suffix.lower() != ".exr":  # metrics are defined on linear HDR values
            raise PgiError(f"{path}: expected a linear .exr image")
    read = [read_exr_and_channels(path) for path in paths]
    grey = {path: channels == 1 for path, (_, channels) in zip(paths, read, strict=True)}
    if len(set(grey.values())) > 1:  # reading repeats a grey channel: refuse it here
        kinds = ", ".join(f"{p} is {'grey' if g else 'colour'}" for p, g in grey.items())
        raise PgiError(f"cannot compare a grey image with a colour one: {kinds}")
    test, ref = read[0][0], read[1][0]
    own: dict[str, float] = {}
    halves: list[np.ndarray] = []
    if args.second_reference:  # two independent references: their mean, and its error
        names = (args.reference, args.second_reference)
        if np.array_equal(ref, read[2][0]) and ref.any():
            raise PgiError(f"{names[0]} and {names[1]} are the same image: the second "
                           "reference must be an independent render (another --seed)")  # fmt: skip
        halves = [ref, read[2][0]]
        try:
            ref, own = average_references(ref, read[2][0], names)
        except ValueError as e:
            raise PgiError(f"{names[0]} vs {names[1]}: {e}") from None
    else:
        own = _recorded_reference_error(Path(args.reference), ref.shape)
    try:
        metrics = compare_images(test, ref)
        if halves:  # the reference's own error removed (variances from the halves alone)
            metrics |= corrected_errors(test, *halves)
    except ValueError as e:
        raise PgiError(f"{args.test} vs {args.reference}: {e}") from None
    metrics |= own
    if args.json:  # undefined metrics (SSIM below 11x11 pixels) are null: NaN is not JSON
        defined = {
            k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in metrics.items()
        }
        print(json.dumps(defined, indent=2, sort_keys=True, allow_nan=False))
    else:
        for key, value in metrics.items():
            print(f"{key:>16}  {value:.6g}")
    if own and not reference_ok(metrics["relmse"], own["ref_relmse"]):
        removed = (
            f"; relmse_corrected, {metrics['relmse_corrected']:.3g} ± "
            f"{metrics['relmse_u']:.2g}, has it removed"
            if "relmse_corrected" in metrics
            else ""
        )
        print(
            f"note: the reference has relMSE {own['ref_relmse']:.3g} of its own, not "
            f"{REF_QUALITY_FACTOR:g}x below this image's {metrics['relmse']:.3g}: it "
            f"limits this comparison (every measured metric includes its error{removed})",
            file=sys.stderr,
        )
    return 0


PLANNED_PREFIX = "# not yet implemented:"
# `pgi reference --source`: renderer.reference.SOURCES, named here without importing Mitsuba.
SOURCE_NAMES = ("mitsuba", "pgi")


def cmd_methods(args: argparse.Namespace) -> int:
    from .known_methods import NOT_YET_IMPLEMENTED
    from .methods import describe, method_ids

    for mid in method_ids():
        print(f"{mid:<10} {describe(mid)}")
    # Workflow configs may name these already (exclude_methods, method_args, expected winners).
    if NOT_YET_IMPLEMENTED:
        print(f"{PLANNED_PREFIX} {', '.join(NOT_YET_IMPLEMENTED)}")
    return 0


def cmd_fingerprint(args: argparse.Namespace) -> int:
    from .fingerprint import fingerprints

    print(json.dumps(fingerprints()))
    return 0


def cmd_validate(args: argparse.Namespace) -> int:
    from .engine import build_native_scene
    from .scene import load_scene

    overrides, _ = split_sets(args.set, "validate")
    scene = load_scene(args.scene, overrides)
    native = build_native_scene(scene)  # what only the core checks (e.g. a too-fine march)
    # Where lights emit: what the light-side methods refuse or warn of, said here as warnings.
    for split in native.emission.split_emitters:
        print(
            f"pgi: warning: {split.describe()}: lt, pm, sppm and ppb refuse this scene (light "
            "paths start in one medium per triangle: split the emitter where the boundary "
            "crosses it); pt and mitsuba render it as it is",
            file=sys.stderr,
        )
    for line in native.emission.stated_elsewhere:
        print(f"pgi: warning: {line}", file=sys.stderr)
    triangles = f"{len(native.triangles)} triangles"
    if native.dropped_triangles:
        triangles += f" ({native.dropped_triangles} degenerate ones dropped)"
    print(
        f"{scene.path}: ok ({len(scene.shapes)} shapes, {triangles}, "
        f"{len(scene.media)} media, {scene.film.width}x{scene.film.height})"
    )
    return 0


class _Parser(argparse.ArgumentParser):
    """Usage mistakes are one line, like every other error (the usage is in --help)."""

    commands: dict[str, argparse.ArgumentParser] = {}  # the top level's, by name

    def parse_known_args(self, args=None, namespace=None):
        # Options no command knows are left over here, at the top level, after a command
        # parsed the rest: point to that command's help, where its options are.
        parsed, extras = super().parse_known_args(args, namespace)
        command = self.commands.get(getattr(parsed, "command", None))
        if extras and command is not None:
            command.error(f"unrecognized arguments: {' '.join(extras)}")
        return parsed, extras

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="pgi", description="Progressive global illumination in participating media."
    )
    parser.add_argument("--version", action="version", version=f"pgi {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    parser.commands = sub.choices  # filled as the commands are added below

    def scene_arg(p: argparse.ArgumentParser, method_params: bool = False) -> None:
        p.add_argument("scene", help="scene name, folder, or scene.yaml file")
        p.add_argument(
            "--set",
            action="append",
            default=[],
            metavar="KEY=VALUE",
            help="override a scene value (e.g. film.width=64)"
            + (" or, as method.KEY=VALUE, a method parameter" if method_params else "")
            + "; repeatable",
        )

    r = sub.add_parser("render", help="render a scene with one method")
    scene_arg(r, method_params=True)
    r.add_argument("--method", required=True, help="method id (see `pgi methods`)")
    r.add_argument(
        "--time",
        type=_positive(float),
        help="render-time budget in seconds (the render ends at the iteration end nearest it)",
    )
    r.add_argument("--spp", type=_positive(int), help="stop after this many samples per pixel")
    r.add_argument(
        "--threads", type=_positive(int), help="worker threads (default: all available cores)"
    )
    r.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    r.add_argument(
        "--snapshots",
        type=_floats,
        help="comma-separated render times (s) at which to also write snapshots, each the "
        "image at the iteration end nearest its time (-o out.exr: out.t1.exr, out.t2.exr, ...)",
    )
    r.add_argument("-o", "--output", required=True, help="output .exr (a .json sidecar is written)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    r.set_defaults(func=cmd_render)

    ref = sub.add_parser(
        "reference", help="render the reference of a scene (Mitsuba 3, checked by pgi's pt)"
    )
    scene_arg(ref)
    ref.add_argument(
        "--spp",
        type=_positive(int),
        required=True,
        help="samples per pixel, rendered in passes of their own seeds (at least 8, whose "
        "spread gives the variance of the mean: OUT.var.exr beside the image)",
    )
    ref.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    ref.add_argument(
        "--threads", type=_positive(int), help="Mitsuba threads (default: all available cores)"
    )
    ref.add_argument(
        "-o", "--output", required=True, help="output .exr (a .json sidecar is written)"
    )
    ref.add_argument(
        "--source",
        default="mitsuba",
        choices=sorted(SOURCE_NAMES),
        help="what renders the passes: mitsuba (default; volpath, one grey render per "
        "channel for chromatic media) or pgi (pgi's pt, for scenes where Mitsuba's reference "
        "is not trustworthy)",
    )
    ref.add_argument(
        "--store",
        metavar="FILE",
        help="keep the passes in FILE (.npz) and extend them: passes it already holds for "
        "the same scene, overrides, seed and code are used, and only the samples still "
        "missing are rendered (a store holding more gives them all)",
    )
    ref.add_argument(
        "--check",
        type=_non_negative_float,
        default=20.0,
        metavar="SECONDS",
        help="check a Mitsuba reference against SECONDS of pgi's pt (seeds of its own; "
        "default 20, about what dense, white media need; 0: no check): one line says whether "
        "it is trustworthy (dead pixels where pt sees light, an image mean outside pt's "
        "confidence interval) and the sidecar keeps the verdict under `trust`",
    )
    ref.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    ref.set_defaults(func=cmd_reference)

    c = sub.add_parser("compare", help="error metrics of an image against a reference")
    c.add_argument("test", help="rendered .exr")
    c.add_argument("reference", help="reference .exr")
    c.add_argument(
        "second_reference",
        nargs="?",
        help="a second, independent reference .exr (another --seed): the comparison is "
        "against their mean, and its own error is estimated from their difference (ref_relmse, "
        "ref_mse; a quarter of halves_relmse, halves_mse) and removed from the MSE-type "
        "metrics (*_corrected, with standard uncertainties *_u). Without it, a reference the "
        "workflow merged from two halves brings that estimate in its JSON sidecar",
    )
    c.add_argument("--json", action="store_true", help="print JSON")
    c.set_defaults(func=cmd_compare)

    m = sub.add_parser("methods", help="list the available methods")
    m.set_defaults(func=cmd_methods)

    f = sub.add_parser(
        "fingerprint",
        help="print, as JSON, digests of the code behind renders and behind references "
        "(the workflow reruns what a change of them affects)",
    )
    f.set_defaults(func=cmd_fingerprint)

    v = sub.add_parser("validate", help="check a scene file")
    scene_arg(v)
    v.set_defaults(func=cmd_validate)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM (a cancelled job, `timeout`, a batch system), raised where Python runs next so
    that it cleans up as after Ctrl-C: temporary files go, finished snapshots stay."""


# Set by the SIGTERM handler, whose exception can be lost on its way: under load, about one
# SIGTERM in 30 to pt's two lanes ran the handler and then ended the render with the plain
# KeyboardInterrupt of the next native pass that saw the signal (where it vanished is not
# known; nothing of ours catches it).
_sigterm_arrived = threading.Event()


def _terminate(signum: int, frame: object) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # a second one must not cut the cleanup
    _sigterm_arrived.set()
    raise Terminated


class StdoutFailed(Exception):
    """Standard output could not be written: its reader went away, or its disk is full."""

    def __init__(self, error: OSError) -> None:
        super().__init__(error.strerror or str(error))
        self.errno = error.errno


class _CheckedStdout:
    """sys.stdout whose write errors say they are stdout's, not those of some file."""

    def __init__(self, stream: object) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except OSError as e:
            raise StdoutFailed(e) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as e:
            raise StdoutFailed(e) from None

    def __getattr__(self, name: str) -> object:
        return getattr(self._stream, name)


def _stdout_failed(e: StdoutFailed) -> int:
    # Nothing more can reach it; without this, Python's exit would complain of it again.
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):  # not a file (a test's capture)
        pass
    if e.errno == errno.EPIPE:  # the reader closed the pipe (`| head`): quietly, as a process
        return 128 + signal.SIGPIPE  # that SIGPIPE ends
    print(f"pgi: error: cannot write to standard output: {e}", file=sys.stderr)
    return 2


def _end_progress_line() -> None:
    """A message after a progress bar starts a line of its own. Without the progress module
    loaded no bar was drawn; importing it here could re-enter an import the error (Ctrl-C
    during start-up) broke off, and raise from that half-initialised module instead."""
    progressive = sys.modules.get(f"{__package__}.progressive")
    if progressive is not None:
        progressive.end_progress_line()


def _interrupted(e: KeyboardInterrupt) -> int:
    _end_progress_line()
    if isinstance(e, Terminated) or _sigterm_arrived.is_set():
        print("pgi: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM
    print("pgi: interrupted", file=sys.stderr)
    return 130


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    main_thread = threading.current_thread() is threading.main_thread()
    _sigterm_arrived.clear()
    on_sigterm = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    stdout = sys.stdout
    # Started with standard output closed (`>&-`): Python has none; what pgi prints is lost,
    # as it would be in /dev/null, and the work itself goes on.
    sink = open(os.devnull, "w") if stdout is None else None  # closed below
    sys.stdout = _CheckedStdout(sink or stdout)
    try:
        args = parser.parse_args(argv)  # --help writes to stdout too
        with native_passes_interruptible():
            code = args.func(args)
        sys.stdout.flush()  # here, not at exit, where its error would escape us
        return code
    except StdoutFailed as e:
        return _stdout_failed(e)
    except PgiError as e:
        _end_progress_line()
        print(f"pgi: error: {printable(str(e))}", file=sys.stderr)
        return 2
    except MemoryError:
        _end_progress_line()
        print(
            "pgi: error: out of memory (a coarser grid bake resolution, a smaller film, fewer "
            "samples per iteration or fewer photons/beams would fit)",
            file=sys.stderr,
        )
        return 2
    except KeyboardInterrupt as e:
        return _interrupted(e)
    except Exception as e:
        interrupt = caused_by_interrupt(e)
        if interrupt is None:
            raise
        return _interrupted(interrupt)
    finally:
        sys.stdout = stdout
        if sink is not None:
            sink.close()
        if on_sigterm is not None:  # None: a handler from outside Python, left in place
            signal.signal(signal.SIGTERM, on_sigterm)


if __name__ == "__main__":
    sys.exit(main())
