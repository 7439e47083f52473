"""Ctrl-C and SIGTERM during a native pass.

Python runs a signal's handler only when the main thread is back in Python, and a pass
through dense media can take minutes without returning (pm on a grid with one voxel of
optical depth 10^4 ignored SIGTERM for over three minutes). While a command runs, a watcher
thread is woken by the signal itself (``signal.set_wakeup_fd``) and sets the native core's
interrupt flag: media tracking stops early, and the pass, back in Python, raises the
handler's exception (KeyboardInterrupt, or the CLI's Terminated) instead of returning a
cut-short result (see ``released`` in cpp/bindings.h).
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import sys
import threading
from collections.abc import Iterator

_WATCHED = {int(signal.SIGINT), int(signal.SIGTERM)}
_STOP = 0  # no signal has number 0: the byte that ends the watcher


def _core_loaded():
    """The native core if a method loaded it, else None: then no pass runs to interrupt.
    Not imported here: what `pgi reference` imports must not include it (its fingerprint
    would follow the C++ sources, and every change of them would rerun the references)."""
    return sys.modules.get(f"{__package__}._core")


@contextlib.contextmanager
def native_passes_interruptible() -> Iterator[None]:
    """Within the block, Ctrl-C and SIGTERM reach native passes as they run."""
    if threading.current_thread() is not threading.main_thread():
        yield  # only the main thread can set the wakeup fd (and runs the handlers)
        return
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    previous = signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)

    def watch() -> None:
        while True:
            select.select([read_end], [], [])
            numbers = os.read(read_end, 512)
            if _STOP in numbers:
                return
            core = _core_loaded()
            if core is not None and _WATCHED.intersection(numbers):
                core.request_interrupt()

    watcher = threading.Thread(target=watch, name="pgi-interrupts", daemon=True)
    watcher.start()
    try:
        yield
    finally:
        signal.set_wakeup_fd(previous)
        os.write(write_end, bytes([_STOP]))
        watcher.join()
        os.close(read_end)
        os.close(write_end)
        core = _core_loaded()
        if core is not None:
            core.clear_interrupt()  # a signal whose handler ended the command already
