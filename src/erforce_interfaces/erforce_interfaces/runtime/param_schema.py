"""Declarative node parameters: one schema file per node, from which everything else derives.

A node's parameters live in ``<package>/params/<node>.yaml``, in the spirit of ros2_controllers'
generate_parameter_library: per parameter its ``type``, ``default_value``, ``description``,
``read_only`` and ``validation``. From that one file come the ROS declarations with their
descriptors (node_support.NodeParams), the checks on start and on every change, the node's
config object (``ParamSchema.parse``: a frozen object with one attribute per parameter) and
the tables of docs/reference.md (``ParamSchema.markdown``). The schema files ship inside the Python package
and in ``share/<package>/params``.

Format::

    velocity_controller:            # the node name
      loop_rate_hz:
        type: double                # bool | int | double | string | <one of those>_array
        default_value: 500.0
        description: "velocity loop rate [Hz]"
        read_only: false            # optional; true: fixed once the node runs
        validation:                 # optional
          bounds<>: [1.0, 20000.0]  # inclusive; also gt<>, gt_eq<>, lt<>, lt_eq<>: [value]
      anti_windup:
        type: string
        default_value: clamp
        description: "integrator anti-windup"
        validation:
          one_of<>: [[clamp, back_calculation]]   # arrays: every element (subset_of<> is the same)
      robot: {shared: robot_description, read_only: false}   # the robot.* group (robot_config.py)
      port:
        type: int
        default_from: erforce_interfaces.ssl.ssl_vision:SSL_VISION_PORT   # instead of default_value: a
        description: "UDP port"               # quantity whose home is code (see "Each default" below)

Bounds on an array apply to every element; ``size_gt<>`` / ``fixed_size<>`` bound its length.

Each default is written once. A physical or protocol quantity (the robot's catching limits, the
carpet's ball model, the field, vision noise, the lockstep tick, a well-known port) is a constant
in code, in the module that owns the concept (``robot_config``, ``catch_time``, ``lockstep``,
``ssl_vision``, ``pid``), and every schema that has it names it with ``default_from``. Every other
parameter has its default only in its node's schema: a core dataclass field of the same name reads
it with ``schema_defaults`` (``gain: float = DEFAULTS["gain"]``), never a literal of its own. Launch
files pass a value only where it differs from the default; a launch argument that hands a knob on
must have a default, and it mirrors the schema's (test_each_default_once lists and checks those).
Checks that relate several parameters (a per-robot list that must match the robot count) are
the node's: its build function raises ValueError. No rclpy import: the cores and docs use it.
"""

from __future__ import annotations

import array
import dataclasses
import importlib
import importlib.resources
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from functools import cache
from types import MappingProxyType
from typing import Any

import yaml

from erforce_interfaces.wire.robot_config import RobotConfig

ROBOT_PREFIX = "robot."
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
ROBOT_GROUP = "robot_description"

