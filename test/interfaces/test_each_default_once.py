"""Each default once: a schema parameter's default is written in its schema (or, for a quantity whose
home is code, in the constant its ``default_from`` names) and nowhere else.

The scan reads every node schema (``src/*/*/params/*.yaml``), then looks through ``src/**/*.py`` and the
launch files for the same value bound to the same name: a keyword argument or a parameter's default, a
dataclass field or assignment, a dict key or ``.get(key, default)``, an argparse option, a YAML key or
launch argument (a node's parameter in a launch file against that node's schemas). Names match when equal
after dropping a unit suffix, or when one ends in the other (at least two words: ``a_max_mps2`` is
``robot_a_max_mps2``). Each hit is a second default that can drift: derive it from the schema
(``param_schema.schema_defaults``) or from the home constant instead. The one exception is a launch
knob (``MIRRORED_KNOBS``), checked equal to the default it mirrors. True/False are left out: too common
to tell one default from another.
"""

from __future__ import annotations

import ast
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
UNITS = frozenset({"s", "m", "mps", "mps2", "hz", "rad", "radps", "radps2", "a", "v", "kg", "bytes", "ms"})


@dataclass(frozen=True)
class Default:
    """One schema parameter's default and where it lives."""

    node: str
    name: str
    value: Any
    where: str  # schema file:line
    home: str | None  # module:CONSTANT of a default_from, else None


def _words(name: str) -> tuple[str, ...]:
    words = tuple(w for w in name.lower().lstrip("-").replace("-", "_").split("_") if w)
    return words[:-1] if len(words) > 1 and words[-1] in UNITS else words


def same_name(binding: str, param: str) -> bool:
    a, b = _words(binding), _words(param)
    if not a or not b:
        return False
    short, long = (a, b) if len(a) <= len(b) else (b, a)
    return short == long or (len(short) >= 2 and long[-len(short):] == short)


def same_value(found: Any, default: Any) -> bool:
    if isinstance(default, bool) or isinstance(found, bool):
        return False  # True/False say too little to call two of them one default
    if isinstance(default, int | float):
        return isinstance(found, int | float) and math.isclose(found, default, rel_tol=0.0, abs_tol=0.0)
    if isinstance(default, str):
        return isinstance(found, str) and found == default
    return False


def schema_defaults(bools: bool = False) -> list[Default]:
    """Every scalar (numeric or string; with ``bools`` boolean too) default of every node schema."""
    out = []
    for path in sorted(SRC.glob("*/*/params/*.yaml")):
        rel = path.relative_to(ROOT)
        root = yaml.compose(path.read_text())
        (node, entries), = root.value
        for key, entry in entries.value:
            if not isinstance(entry, yaml.MappingNode):
                continue
            fields = {k.value: v for k, v in entry.value}
            line = key.start_mark.line + 1
            if "default_value" in fields and isinstance(fields["default_value"], yaml.ScalarNode):
                value = yaml.safe_load(yaml.serialize(fields["default_value"]))
                out.append(Default(node.value, key.value, value, f"{rel}:{line}", None))
            elif "default_from" in fields:
                home = fields["default_from"].value
                module, _, attribute = home.partition(":")
                value = getattr(__import__(module, fromlist=[attribute]), attribute)
                out.append(Default(node.value, key.value, value, f"{rel}:{line}", home))
    return [d for d in out if isinstance(d.value, int | float | str) and (bools or not isinstance(d.value, bool))]


# ------------------------------------------------------------------ bindings in Python
def _literal(node: ast.AST) -> Any:
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd) \
            and isinstance(node.operand, ast.Constant) and isinstance(node.operand.value, int | float):
        return -node.operand.value if isinstance(node.op, ast.USub) else node.operand.value
    return None


