"""User-facing errors: the CLI prints them as one line and exits non-zero."""

import datetime
import re
import reprlib
from pathlib import Path
from typing import Any


class PgiError(Exception):
    """A mistake in user input (scene file, option, image) with a message that says what to fix."""


def shorten(text: str, limit: int = 40) -> str:
    """Text quoted from user input in a message, cut to `limit` characters."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def printable(text: str) -> str:
    """A message with the control characters a user's input may carry (a NUL in a file name,
    an escape sequence) written as escapes, so that a terminal shows them."""
    return "".join(
        c if c.isprintable() or c == "\n" else c.encode("unicode_escape").decode() for c in text
    )


def one_line(text: str, limit: int = 160) -> str:
    """A library's message quoted in ours: whitespace runs collapsed, cut to `limit`
    characters (a corrupt file can make one gigabytes long)."""
    return shorten(" ".join(text.split()), limit)


def not_a_file(path: Path) -> str:
    """Why ``path``, which the caller found is not a regular file, cannot be read as one:
    "not found", or what it is instead."""
    if "\0" in str(path):
        return "cannot exist: its name has a NUL character"
    if path.is_symlink() and not path.exists():
        return "is a symbolic link to nothing (its target is missing, or the links loop)"
    if path.is_dir():
        return "is a folder"
    if path.exists():
        return "is not a regular file (a device, pipe or socket)"
    return "not found"


def mitsuba_cause(text: str) -> str:
    """The cause at the end of a Mitsuba error, without the source locations and plugin
    contexts it is wrapped in ('[parser.cpp:1718] At dictionary node ...: [PLYMesh] Error
    while loading PLY file "x.ply": [ply.h:213] "x.ply": could not parse ...')."""
    last = re.split(r"\[[A-Za-z_][\w.]*(?::\d+)?\]\s*", text.strip())[-1]
    return re.sub(r'^"[^"]*":\s*', "", last).strip() or text.strip()


class _YamlRepr(reprlib.Repr):
    """Values as a YAML file writes them, at any depth: true, false, null and dates as
    written, not Python's True, None and datetime.date(2001, 1, 1)."""

    def repr_bool(self, value: bool, level: int) -> str:
        return "true" if value else "false"

    def repr_NoneType(self, value: None, level: int) -> str:  # noqa: N802 (reprlib's naming)
        return "null"

    def repr_date(self, value: datetime.date, level: int) -> str:
        return value.isoformat()

    repr_datetime = repr_date


def shorten_repr(value: Any, limit: int = 40) -> str:
    """The repr of a value quoted in a message, cut to `limit` characters. Built with bounded
    depth and length: YAML aliases nested a few levels deep make a small file a value whose
    full repr takes gigabytes (the check of `stresses: [*a8]` once took 10 s and 750 MB).
    Written as YAML writes values (_YamlRepr): they come from scene files and overrides."""
    if isinstance(value, int) and value.bit_length() > 256:  # repr refuses over 4300 digits
        return f"an integer of about {int(value.bit_length() * 0.30103)} digits"
    bounded = _YamlRepr()
    bounded.maxlevel = 4
    bounded.maxlist = bounded.maxtuple = bounded.maxdict = bounded.maxset = limit
    bounded.maxstring = bounded.maxother = bounded.maxlong = 2 * limit + 10
    return shorten(bounded.repr(value), limit)


def caused_by_interrupt(error: BaseException | None) -> KeyboardInterrupt | None:
    """The interrupt (Ctrl-C, or the CLI's SIGTERM) that caused this error, if one did
    (Mitsuba's JIT re-raises it as a RuntimeError)."""
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return error
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return None
