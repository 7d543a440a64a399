"""Messages as text and from text, on rclpy alone (no rosidl_runtime_py): a message class from its type name,
a message as the dict / YAML / CSV that rosidl_runtime_py's converters produce, field paths (``a.b[0]``), and a
message filled from a YAML dict (with ``now`` stamps), each error a ``ToolError`` naming the field.

Used by ``erforce-topic`` (echo, pub) and the tests that read a graph the way a person does.
"""

from __future__ import annotations

import array
import importlib
import re
import sys
from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import rosidl_parser.definition as idl
import yaml


class ToolError(Exception):
    """A mistake the user can fix: reported as one line on stderr, exit code 1."""


# --------------------------------------------------------------------------------------------------
# Message types
# --------------------------------------------------------------------------------------------------


def get_message_class(type_name: str) -> type:
    """``pkg/msg/Type`` or ``pkg/Type`` -> the generated Python class (imported from ``pkg.msg``)."""
    parts = type_name.strip("/").split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or parts[1] != "msg" or not all(parts):
        raise ToolError(f"invalid message type '{type_name}': expected pkg/msg/Type or pkg/Type")
    pkg, _, name = parts
    try:
        cls = getattr(importlib.import_module(f"{pkg}.msg"), name)
    except (ImportError, AttributeError, ValueError):
        raise ToolError(f"unknown message type '{type_name}'") from None
    if not hasattr(cls, "get_fields_and_field_types"):
        raise ToolError(f"'{type_name}' is not a message type")
    return cls


def _class_of_namespaced(t: idl.NamespacedType) -> type:
    return getattr(importlib.import_module(".".join(t.namespaces)), t.name)


def _idl_type_name(t: Any) -> str:
    if isinstance(t, idl.BasicType):
        return t.typename
    if isinstance(t, idl.AbstractWString):
        return "wstring"
    if isinstance(t, idl.AbstractString):
        return "string"
    if isinstance(t, idl.NamespacedType):
        return "/".join(t.namespaced_name())
    if isinstance(t, idl.NamedType):
        return t.name
    return "unknown"


def new_message(cls: type) -> Any:
    """An instance whose setters check types and bounds (off by default in Jazzy)."""
    try:
        return cls(check_fields=True)
    except TypeError:  # message classes generated before check_fields existed
        return cls()


def _slot_types(msg: Any) -> dict[str, Any]:
    return dict(zip(msg.get_fields_and_field_types(), msg.SLOT_TYPES, strict=True))


# --------------------------------------------------------------------------------------------------
# Message -> dict / YAML / CSV (the text rosidl_runtime_py's converters produce)
# --------------------------------------------------------------------------------------------------


def _array_summary(value: Any, t: Any) -> str:
    item = _idl_type_name(t.value_type)
    if isinstance(t, idl.Array):
        return f"<array type: {item}[{t.size}]>"
    if isinstance(t, idl.BoundedSequence):
        return f"<sequence type: {item}[{t.maximum_size}], length: {len(value)}>"
    return f"<sequence type: {item}, length: {len(value)}>"


def to_plain(value: Any, t: Any = None, *, truncate: int | None, no_arr: bool, no_str: bool) -> Any:
    """One field value -> plain Python (str, int, float, bool, list, OrderedDict)."""
    if isinstance(value, bytes):  # byte / octet fields
        if truncate is not None and len(value) > truncate:
            return "".join(map(chr, value[:truncate])) + "..."
        return "".join(map(chr, value))
    if isinstance(value, str):
        if no_str:
            return f"<string length: <{len(value)}>>"
        if truncate is not None and len(value) > truncate:
            return value[:truncate] + "..."
        return value
    if isinstance(value, list | tuple | array.array | np.ndarray):
        if no_arr and t is not None:
            return _array_summary(value, t)
        shown = value[:truncate] if truncate is not None else value
        out = [to_plain(v, truncate=truncate, no_arr=no_arr, no_str=no_str) for v in shown]
        return [*out, "..."] if len(value) > len(out) else out
    if isinstance(value, np.generic):  # numpy scalars (elements of fixed-size arrays)
        return value.item()
    if isinstance(value, bool | int | float):
        return value
    return message_to_ordereddict(value, truncate_length=truncate, no_arr=no_arr, no_str=no_str)


def message_to_ordereddict(
    msg: Any, *, truncate_length: int | None = None, no_arr: bool = False, no_str: bool = False
) -> OrderedDict:
    """Fields in .msg order; arrays (list, array.array, numpy) become lists, nested messages dicts."""
    return OrderedDict(
        (name, to_plain(getattr(msg, name), t, truncate=truncate_length, no_arr=no_arr, no_str=no_str))
        for name, t in _slot_types(msg).items()
    )


