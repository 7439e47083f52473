"""Checks of user-given numbers against a range, shared by the scene loader and method
parameters so that both word their errors alike."""

from __future__ import annotations

import math
from typing import Any

# Counts, depths and indices reach the native core (and Mitsuba) as 32-bit ints.
INT32_MAX = 2**31 - 1


def number_problem(
    v: Any,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
) -> str | None:
    """None if ``v`` is a finite number in the range, else what was expected, e.g.
    ``"a number > 0 and <= 1"``."""
    # An integer past float's range (a YAML hex literal can be thousands of digits) is no
    # finite number either; math.isfinite would raise on it.
    ok = isinstance(v, int | float) and not isinstance(v, bool)
    ok = ok and (v.bit_length() <= 1000 if isinstance(v, int) else math.isfinite(v))
    if ok and lo is not None:
        ok = v > lo if lo_open else v >= lo
    if ok and hi is not None:
        ok = v < hi if hi_open else v <= hi
    if ok:
        return None
    bounds = []
    if lo is not None:
        bounds.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        bounds.append(f"{'<' if hi_open else '<='} {hi:g}")
    return "a number" + (" " + " and ".join(bounds) if bounds else "")


def integer_problem(v: Any, lo: int | None = None, hi: int | None = None) -> str | None:
    """None if ``v`` is an integer (not a bool) in [lo, hi], else what was expected, e.g.
    ``"an integer >= 1 and <= 16384"``."""
    ok = isinstance(v, int) and not isinstance(v, bool)
    ok = ok and (lo is None or v >= lo) and (hi is None or v <= hi)
    if ok:
        return None
    bounds = ([f">= {lo}"] if lo is not None else []) + ([f"<= {hi}"] if hi is not None else [])
    return "an integer" + (" " + " and ".join(bounds) if bounds else "")
