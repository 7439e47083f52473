"""Method parameters (``--set method.KEY=VALUE``): read with their types and ranges checked,
so that a mistake is one line naming the method, the key and what was expected."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Mapping
from typing import Any

from ..errors import PgiError, shorten_repr
from ..ranges import INT32_MAX, integer_problem, number_problem
from ..scene.model import Film

# Memory one path of a batch may take (its state, rays, shadow rays and records): rough,
# generous bounds. Measured as the growth of peak memory from 1 to 4 million paths: camera
# paths 462 bytes (ppb) and 247 (pm) on cbox-fog; pt, whose paths in flight are a few
# thousand a lane, keeps 24 bytes per path of the wave (its radiance; cbox-grid), and its film
# with the image handed back and written about 60 bytes a pixel more (82 in all at one path
# per pixel, 1 to 4 million pixels on cbox; the other methods' bounds cover their film); Mitsuba's
# wavefront 84-94 bytes per sample (cbox-fog, cbox-grid); light paths with their vertex,
# photon and beam records 1.7 KB (pm, sppm), 2.5 KB (lt) and 3.3 KB (ppb), in the peak
# memory of 2 million paths through cbox-fog.
CAMERA_PATH_BYTES = 640
PT_WAVE_PATH_BYTES = 64
PT_PIXEL_BYTES = 128
MITSUBA_SAMPLE_BYTES = 128
LIGHT_PATH_BYTES = 4096


def physical_memory() -> int:
    """Bytes of RAM on this machine (0 where the system does not say)."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 0


def over_half_memory(needed: int) -> str:
    """'' if `needed` bytes fit in half this machine's memory, else what to say of them
    ("about N GiB, more than half this machine's M GiB"): Linux grants larger allocations
    and then kills the process, or a library crashes, with no message."""
    total = physical_memory()
    if not total or needed <= total // 2:
        return ""
    return f"about {needed / 2**30:.0f} GiB, more than half this machine's {total / 2**30:.0f} GiB"


# Radii below this fraction of the scene's bounding-sphere radius find no photon, and at
# ~1e-150 of it 1 / (pi r^2) overflows into non-finite samples.
MIN_RADIUS_FRACTION = 1e-9
# A kernel wider than the scene's bounding sphere takes every photon or beam everywhere: it
# blurs the image flat and is slow (pm at radius 1e30: 20x the time of the default).
MAX_RADIUS_FRACTION = 2.0


def budget_divisor(wanted: int, spp_budget: int | None) -> int:
    """Samples per pixel per iteration: ``wanted``, lowered to the largest divisor of the spp
    budget not above it, so that whole iterations meet the budget exactly."""
    if not spp_budget:
        return wanted
    return max(d for d in range(1, min(wanted, spp_budget) + 1) if spp_budget % d == 0)


