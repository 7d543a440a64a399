"""``erforce-launch``'s command line: FILE or PKG FILE with name:=value arguments; ``--show-args``,
``--print`` (the resolved plan) or run."""


from __future__ import annotations

import argparse
import os
import shlex
import shutil
import sys
import tempfile
from pathlib import Path

from erforce_interfaces.tools.launcher.launch_file import ProcessSpec, Resolver, _shown, declared_args
from erforce_interfaces.tools.launcher.runner import STANDBY_AGAIN_S, STANDBY_FIRST_S, Runner
from erforce_interfaces.tools.launcher.syntax import LaunchError
from erforce_interfaces.wire.ament_index import (
    find_package_share,
)

PROG = "erforce-launch"



def format_args(args: list[tuple[str, str | None, str]]) -> str:
    """The ``--show-args`` text, laid out like ros2 launch's."""
    if not args:
        return "No arguments.\n"
    lines = ["Arguments (pass arguments as '<name>:=<value>'):", ""]
    for name, default, description in args:
        lines += [f"    '{name}':", f"        {description or 'no description given'}",
                  f"        (default: '{default}')" if default is not None else "        (required)", ""]
    return "\n".join(lines)


def format_plan(specs: list[ProcessSpec]) -> str:
    """The ``--print`` text: one line per process, then its settings and generated parameter files."""
    lines = []
    for s in specs:
        lines.append(f"[{s.label}] {shlex.join(s.cmd)}")
        flags = [f"output={s.output}"]
        if s.respawn:
            flags.append(f"respawn=true respawn_delay={s.respawn_delay_s:g}")
        if s.cwd:
            flags.append(f"cwd={s.cwd}")
        lines.append(f"    # {' '.join(flags)}  ({s.source})")
        for name in sorted(k for k in s.env if os.environ.get(k) != s.env[k]):
            lines.append(f"    # env {name}={s.env[name]}")
        for name in sorted(set(os.environ) - set(s.env)):
            lines.append(f"    # env unset {name}")
        for path, content in s.param_files:
            lines.append(f"    # {path}:")
            lines += ["    " + row for row in content.splitlines()]
    return "\n".join(lines) + ("\n" if lines else "")


# ========================================================================== command line
def _parse_cli(argv: list[str] | None) -> tuple[argparse.Namespace, Path, str, dict[str, str]]:
    parser = argparse.ArgumentParser(
        prog=PROG, usage=f"{PROG} [options] FILE | PKG FILE [name:=value ...]",
        description="Run a ROS 2 YAML launch file (the ros2 launch format) without launch_ros.",
        epilog="Examples: erforce-launch erforce_interfaces talker_listener.launch.yaml rate_hz:=20.0   |   "
               "erforce-launch path/to/file.launch.yaml --print")
    parser.add_argument("targets", nargs="+", metavar="TARGET", help="FILE, or PKG FILE, then name:=value arguments")
    parser.add_argument("-s", "--show-args", action="store_true", help="show the launch arguments and exit")
    parser.add_argument("-p", "--print", action="store_true", dest="print_only",
                        help="dry run: print the resolved command lines and the generated parameter files "
                             "(shown inline; their temporary paths are removed on exit), start nothing")
    parser.add_argument("--sigterm-timeout", type=float, default=5.0, metavar="S",
                        help="seconds between SIGINT and SIGTERM at shutdown (default 5)")
    parser.add_argument("--sigkill-timeout", type=float, default=5.0, metavar="S",
                        help="seconds between SIGTERM and SIGKILL at shutdown (default 5)")
    parser.add_argument("--shutdown-on-exit", action="store_true",
                        help="shut everything down when any non-respawning process exits")
    parser.add_argument("--no-standby", action="store_false", dest="standby",
                        help="respawn by a fresh start only; by default the respawning nodes of the stack share "
                             f"a warm standby (their imports done, no DDS), started {STANDBY_FIRST_S:g} s after the "
                             f"graph and {STANDBY_AGAIN_S:g} s after each respawn, that becomes whichever of them "
                             "dies (docs/graph.md, 'Self-healing')")
    ns = parser.parse_args(argv)
    for value in (ns.sigterm_timeout, ns.sigkill_timeout):
        if not 0.0 <= value < float("inf"):
            raise LaunchError("", f"timeouts must be finite and >= 0, got {value}")
    positional = [t for t in ns.targets if ":=" not in t]
    cli_args: dict[str, str] = {}
    for t in ns.targets:
        if ":=" in t:
            name, value = t.split(":=", 1)
            if not name:
                raise LaunchError("", f"bad launch argument '{t}': expected name:=value")
            cli_args[name] = value
    if len(positional) == 1:
        path, shown = Path(positional[0]), positional[0]
        if not path.is_file():
            raise LaunchError("", f"launch file not found: {shown} (or give PKG FILE)")
    elif len(positional) == 2:
        pkg, name = positional
        share = find_package_share(pkg)
        if share is None:
            raise LaunchError("", f"package '{pkg}' not found")
        candidates = [share / "launch" / name, share / name, *sorted(share.rglob(name))]
        found = next((c for c in candidates if c.is_file()), None)
        if found is None:
            files = sorted(p.name for p in (share / "launch").glob("*launch*")) if (share / "launch").is_dir() else []
            raise LaunchError("", f"file '{name}' not found in package '{pkg}' ({share}); "
                              f"launch files: {', '.join(files) or 'none'}")
        path, shown = found, _shown(found)
    else:
        raise LaunchError("", f"expected FILE or PKG FILE before the name:=value arguments, got {positional}")
    return ns, path, shown, cli_args


def main(argv: list[str] | None = None) -> int:
    param_dir = None
    try:
        ns, path, shown, cli_args = _parse_cli(argv)
        if ns.show_args:
            sys.stdout.write(format_args(declared_args(path, cli_args)))
            return 0
        param_dir = Path(tempfile.mkdtemp(prefix="erforce_launch_"))
        specs = Resolver(cli_args, param_dir).resolve(path, shown)
        if ns.print_only:
            sys.stdout.write(format_plan(specs))
            return 0
        return Runner(specs, ns.sigterm_timeout, ns.sigkill_timeout, ns.shutdown_on_exit, standby=ns.standby).run()
    except LaunchError as exc:
        sys.stderr.write(f"{PROG}: error: {exc}\n")
        return 2
    except KeyboardInterrupt:  # Ctrl-C before any node started (the Runner handles it from then on)
        return 130
    finally:
        if param_dir is not None:
            shutil.rmtree(param_dir, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
