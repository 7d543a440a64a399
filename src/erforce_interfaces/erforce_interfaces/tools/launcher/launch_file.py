"""``erforce-launch``: run ROS 2 YAML launch files without the ``launch``/``launch_ros`` packages.

The files are ordinary ROS 2 YAML launch files; the same file works with ``ros2 launch``. Three stages:
**parse** (``syntax``: PyYAML keeping every key's line, so each error is one line
``erforce-launch: error: FILE:LINE: <what>``), **resolve** (this module: actions in order with a ``Scope``,
``$(...)`` substitutions, packages and parameter files, into a list of ``ProcessSpec``) and **run**
(``runner``: one process per spec, output prefixed ``[label]``, respawn, the shutdown ladder).

It is as strict as ``ros2 launch`` on Jazzy, whose rules it follows, and resolves everything before the
first process starts, so an error never leaves half a graph running. Every child runs in its own process
group: Ctrl-C reaches the launcher alone, which sends SIGINT, then SIGTERM and SIGKILL after
``sigterm_timeout``/``sigkill_timeout``, and always reaps. A respawning node of ours is taken over by the
warm standby (erforce_interfaces.runtime.standby). The supported actions and substitutions, and every deliberate
deviation from ``ros2 launch``, are listed in docs/reference.md ("erforce-launch"). Exit status: 0; 1 when
a non-respawning process failed before shutdown; 2 for a bad command line or launch file (nothing started).
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import itertools
import math
import os
import re
import shlex
import shutil
import sys
import tempfile
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import yaml

from erforce_interfaces.runtime.param_schema import ParamSchema
from erforce_interfaces.tools.launcher.syntax import (
    LaunchError,
    MarkedDict,
    MarkedList,
    Subst,
    SubstitutionError,
    check_substitution,
    homogeneous_list,
    launch_bool,
    launch_equals,
    load_launch_entries,
    parse_substitutions,
    typed_value,
    yaml_type_name,
)
from erforce_interfaces.wire.ament_index import (
    ament_prefixes,
    console_scripts,
    distribution,
    find_package_prefix,
    find_package_share,
    package_executables,
)


# ================================================================= executables
def find_executable(pkg: str, exe: str) -> list[str]:
    """The command that runs ``exe`` of ``pkg``; raises SubstitutionError naming what is missing."""
    for prefix in ament_prefixes():
        candidate = prefix / "lib" / pkg / exe
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return [str(candidate)]
    script = console_scripts(pkg).get(exe)
    if script is not None:
        beside_python = Path(sys.executable).parent / exe
        if beside_python.is_file() and os.access(beside_python, os.X_OK):
            return [str(beside_python)]
        code = (f"import importlib, sys\nf = importlib.import_module({script.module!r})\n"
                f"for a in {script.attr.split('.')!r}: f = getattr(f, a)\nsys.exit(f())")
        return [sys.executable, "-c", code]
    known = find_package_share(pkg) or distribution(pkg) or any(
        (p / "lib" / pkg).is_dir() for p in ament_prefixes())
    if not known:
        raise SubstitutionError(f"package '{pkg}' not found")
    listing = ", ".join(package_executables(pkg)) or "none"
    raise SubstitutionError(f"package '{pkg}' has no executable '{exe}' (executables: {listing})")


@functools.cache
def node_schema(pkg: str, exe: str) -> ParamSchema | None:
    """The parameter schema of executable ``exe`` of ``pkg`` (``params/<exe>.yaml`` in the Python package or
    the share folder, erforce_interfaces.runtime.param_schema), or None; the package is not imported."""
    folders = []
    try:
        spec = importlib.util.find_spec(pkg) if pkg.isidentifier() else None
    except (ImportError, ValueError):
        spec = None
    folders += [Path(loc) for loc in (spec.submodule_search_locations or [])] if spec else []
    share = find_package_share(pkg)
    folders += [share] if share is not None else []
    for folder in folders:
        path = folder / "params" / f"{exe}.yaml"
        if path.is_file():
            try:
                schema = ParamSchema.from_yaml_text(path.read_text(), str(path))
            except (ValueError, yaml.YAMLError):
                return None
            return schema if schema.node == exe else None
    return None


def _as_declared(schema: ParamSchema | None, name: str, value: Any) -> Any:
    """An inline parameter's value with the type its node declares it (0 for a double is 0.0)."""
    if isinstance(value, dict):
        return {k: _as_declared(schema, f"{name}.{k}", v) for k, v in value.items()}
    spec = schema.by_name.get(name) if schema is not None else None
    return value if spec is None else spec.coerce(value)


