"""Method parameters (``--set method.KEY=VALUE``): read with their types and ranges checked,
so that a mistake is one line naming the method, the key and what was expected."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ..errors import PgiError
from ..ranges import integer_problem, number_problem


class MethodParams:
    def __init__(self, method: str, params: dict[str, Any], known: Iterable[str]) -> None:
        known = set(known)
        unknown = set(params) - known
        if unknown:
            names = ", ".join(sorted(known))
            raise PgiError(
                f"method {method}: unknown parameter(s) {sorted(unknown)}; known: {names}"
            )
        self.method, self.params = method, params

    def _fail(self, key: str, expected: str) -> None:
        raise PgiError(f"method {self.method}: {key} must be {expected}, got {self.params[key]!r}")

    def integer(self, key: str, default: int, lo: int | None = None) -> int:
        """An integer parameter (>= lo when given)."""
        if key not in self.params:
            return default
        expected = integer_problem(self.params[key], lo)
        if expected:
            self._fail(key, expected)
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
            return float(default)
        expected = number_problem(self.params[key], lo, hi, lo_open, hi_open)
        if expected:
            self._fail(key, expected)
        return float(self.params[key])