class _MessageDumper(yaml.SafeDumper):
    """SafeDumper that writes OrderedDicts as plain mappings in field order."""


_MessageDumper.add_representer(
    OrderedDict, lambda dumper, data: dumper.represent_mapping("tag:yaml.org,2002:map", data.items())
)


def dump_yaml(data: Any, flow_style: bool = False) -> str:
    return yaml.dump(
        data, Dumper=_MessageDumper, allow_unicode=True, width=sys.maxsize,
        default_flow_style=flow_style, sort_keys=False,
    )


def message_to_yaml(
    msg: Any, *, truncate_length: int | None = None, no_arr: bool = False, no_str: bool = False,
    flow_style: bool = False,
) -> str:
    """Block-style YAML of a message, byte-identical to rosidl_runtime_py.message_to_yaml."""
    plain = message_to_ordereddict(msg, truncate_length=truncate_length, no_arr=no_arr, no_str=no_str)
    return dump_yaml(plain, flow_style)


def message_to_csv(
    msg: Any, *, truncate_length: int | None = None, no_arr: bool = False, no_str: bool = False
) -> str:
    """All leaf values of a message, depth first, comma-separated (ros2 topic echo --csv)."""

    def text(value: Any, t: Any = None) -> str:
        if isinstance(value, list | tuple | array.array | np.ndarray):
            if no_arr and t is not None:
                return _array_summary(value, t)
            items = [text(v) for v in (value[:truncate_length] if truncate_length is not None else value)]
            return ",".join(items + (["..."] if len(items) < len(value) else []))
        if isinstance(value, bool | bytes | float | int | str | np.generic):
            if isinstance(value, str) and no_str:
                return f"<string length: <{len(value)}>>"
            if isinstance(value, bytes | str) and truncate_length is not None and len(value) > truncate_length:
                value = value[:truncate_length] + (b"..." if isinstance(value, bytes) else "...")
            return str(value)
        return message_to_csv(value, truncate_length=truncate_length, no_arr=no_arr, no_str=no_str)

    return ",".join(text(getattr(msg, name), t) for name, t in _slot_types(msg).items())


_FIELD_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def parse_field_path(path: str) -> list[str | int]:
    """``"a.b[2].c"`` or ``"a.b.2.c"`` -> ``["a", "b", 2, "c"]``."""
    tokens: list[str | int] = []
    pos = 0
    for m in _FIELD_TOKEN.finditer(path):
        gap = path[pos:m.start()]
        if gap not in ("", "."):
            raise ToolError(f"invalid field '{path}'")
        name, index = m.groups()
        tokens.append(int(index) if index is not None else int(name) if name.isdigit() else name)
        pos = m.end()
    if not tokens or path[pos:] not in ("", "."):
        raise ToolError(f"invalid field '{path}'")
    return tokens


def get_field(msg: Any, path: Sequence[str | int]) -> Any:
    """The value at ``path`` (field names and list indices) inside ``msg``."""
    value = msg
    for i, token in enumerate(path):
        where = ".".join(map(str, path[: i + 1]))
        if isinstance(token, int):
            if not isinstance(value, list | tuple | array.array | np.ndarray):
                raise ToolError(f"invalid field '{where}': not an array")
            if not -len(value) <= token < len(value):
                raise ToolError(f"invalid field '{where}': index out of range (length {len(value)})")
            value = value[token]
        elif hasattr(value, "get_fields_and_field_types") and token in value.get_fields_and_field_types():
            value = getattr(value, token)
        else:
            raise ToolError(f"invalid field '{where}': {type(value).__name__} has no field '{token}'")
    return value


# --------------------------------------------------------------------------------------------------
# dict (from YAML) -> message
# --------------------------------------------------------------------------------------------------