# ====================================================================== 2. resolve: scopes
@dataclass
class ProcessSpec:
    """One process to run, fully resolved (what ``--print`` shows)."""

    label: str  # "talker-1": executable name and a launch-wide counter, like ros2 launch
    cmd: list[str]
    env: dict[str, str]
    cwd: str | None = None
    output: str = "log"  # screen | log | both
    respawn: bool = False
    respawn_delay_s: float = 0.0
    respawn_max_retries: int = -1  # -1: unlimited
    sigterm_timeout_s: float | None = None  # None: the command-line default
    sigkill_timeout_s: float | None = None
    param_files: list[tuple[str, str]] = field(default_factory=list)  # (path, content) written by us
    source: str = ""  # FILE:LINE of the action
    standby: bool = False  # it can wait as a warm standby (erforce_interfaces.runtime.standby): our nodes


@dataclass
class Scope:
    """What ros2 launch keeps in its LaunchContext; a scoped group works on a copy."""

    configs: dict[str, str]  # launch configurations; 'ros_namespace' is the pushed namespace
    env: dict[str, str]
    remaps: list[tuple[str, str]] = field(default_factory=list)
    global_params: list[tuple[str, str]] = field(default_factory=list)

    def copy(self) -> Scope:
        return Scope(dict(self.configs), dict(self.env), list(self.remaps), list(self.global_params))


@dataclass
class _File:
    path: Path  # absolute
    shown: str  # as the user wrote it, for messages
    after_include: bool = False  # an include ran since this file began: Jazzy's $(dirname) is wrong from here
    static: bool = False  # launch's look-ahead without a context: no $(dirname), no $(var)

    def at(self, line: int) -> str:
        return f"{self.shown}:{line}"


_NO_FILE = _File(Path("/"), "<static>", static=True)


@dataclass
class _Declared:
    """An ``arg`` as launch's look-ahead sees it (DeclareLaunchArgument)."""

    name: str
    description: str
    has_default: bool
    conditional: bool
    where: str  # FILE:LINE of the declaration


@dataclass
class _IncludeChain:
    """The includes below one include of the checked file, as launch lists them for its check: one list per
    include of the checked file, which every include below it joins, before or after the arg."""

    where: str  # FILE:LINE of the checked file's include
    names: list[list[str] | None] = field(default_factory=list)  # per include its arg names (None: not static)


_COND = {"if", "unless"}
_PROCESS_KEYS = {"output", "respawn", "respawn_delay", "respawn_max_retries", "env", "cwd", "launch-prefix",
                 "sigterm_timeout", "sigkill_timeout", "emulate_tty"}
_ACTION_KEYS: dict[str, set[str]] = {
    "arg": {"name", "default", "description", "choice"},
    "let": {"name", "value"},
    "node": {"pkg", "exec", "exec_name", "name", "namespace", "param", "remap", "args", "ros_args"} | _PROCESS_KEYS,
    "executable": {"cmd", "name"} | _PROCESS_KEYS,
    "include": {"file", "arg"},
    "group": {"scoped", "forwarding", "keep", "children"},
    "push_ros_namespace": {"namespace"},
    "set_env": {"name", "value"},
    "unset_env": {"name"},
    "set_remap": {"from", "to"},
    "set_parameter": {"name", "value"},
    "log": {"message"},
}
_ALIASES = {"push-ros-namespace": "push_ros_namespace"}  # the only dashed spelling launch_ros exposes
_NODE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NAMESPACE = re.compile(r"/|(/[A-Za-z_][A-Za-z0-9_]*)+")
_TRUE, _FALSE = {"true", "1"}, {"false", "0"}
_LITERAL_EXAMPLES = {float: "0.1", int: "3", bool: "true"}
# what ros2 launch on Jazzy does with a string where it reads a plain value (docs/launch_attributes.md)
_LITERAL_FAILS = {float: "fails with \"'<' not supported between instances of 'str' and 'float'\"",
                  int: "keeps the text and fails when it compares it with the retry count",
                  bool: "takes the text as true",
                  "allow_substs": "fails: \"'ParameterFile()' expected 'allow_subst' to be one of [<class 'bool'>]\""}


def prefix_namespace(base: str | None, ns: str | None) -> str | None:
    """launch_ros semantics: a relative ``ns`` goes below ``base``; an absolute one replaces it."""
    if base is None or base == "":
        return ns
    if ns is None:
        return base
    if ns.startswith("/"):
        return ns
    return base.rstrip("/") + "/" + ns if ns else base


def make_absolute(ns: str | None) -> str | None:
    return None if ns is None else ns if ns.startswith("/") else "/" + ns


def _line(d: MarkedDict, key: str) -> int:
    return d.key_lines.get(key, d.line)


