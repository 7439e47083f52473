"""Registry of progressive methods: id -> class. Each method lives in its own module; the ids
are listed in renderer.known_methods."""

from __future__ import annotations

from collections.abc import Iterable
from importlib import import_module
from typing import Protocol

import numpy as np

from ..errors import PgiError
from ..known_methods import EXAMPLES, IMPLEMENTED
from ..scene.model import Scene
from ..scene.yaml_dialect import parse_yaml_value


class Method(Protocol):
    """A progressive method: each iteration is an independent estimate, the image their mean."""

    id: str
    parameters: frozenset[str]  # the KEYs `--set method.KEY=VALUE` may set
    method_params: dict  # after __init__: each parameter that applies, with the value used

    # spp_budget: the run stops at this many samples per pixel; methods that batch
    # samples per iteration keep their batches a divisor of it.
    def __init__(
        self, scene: Scene, *, seed: int, threads: int, params: dict, spp_budget: int | None = None
    ) -> None: ...
    def run_iteration(self, iteration: int) -> None: ...
    def image(self) -> np.ndarray: ...
    def stats(self) -> dict: ...


# Scene settings a method does not read: overriding one would render the method unchanged
# under another name (a study variant, say), so a render refuses it. Per method: who renders
# it (named in the message: `pgi reference` is Mitsuba too) and the settings.
UNREAD_SETTINGS: dict[str, tuple[str, tuple[str, ...]]] = {
    # ours only: Mitsuba always uses its own transmittance estimator and roulette
    "mitsuba": ("Mitsuba", ("integrator.estimator", "integrator.march_step", "integrator.rr")),
}


def check_overrides(method_id: str, overrides: list[str] | tuple[str, ...]) -> None:
    """Refuses `key=value` scene overrides that the method would ignore, also when given
    as part of a mapping (`integrator={estimator: delta}`)."""
    if method_id not in UNREAD_SETTINGS:
        return
    reader, settings = UNREAD_SETTINGS[method_id]
    for kv in overrides:
        key, _, raw = kv.partition("=")
        key = key.strip()
        for setting in settings:
            below = setting[len(key) + 1 :].split(".") if setting.startswith(key + ".") else None
            if key == setting or (below and _holds(parse_yaml_value(raw, f"--set {key}"), below)):
                raise PgiError(f"--set {kv}: {reader} does not read this setting")


def _holds(value: object, keys: list[str]) -> bool:
    """Whether nested mappings `value` have the key path `keys`."""
    for k in keys:
        if not isinstance(value, dict) or k not in value:
            return False
        value = value[k]
    return True


def check_method_parameters(method_id: str, names: Iterable[str]) -> None:
    """Refuses `method.KEY` names the method does not know, before any scene is loaded."""
    from .params import MethodParams

    cls = get_method(method_id)
    MethodParams(method_id, dict.fromkeys(names), cls.parameters, getattr(cls, "renamed", {}))


def method_ids() -> list[str]:
    return list(IMPLEMENTED)


def describe(method_id: str) -> str:
    return IMPLEMENTED[method_id][2]


def get_method(method_id: str) -> type[Method]:
    """The class of a method of the study, or of an example (known_methods.EXAMPLES)."""
    known = {**IMPLEMENTED, **EXAMPLES}
    if method_id not in known:
        raise PgiError(f"unknown method {method_id!r}; expected one of: {', '.join(method_ids())}")
    # The method's module imports only now: listing methods or rendering with one does not
    # load the others' dependencies.
    module, cls, _ = known[method_id]
    return getattr(import_module(f"{__name__}.{module}"), cls)
