"""Keeps the generated sections of docs/reference.md in sync with the code.

A section sits between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``. Regenerate all
with ``./run exec python -m erforce_interfaces.tools.docs [FILE ...]`` (default docs/reference.md); a
test fails when any section is stale, so the topic and parameter tables cannot drift.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from pathlib import Path

from erforce_interfaces.runtime.param_schema import ParamSchema, load_schema, robot_param_specs
from erforce_interfaces.wire.contract import topic_table_markdown

REFERENCE = Path(__file__).resolve().parents[4] / "docs" / "reference.md"

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


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    for path in [Path(a) for a in argv] or [REFERENCE]:
        old = path.read_text()
        new = render(old)
        if new != old:
            path.write_text(new)
            print(f"updated {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
