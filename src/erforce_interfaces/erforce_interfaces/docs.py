"""Keeps the generated sections of README.md in sync with the code.

A section sits between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``. Regenerate all
with ``./run exec python -m erforce_interfaces.docs README.md``; a test fails when any
section is stale, so the README's topic and parameter tables cannot drift.
"""

from __future__ import annotations

import importlib
import re
import sys
from collections.abc import Callable
from pathlib import Path

from erforce_interfaces.contract import topic_table_markdown
from erforce_interfaces.node_support import params_markdown, robot_param_specs

# Node modules and the name of their ParamSpec tuple; a module not written yet is skipped.
NODE_PARAMS = (
    ("ball_predictor", "erforce_ball_model.ball_predictor_node", "PARAMS"),
    ("velocity_controller", "erforce_motion.velocity_controller_node", "PARAMS"),
    ("motor_boards", "erforce_motion.motor_boards_node", "PARAMS"),
    ("plant", "erforce_sim.plant_node", "PARAMS"),
    ("catcher", "erforce_ball_model.catcher_node", "PARAMS"),
    # the team hosts: their own parameters; the rest are the per-robot nodes' (README, "A team on the graph")
    ("team_firmware", "erforce_motion.team_firmware_node", "OWN_PARAMS"),
    ("team_catcher", "erforce_ball_model.team_catcher_node", "OWN_PARAMS"),
)


def _node_params_section() -> str:
    parts = [
        "#### `robot.*` (every node that needs the robot description; `config/robot.yaml` sets them all)\n\n"
        + params_markdown(robot_param_specs(), skip_robot=False)
    ]
    for node, module, attr in NODE_PARAMS:
        try:
            specs = getattr(importlib.import_module(module), attr)
        except ModuleNotFoundError:
            continue
        parts.append(f"#### `{node}`\n\n{params_markdown(specs)}")
    return "\n\n".join(parts)


def _bench_results_section() -> str:
    results = Path(__file__).resolve().parents[3] / "bench" / "RESULTS.md"
    if not results.exists():
        return "No results yet: run `./run bench`."
    return results.read_text().strip()


SECTIONS: dict[str, Callable[[], str]] = {
    "topic-table": topic_table_markdown,
    "node-params": _node_params_section,
    "bench-results": _bench_results_section,
}


def render(text: str) -> str:
    for name, make in SECTIONS.items():
        pattern = re.compile(rf"(<!-- {name}:begin -->\n).*?(<!-- {name}:end -->)", re.S)
        if pattern.search(text):
            text = pattern.sub(lambda m, make=make: m.group(1) + make() + "\n" + m.group(2), text)
    return text


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    path = Path(argv[0] if argv else "README.md")
    old = path.read_text()
    new = render(old)
    if new != old:
        path.write_text(new)
        print(f"updated {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
