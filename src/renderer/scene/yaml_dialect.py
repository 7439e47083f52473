"""The YAML dialect of scene files: YAML 1.2 numbers and booleans, no duplicate keys, and
every reading error as one PgiError that names the file and line (or the value given)."""

from __future__ import annotations

import re
from collections.abc import Hashable
from pathlib import Path
from typing import Any

import yaml

from renderer.errors import PgiError, one_line, shorten
from renderer.errors import shorten_repr as _describe


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate mapping keys instead of keeping the last one."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # "<<: *anchor": keys given beside
                continue  # it override the anchor's, as YAML's merge means
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, Hashable):  # e.g. {[1]: 2}: the set below would raise
                raise yaml.constructor.ConstructorError(
                    None, None, "found unhashable key", key_node.start_mark
                )
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


# Numbers and booleans as YAML 1.2 reads them, not YAML 1.1 (PyYAML): 1e-3 is a number, not
# text; 1:20 is not 80 (base 60), 0100 not 64 (octal) and 1_000 not 1000 (digit groups), which
# a scene would misread silently: they stay text, and the validator asks for a number. Only
# true/false are booleans: `material: off` names a material "off", not False.
_INT, _FLOAT = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
_BOOL = "tag:yaml.org,2002:bool"
_UniqueKeyLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT, _FLOAT, _BOOL)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_UniqueKeyLoader.add_implicit_resolver(
    _BOOL, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")
)
_UniqueKeyLoader.add_implicit_resolver(
    _INT, re.compile(r"^[-+]?(?:0|[1-9][0-9]*|0x[0-9a-fA-F]+)$"), list("-+0123456789")
)
_UniqueKeyLoader.add_implicit_resolver(
    _FLOAT,
    re.compile(
        r"^(?:[-+]?[0-9]+\.[0-9]*(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?\.[0-9]+(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?[0-9]+[eE][-+]?[0-9]+"
        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
    ),
    list("-+0123456789."),
)


class _TooDeep(yaml.YAMLError):
    """Nesting deeper than the YAML reader's recursion can follow."""

    problem = "nested too deeply"


class _BadScalar(yaml.YAMLError):
    """A scalar YAML's constructors cannot convert (an integer of over 4300 digits)."""

    def __init__(self, problem: str) -> None:
        super().__init__(problem)
        self.problem = problem


def _load_yaml(text: str) -> Any:
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader subclass)
    except RecursionError:
        raise _TooDeep() from None
    except ValueError as e:  # Python's own limit on int() of long digit strings, or a date
        digits = "digits" in str(e)
        raise _BadScalar(
            "an integer of over 4300 digits" if digits else one_line(str(e), 80)
        ) from None


def parse_yaml_value(text: str, where: str) -> Any:
    """A value given on the command line, read as scene files are (1e-3 is a number).
    A value YAML cannot read is a PgiError naming `where`, the value (shortened) and why."""
    try:
        return _load_yaml(text)
    except yaml.YAMLError as e:
        why = getattr(e, "problem", None)
        raise PgiError(
            f"{where}: value {_describe(text)} is not valid YAML"
            + (f" ({shorten(why, 60)})" if why else "")
        ) from None


def read_scene_yaml(path: Path) -> dict:
    """The mapping of scene keys in the scene file ``path`` (the main file or an included
    one); a file that cannot be read, or holds no such mapping, is a PgiError naming it."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise PgiError(f"{path}: cannot read: {e.strerror}") from e
    except UnicodeDecodeError as e:
        raise PgiError(
            f"{path}: not a UTF-8 text file (byte {e.start}: {e.reason}); scene files are YAML"
        ) from None
    doc = _parse_yaml_file(path, text)
    if doc is None:
        raise PgiError(f"{path}: the file is empty; a scene file is a mapping of scene keys")
    if not isinstance(doc, dict):
        raise PgiError(f"{path}: expected a mapping of scene keys at the top level")
    return doc


def _parse_yaml_file(path: Path, text: str) -> Any:
    """The document in ``text`` (read from ``path``); invalid YAML is a PgiError naming the
    file and the line."""
    try:
        return _load_yaml(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark else str(path)
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise PgiError(f"{where}: invalid YAML: {problem}") from None


def check_yaml_file(path: Path) -> tuple[Any, str] | None:
    """Reads a YAML file as scene files are read, for files another reader loads (workflow
    configs): a key given twice is a PgiError naming the line, not the last one silently kept.
    Returns the document and the text it was read from (None if the file cannot be read:
    that reader says so itself)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    return _parse_yaml_file(path, text), text