class MethodParams:
    """``params`` as given; ``known``: the names the method reads; ``renamed``: old name -> the
    name(s) it now goes by (given under an old name, a value is taken under the new ones, with
    a warning on stderr; both old and new is an error)."""

    def __init__(
        self,
        method: str,
        params: dict[str, Any],
        known: Iterable[str],
        renamed: Mapping[str, tuple[str, ...]] | None = None,
    ) -> None:
        params = dict(params)
        for old, new in (renamed or {}).items():
            if old not in params:
                continue
            if clash := [n for n in new if n in params]:
                raise PgiError(
                    f"method {method}: {old} is an old name of {clash[0]}: give only one"
                )
            value = params.pop(old)
            params.update(dict.fromkeys(new, value))
            print(
                f"pgi: warning: method {method}: {old} is an old name: "
                f"use {' and '.join(f'{n}={shorten_repr(value)}' for n in new)}",
                file=sys.stderr,
            )
        known = set(known)
        unknown = set(params) - known
        if unknown:
            names = ", ".join(sorted(known))
            raise PgiError(
                f"method {method}: unknown parameter(s) {sorted(unknown)}; known: {names}"
            )
        self.method, self.params = method, params
        # every parameter read, with the value used (defaults included): the sidecar's record
        self.used: dict[str, Any] = {}

    def fail(self, key: str, expected: str) -> None:
        got = shorten_repr(self.params[key])  # as YAML writes it: true, null, not True, None
        raise PgiError(f"method {self.method}: {key} must be {expected}, got {got}")

    def integer(self, key: str, default: int, lo: int | None = None, hi: int = INT32_MAX) -> int:
        """An integer parameter in [lo, hi] (counts reach the native core as 32-bit ints)."""
        if key not in self.params:
            self.used[key] = default
            return default
        expected = integer_problem(self.params[key], lo, hi)
        if expected:
            self.fail(key, expected)
        self.used[key] = self.params[key]
        return self.params[key]

    def flag(self, key: str, default: bool) -> bool:
        """A yes/no parameter (true or false)."""
        if key not in self.params:
            self.used[key] = default
            return default
        if not isinstance(self.params[key], bool):
            self.fail(key, "true or false")
        self.used[key] = self.params[key]
        return self.params[key]

    def choice(self, key: str, default: str, options: Iterable[str]) -> str:
        """One of the words ``options``."""
        options = tuple(options)
        if key not in self.params:
            self.used[key] = default
            return default
        if self.params[key] not in options:
            self.fail(key, " or ".join(options))
        self.used[key] = self.params[key]
        return self.params[key]

    def number(
        self,
        key: str,
        default: float,
        lo: float | None = None,
        hi: float | None = None,
        lo_open: bool = False,
        hi_open: bool = False,
    ) -> float:
        """A finite number in the given range (open or closed at each end)."""
        if key not in self.params:
            self.used[key] = float(default)
            return float(default)
        expected = number_problem(self.params[key], lo, hi, lo_open, hi_open)
        if expected:
            self.fail(key, expected)
        self.used[key] = float(self.params[key])
        return float(self.params[key])

    def radius(
        self, name: str, default_relative: float, scene_radius: float, zero_allowed: str = ""
    ) -> float:
        """A kernel radius, in world units, given either as ``{name}_world`` (world units) or as
        ``{name}_relative`` (a fraction of the scene's bounding-sphere radius), not both; by
        default ``default_relative``. Radii below MIN_RADIUS_FRACTION of the scene find no
        photon (and 1 / (pi r^2) overflows near 1e-150), radii above MAX_RADIUS_FRACTION take
        every photon everywhere. ``zero_allowed``: what a radius of 0 means where it is allowed."""
        given = self.given_radius(name, scene_radius, zero_allowed)
        if given is not None:
            return given
        return self.number(f"{name}_relative", default_relative) * scene_radius

    def given_radius(self, name: str, scene_radius: float, zero_allowed: str = "") -> float | None:
        """``radius``'s value in world units if ``{name}_world`` or ``{name}_relative`` is given
        (checked as there), else None: the method derives the radius itself."""
        world, relative = f"{name}_world", f"{name}_relative"
        if world in self.params and relative in self.params:
            raise PgiError(f"method {self.method}: give {world} or {relative}, not both")
        if world not in self.params and relative not in self.params:
            return None
        key, scale = (world, scene_radius) if world in self.params else (relative, 1.0)
        lo, hi = MIN_RADIUS_FRACTION * scale, MAX_RADIUS_FRACTION * scale
        value = self.number(key, 0.0, lo=0 if zero_allowed else lo, hi=hi)
        if zero_allowed and 0 < value < lo:
            self.fail(key, f"0 ({zero_allowed}) or >= {lo:g}")
        return value if key == world else value * scene_radius

    def given_radius_key(self, name: str) -> str:
        """Which of ``{name}_world`` and ``{name}_relative`` was given (given_radius checked it)."""
        return f"{name}_world" if f"{name}_world" in self.params else f"{name}_relative"

    def neighbours(self, name: str, given: float | None, default: int) -> int:
        """k of a pilot's k nearest for kernel ``name``: ``{name}_neighbours``, or 0 where the
        radius is ``given`` (then the key is refused: it would have no effect)."""
        key = f"{name}_neighbours"
        self.refuse_unused(key, given is None, f"with {name}_world or {name}_relative")
        return 0 if given is not None else self.integer(key, default, lo=1)

    def refuse_unused(self, key: str, used: bool, why: str) -> None:
        """A parameter given where it has no effect is a mistake, not something to ignore."""
        if key in self.params and not used:
            raise PgiError(f"method {self.method}: {key} has no effect {why}")
        if not used:  # its default played no part either
            self.used.pop(key, None)

    def paths_fit_in_memory(
        self,
        key: str,
        paths: int,
        what: str = "camera paths",
        remedy: str = "",
        path_bytes: int = CAMERA_PATH_BYTES,
        extra_bytes: int = 0,
    ) -> None:
        """Refuse a batch of paths whose state (with `extra_bytes` besides) would take over
        half the machine's memory: Linux grants such allocations and then kills the process,
        with no message. The message says to lower `remedy` (default: the parameter `key`)."""
        if too_much := over_half_memory(paths * path_bytes + extra_bytes):
            raise PgiError(
                f"method {self.method}: {key} gives batches of {paths:,} {what}, {too_much}: "
                f"lower {remedy or f'method.{key}'}"
            )

    def camera_paths_fit_in_memory(
        self,
        key: str,
        spp: int,
        film: Film,
        path_bytes: int = CAMERA_PATH_BYTES,
        pixel_bytes: int = 0,
    ) -> None:
        """paths_fit_in_memory for a batch of `spp` camera paths per pixel of `film`, with
        `pixel_bytes` a pixel besides; at one per pixel only the film's size can be lowered."""
        pixels = film.width * film.height
        remedy = "the film's size" if spp == 1 else f"method.{key} or the film's size"
        self.paths_fit_in_memory(
            key, spp * pixels, "camera paths", remedy, path_bytes, pixels * pixel_bytes
        )

    def light_paths_fit_in_memory(self, key: str, paths: int, remedy: str = "") -> None:
        """paths_fit_in_memory for a batch of light paths, which keep their records."""
        self.paths_fit_in_memory(key, paths, "light paths", remedy, LIGHT_PATH_BYTES)

    def spp_per_iteration(self, key: str, default: int, spp_budget: int | None) -> int:
        """Samples per pixel of one iteration; with an spp budget it must divide it, so that
        the run stops exactly at the budget."""
        spp = self.integer(key, default, lo=1)
        if spp_budget and spp_budget % spp:
            raise PgiError(f"method {self.method}: {key} {spp} must divide --spp {spp_budget}")
        return spp