def python_bindings(path: Path) -> list[tuple[str, Any, int]]:
    """(name, literal, line) of every literal bound to a name in one module."""
    tree = ast.parse(path.read_text(), str(path))
    out: list[tuple[str, Any, int]] = []

    def bind(name: str, value_node: ast.AST | None) -> None:
        if value_node is None:
            return
        value = _literal(value_node)
        if value is not None:
            out.append((name, value, value_node.lineno))

    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            for kw in node.keywords:
                if kw.arg is not None:
                    bind(kw.arg, kw.value)
            func = node.func
            attr = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
            first = _literal(node.args[0]) if node.args else None
            key_at = {"get": 0, "setdefault": 0, "getattr": 1}.get(attr)
            if key_at is not None and len(node.args) >= key_at + 2 and isinstance(_literal(node.args[key_at]), str):
                bind(_literal(node.args[key_at]), node.args[key_at + 1])
            if attr == "add_argument" and isinstance(first, str):
                for kw in node.keywords:
                    if kw.arg == "default":
                        bind(first, kw.value)
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            args = node.args
            positional = args.posonlyargs + args.args
            for arg, default in zip(positional[len(positional) - len(args.defaults):], args.defaults, strict=True):
                bind(arg.arg, default)
            for arg, default in zip(args.kwonlyargs, args.kw_defaults, strict=True):
                bind(arg.arg, default)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            value = node.value
            if isinstance(value, ast.Call):  # dataclasses.field(default=...)
                value = next((kw.value for kw in value.keywords if kw.arg == "default"), None)
            bind(node.target.id, value)
        elif isinstance(node, ast.Assign):
            for target in node.targets:
                if isinstance(target, ast.Name):
                    bind(target.id, node.value)
        elif isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values, strict=True):
                key_value = _literal(key) if key is not None else None
                if isinstance(key_value, str):
                    bind(key_value, value)
    return out


# ------------------------------------------------------------------ bindings in launch files
def yaml_bindings(path: Path) -> list[tuple[str, Any, int, str | None, bool]]:
    """(name, scalar, line, the node's exec or None, a launch argument?) of every YAML key with a scalar
    value, every launch argument's default and every ``{name: ..., value: ...}`` of a launch file."""
    out: list[tuple[str, Any, int, str | None, bool]] = []

    def scalar(node: yaml.Node) -> Any:
        try:
            return yaml.safe_load(node.value) if node.style in (None, "") or node.tag.endswith(":str") \
                else node.value
        except yaml.YAMLError:
            return node.value

    def walk(node: yaml.Node, context: str | None, in_arg: bool) -> None:
        if isinstance(node, yaml.MappingNode):
            fields = {k.value: v for k, v in node.value if isinstance(k, yaml.ScalarNode)}
            if isinstance(fields.get("exec"), yaml.ScalarNode):
                context = fields["exec"].value
            named = fields.get("name")
            for field in ("default", "value"):
                if isinstance(named, yaml.ScalarNode) and isinstance(fields.get(field), yaml.ScalarNode):
                    out.append((named.value, scalar(fields[field]), fields[field].start_mark.line + 1, context,
                                in_arg and field == "default"))
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode) and isinstance(value, yaml.ScalarNode):
                    out.append((key.value, scalar(value), value.start_mark.line + 1, context, False))
                else:
                    walk(value, context, key.value == "arg")
        elif isinstance(node, yaml.SequenceNode):
            for item in node.value:
                walk(item, context, in_arg)

    walk(yaml.compose(path.read_text()), None, False)
    return out


def launch_files() -> list[Path]:
    return sorted(SRC.glob("*/launch/*.launch.yaml"))


# Node executables whose parameters come from more than one schema (param_schema.HostSchema, or two nodes'
# cores in one process); any other executable's parameters are its own schema's.
HOSTS = {
    "team_catcher": ("team_catcher", "catcher"),
    "passing_game": ("passing_game", "catcher"),
    "team_firmware": ("team_firmware", "velocity_controller", "motor_boards"),
    "ssl_ball_predictor": ("ball_predictor", "ssl_vision_bridge"),
}

