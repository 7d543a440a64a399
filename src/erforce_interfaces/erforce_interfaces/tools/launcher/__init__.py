"""``erforce-launch``: runs a ROS 2 YAML launch file (the ``ros2 launch`` format) without launch_ros, in three
steps: ``syntax`` reads the file (YAML with lines, the ``$(...)`` grammar), ``launch_file`` resolves it
(scopes, includes, arguments, nodes) into ``ProcessSpec``s, and ``runner`` runs them (output, respawns, warm
standbys, shutdown); ``cli`` is the command line. ``launch_file``'s docstring lists where it differs from
``ros2 launch``.

A developer tool: the test harness and the demo start it as a process; no node imports it.
"""

from erforce_interfaces.tools.launcher.cli import PROG, format_args, format_plan, main
from erforce_interfaces.tools.launcher.launch_file import (
    ProcessSpec,
    Resolver,
    declared_args,
    find_executable,
    node_schema,
    prefix_namespace,
)
from erforce_interfaces.tools.launcher.runner import FAILED_TO_START, STANDBY_AGAIN_S, STANDBY_FIRST_S, Runner
from erforce_interfaces.tools.launcher.syntax import LaunchError, Subst, SubstitutionError, parse_substitutions

__all__ = [
    "FAILED_TO_START", "PROG", "STANDBY_AGAIN_S", "STANDBY_FIRST_S", "LaunchError", "ProcessSpec", "Resolver",
    "Runner", "Subst", "SubstitutionError", "declared_args", "find_executable", "format_args", "format_plan", "main",
    "node_schema", "parse_substitutions", "prefix_namespace",
]
