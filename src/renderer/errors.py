"""User-facing errors: the CLI prints them as one line and exits non-zero."""

from typing import Any


class PgiError(Exception):
    """A mistake in user input (scene file, option, image) with a message that says what to fix."""


def shorten(text: str, limit: int = 40) -> str:
    """Text quoted from user input in a message, cut to `limit` characters."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def one_line(text: str, limit: int = 160) -> str:
    """A library's message quoted in ours: whitespace runs collapsed, cut to `limit`
    characters (a corrupt file can make one gigabytes long)."""
    return shorten(" ".join(text.split()), limit)


def shorten_repr(value: Any, limit: int = 40) -> str:
    """The repr of a value quoted in a message, cut to `limit` characters."""
    return shorten(repr(value), limit)