# Launch arguments that hand a knob on to a node parameter and default to that parameter's default: ros2
# launch has no "unset", so an optional knob needs a default, and it can only be this one. Each is
# listed with the parameter it mirrors (launch file, argument) -> (node, parameter); the test below
# fails when the two differ, so the schema stays the one source. An argument not listed here must not
# repeat a schema default.
MIRRORED_KNOBS = {
    ("talker_listener", "rate_hz"): ("talker", "rate_hz"),
    ("team", "team"): ("team_firmware", "team"),
    ("team", "lockstep_topics"): ("team_firmware", "lockstep_topics"),
    ("team", "status_rate_hz"): ("motor_boards", "status_rate_hz"),
    ("demo", "pacing"): ("plant", "pacing"),
    ("demo", "real_time_factor"): ("plant", "real_time_factor"),
    ("demo", "field"): ("plant", "field"),
    ("demo", "robot_a_max_mps2"): ("ball_predictor", "robot_a_max_mps2"),
    ("demo", "robot_v_max_mps"): ("ball_predictor", "robot_v_max_mps"),
    ("demo", "ssl_vision_port"): ("plant", "ssl_vision_port"),
    ("demo", "camera_alignment"): ("ssl_vision_bridge", "camera_alignment"),
    ("receiver", "robot_a_max_mps2"): ("catcher", "a_max_mps2"),
    ("receiver", "robot_v_max_mps"): ("catcher", "v_max_mps"),
    ("receiver", "field"): ("catcher", "field"),
    ("sim_one_robot", "pacing"): ("plant", "pacing"),
    ("sim_one_robot", "real_time_factor"): ("plant", "real_time_factor"),
    ("sim_one_robot", "seed"): ("plant", "seed"),
    ("sim_one_robot", "stop_after_s"): ("plant", "stop_after_s"),
    ("ssl_world", "real_time_factor"): ("plant", "real_time_factor"),
    ("ssl_world", "team_color"): ("plant", "team_color"),
    ("ssl_world", "ball_a_slide_mps2"): ("plant", "ball_a_slide_mps2"),
    ("ssl_world", "ball_a_roll_mps2"): ("plant", "ball_a_roll_mps2"),
    ("ssl_world", "kick_spin_ratio"): ("plant", "kick_spin_ratio"),
    ("ssl_world", "ssl_vision_port"): ("plant", "ssl_vision_port"),
    ("ssl_world", "robot_control_port"): ("ssl_sim_server", "robot_control_port"),
    ("ssl_world", "opponent_robot_control_port"): ("ssl_sim_server", "opponent_robot_control_port"),
    ("ssl_world", "simulator_control_port"): ("ssl_sim_server", "control_port"),
    ("team_sim", "simulator_host"): ("ssl_sim_bridge", "simulator_host"),
    ("team_sim", "command_port"): ("ssl_sim_bridge", "command_port"),
    ("team_sim", "opponent_command_port"): ("ssl_sim_bridge", "command_port"),
    ("team_sim", "simulator_control_port"): ("ssl_sim_bridge", "control_port"),
    ("team_sim", "ssl_vision_interface"): ("plant", "ssl_vision_interface"),
    ("team_sim", "defend_side"): ("ssl_sim_bridge", "defend_side"),
    ("team_sim", "pacing"): ("plant", "pacing"),
    ("team_sim", "real_time_factor"): ("plant", "real_time_factor"),
    ("team_sim", "num_robots"): ("ball_predictor", "num_robots"),
    ("team_sim", "num_opponents"): ("passing_game", "num_opponents"),
    ("team_sim", "team_color"): ("plant", "team_color"),
    ("team_sim", "ssl_vision_port"): ("plant", "ssl_vision_port"),
    ("team_sim", "predictor_timing_log_every"): ("ball_predictor", "timing_log_every"),
    ("team_sim", "camera_alignment"): ("ssl_vision_bridge", "camera_alignment"),
}


def _launch_name(path: Path) -> str:
    return path.name.removesuffix(".launch.yaml")


