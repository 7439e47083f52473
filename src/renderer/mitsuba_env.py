"""Import Mitsuba 3 with an RGB variant chosen for this machine.

``llvm_ad_rgb`` is ~2-3x faster than ``scalar_rgb`` but needs LLVM >= 16 (Debian's default
LLVM 15 crashes Dr.Jit). We look for a suitable ``libLLVM`` in the standard library folders and
point ``DRJIT_LIBLLVM_PATH`` at it before Dr.Jit starts; without one we use ``scalar_rgb``.
``PGI_MITSUBA_VARIANT`` overrides the choice; only RGB variants (``*_rgb``) are accepted.
"""

from __future__ import annotations

import contextlib
import glob
import os
import re
import signal
import sys
import threading
from collections.abc import Iterator
from types import ModuleType

from renderer.errors import PgiError, one_line

LIB_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib64",
    "/usr/lib",
    "/usr/local/lib",
    "/usr/lib/llvm-*/lib",
)
MIN_LLVM = 16


def find_libllvm() -> str | None:
    """Path of the newest libLLVM with major version >= 16 in the standard folders, or None."""
    best: tuple[int, str] | None = None
    for d in LIB_DIRS:
        for path in glob.glob(f"{d}/libLLVM-*.so*") + glob.glob(f"{d}/libLLVM.so.*"):
            m = re.match(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
            if m and int(m.group(1)) >= MIN_LLVM and (best is None or int(m.group(1)) > best[0]):
                best = (int(m.group(1)), path)
    return best[1] if best else None


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Ctrl-C and SIGTERM wait until the block ends. Dr.Jit broken off while it starts (an
    interrupt raised in Mitsuba's import or set_variant) can abort the interpreter at exit
    with "Fatal Python error" instead of a clean exit; after the block, the signal is handled
    as it would have been."""
    if threading.current_thread() is not threading.main_thread():
        yield  # only the main thread runs Python's signal handlers
        return
    caught: list[int] = []
    # A handler installed outside Python (getsignal gives None) could not be put back.
    held = [s for s in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(s) is not None]
    handlers = {s: signal.signal(s, lambda signum, frame: caught.append(signum)) for s in held}
    try:
        yield
    finally:
        for s, handler in handlers.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(caught):
            signal.raise_signal(s)  # now the handler restored above takes it


def import_mitsuba(variant: str | None = None) -> ModuleType:
    """The ``mitsuba`` module with a variant set (see the module docstring for the choice)."""
    with signals_held():
        return _import_mitsuba(variant)


def _import_mitsuba(variant: str | None) -> ModuleType:
    variant = variant or os.environ.get("PGI_MITSUBA_VARIANT") or None
    if variant is None and "DRJIT_LIBLLVM_PATH" not in os.environ:
        lib = find_libllvm()
        if lib:
            os.environ["DRJIT_LIBLLVM_PATH"] = lib
    import mitsuba as mi

    if variant is not None:
        if not variant.endswith("_rgb"):
            # Spectral and mono variants upsample our RGB values to spectra (and emission to
            # D65-based spectra): the reference would not be the scene we render.
            raise PgiError(
                f"Mitsuba variant {variant!r}: pgi needs an RGB variant (one ending in _rgb, "
                "e.g. llvm_ad_rgb or scalar_rgb), as its scenes are RGB"
            )
        if mi.variant() != variant:
            try:
                mi.set_variant(variant)
            except Exception as e:
                raise PgiError(f"cannot use Mitsuba variant {variant!r}: {e}") from e
        return mi
    if mi.variant() is None or not mi.variant().endswith("_rgb"):
        if "DRJIT_LIBLLVM_PATH" in os.environ and "llvm_ad_rgb" in mi.variants():
            try:
                mi.set_variant("llvm_ad_rgb")
                return mi
            except Exception as e:
                # Still a correct render, 2-3x slower: a timed comparison must know.
                print(
                    f"pgi: note: Mitsuba's llvm_ad_rgb variant failed ({one_line(str(e))}); "
                    "using scalar_rgb, 2-3x slower",
                    file=sys.stderr,
                )
        mi.set_variant("scalar_rgb")
    return mi


def set_threads(n: int) -> None:
    """Number of worker threads Mitsuba renders with (Dr.Jit's thread pool, all variants)."""
    import drjit as dr

    if n < 1:
        raise PgiError(f"thread count must be >= 1, got {n}")
    dr.set_thread_count(n)
