"""Keeps what is generated from the code in sync with it: the sections of docs/reference.md and the
robot description file, config/robot.yaml.

A section sits between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``. Regenerate all
with ``./run exec python -m erforce_interfaces.tools.docs [FILE ...]`` (default docs/reference.md and
config/robot.yaml); a test fails when either is stale, so the topic and parameter tables and the robot
file cannot drift from the code.
"""

from __future__ import annotations

import math
import re
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from erforce_interfaces.runtime.param_schema import ROBOT_PREFIX, ParamSchema, load_schema, robot_param_specs
from erforce_interfaces.wire.contract import topic_table_markdown

REFERENCE = Path(__file__).resolve().parents[4] / "docs" / "reference.md"
ROBOT_YAML = Path(__file__).resolve().parents[2] / "config" / "robot.yaml"

# (package, node) of every node's parameter schema (<package>/params/<node>.yaml)
NODE_SCHEMAS = (
    ("erforce_ball_model", "ball_predictor"),
    ("erforce_motion", "velocity_controller"),
    ("erforce_motion", "motor_boards"),
    ("erforce_sim", "plant"),
    ("erforce_ball_model", "catcher"),
    ("erforce_ball_model", "ssl_vision_bridge"),
    ("erforce_sim", "ssl_sim_bridge"),
    ("erforce_sim", "ssl_sim_server"),
    ("erforce_sim", "field_view"),
    # the team hosts: their own parameters; the rest are the per-robot nodes' (docs/launch.md, "A team")
    ("erforce_motion", "team_firmware"),
    ("erforce_ball_model", "team_catcher"),
    # our team's AI on the graph: its own parameters; the receiver's are the catcher's
    ("erforce_ball_model", "passing_game"),
)


def _node_params_section() -> str:
    robot = ParamSchema("robot", robot_param_specs())
    parts = [
        "#### `robot.*` (every node that needs the robot description; `config/robot.yaml` sets them all)\n\n"
        + robot.markdown(skip_robot=False)
    ]
    for package, node in NODE_SCHEMAS:
        schema = load_schema(package, node)
        where = f"`src/{package}/{package}/params/{node}.yaml`"
        read_only = [s for s in schema.specs if s.name.startswith("robot.") and s.read_only]
        note = "; `robot.*` read-only" if read_only else ""
        parts.append(f"#### `{node}` ({where}{note})\n\n{schema.markdown()}")
    return "\n\n".join(parts)


SECTIONS: dict[str, Callable[[], str]] = {
    "topic-table": topic_table_markdown,
    "node-params": _node_params_section,
}


def render(text: str) -> str:
    for name, make in SECTIONS.items():
        pattern = re.compile(rf"(<!-- {name}:begin -->\n).*?(<!-- {name}:end -->)", re.S)
        if pattern.search(text):
            text = pattern.sub(lambda m, make=make: m.group(1) + make() + "\n" + m.group(2), text)
    return text


_ROBOT_YAML_HEAD = """\
# The robot description as a ROS 2 parameter file, shared by every node that needs it:
# velocity_controller and motor_boards (kinematics, actuator model), plant (the physics),
# ball_predictor (dribbler offset). Pass it with `--params-file` or a launch `param: [{from: ...}]`.
# SI units (REP 103). Every value is RobotConfig's default (erforce_interfaces/wire/robot_config.py):
# this file is generated from it (`./run exec python -m erforce_interfaces.tools.docs`; a test fails
# while it is stale). For your robots, pass a copy with your values as the launch argument robot_config.
/**:
  ros__parameters:
    robot:
"""


def _yaml_number(value: float) -> str:
    """A float as YAML 1.1 reads it back as the same float (always a dot, never an exponent)."""
    return np.format_float_positional(float(value), trim="0")


def robot_yaml_text() -> str:
    """config/robot.yaml: every ``robot.*`` parameter at its default, with its documentation."""
    lines = []
    for spec in robot_param_specs():
        name = spec.name.removeprefix(ROBOT_PREFIX)
        if isinstance(spec.default, list | tuple):
            value = "[" + ", ".join(_yaml_number(v) for v in spec.default) + "]"
            if name.endswith("_rad"):
                value += "  # " + ", ".join(f"{math.degrees(v):g}" for v in spec.default) + " deg"
        else:
            value = _yaml_number(spec.default)
        lines += [f"      # {spec.description}", f"      {name}: {value}"]
    return _ROBOT_YAML_HEAD + "\n".join(lines) + "\n"


def _write_if_changed(path: Path, new: str) -> None:
    if path.read_text() != new:
        path.write_text(new)
        print(f"updated {path}")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    for path in [Path(a) for a in argv] or [REFERENCE]:
        _write_if_changed(path, render(path.read_text()))
    if not argv:
        _write_if_changed(ROBOT_YAML, robot_yaml_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
