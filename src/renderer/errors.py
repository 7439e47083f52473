"""User-facing errors: the CLI prints them as one line and exits non-zero."""


class PgiError(Exception):
    """A mistake in user input (scene file, option, image) with a message that says what to fix."""