_SCALAR_TYPES: dict[str, tuple[type, ...]] = {
    "bool": (bool,), "int": (int,), "double": (float, int), "string": (str,),
}
TYPES = (*_SCALAR_TYPES, *(f"{t}_array" for t in _SCALAR_TYPES))
_TYPE_OF_DEFAULT = {bool: "bool", int: "int", float: "double", str: "string"}


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: type, default, description, bounds, allowed values, read-only."""

    name: str
    type: str
    default: Any
    description: str
    lower: float | None = None
    upper: float | None = None
    lower_open: bool = False  # True: the value must be > lower, not >= lower
    upper_open: bool = False
    one_of: tuple | None = None
    min_size: int = 0
    max_size: int | None = None
    read_only: bool = False

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ValueError(f"{self.name}: unknown type {self.type!r}; known: {', '.join(TYPES)}")
        if self.is_array:
            object.__setattr__(self, "default", tuple(self.default))
        reason = self.check(self.default)
        if reason:
            raise ValueError(f"default of {reason}")

    @property
    def is_array(self) -> bool:
        return self.type.endswith("_array")

    @property
    def element_type(self) -> str:
        return self.type.removesuffix("_array")

    def coerce(self, value: Any) -> Any:
        """``value`` as this parameter takes it: an integer for a double (also inside a double array)
        becomes that float, as a YAML or launch file writes ``0`` for 0.0; anything else is returned as
        it is, for ``check`` to judge."""
        if self.element_type != "double":
            return value

        def one(v: Any) -> Any:
            return float(v) if isinstance(v, int) and not isinstance(v, bool) else v

        if self.is_array:
            return [one(v) for v in value] if isinstance(value, list | tuple | array.array) else value
        return one(value)

    def check(self, value: Any) -> str | None:
        """Why ``value`` is unacceptable (a sentence naming the parameter), or None."""
        if self.is_array:
            if not isinstance(value, list | tuple | array.array):
                return f"{self.name}: expected a list, got {value!r}"
            values = list(value)
            if len(values) < self.min_size:
                return f"{self.name}: needs at least {self.min_size} value(s), got {len(values)}"
            if self.max_size is not None and len(values) > self.max_size:
                return f"{self.name}: takes at most {self.max_size} value(s), got {len(values)}"
        else:
            values = [value]
        kinds = _SCALAR_TYPES[self.element_type]
        for v in values:
            if not isinstance(v, kinds) or (isinstance(v, bool) and bool not in kinds):
                return f"{self.name}: expected {self.element_type}, got {v!r}"
            if isinstance(v, float) and not math.isfinite(v):
                return f"{self.name}: must be finite, got {v!r}"
            if self.one_of is not None and v not in self.one_of:
                return f"{self.name}: must be one of {', '.join(map(str, self.one_of))}; got {v!r}"
            if isinstance(v, bool) or not isinstance(v, int | float):
                continue
            if self.lower is not None and (v < self.lower or (self.lower_open and v == self.lower)):
                return f"{self.name}: {v!r} is {'at or ' if self.lower_open else ''}below the minimum {self.lower!r}"
            if self.upper is not None and (v > self.upper or (self.upper_open and v == self.upper)):
                return f"{self.name}: {v!r} is {'at or ' if self.upper_open else ''}above the maximum {self.upper!r}"
        return None

    def constraint_text(self) -> str:
        parts = []
        if self.lower is not None or self.upper is not None:
            lo = "(−∞" if self.lower is None else f"{'(' if self.lower_open else '['}{self.lower:g}"
            hi = "∞)" if self.upper is None else f"{self.upper:g}{')' if self.upper_open else ']'}"
            parts.append(f"{lo}, {hi}")
        if self.one_of is not None:
            parts.append(" | ".join(map(str, self.one_of)))
        if self.min_size:
            parts.append(f"≥ {self.min_size} values")
        if self.read_only:
            parts.append("read-only")
        return "; ".join(parts) or "—"

    def default_text(self) -> str:
        if self.is_array:
            return f"`{list(self.default)!r}`"
        return f"`{self.default!r}`"


def _default_from(reference: Any, name: str, where: str) -> Any:
    """The value of ``package.module:CONSTANT``."""
    module_name, _, attribute = str(reference).partition(":")
    try:
        return getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError, ValueError) as exc:
        raise ValueError(f"{where}: {name}: default_from {reference!r} is no module:CONSTANT ({exc})") from None


def _spec_from_yaml(name: str, entry: Mapping[str, Any], where: str) -> ParamSpec:
    unknown = set(entry) - {"type", "default_value", "default_from", "description", "read_only", "validation"}
    if unknown or "type" not in entry or ("default_value" in entry) == ("default_from" in entry) \
            or "description" not in entry:
        raise ValueError(f"{where}: {name}: needs type, default_value or default_from, description (and may have "
                         f"read_only, validation); unknown keys: {sorted(unknown)}")
    kw: dict[str, Any] = {}
    for rule, args in (entry.get("validation") or {}).items():
        args = list(args) if isinstance(args, list | tuple) else [args]
        if rule == "bounds<>":
            kw["lower"], kw["upper"] = args
        elif rule in ("gt<>", "gt_eq<>"):
            kw["lower"], kw["lower_open"] = args[0], rule == "gt<>"
        elif rule in ("lt<>", "lt_eq<>"):
            kw["upper"], kw["upper_open"] = args[0], rule == "lt<>"
        elif rule in ("one_of<>", "subset_of<>"):
            kw["one_of"] = tuple(args[0])
        elif rule == "size_gt<>":
            kw["min_size"] = int(args[0]) + 1
        elif rule == "fixed_size<>":
            kw["min_size"] = kw["max_size"] = int(args[0])
        else:
            raise ValueError(f"{where}: {name}: unknown validation {rule!r}")
    for key in ("lower", "upper"):
        if key in kw and (isinstance(kw[key], bool) or not isinstance(kw[key], int | float)):
            raise ValueError(f"{where}: {name}: bound {kw[key]!r} is not a number (YAML wants 1.0e-6, not 1e-6)")
    default = entry["default_value"] if "default_value" in entry else _default_from(entry["default_from"], name, where)
    if entry["type"] == "double" and isinstance(default, int) and not isinstance(default, bool):
        default = float(default)
    if entry["type"] == "double_array":
        default = [float(v) for v in default]
    return ParamSpec(name, entry["type"], default, str(entry["description"]).strip(),
                     read_only=bool(entry.get("read_only", False)), **kw)


def robot_param_specs(read_only: bool = False) -> tuple[ParamSpec, ...]:
    """The ``robot.*`` group: RobotConfig's fields, with its documentation and per-field bounds.

    RobotConfig also checks the description as a whole (wheel layout rank, wheel speeds against the
    motor, ...) when a node parses the group.
    """
    specs = []
    defaults = RobotConfig().to_dict()
    for f in fields(RobotConfig):
        meta = f.metadata
        default = defaults[f.name]
        kind = "double_array" if isinstance(default, list) else _TYPE_OF_DEFAULT[type(default)]
        specs.append(ParamSpec(ROBOT_PREFIX + f.name, kind, default, meta.get("doc", ""),
                               lower=meta.get("gt"), lower_open="gt" in meta,
                               upper=meta.get("le"), min_size=meta.get("min_size", 0), read_only=read_only))
    return tuple(specs)


class ParamSchema:
    """The parameters of one node, in declaration order."""

    def __init__(self, node: str, specs: Iterable[ParamSpec], robot: bool = False) -> None:
        self.node = node
        self.specs = tuple(specs)
        self.by_name = {s.name: s for s in self.specs}
        if len(self.by_name) != len(self.specs):
            raise ValueError(f"{node}: a parameter is listed twice")
        self.has_robot = robot
        own = [s for s in self.specs if not s.name.startswith(ROBOT_PREFIX)]
        attrs = [(s.name, Any) for s in own] + ([("robot", RobotConfig)] if robot else [])
        # The config object: one attribute per parameter, robot.* as one RobotConfig.
        self.config_type = dataclasses.make_dataclass(
            "".join(p.title() for p in node.split("_")) + "Params", attrs, frozen=True)

    @classmethod
    def from_yaml_text(cls, text: str, where: str = "<schema>") -> ParamSchema:
        data = yaml.load(text, Loader=_LOADER)
        if not isinstance(data, dict) or len(data) != 1:
            raise ValueError(f"{where}: expected one top-level key, the node name")
        (node, entries), = data.items()
        specs: list[ParamSpec] = []
        robot = False
        for name, entry in (entries or {}).items():
            if isinstance(entry, dict) and "shared" in entry:
                if entry["shared"] != ROBOT_GROUP or name != "robot":
                    raise ValueError(f"{where}: {name}: the only shared group is robot: {{shared: {ROBOT_GROUP}}}")
                specs += robot_param_specs(read_only=bool(entry.get("read_only", False)))
                robot = True
            else:
                specs.append(_spec_from_yaml(name, entry or {}, where))
        return cls(node, specs, robot)

    def default(self, name: str) -> Any:
        return self.by_name[name].default

    def defaults(self) -> dict[str, Any]:
        return {s.name: s.default for s in self.specs}

    def check(self, values: Mapping[str, Any]) -> None:
        """Raise ValueError naming the first value that breaks its parameter's rules."""
        for s in self.specs:
            reason = s.check(values[s.name])
            if reason:
                raise ValueError(f"invalid parameter {reason}")

    def parse(self, values: Mapping[str, Any]):
        """The config object of a complete set of values; ValueError when a value or the robot is invalid."""
        self.check(values)
        own = {}
        for s in self.specs:
            if not s.name.startswith(ROBOT_PREFIX):
                v = values[s.name]
                own[s.name] = tuple(v) if s.is_array else (float(v) if s.type == "double" else v)
        if self.has_robot:
            robot = {k[len(ROBOT_PREFIX):]: v for k, v in values.items() if k.startswith(ROBOT_PREFIX)}
            try:
                own["robot"] = RobotConfig.from_dict(robot)
            except ValueError as exc:
                raise ValueError(f"invalid parameter robot.{exc}") from None
        return self.config_type(**own)

    def markdown(self, skip_robot: bool = True) -> str:
        """The documentation table (``robot.*`` is documented once, separately)."""
        rows = ["| parameter | type | default | valid | description |", "|---|---|---|---|---|"]
        for s in self.specs:
            if skip_robot and s.name.startswith(ROBOT_PREFIX):
                continue
            cells = [f"`{s.name}`", s.type, s.default_text(), s.constraint_text(), s.description]
            rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        return "\n".join(rows)



