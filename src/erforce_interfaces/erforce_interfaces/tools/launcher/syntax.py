"""Reading a launch file: YAML with each entry's line (for errors that name FILE:LINE), the
``$(name arg ...)`` substitution grammar and how text becomes a value (booleans, ``equals``, typed parameter
values and lists), checked against what ros2 launch on Jazzy accepts."""


from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml


class LaunchError(Exception):
    """A problem with the command line or a launch file; ``where`` is ``FILE:LINE`` or ''."""

    def __init__(self, where: str, message: str) -> None:
        super().__init__(message)
        self.where = where
        self.message = message

    def __str__(self) -> str:
        text = f"{self.where}: {self.message}" if self.where else self.message
        return " ".join(text.split())  # always one line


# =============================================================== 1. parse: YAML with lines
class MarkedDict(dict):
    """A YAML mapping that remembers its own line and the line of each key (1-based)."""

    line: int = 0
    key_lines: dict = {}  # noqa: RUF012 - replaced per instance by the loader, never mutated


class MarkedList(list):
    """A YAML sequence that remembers its own line and the line of each item (1-based)."""

    line: int = 0
    item_lines: tuple | list = ()


class _MarkedLoader(yaml.SafeLoader):
    pass


def _construct_mapping(loader: _MarkedLoader, node: yaml.MappingNode) -> MarkedDict:
    loader.flatten_mapping(node)
    out = MarkedDict()
    out.line, out.key_lines = node.start_mark.line + 1, {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            duplicate = key in out
        except TypeError:
            raise yaml.constructor.ConstructorError(None, None, "a key must be a scalar", key_node.start_mark) from None
        if duplicate:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate key '{key}'", key_node.start_mark)
        out[key] = loader.construct_object(value_node, deep=True)
        out.key_lines[key] = key_node.start_mark.line + 1
    return out


def _construct_sequence(loader: _MarkedLoader, node: yaml.SequenceNode) -> MarkedList:
    out = MarkedList(loader.construct_object(child, deep=True) for child in node.value)
    out.line, out.item_lines = node.start_mark.line + 1, [child.start_mark.line + 1 for child in node.value]
    return out


_MarkedLoader.add_constructor("tag:yaml.org,2002:map", _construct_mapping)
_MarkedLoader.add_constructor("tag:yaml.org,2002:seq", _construct_sequence)


def load_launch_entries(path: Path, shown: str) -> MarkedList:
    """The ``launch:`` list of a YAML launch file, with line numbers."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise LaunchError(shown, f"cannot read launch file: {exc.strerror}") from None
    try:
        doc = yaml.load(text, Loader=_MarkedLoader)  # a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = f":{mark.line + 1}" if mark else ""
        started = ""
        if exc.context and exc.context_mark and exc.problem and exc.context_mark is not mark:
            started = f" ({exc.context} started at line {exc.context_mark.line + 1})"
        raise LaunchError(f"{shown}{line}", f"invalid YAML: {exc.problem or exc.context}{started}") from None
    except yaml.YAMLError as exc:
        raise LaunchError(shown, f"invalid YAML: {exc}") from None
    if not isinstance(doc, MarkedDict) or "launch" not in doc:
        raise LaunchError(f"{shown}:1", "expected a top-level 'launch:' list")
    for key in doc:
        if key != "launch":
            raise LaunchError(f"{shown}:{doc.key_lines[key]}", f"unknown top-level key '{key}' (only 'launch')")
    entries = doc["launch"]
    if entries is None:
        return MarkedList()
    if not isinstance(entries, MarkedList):
        raise LaunchError(f"{shown}:{doc.key_lines['launch']}", "'launch' must be a list of actions")
    _check_file_substitutions(entries, shown, doc.key_lines["launch"])
    return entries


# ========================================================== substitutions: $(name arg ...)
@dataclass(frozen=True)
class Subst:
    """One ``$(name args...)``; each argument is itself a list of text and substitutions."""

    name: str
    args: tuple[tuple[str | Subst, ...], ...]


class SubstitutionError(Exception):
    pass


_SUBST_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]*")
_SPACE = " \t\r\n"


def parse_substitutions(text: str) -> list[str | Subst]:
    """Split ``text`` into literal strings and ``Subst`` trees (nesting and quoting allowed)."""
    parts, _ = _parse_parts(text, 0, None)
    return parts


def _parse_parts(text: str, pos: int, stop: str | None) -> tuple[list[str | Subst], int]:
    parts: list[str | Subst] = []
    buf: list[str] = []
    while pos < len(text):
        if text.startswith("$(", pos):
            if buf:
                parts.append("".join(buf))
                buf = []
            sub, pos = _parse_subst(text, pos + 2)
            parts.append(sub)
            continue
        if stop is not None and text[pos] in stop:
            break
        buf.append(text[pos])
        pos += 1
    if buf:
        parts.append("".join(buf))
    return parts, pos


def _parse_subst(text: str, pos: int) -> tuple[Subst, int]:
    m = _SUBST_NAME.match(text, pos)
    if not m:
        raise SubstitutionError("expected a substitution name after '$('")
    name, pos, args = m.group(), m.end(), []
    while True:
        if pos >= len(text):
            raise SubstitutionError(f"'$({name}' is missing its ')'")
        if text[pos] == ")":
            return Subst(name, tuple(args)), pos + 1
        if text[pos] not in _SPACE:
            raise SubstitutionError(f"unexpected {text[pos]!r} after '$({name}'")
        while pos < len(text) and text[pos] in _SPACE:
            pos += 1
        if pos < len(text) and text[pos] != ")":
            arg: list[str | Subst] = []
            while pos < len(text) and text[pos] not in _SPACE + ")":
                quote = text[pos] if text[pos] in "'\"" else None
                if quote:
                    seg, pos = _parse_parts(text, pos + 1, quote)
                    if pos >= len(text):
                        raise SubstitutionError(f"unterminated {quote} in '$({name} ...)'")
                    pos += 1
                else:
                    seg, pos = _parse_parts(text, pos, _SPACE + ")'\"")
                arg.extend(seg)
            args.append(tuple(arg))


# (min, max) argument count of each substitution erforce-launch evaluates
SUBSTITUTIONS = {"var": (1, 1), "env": (1, 2), "find-pkg-share": (1, 1), "find-pkg-prefix": (1, 1),
                 "find-exec": (1, 1), "dirname": (0, 0), "filename": (0, 0), "anon": (1, 1), "equals": (2, 2),
                 "not-equals": (2, 2), "not": (1, 1), "and": (2, 2), "or": (2, 2)}
# launch and launch_ros have these too; erforce-launch does not evaluate them
_NOT_EVALUATED = ("eval", "command", "exec-in-pkg", "param", "if", "file-content", "launch_log_dir", "log_dir")
_UNKNOWN_HINTS = {"optenv": "a ROS 1 substitution; ROS 2 writes $(env NAME default)",
                  "arg": "a ROS 1 substitution; ROS 2 writes $(var NAME)",
                  "find": "a ROS 1 substitution; ROS 2 writes $(find-pkg-share PKG)"}


def check_substitution(sub: Subst) -> None:
    """Reject what ros2 launch's parser rejects, when it loads the file: an unknown name, a wrong count."""
    if sub.name in ("any", "all"):
        # launch exposes them, but its parser calls AnySubstitution(args=[...]) while the constructor
        # takes *args: the TypeError makes ros2 launch reject every file that uses them
        raise SubstitutionError(f"'$({sub.name})' fails in ros2 launch on Jazzy (TypeError from its parser); "
                                f"nest '$({'or' if sub.name == 'any' else 'and'})' instead")
    if sub.name in _NOT_EVALUATED:
        raise SubstitutionError(f"unsupported substitution '$({sub.name})' (supported: {', '.join(SUBSTITUTIONS)})")
    if sub.name not in SUBSTITUTIONS:
        hint = _UNKNOWN_HINTS.get(sub.name, f"known: {', '.join(SUBSTITUTIONS)}")
        raise SubstitutionError(f"Unknown substitution: {sub.name} ({hint})")
    lo, hi = SUBSTITUTIONS[sub.name]
    if not lo <= len(sub.args) <= hi:
        raise SubstitutionError(f"'$({sub.name})' takes {lo}..{hi} argument(s), got {len(sub.args)}")
    for arg in sub.args:
        for part in arg:
            if isinstance(part, Subst):
                check_substitution(part)


def _check_file_substitutions(node: Any, shown: str, line: int) -> None:
    """Parse every substitution of a loaded file, taken branch or not, as ros2 launch's parser does."""
    if isinstance(node, MarkedDict):
        for key, value in node.items():
            if key != "description":  # launch takes an arg's description as plain text
                _check_file_substitutions(value, shown, node.key_lines.get(key, node.line))
    elif isinstance(node, MarkedList):
        for value, item_line in zip(node, node.item_lines, strict=True):
            _check_file_substitutions(value, shown, item_line)
    elif isinstance(node, str) and "$(" in node:
        try:
            for part in parse_substitutions(node):
                if isinstance(part, Subst):
                    check_substitution(part)
        except SubstitutionError as exc:
            raise LaunchError(f"{shown}:{line}", f"{exc} (in '{node}')") from None


def launch_equals(left: str, right: str) -> bool:
    """launch's EqualsSubstitution: bool-like pair as booleans, number pair with math.isclose, else as text."""
    bools = ("true", "false", "1", "0")
    if left.lower() in bools and right.lower() in bools:
        return (left.lower() in ("true", "1")) == (right.lower() in ("true", "1"))
    try:
        return math.isclose(float(left), float(right))
    except ValueError:
        return left == right


def launch_bool(name: str, text: str) -> bool:
    """launch's coerce_to_type(text, bool): exactly '1'/'0', else whatever YAML 1.1 loads as a bool."""
    try:
        value = yaml.safe_load({"1": "true", "0": "false"}.get(text, text))
    except yaml.YAMLError:  # launch turns a YAML failure into "cannot convert"
        value = None
    if not isinstance(value, bool):
        raise SubstitutionError(f"'$({name})' needs a boolean (true/false, 1/0, yes/no, on/off), got '{text}'")
    return value


def yaml_type_name(value: Any) -> str:
    return {MarkedDict: "a mapping", MarkedList: "a list", type(None): "nothing"}.get(type(value), type(value).__name__)


def typed_value(text: str) -> Any:
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    return value if isinstance(value, bool | int | float | str | list) else text


def homogeneous_list(values: list, where: str) -> list:
    kinds = {bool if isinstance(v, bool) else type(v) for v in values}
    if kinds == {int, float}:
        return [float(v) for v in values]
    if len(kinds) > 1 or (kinds and not kinds <= {bool, int, float, str}):
        raise LaunchError(where, "a list parameter needs elements of one type (bool, int, float or string)")
    return values