def second_defaults() -> list[str]:
    """Every literal in src/ (Python) and the launch files that repeats a schema parameter's default."""
    defaults = schema_defaults()
    homes = set()
    for d in defaults:
        if d.home:
            module, _, attribute = d.home.partition(":")
            homes.add((module.replace(".", "/"), attribute))
    nodes = {d.node for d in defaults}
    found = []
    sources = [(p, [(*b, None, False) for b in python_bindings(p)]) for p in sorted(SRC.glob("*/*/**/*.py"))]
    sources += [(p, yaml_bindings(p)) for p in launch_files()]
    for path, bindings in sources:
        rel = path.relative_to(ROOT)
        module = str(path.relative_to(path.parents[len(path.relative_to(SRC).parts) - 2])).removesuffix(".py")
        for name, value, line, context, is_arg in bindings:
            if (module, name) in homes or (is_arg and (_launch_name(path), name) in MIRRORED_KNOBS):
                continue
            own = HOSTS.get(context, (context,)) if context in nodes or context in HOSTS else None
            for d in defaults:
                if (own is None or d.node in own) and same_value(value, d.value) \
                        and same_name(name.rpartition(".")[2], d.name):
                    found.append(f"{rel}:{line}: {name} = {value!r} repeats {d.node}.{d.name} ({d.where})")
                    break
    return found


def test_the_scan_finds_a_second_default_in_each_kind_of_binding(tmp_path):
    """The scan itself: each binding kind it claims to read is found, with its line."""
    module = tmp_path / "m.py"
    module.write_text("A_MAX_MPS2 = 4.5\n"
                      "@dataclass\nclass C:\n    a_max_mps2: float = 4.5\n    f: float = field(default=1.0)\n"
                      "def f(v_max_mps=2.5):\n    g(reaction_s=0.1, x=7)\n    return {'field': 'division_b'}\n"
                      "p.add_argument('--robot-a-max', default=-0.3)\nq = d.get('seed', 0)\n")
    got = {(n, v, line) for n, v, line in python_bindings(module)}
    assert {("A_MAX_MPS2", 4.5, 1), ("a_max_mps2", 4.5, 4), ("f", 1.0, 5), ("v_max_mps", 2.5, 6),
            ("reaction_s", 0.1, 7), ("field", "division_b", 8), ("--robot-a-max", -0.3, 9),
            ("seed", 0, 10)} <= got
    launch = tmp_path / "x.launch.yaml"
    launch.write_text("launch:\n  - arg: {name: robot_a_max_mps2, default: \"4.5\"}\n"
                      "  - node:\n      exec: plant\n      param:\n        - {name: field, value: division_a}\n"
                      "      other: {seed: 3}\n")
    got = set(yaml_bindings(launch))
    assert {("robot_a_max_mps2", 4.5, 2, None, True), ("field", "division_a", 6, "plant", False),
            ("seed", 3, 7, "plant", False)} <= got
    assert same_name("ROBOT_A_MAX_MPS2", "a_max_mps2") and same_name("--robot-a-max", "robot_a_max_mps2")
    assert not same_name("port", "foxglove_port") and not same_name("rate_hz", "clock_rate_hz")
    assert same_value(11, 11.0) and not same_value(True, 1) and not same_value("0", 0)


def test_each_schema_default_is_written_once():
    found = second_defaults()
    assert not found, f"{len(found)} second default(s) of a schema parameter:\n" + "\n".join(found)


def test_a_launch_knob_defaults_to_the_parameter_it_mirrors():
    by_node = {(d.node, d.name): d for d in schema_defaults(bools=True)}
    args = {(_launch_name(p), name): (value, f"{p.relative_to(ROOT)}:{line}")
            for p in launch_files() for name, value, line, _, is_arg in yaml_bindings(p) if is_arg}
    for (launch, arg), (node, param) in MIRRORED_KNOBS.items():
        assert (launch, arg) in args, f"{launch}.launch.yaml has no argument {arg}: drop it from MIRRORED_KNOBS"
        value, where = args[launch, arg]
        default = by_node[node, param]
        mirrored = yaml.safe_load(str(value)) is default.value if isinstance(default.value, bool) else \
            same_value(value, default.value)
        assert mirrored, \
            f"{where}: {arg} defaults to {value!r}, {node}.{param} to {default.value!r} ({default.where})"