_FLOAT_TYPES = {"float", "double", "long double"}
_INT_RANGES = {
    f"{sign}int{bits}": (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if sign == "" else (0, 2**bits - 1)
    for sign in ("", "u") for bits in (8, 16, 32, 64)
} | {"char": (0, 255), "wchar": (0, 0xFFFF)}

#: Sets a ``builtin_interfaces/Time`` inside a message; pub calls these before each publish.
StampSetter = Callable[[Any], None]


def _basic_value(typename: str, value: Any, where: str) -> Any:
    if typename in _FLOAT_TYPES:
        if isinstance(value, str):  # YAML 1.1 reads "1e-5" (no dot) as a string
            try:
                return float(value)
            except ValueError:
                pass
        if isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
        raise ToolError(f"field '{where}': expected a number, got {value!r}")
    if typename in _INT_RANGES:
        if typename in ("char", "wchar") and isinstance(value, str) and len(value) == 1:
            return value
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not isinstance(value, int) or isinstance(value, bool):
            raise ToolError(f"field '{where}': expected an integer, got {value!r}")
        lo, hi = _INT_RANGES[typename]
        if not lo <= value <= hi:
            raise ToolError(f"field '{where}': {value} is out of the {typename} range [{lo}, {hi}]")
        return value
    if typename == "boolean":
        if isinstance(value, bool):
            return value
        raise ToolError(f"field '{where}': expected true or false, got {value!r}")
    if typename in ("octet", "byte"):
        if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 255:
            return bytes([value])
        if isinstance(value, bytes | str) and len(value) == 1:
            return value.encode("latin-1") if isinstance(value, str) else value
        raise ToolError(f"field '{where}': expected a byte (0..255), got {value!r}")
    return value


def _field_value(t: Any, current: Any, value: Any, where: str, stamps: list[StampSetter]) -> Any:
    """The value to assign to a field of IDL type ``t`` (current value ``current``) from YAML ``value``."""
    if isinstance(t, idl.NamespacedType):
        cls = type(current) if current is not None else _class_of_namespaced(t)
        full = "/".join(t.namespaced_name())
        if full == "std_msgs/msg/Header" and value == "auto":
            header = new_message(cls)
            stamps.append(lambda stamp: setattr(header, "stamp", stamp))
            return header
        if full == "builtin_interfaces/msg/Time" and value == "now":
            stamp = new_message(cls)
            stamps.append(lambda now: (setattr(stamp, "sec", now.sec), setattr(stamp, "nanosec", now.nanosec)))
            return stamp
        sub = new_message(cls)
        _set_fields(sub, value, where, stamps)
        return sub
    if isinstance(t, idl.AbstractNestedType):
        if isinstance(value, str) and isinstance(t.value_type, idl.BasicType) and t.value_type.typename in (
            "octet", "byte", "uint8", "char",
        ):
            value = list(value.encode("latin-1")) if t.value_type.typename != "char" else list(value)
        if not isinstance(value, list | tuple):
            raise ToolError(f"field '{where}': expected a list, got {value!r}")
        if isinstance(t, idl.Array) and len(value) != t.size:
            raise ToolError(f"field '{where}': expected exactly {t.size} elements, got {len(value)}")
        if isinstance(t, idl.BoundedSequence) and len(value) > t.maximum_size:
            raise ToolError(f"field '{where}': at most {t.maximum_size} elements allowed, got {len(value)}")
        items = [_field_value(t.value_type, None, v, f"{where}[{i}]", stamps) for i, v in enumerate(value)]
        if isinstance(current, np.ndarray):
            return np.array(items, dtype=current.dtype)
        if isinstance(current, array.array):
            return array.array(current.typecode, items)
        return items
    if isinstance(t, idl.AbstractString):
        if isinstance(value, dict | list):
            raise ToolError(f"field '{where}': expected a string, got {value!r}")
        return value if isinstance(value, str) else str(value)
    return _basic_value(t.typename, value, where)


def _set_fields(msg: Any, values: Any, path: str, stamps: list[StampSetter]) -> None:
    if values is None:
        values = {}
    if not isinstance(values, dict):
        raise ToolError(f"field '{path or '<message>'}': expected a mapping, got {values!r}")
    slots = _slot_types(msg)
    for name, value in values.items():
        where = f"{path}.{name}" if path else str(name)
        if name not in slots:
            raise ToolError(
                f"unknown field '{where}' in {type(msg).__name__} (fields: {', '.join(slots) or 'none'})"
            )
        converted = _field_value(slots[name], getattr(msg, name), value, where, stamps)
        try:
            setattr(msg, name, converted)
        except (AssertionError, TypeError, ValueError, OverflowError) as exc:
            raise ToolError(f"field '{where}': {exc}") from None


def set_message_fields(msg: Any, values: dict | None) -> list[StampSetter]:
    """Fill ``msg`` from a (YAML-loaded) dict, converting numbers to each field's type.

    ``header: auto`` and ``stamp: now`` (for std_msgs/Header and builtin_interfaces/Time fields)
    are accepted as ros2 topic pub does: the returned setters put the current time into those
    fields and are called before every publish. Raises ToolError naming the offending field.
    """
    stamps: list[StampSetter] = []
    _set_fields(msg, values, "", stamps)
    return stamps