class HostSchema(ParamSchema):
    """The parameters of a node that hosts other nodes' cores (a team's firmware in one process).

    Its own schema's parameters, then each hosted node's under a prefix (the same names, ranges and
    defaults, one truth), then ``robot.*`` once. A hosted parameter listed in ``skip`` means nothing in
    the host: it is not declared and keeps its default. ``parse`` gives ``(own config, {prefix: hosted
    config})``, each the object its own schema makes, so the hosted nodes' build functions apply as is.
    """

    def __init__(self, own: ParamSchema, hosted: Mapping[str, tuple[ParamSchema, Iterable[str]]]) -> None:
        self.own = own
        self.hosted = {prefix: (schema, frozenset(skip)) for prefix, (schema, skip) in hosted.items()}
        specs = [s for s in own.specs if not s.name.startswith(ROBOT_PREFIX)]
        for prefix, (schema, skip) in self.hosted.items():
            specs += [dataclasses.replace(s, name=prefix + s.name) for s in schema.specs
                      if not s.name.startswith(ROBOT_PREFIX) and s.name not in skip]
        specs += [s for s in own.specs if s.name.startswith(ROBOT_PREFIX)]
        self.node, self.specs, self.has_robot = own.node, tuple(specs), own.has_robot
        self.by_name = {s.name: s for s in self.specs}
        if len(self.by_name) != len(self.specs):
            raise ValueError(f"{own.node}: a parameter is listed twice")
        self.config_type = None

    def parse(self, values: Mapping[str, Any]):
        self.check(values)
        own = self.own.parse({s.name: values[s.name] for s in self.own.specs})
        hosted = {}
        for prefix, (schema, skip) in self.hosted.items():
            hosted[prefix] = schema.parse({
                s.name: s.default if s.name in skip else values[s.name if s.name.startswith(ROBOT_PREFIX) else
                                                                prefix + s.name]
                for s in schema.specs})
        return own, hosted