class Resolver:
    """Walks launch files in order and produces the ``ProcessSpec`` list."""

    MAX_INCLUDE_DEPTH = 40

    def __init__(self, cli_args: dict[str, str], param_dir: Path, out: TextIO | None = None) -> None:
        self.cli_args = dict(cli_args)
        self.param_dir = param_dir
        self.out = out or sys.stdout
        self.processes: list[ProcessSpec] = []
        self._count = itertools.count(1)
        self._anon: dict[str, str] = {}
        self._depth = 0
        self._last_included: Path | None = None  # what Jazzy's $(dirname) says after an include
        self._base_env = dict(os.environ)
        # Safe by default: discovery stays on this computer unless the user chose a range
        # (docs/graph.md, "DDS discovery"); the launch files say the same for `ros2 launch`.
        self._base_env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

    def resolve(self, path: Path, shown: str) -> list[ProcessSpec]:
        # ros2 launch includes the file it is given with the command-line args as the include's args
        f = _File(path.resolve(), shown)
        entries = load_launch_entries(path, shown)
        self._check_required_args(f, entries, list(self.cli_args), "")
        self._run_entries(f, entries, Scope(dict(self.cli_args), dict(self._base_env)))
        return self.processes

    # ------------------------------------------------------- launch's required-argument check
    def _check_required_args(self, f: _File, entries: MarkedList, given: list[str], where: str) -> None:
        """launch's check when it includes a file (the command line's file too), before any of it runs.

        Every ``arg`` without a default that is not under a condition, in the file and in the files its
        includes name statically (a path without $(var)/$(dirname)), must be among the include's arg names
        or, for one below an include of the file, the arg names of the includes there. As in launch, the
        names found accumulate over the check, and a required arg's value from the including scope does
        not count."""
        names = list(given)
        for arg, chain in self._declarations(f, entries):
            if arg.conditional or arg.has_default:
                continue
            if chain is not None:
                for more in chain.names:
                    names.extend(more or [])
            if arg.name in names:
                continue
            if not where and chain is None:  # the command line's own file: say how to pass it
                raise LaunchError(arg.where, f"required argument '{arg.name}' not given; arguments of "
                                  f"{f.shown}: {_describe_args(declared_args(f.path))}; pass {arg.name}:=VALUE")
            raise LaunchError(chain.where if chain is not None and not where else where,
                              f"Included launch description missing required argument '{arg.name}' "
                              f"(description: '{arg.description}'), given: [{', '.join(names)}]; pass it in "
                              "the include's 'arg' list")

    def _declarations(self, f: _File, entries: MarkedList) -> list[tuple[_Declared, _IncludeChain | None]]:
        """The args launch's look-ahead finds, first declaration of a name only, each with the include chain
        it sits below (None: in the file itself)."""
        found: list[tuple[_Declared, _IncludeChain | None]] = []
        static_scope = Scope({}, dict(os.environ))

        def walk(shown: str, items: Any, conditional: bool, chain: _IncludeChain | None, depth: int) -> None:
            for item in items if isinstance(items, MarkedList) else []:
                if not isinstance(item, MarkedDict) or len(item) != 1:
                    continue
                ((kind, body),) = item.items()
                kind = _ALIASES.get(kind, kind)
                own_condition = isinstance(body, MarkedDict) and bool(_COND & set(body))
                if kind == "arg" and isinstance(body, MarkedDict) and isinstance(body.get("name"), str):
                    if all(a.name != body["name"] for a, _ in found):
                        found.append((_Declared(body["name"], str(body.get("description", "")), "default" in body,
                                                conditional or own_condition, f"{shown}:{body.line}"), chain))
                elif kind == "group":
                    children = body if isinstance(body, MarkedList) else body.get("children") \
                        if isinstance(body, MarkedDict) else None
                    if isinstance(body, MarkedDict) and body.get("scoped", True) is not False \
                            and body.get("forwarding", True) is False:
                        continue  # launch's look-ahead stops at the reset of the configurations
                    walk(shown, children, own_condition, chain, depth)  # a condition marks direct children only
                elif kind == "include" and isinstance(body, MarkedDict) and depth < self.MAX_INCLUDE_DEPTH:
                    line = _line(body, "file")
                    below = chain or _IncludeChain(f"{shown}:{line}")
                    below.names.append(self._static_names(body, static_scope))
                    included = self._static_load(body, static_scope)
                    if included is not None:
                        walk(*included, False, below, depth + 1)  # an include's condition does not count

        walk(f.shown, entries, False, None, 0)
        return found

    def _static_names(self, body: MarkedDict, scope: Scope) -> list[str] | None:
        try:
            return [self._str(_NO_FILE, e, "name", scope, required=True)
                    for e in self._dicts(_NO_FILE, body, "arg", "include")]
        except LaunchError:
            return None

    def _static_load(self, body: MarkedDict, scope: Scope) -> tuple[str, MarkedList] | None:
        """(shown, entries) of an include's file when its path needs no context, else None (launch skips it)."""
        try:
            path = Path(self._str(_NO_FILE, body, "file", scope, required=True))
            shown = _shown(path)
            return shown, load_launch_entries(path, shown)
        except LaunchError:
            return None

    # ------------------------------------------------------------------ files and actions

    def _run_entries(self, f: _File, entries: MarkedList, scope: Scope) -> None:
        for item, line in zip(entries, entries.item_lines, strict=True):
            if not isinstance(item, MarkedDict) or len(item) != 1:
                raise LaunchError(f.at(line), "each entry must be a mapping with one action key, e.g. '- node: {...}'")
            ((kind, body),) = item.items()
            kline = item.key_lines[kind]
            kind = _ALIASES.get(kind, kind)
            if kind not in _ACTION_KEYS:
                known = ", ".join(sorted(_ACTION_KEYS))
                raise LaunchError(f.at(kline), f"unknown action '{kind}' (known: {known})")
            if kind == "group" and isinstance(body, MarkedList):
                self._run_entries(f, body, scope.copy())
                continue
            if not isinstance(body, MarkedDict):
                raise LaunchError(f.at(kline), f"'{kind}' needs a mapping of attributes")
            allowed = _ACTION_KEYS[kind] | _COND
            for key in body:
                if key not in allowed:
                    raise LaunchError(f.at(_line(body, key)),
                                      f"unknown key '{key}' in '{kind}' (known: {', '.join(sorted(allowed))})")
            if not self._condition(f, body, scope):
                continue
            getattr(self, "_do_" + kind)(f, body, scope)

    def _condition(self, f: _File, d: MarkedDict, scope: Scope) -> bool:
        if "if" in d and not self._bool(f, d, "if", scope, False):
            return False
        return not ("unless" in d and self._bool(f, d, "unless", scope, False))

    def _do_arg(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        name = self._plain(f, d, "name", required=True)
        self._raw(f, d, "description")
        if name not in scope.configs:
            if "default" not in d:
                raise LaunchError(f.at(d.line), f"required argument '{name}' not given; arguments of "
                                  f"{f.shown}: {_describe_args(declared_args(f.path))}; pass {name}:=VALUE")
            scope.configs[name] = self._str(f, d, "default", scope)
        choices = [self._plain(f, c, "value", required=True) for c in self._dicts(f, d, "choice", "arg")]
        if choices and scope.configs[name] not in choices:
            raise LaunchError(f.at(d.line), f"argument '{name}' is '{scope.configs[name]}', "
                              f"not one of: {', '.join(choices)}")

    def _do_let(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        scope.configs[self._str(f, d, "name", scope, required=True)] = self._str(f, d, "value", scope, required=True)

    def _do_include(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        text = self._str(f, d, "file", scope, required=True)
        where = f.at(_line(d, "file"))
        path = Path(text) if Path(text).is_absolute() else Path.cwd() / text
        if not path.is_file():
            raise LaunchError(where, f"included file not found: {text} (relative paths are taken from the "
                              "working directory, as in ros2 launch: write $(find-pkg-share PKG)/...)")
        if path.suffix not in (".yaml", ".yml"):
            raise LaunchError(where, f"only YAML launch files can be included, not '{path.name}'")
        self._depth += 1
        if self._depth > self.MAX_INCLUDE_DEPTH:
            raise LaunchError(where, f"includes nested deeper than {self.MAX_INCLUDE_DEPTH} (an include cycle?)")
        args = self._dicts(f, d, "arg", "include")
        names = [self._str(f, a, "name", scope, required=True) for a in args]
        child = _File(path.resolve(), _shown(path))
        entries = load_launch_entries(path, child.shown)  # launch parses the whole file first
        self._check_required_args(child, entries, names, where)
        # From here launch's "current launch file" is the included one, for its args' values too, and in
        # Jazzy it stays so in this file after the include (ros2/launch#618)
        f.after_include, self._last_included = True, child.path
        for a, name in zip(args, names, strict=True):
            # set in the current scope (an include is not scoped), one after the other
            scope.configs[name] = self._str(f, a, "value", scope, required=True, here=child)
        self._run_entries(child, entries, scope)
        self._depth -= 1

    def _do_group(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        children = d.get("children")
        if not isinstance(children, MarkedList):
            raise LaunchError(f.at(_line(d, "children")), "'group' needs 'children': a list of actions")
        scoped = self._literal(f, d, "scoped", bool, True)
        forwarding = self._literal(f, d, "forwarding", bool, True)
        keeps = self._dicts(f, d, "keep", "group")
        if scoped and not forwarding:
            # launch evaluates them all, then clears the configurations (namespace, remaps, global
            # parameters too) and the environment, and sets them
            kept = {self._str(f, k, "name", scope, required=True): self._str(f, k, "value", scope, required=True)
                    for k in keeps}
            inner = Scope(kept, dict(self._base_env))
        else:
            inner = scope.copy() if scoped else scope
            for k in keeps:  # set one after the other, in the group's scope
                inner.configs[self._str(f, k, "name", inner, required=True)] = self._str(f, k, "value", inner,
                                                                                        required=True)
        self._run_entries(f, children, inner)

    def _do_push_ros_namespace(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        pushed = self._str(f, d, "namespace", scope, required=True)
        scope.configs["ros_namespace"] = prefix_namespace(scope.configs.get("ros_namespace"), pushed) or ""

    def _do_set_env(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        scope.env[self._str(f, d, "name", scope, required=True)] = self._str(f, d, "value", scope, required=True)

    def _do_unset_env(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        scope.env.pop(self._str(f, d, "name", scope, required=True), None)

    def _do_set_remap(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        rule = (self._str(f, d, "from", scope, required=True), self._str(f, d, "to", scope, required=True))
        scope.remaps.append(rule)

    def _do_set_parameter(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        self._raw(f, d, "value", required=True)  # launch_ros reads it as text (a substitution), typed by YAML
        text = yaml.safe_dump(self._param_value(f, d, scope), default_flow_style=True, width=1 << 30)
        scope.global_params.append((self._str(f, d, "name", scope, required=True),
                                    text.removesuffix("\n").removesuffix("\n...")))

    def _do_log(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        print(f"[INFO] [launch.user]: {self._str(f, d, 'message', scope, required=True)}", file=self.out, flush=True)

    def _do_executable(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        cmd = self._split(f, d, "cmd", scope)
        if not cmd:
            raise LaunchError(f.at(_line(d, "cmd")), "'cmd' of 'executable' is empty")
        found = shutil.which(cmd[0], path=scope.env.get("PATH"))
        if not found:
            raise LaunchError(f.at(_line(d, "cmd")), f"executable '{cmd[0]}' not found (or not executable)")
        cmd[0] = found
        label = f"{self._str(f, d, 'name', scope) or Path(cmd[0]).name}-{next(self._count)}"
        self.processes.append(self._process(f, d, scope, label, cmd))

    def _do_node(self, f: _File, d: MarkedDict, scope: Scope) -> None:
        exe = self._str(f, d, "exec", scope, required=True)
        pkg = self._str(f, d, "pkg", scope)
        where = f.at(_line(d, "pkg" if pkg else "exec"))
        if pkg:
            try:
                cmd = find_executable(pkg, exe)
            except SubstitutionError as exc:
                raise LaunchError(where, str(exc)) from None
        else:
            found = shutil.which(exe, path=scope.env.get("PATH"))
            if not found:
                raise LaunchError(where, f"executable '{exe}' not found on PATH (give 'pkg' to search a package)")
            cmd = [found]
        label = f"{self._str(f, d, 'exec_name', scope) or Path(exe).name}-{next(self._count)}"
        cmd += self._split(f, d, "args", scope)
        ros_args = self._split(f, d, "ros_args", scope)
        cmd += ["--ros-args", *ros_args] if ros_args else []
        cmd.append("--ros-args")
        name = self._str(f, d, "name", scope)
        if name is not None:
            if not _NODE_NAME.fullmatch(name):
                raise LaunchError(f.at(_line(d, "name")), f"invalid node name '{name}'")
            cmd += ["-r", f"__node:={name}"]
        namespace = make_absolute(prefix_namespace(scope.configs.get("ros_namespace"),
                                                   self._str(f, d, "namespace", scope)))
        if namespace is not None:
            if not _NAMESPACE.fullmatch(namespace):
                raise LaunchError(f.at(_line(d, "namespace")), f"invalid namespace '{namespace}'")
            cmd += ["-r", f"__ns:={namespace}"]
        for pname, pvalue in scope.global_params:
            cmd += ["-p", f"{pname}:={pvalue}"]
        # launch_ros keys inline parameters by the full node name when name and namespace are known
        param_key = prefix_namespace(namespace, name) if name is not None and namespace is not None else "/**"
        schema = node_schema(pkg, exe) if pkg else None
        files = self._params(f, d, scope, label, param_key, cmd, schema)
        remaps = list(scope.remaps)
        for r in self._dicts(f, d, "remap", "node"):
            remaps.append((self._str(f, r, "from", scope, required=True), self._str(f, r, "to", scope, required=True)))
        for src, dst in remaps:
            cmd += ["-r", f"{src}:={dst}"]
        spec = self._process(f, d, scope, label, cmd)
        spec.param_files = files
        spec.standby = schema is not None  # a node of ours: it starts through node_support.run_node
        self.processes.append(spec)

    # ------------------------------------------------------------------------ parameters
    def _params(self, f: _File, d: MarkedDict, scope: Scope, label: str, key: str,
                cmd: list[str], schema: ParamSchema | None = None) -> list[tuple[str, str]]:
        files: list[tuple[str, str]] = []
        pending: dict[str, Any] = {}

        def write(content: str) -> str:
            path = self.param_dir / f"{label}.params-{len(files) + 1}.yaml"
            path.write_text(content)
            files.append((str(path), content))
            cmd.extend(["--params-file", str(path)])
            return str(path)

        def flush() -> None:
            if pending:
                write(yaml.safe_dump({key: {"ros__parameters": dict(pending)}}, default_flow_style=False,
                                     sort_keys=False))
                pending.clear()

        for entry in self._dicts(f, d, "param", "node"):
            if "from" in entry:
                bad = set(entry) - {"from", "allow_substs"}
                if bad:
                    raise LaunchError(f.at(_line(entry, sorted(bad)[0])),
                                      f"'param' with 'from' takes no '{sorted(bad)[0]}'")
                flush()
                text = self._str(f, entry, "from", scope)
                path = os.path.abspath(text)
                if not os.path.isfile(path):
                    raise LaunchError(f.at(_line(entry, "from")), f"parameter file not found: {text}")
                if self._literal(f, entry, "allow_substs", bool, False):
                    write(self._sub(Path(path).read_text(), scope, f, _line(entry, "from")))
                else:
                    cmd.extend(["--params-file", path])
            else:
                name, value = self._param_entry(f, entry, scope)
                pending[name] = _as_declared(schema, name, value)
        flush()
        return files

    def _param_entry(self, f: _File, entry: MarkedDict, scope: Scope) -> tuple[str, Any]:
        for k in entry:
            if k not in ("name", "value", "param"):
                raise LaunchError(f.at(_line(entry, k)), f"unknown key '{k}' in 'param' (known: from, name, value, "
                                  "param, allow_substs)")
        name = self._str(f, entry, "name", scope, required=True)
        if ("value" in entry) == ("param" in entry):
            raise LaunchError(f.at(entry.line), f"parameter '{name}' needs exactly one of 'value' or 'param'")
        if "param" in entry:
            return name, dict(self._param_entry(f, e, scope) for e in self._dicts(f, entry, "param", "param"))
        return name, self._param_value(f, entry, scope)

    def _param_value(self, f: _File, d: MarkedDict, scope: Scope) -> Any:
        """Like launch_ros: substituted strings are typed by YAML ('10.0' -> 10.0, 'true' -> True)."""
        raw, line = d.get("value"), _line(d, "value")
        if isinstance(raw, MarkedList):
            values = [typed_value(self._sub(v, scope, f, line)) if isinstance(v, str) else v for v in raw]
            return homogeneous_list(values, f.at(line))
        if isinstance(raw, str):
            value = typed_value(self._sub(raw, scope, f, line))
            return homogeneous_list(value, f.at(line)) if isinstance(value, list) else value
        if isinstance(raw, bool | int | float):
            return raw
        raise LaunchError(f.at(line), f"parameter value must be a scalar or a list, got {yaml_type_name(raw)}")

    # ------------------------------------------------------------------ process attributes
    def _process(self, f: _File, d: MarkedDict, scope: Scope, label: str, cmd: list[str]) -> ProcessSpec:
        env = dict(scope.env)
        for e in self._dicts(f, d, "env", "node"):
            env[self._str(f, e, "name", scope, required=True)] = self._str(f, e, "value", scope, required=True)
        output = self._str(f, d, "output", scope) or "log"
        if output not in ("screen", "log", "both"):
            raise LaunchError(f.at(_line(d, "output")), f"'output' must be screen, log or both, not '{output}'")
        cwd = self._str(f, d, "cwd", scope)
        if cwd is not None and not os.path.isdir(cwd):
            raise LaunchError(f.at(_line(d, "cwd")), f"'cwd' is not a directory: {cwd}")
        prefix = self._split(f, d, "launch-prefix", scope)
        self._literal(f, d, "emulate_tty", bool, False)  # accepted; our children never get a tty
        return ProcessSpec(
            label=label, cmd=prefix + cmd, env=env, cwd=cwd, output=output,
            respawn=self._typed_bool(f, d, "respawn", scope),
            respawn_delay_s=self._literal(f, d, "respawn_delay", float, 0.0),
            respawn_max_retries=self._literal(f, d, "respawn_max_retries", int, -1, minimum=-math.inf),
            sigterm_timeout_s=self._literal(f, d, "sigterm_timeout", float, None),
            sigkill_timeout_s=self._literal(f, d, "sigkill_timeout", float, None),
            source=f.at(d.line),
        )

    # ------------------------------------------------------------------ typed attributes
    def _sub(self, text: str, scope: Scope, f: _File, line: int, here: _File | None = None) -> str:
        """``text`` substituted; errors name ``f``'s line; ``$(dirname)`` is ``here``'s folder (default ``f``)."""
        try:
            return self._evaluate(parse_substitutions(text), scope, here or f)
        except SubstitutionError as exc:
            raise LaunchError(f.at(line), f"{exc} (in '{text}')") from None

    def _raw(self, f: _File, d: MarkedDict, key: str, required: bool = False) -> str | None:
        if key not in d:
            if required:
                raise LaunchError(f.at(d.line), f"missing required key '{key}'")
            return None
        value = d[key]
        if not isinstance(value, str):
            # launch_yaml does no coercion either: ros2 launch rejects the same file
            raise LaunchError(f.at(_line(d, key)), f"'{key}' must be a string, got {yaml_type_name(value)} "
                              f"{value!r} (quote it)")
        return value

    def _plain(self, f: _File, d: MarkedDict, key: str, required: bool = False) -> str | None:
        """Text launch takes as it is (an arg's name, a choice): a substitution there would never be evaluated."""
        raw = self._raw(f, d, key, required)
        if raw is not None and "$(" in raw:
            raise LaunchError(f.at(_line(d, key)), f"'{key}' is plain text in ros2 launch, which takes a "
                              f"substitution there literally: write the text itself, not '{raw}'")
        return raw

    def _str(self, f: _File, d: MarkedDict, key: str, scope: Scope, required: bool = False,
             here: _File | None = None) -> str | None:
        raw = self._raw(f, d, key, required)
        return None if raw is None else self._sub(raw, scope, f, _line(d, key), here)

    def _split(self, f: _File, d: MarkedDict, key: str, scope: Scope) -> list[str]:
        try:
            return shlex.split(self._str(f, d, key, scope) or "")
        except ValueError as exc:
            raise LaunchError(f.at(_line(d, key)), f"cannot split '{key}' into arguments: {exc}") from None

    def _bool(self, f: _File, d: MarkedDict, key: str, scope: Scope, default: bool) -> bool:
        """A condition (``if``/``unless``; launch's IfCondition): text, substituted, then true/false/1/0."""
        if key not in d:
            return default
        text = self._str(f, d, key, scope).strip().lower()
        if text not in _TRUE | _FALSE:
            raise LaunchError(f.at(_line(d, key)), f"'{key}' must be true or false, got '{text}'")
        return text in _TRUE

    def _typed_bool(self, f: _File, d: MarkedDict, key: str, scope: Scope) -> bool:
        """``respawn``: text, substituted, then launch's coercion to bool (1/0 or a YAML boolean)."""
        if key not in d:
            return False
        try:
            return launch_bool(key, self._str(f, d, key, scope))
        except SubstitutionError:
            raise LaunchError(f.at(_line(d, key)), f"'{key}' must be true or false, got '{d[key]}'") from None

    def _literal(self, f: _File, d: MarkedDict, key: str, kind: type, default: Any, minimum: float = 0.0) -> Any:
        """An attribute launch reads as a plain YAML value of ``kind`` (float, int or bool), never substituted:
        a string, even '0.1', is refused (launch compares it with a number, or takes the text as true)."""
        if key not in d:
            return default
        value = d[key]
        if isinstance(value, str):
            what = _LITERAL_FAILS.get(key) or _LITERAL_FAILS[kind]
            raise LaunchError(f.at(_line(d, key)), f"'{key}' is a plain YAML {kind.__name__} in ros2 launch on Jazzy, "
                              f"not a substitution or a string (it {what}): write e.g. "
                              f"'{key}: {_LITERAL_EXAMPLES[kind]}'; got {value!r}")
        if type(value) is not kind:  # exact: launch_yaml does not coerce (1 is no float, true no int)
            raise LaunchError(f.at(_line(d, key)), f"'{key}' must be a YAML {kind.__name__} (e.g. "
                              f"{_LITERAL_EXAMPLES[kind]}), got {yaml_type_name(value)} {value!r}")
        if kind is not bool and not minimum <= value < float("inf"):
            raise LaunchError(f.at(_line(d, key)), f"'{key}' must be a finite number >= {minimum:g}, got {value!r}")
        return value

    def _dicts(self, f: _File, d: MarkedDict, key: str, kind: str) -> list[MarkedDict]:
        value = d.get(key)
        if value is None:
            return []
        if not isinstance(value, MarkedList) or not all(isinstance(v, MarkedDict) for v in value):
            raise LaunchError(f.at(_line(d, key)), f"'{key}' of '{kind}' must be a list of mappings")
        return list(value)

    # -------------------------------------------------------------------- substitutions
    def _evaluate(self, parts: list[str | Subst] | tuple, scope: Scope, f: _File) -> str:
        return "".join(p if isinstance(p, str) else self._apply(p, scope, f) for p in parts)

    def _apply(self, sub: Subst, scope: Scope, f: _File) -> str:
        check_substitution(sub)
        args = [self._evaluate(a, scope, f) for a in sub.args]
        if sub.name == "var":
            if args[0] not in scope.configs:
                raise SubstitutionError(f"launch configuration '{args[0]}' is not set (declare it with arg or let)")
            return scope.configs[args[0]]
        if sub.name == "env":
            if args[0] in scope.env:
                return scope.env[args[0]]
            if len(args) == 2:
                return args[1]
            raise SubstitutionError(f"environment variable '{args[0]}' is not set")
        if sub.name in ("find-pkg-share", "find-pkg-prefix"):
            found = (find_package_share if sub.name == "find-pkg-share" else find_package_prefix)(args[0])
            if found is None:
                raise SubstitutionError(f"package '{args[0]}' not found")
            return str(found)
        if sub.name == "find-exec":
            found = shutil.which(args[0], path=scope.env.get("PATH"))
            if found is None:
                raise SubstitutionError(f"executable '{args[0]}' not found on PATH")
            return found
        if sub.name in ("dirname", "filename"):
            if f.static:
                raise SubstitutionError(f"'$({sub.name})' needs a launch file")
            if f.after_include:
                last = self._last_included
                said = f"the folder of the last included file ({last.parent if last else '?'})" \
                    if sub.name == "dirname" else f"the last included file ({last})"
                raise SubstitutionError(
                    f"'$({sub.name})' after an include is refused: ros2 launch on Jazzy resolves it to {said}, "
                    f"not to {f.shown}'s (ros2/launch#618); write $(find-pkg-share PKG)/... or use it before "
                    "the first include")
            return str(f.path.parent if sub.name == "dirname" else f.path)
        if sub.name in ("equals", "not-equals"):
            return str(launch_equals(*args) == (sub.name == "equals")).lower()
        if sub.name in ("not", "and", "or"):
            values = [launch_bool(sub.name, a) for a in args]  # all checked first, as launch does
            result = not values[0] if sub.name == "not" else (all if sub.name == "and" else any)(values)
            return str(result).lower()
        return self._anon.setdefault(args[0], f"{args[0]}_{uuid.uuid4().hex[:12]}")  # anon


def _shown(path: Path) -> str:
    rel = os.path.relpath(path)
    return rel if not rel.startswith("..") else str(path)


def declared_args(path: Path, cli_args: dict[str, str] | None = None) -> list[tuple[str, str | None, str]]:
    """(name, default, description) of the args a file declares, groups and includes included.

    Static: include paths are resolved with the command-line args and defaults; an include that
    cannot be resolved that way is skipped (as ros2 launch --show-args does)."""
    found: list[tuple[str, str | None, str]] = []
    resolver = Resolver({}, Path(tempfile.gettempdir()))
    scope = Scope(dict(cli_args or {}), dict(os.environ))

    def walk(f: _File, entries: Any, depth: int) -> None:
        for item in entries if isinstance(entries, MarkedList) else []:
            if not isinstance(item, MarkedDict) or len(item) != 1:
                continue
            ((kind, body),) = item.items()
            if kind == "arg" and isinstance(body, MarkedDict) and isinstance(body.get("name"), str):
                if any(name == body["name"] for name, _, _ in found):
                    continue  # the first declaration of a name counts, as in ros2 launch --show-args
                default, desc = body.get("default"), body.get("description")
                found.append((body["name"], default if isinstance(default, str) else None,
                              desc if isinstance(desc, str) else ""))
                if isinstance(default, str):
                    with contextlib.suppress(LaunchError):
                        scope.configs.setdefault(body["name"], resolver._sub(default, scope, f, 0))
            elif kind == "group":
                walk(f, body.get("children") if isinstance(body, MarkedDict) else body, depth)
            elif kind == "include" and isinstance(body, MarkedDict) and depth < 10:
                with contextlib.suppress(LaunchError):
                    inc = Path(resolver._str(f, body, "file", scope, required=True))
                    walk(_File(inc.resolve(), str(inc)), load_launch_entries(inc, str(inc)), depth + 1)

    walk(_File(path.resolve(), str(path)), load_launch_entries(path, str(path)), 0)
    return found


def _describe_args(args: list[tuple[str, str | None, str]]) -> str:
    return ", ".join(f"{n}={d!r}" if d is not None else f"{n} (required)" for n, d, _ in args) or "none"