def fields_for(cls: type, config: Any, **given: Any) -> dict[str, Any]:
    """The constructor arguments of dataclass ``cls`` taken by name from a node's config object.

    ``given`` supplies the fields that are not parameters of the node; every other field of ``cls``
    must be one, so a core option added later cannot silently stay at its default in the node.
    """
    out = dict(given)
    for f in fields(cls):
        if f.name in given or not f.init:
            continue
        if not hasattr(config, f.name):
            raise TypeError(f"{cls.__name__}.{f.name} is neither a parameter of the node nor given")
        out[f.name] = getattr(config, f.name)
    return out


def check_finite_fields(config: Any, names: Iterable[str], lower: float, upper: float = math.inf, *,
                        lower_open: bool = False, upper_open: bool = False) -> None:
    """A ValueError naming ``<class>.<field>`` for the first of ``config``'s fields ``names`` that is not a finite
    number from ``lower`` to ``upper`` (either end left out when open, as a schema's ``gt<>`` / ``lt<>``): the check
    a core config makes of its own fields, as it is also built without a node's schema."""
    for name in names:
        v = getattr(config, name)
        if not (isinstance(v, int | float) and math.isfinite(v) and (v > lower if lower_open else v >= lower)
                and (v < upper if upper_open else v <= upper)):
            bound = (f"{'>' if lower_open else '>='} {lower:g}" if upper == math.inf else
                     f"in {'(' if lower_open else '['}{lower:g}, {upper:g}{')' if upper_open else ']'}")
            raise ValueError(f"{type(config).__name__}.{name}: must be finite and {bound}, got {v!r}")


def _schema_text(package: str, node: str) -> str:
    return (importlib.resources.files(package) / "params" / f"{node}.yaml").read_text()


@cache
def schema_defaults(package: str, node: str) -> Mapping[str, Any]:
    """The ``default_value`` of each parameter of ``<package>/params/<node>.yaml``, checked and typed as
    the node declares it (a double array as a tuple): a core's dataclass field that is also a node
    parameter takes its default from here (``gain: float = DEFAULTS["gain"]``), so the number is
    written once. Only this file is read, and no ``default_from`` is imported, so a module that a
    schema names may call it at import time; a ``default_from`` parameter is not in it (import its
    constant instead).
    """
    where = f"{package}/params/{node}.yaml"
    (_, entries), = yaml.load(_schema_text(package, node), Loader=_LOADER).items()
    return MappingProxyType({name: _spec_from_yaml(name, entry, where).default for name, entry in entries.items()
                             if isinstance(entry, dict) and "default_value" in entry})


@cache
def load_schema(package: str, node: str) -> ParamSchema:
    """The schema ``<package>/params/<node>.yaml`` (package data of the Python package)."""
    schema = ParamSchema.from_yaml_text(_schema_text(package, node), f"{package}/params/{node}.yaml")
    if schema.node != node:
        raise ValueError(f"{package}/params/{node}.yaml describes node {schema.node!r}")
    return schema
