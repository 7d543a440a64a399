"""erforce-launch: YAML launch files resolved like ros2 launch, real processes, one-line errors.

Resolution tests run in-process (fast, no DDS); the graph tests start the launcher as a real
process in a private DDS domain (the ``ros_graph`` harness) and tear it down with signals.
"""

from __future__ import annotations

import os
import re
import signal
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.tools.launcher import (
    LaunchError,
    Resolver,
    Subst,
    SubstitutionError,
    declared_args,
    main,
    parse_substitutions,
    prefix_namespace,
)
from erforce_interfaces.wire.contract import DDS_PROFILE_VARIABLES

HERE = Path(__file__).parent / "launch_files"
REPO = Path(__file__).resolve().parents[2]
TALKER_LISTENER = REPO / "src" / "erforce_interfaces" / "launch" / "talker_listener.launch.yaml"
LAUNCHER = str(Path(sys.executable).with_name("erforce-launch"))
# the ament index ./run setup registers the packages in: <prefix>/lib/<pkg>/<exe> and <prefix>/share/<pkg>
BIN = Path(sys.prefix) / "lib" / "erforce_interfaces"
SHARE = Path(sys.prefix) / "share"


def resolve(path: Path, **args: str) -> dict:
    """label -> ProcessSpec of a launch file, resolved without starting anything."""
    with tempfile.TemporaryDirectory() as param_dir:
        specs = Resolver(args, Path(param_dir)).resolve(path, path.name)
        for spec in specs:  # the generated files exist while resolving; keep what they said
            assert all(Path(p).read_text() == content for p, content in spec.param_files)
    return {s.label: s for s in specs}


def node_name(spec) -> str:
    """The node name a spec's command gives (``-r __node:=NAME``)."""
    return next(arg.removeprefix("__node:=") for arg in spec.cmd if arg.startswith("__node:="))


def applied(params: dict, package: str, node: str) -> dict:
    """What the node runs with: its schema's defaults, then the launch file's values (which give only
    what differs)."""
    return {**load_schema(package, node).defaults(), **params}


def params_of(spec) -> dict:
    """The generated (inline) parameter files of a spec, merged in order."""
    merged: dict = {}
    for _, content in spec.param_files:
        for key, body in yaml.safe_load(content).items():
            merged.setdefault(key, {}).update(body["ros__parameters"])
    return merged


def ros_args(spec) -> list[str]:
    return spec.cmd[spec.cmd.index("--ros-args") :]


def alive(pid: int) -> bool:
    """A pid that still runs (a zombie nobody reaped counts as gone)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def started_pids(output: str) -> list[int]:
    return [int(p) for p in re.findall(r"process started with pid \[(\d+)\]", output)]


def substituted(tmp_path: Path, text: str, **args: str) -> str:
    """What ``text`` substitutes to in a launch file (read back as an executable's name)."""
    path = tmp_path / "subst.launch.yaml"
    path.write_text(yaml.safe_dump({"launch": [{"executable": {"cmd": "true", "name": text}}]}))
    (label,) = resolve(path, **args)
    return label.removesuffix("-1")


# ============================================================ substitutions and namespaces
def test_substitutions_parse_nested_and_quoted_arguments():
    parts = parse_substitutions("a $(find-pkg-share $(var pkg))/x $(env 'MY VAR' \"d $(var y)\")!")
    assert parts[0] == "a "
    assert parts[1] == Subst("find-pkg-share", ((Subst("var", (("pkg",),)),),))
    assert parts[2] == "/x "
    assert parts[3] == Subst("env", (("MY VAR",), ("d ", Subst("var", (("y",),)))))
    assert parts[4] == "!"


@pytest.mark.parametrize("text", ["$(var x", "$(", "$(var 'x)", "$(1var)", "$(var$(x))"])
def test_substitution_syntax_errors_are_reported(text):
    with pytest.raises(SubstitutionError):
        parse_substitutions(text)


@given(st.text(alphabet=st.characters(blacklist_characters="$"), max_size=40))
def test_text_without_substitutions_is_literal(text):
    assert parse_substitutions(text) == ([text] if text else [])


@settings(deadline=None)  # each example resolves a launch file: its time is the machine's load, not the rule's
@given(st.from_regex(r"[A-Za-z][A-Za-z0-9_]{0,12}", fullmatch=True), st.text(alphabet="ab _.'\"", max_size=8))
def test_any_let_value_comes_back_through_var(name, value):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "roundtrip.launch.yaml"
        path.write_text(yaml.safe_dump({"launch": [
            {"let": {"name": name, "value": value}},
            {"executable": {"cmd": "true", "name": f"x$(var {name})y"}}]}))
        (spec,) = resolve(path).values()
    assert spec.label == f"x{value}y-1"


# launch's EqualsSubstitution: both in true/false/1/0 (any case) -> booleans; both floats -> math.isclose; else text
EQUALS = [
    ("1.0", "1", True), ("1", "1.0", True), ("1e3", "1000", True), ("0.0", "-0", True),
    ("1", "1.0000000001", True), ("1", "1.00001", False), ("nan", "nan", False), ("1", "2", False),
    ("true", "1", True), ("True", "TRUE", True), ("false", "0", True), ("FALSE", "1", False), ("true", "0", False),
    ("yes", "true", False),  # 'yes' is no bool for equals (only for not/and/or), and no float: text
    ("abc", "abc", True), ("abc", "ABC", False), ("", "", True), ("a b", "a b", True), ("1", "one", False),
]


@pytest.mark.parametrize(("left", "right", "equal"), EQUALS, ids=[f"{a!r}-{b!r}" for a, b, _ in EQUALS])
def test_equals_and_not_equals_like_jazzy(tmp_path, left, right, equal):
    assert substituted(tmp_path, f"$(equals '{left}' '{right}')") == str(equal).lower()
    assert substituted(tmp_path, f"$(not-equals '{left}' '{right}')") == str(not equal).lower()
    # the same through launch configurations
    assert substituted(tmp_path, "$(equals $(var a) $(var b))", a=left, b=right) == str(equal).lower()


@pytest.mark.parametrize(("value", "negated"), [
    ("true", "false"), ("false", "true"), ("1", "false"), ("0", "true"), ("True", "false"), ("FALSE", "true"),
    ("yes", "false"), ("No", "true"), ("on", "false"), ("OFF", "true"),  # YAML 1.1 booleans, as launch reads them
])
def test_not_takes_what_launch_coerces_to_bool(tmp_path, value, negated):
    assert substituted(tmp_path, f"$(not {value})") == negated


@pytest.mark.parametrize(("left", "right", "conj", "disj"), [
    ("true", "true", "true", "true"), ("true", "false", "false", "true"),
    ("false", "true", "false", "true"), ("false", "false", "false", "false"),
    ("1", "True", "true", "true"), ("yes", "0", "false", "true"), ("0", "off", "false", "false"),
    ("no", "On", "false", "true"),
])
def test_and_or_truth_tables(tmp_path, left, right, conj, disj):
    assert substituted(tmp_path, f"$(and {left} {right})") == conj
    assert substituted(tmp_path, f"$(or {left} {right})") == disj


@pytest.mark.parametrize(("a", "expected"), [("1", "false"), ("1.0", "false"), ("2", "true"), ("x", "true")])
def test_boolean_substitutions_nest(tmp_path, a, expected):
    assert substituted(tmp_path, "$(not $(equals $(var a) 1))", a=a) == expected
    assert substituted(tmp_path, "$(and $(not-equals $(var a) 1) $(or $(var f) 1))", a=a, f="false") == expected


@pytest.mark.parametrize(("base", "ns", "expected"), [
    (None, None, None), (None, "a", "a"), ("a", None, "a"), ("/a", "b", "/a/b"), ("/a", "/b", "/b"),
    ("/", "b", "/b"), ("a/", "b", "a/b"), ("", "b", "b"),
])
def test_prefix_namespace_like_launch_ros(base, ns, expected):
    assert prefix_namespace(base, ns) == expected


# ====================================================================== resolution (--print)
def test_talker_listener_resolves_to_the_ros2_launch_command_lines(tmp_path):
    specs = resolve(TALKER_LISTENER, rate_hz="33.0", ns="/x/y")
    assert list(specs) == ["talker-1", "listener-2"]
    talker, listener = specs["talker-1"], specs["listener-2"]
    assert talker.cmd[0] == str(BIN / "talker")
    assert ros_args(talker)[:5] == ["--ros-args", "-r", "__node:=talker", "-r", "__ns:=/x/y"]
    assert ros_args(talker)[5] == "--params-file"
    # name and namespace known: launch_ros keys the generated file by the full node name
    assert params_of(talker) == {"/x/y/talker": {"rate_hz": 33.0, "text": "hello from the talker"}}
    assert ros_args(listener) == ["--ros-args", "-r", "__node:=listener", "-r", "__ns:=/x/y"]
    assert talker.output == listener.output == "screen"


def test_include_groups_and_namespaces_resolve_like_ros2_launch():
    specs = resolve(HERE / "outer.launch.yaml", with_optional="true")
    talker = specs["talker-1"]
    params_file = str(HERE / "talker_params.yaml")
    assert ros_args(talker) == [
        "--ros-args", "-r", "__node:=talker", "-r", "__ns:=/team/bot1",  # pushed 'team' + include arg
        "--params-file", os.path.abspath(params_file),  # 'from' entries keep their order...
        "--params-file", talker.param_files[0][0],  # ...before the later inline entries
        "-r", "chatter:=/bot1/chat",
    ]
    assert params_of(talker) == {"/team/bot1/talker": {
        "text": "from bot1", "gains": [1.0, 2.5], "nested": {"flag": True, "words": "x y"},
        "share_dir": str(SHARE / "erforce_interfaces"),  # $(find-pkg-share $(var pkg))
    }}
    assert (talker.respawn, talker.respawn_delay_s, talker.output) == (True, 0.5, "both")
    assert talker.env["ERFORCE_LAUNCH_TEST"] == "outer-bot1"
    # the unscoped group's namespace leaks out; the scoped group's 'team' does not
    assert ros_args(specs["listener-2"]) == ["--ros-args", "-r", "__node:=after_unscoped", "-r", "__ns:=/abs"]
    # forwarding: false starts from nothing but 'keep': no namespace, no set_env, no 'robot'
    isolated = specs["listener-3"]
    assert isolated.cmd[1:3] == ["--flag", "k-bot1"]
    assert ros_args(isolated) == ["--ros-args", "-r", "__node:=isolated"]
    assert "ERFORCE_LAUNCH_TEST" not in isolated.env
    # 'if' true, 'ros_namespace' alias, no name: relative namespace below the leaked /abs
    assert ros_args(specs["listener-4"]) == ["--ros-args", "-r", "__ns:=/abs/opt"]
    assert "listener-4" not in resolve(HERE / "outer.launch.yaml", with_optional="false")


def test_command_line_arg_overrides_defaults_also_inside_includes(tmp_path):
    inner = tmp_path / "inner.launch.yaml"
    inner.write_text(textwrap.dedent("""\
        launch:
          - arg: {name: who, default: "inner-default"}
          - let: {name: leaked, value: "from-inner"}
          - executable: {cmd: "true", name: "i-$(var who)"}
        """))
    outer = tmp_path / "outer.launch.yaml"
    outer.write_text(textwrap.dedent(f"""\
        launch:
          - include: {{file: "$(dirname)/inner.launch.yaml"}}
          - executable: {{cmd: "true", name: "o-$(var leaked)"}}
          - include: {{file: "{inner}", arg: [{{name: who, value: "passed"}}]}}
        """))
    assert list(resolve(outer)) == ["i-inner-default-1", "o-from-inner-2", "i-passed-3"]
    # a command-line value wins over the default, but an include's own arg wins over both
    assert list(resolve(outer, who="cli")) == ["i-cli-1", "o-from-inner-2", "i-passed-3"]


def test_global_actions_conditions_and_env(tmp_path, monkeypatch):
    monkeypatch.setenv("ERFORCE_DROP_ME", "1")
    path = tmp_path / "misc.launch.yaml"
    path.write_text(textwrap.dedent("""\
        launch:
          - arg: {name: sim, default: "True"}
          - set_remap: {from: "/tf", to: "tf"}
          - set_parameter: {name: use_sim_time, value: "$(var sim)"}
          - unset_env: {name: ERFORCE_DROP_ME}
          - node: {pkg: erforce_interfaces, exec: talker, unless: "$(var sim)"}
          - node:
              pkg: erforce_interfaces
              exec: talker
              exec_name: renamed
              args: "--a 'b c'"
              ros_args: "--log-level debug"
              env: [{name: ERFORCE_X, value: "$(env ERFORCE_NOT_SET fallback)"}]
              remap: [{from: a, to: b}]
              launch-prefix: "nice -n 1"
        """))
    (spec,) = resolve(path).values()
    assert spec.label == "renamed-1"
    assert spec.cmd == ["nice", "-n", "1", str(BIN / "talker"), "--a", "b c", "--ros-args", "--log-level", "debug",
                        "--ros-args", "-p", "use_sim_time:=true", "-r", "/tf:=tf", "-r", "a:=b"]
    assert spec.env["ERFORCE_X"] == "fallback"
    assert "ERFORCE_DROP_ME" not in spec.env


def test_boolean_conditions_choose_includes_and_nodes(tmp_path):
    (tmp_path / "second.launch.yaml").write_text(textwrap.dedent("""\
        launch:
          - arg: {name: who}
          - node: {pkg: erforce_interfaces, exec: listener, name: "$(var who)"}
        """))
    path = tmp_path / "receivers.launch.yaml"
    path.write_text(textwrap.dedent("""\
        launch:
          - arg: {name: receivers, default: "1"}
          - arg: {name: sim, default: "false"}
          - include:
              if: $(not-equals $(var receivers) 1)
              file: "$(dirname)/second.launch.yaml"
              arg: [{name: who, value: second}]
          - node: {pkg: erforce_interfaces, exec: listener, exec_name: only_two, if: "$(equals $(var receivers) 2)"}
          - node:
              pkg: erforce_interfaces
              exec: talker
              unless: $(or $(var sim) $(equals $(var receivers) 0))
        """))
    assert list(resolve(path)) == ["talker-1"]
    assert list(resolve(path, receivers="1.0")) == ["talker-1"]  # equal as numbers
    specs = resolve(path, receivers="2")
    assert list(specs) == ["listener-1", "only_two-2", "talker-3"]
    assert ros_args(specs["listener-1"]) == ["--ros-args", "-r", "__node:=second"]
    assert list(resolve(path, receivers="3")) == ["listener-1", "talker-2"]
    assert list(resolve(path, receivers="0")) == ["listener-1"]
    assert list(resolve(path, receivers="2", sim="True")) == ["listener-1", "only_two-2"]


def test_print_and_pkg_file_form_on_the_command_line(capsys):
    assert main(["erforce_interfaces", "talker_listener.launch.yaml", "rate_hz:=12.5", "--print"]) == 0
    out = capsys.readouterr().out
    first = out.splitlines()[0]
    assert first.startswith(f"[talker-1] {BIN / 'talker'} --ros-args -r __node:=talker -r __ns:=/demo --params-file ")
    assert "        rate_hz: 12.5" in out.splitlines()
    assert re.search(r"^\[listener-2\] .*/listener --ros-args -r __node:=listener -r __ns:=/demo$", out, re.M)


@pytest.mark.parametrize(("launch_file", "args"), [
    ("erforce_sim/launch/demo.launch.yaml", {}),
    ("erforce_sim/launch/demo.launch.yaml", {"receivers": "3"}),
    ("erforce_sim/launch/receiver.launch.yaml", {"robot": "robot_2", "team_robot_ids": "[0, 2]",
                                                 "robot_side": "false"}),
    ("erforce_sim/launch/sim_one_robot.launch.yaml", {}),
    ("erforce_motion/launch/robot.launch.yaml", {}),
    ("erforce_motion/launch/team.launch.yaml", {}),
    ("erforce_sim/launch/team_sim.launch.yaml", {}),
])
def test_launch_files_give_every_node_the_stacks_dds_profile_unless_one_is_set(launch_file, args, monkeypatch):
    path = REPO / "src" / launch_file
    for name in DDS_PROFILE_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    specs = resolve(path, **args)
    assert specs
    for spec in specs.values():
        assert {name: spec.env[name] for name in DDS_PROFILE_VARIABLES} == dict.fromkeys(
            DDS_PROFILE_VARIABLES, str(SHARE / "erforce_interfaces/config/fastdds_profile.xml"))
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", "/robot/udp_only.xml")  # the user's own
    assert {spec.env["FASTRTPS_DEFAULT_PROFILES_FILE"] for spec in resolve(path, **args).values()} == {
        "/robot/udp_only.xml"}


def test_team_sim_takes_its_robots_as_a_list_argument():
    """11 robots of ours and 3 opponents by default, both teams' firmware in one team_firmware (or with
    firmware_processes per_team each team in its own) on the field lockstep topics, /clock at 50 Hz, the plant
    and the predictor sized alike, the 3 opponents (ids 0, 1, 2 of their own) driven by an interceptor; a robot
    is removed or added by the list, without editing a file."""
    one = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml")
    assert [label.rsplit("-", 1)[0] for label in one] == ["plant", "ball_predictor", "team_catcher", "team_firmware"]
    firmware = applied(next(params_of(s)["/**"] for s in one.values() if node_name(s) == "team_firmware"),
                       "erforce_motion", "team_firmware")
    assert firmware["robot_ids"] == list(range(11)) and firmware["opponent_ids"] == [0, 1, 2]
    assert firmware["team"] == "ours" and firmware["lockstep_topics"] == "field"
    assert next(params_of(s)["/**"] for s in one.values() if node_name(s) == "plant")["clock_rate_hz"] == 50.0
    specs = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml", firmware_processes="per_team")
    assert [label.rsplit("-", 1)[0] for label in specs] == [
        "plant", "ball_predictor", "team_catcher", "team_firmware", "team_firmware"]
    params = {node_name(spec): params_of(spec)["/**"] for spec in specs.values()}
    params["team_firmware"] = applied(params["team_firmware"], "erforce_motion", "team_firmware")
    assert params["team_firmware"]["robot_ids"] == list(range(11)) and params["team_firmware"]["team"] == "ours"
    assert params["opponent_firmware"]["robot_ids"] == [0, 1, 2] and params["opponent_firmware"]["team"] == "opponents"
    plant, predictor, interceptor = params["plant"], params["ball_predictor"], params["opponent_interceptor"]
    assert len(plant["robot_poses"]) == 3 * 11 and predictor["num_robots"] == 11
    assert len(plant["opponent_poses"]) == 3 * 3 and predictor["num_opponents"] == 3
    assert plant["team_color"] == "blue" and plant["vision_output"] == "ros"
    assert {plant["lockstep_topics"], params["team_firmware"]["lockstep_topics"],
            params["opponent_firmware"]["lockstep_topics"]} == {"field"}
    assert interceptor["robot_ids"] == [0, 1, 2] and interceptor["as_team"] and interceptor["team"] == "opponents"
    assert interceptor["field"] == plant["field"] == "division_a" and interceptor["press_lanes"] is False
    assert plant["ground_truth_rate_hz"] == 10.0
    assert params["team_firmware"]["motor_boards.status_rate_hz"] == 10.0
    per_robot = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml", lockstep_topics="per_robot",
                        opponents_intercept="false", firmware_processes="per_team")
    assert [label.rsplit("-", 1)[0] for label in per_robot] == ["plant", "ball_predictor", "team_firmware",
                                                                "team_firmware"]
    assert {params_of(s)["/**"]["lockstep_topics"] for s in per_robot.values() if "lockstep_topics" in
            params_of(s)["/**"]} == {"per_robot"}
    three = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml", robot_ids="[0, 2, 5]", opponent_ids="[1]",
                    firmware_processes="per_team")
    firmware = {node_name(s): params_of(s)["/**"]["robot_ids"] for s in three.values() if "robot_ids" in
                params_of(s)["/**"] and node_name(s).endswith("firmware")}
    assert firmware == {"team_firmware": [0, 2, 5], "opponent_firmware": [1]}
    three = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml", robot_ids="[0, 2, 5]", opponent_ids="[1]")
    assert [(params_of(s)["/**"]["robot_ids"], params_of(s)["/**"]["opponent_ids"]) for s in three.values()
            if node_name(s).endswith("firmware")] == [([0, 2, 5], [1])]
    ssl = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml", vision="ssl", team_color="yellow",
                  ssl_vision_process="own")
    ssl_params = {node_name(spec): params_of(spec)["/**"] for spec in ssl.values()}
    assert ssl_params["plant"]["vision_output"] == "ssl"
    assert ssl_params["plant"]["team_color"] == ssl_params["ssl_vision_bridge"]["team_color"] == "yellow"
    assert ssl_params["ssl_vision_bridge"]["num_robots"] == 11
    # the bridge is where the AI's vision enters: under the predictor's priority, never below the world's
    bridge = next(spec for spec in ssl.values() if node_name(spec) == "ssl_vision_bridge")
    assert "erforce-realtime" in bridge.cmd[0] and bridge.cmd[1] == "10"


def test_team_sim_on_an_outside_world_starts_only_the_ai_side():
    """world:=ssl: no plant and no firmware; the bridge (in the predictor's process by default) on the cameras'
    capture time and the world's geometry; one ssl_sim_bridge per colour, ours taking the placements."""
    specs = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml", world="ssl", ai="passing",
                    team_color="yellow", defend_side="positive_x", command_port="20301",
                    opponent_command_port="20302", simulator_control_port="20300")
    assert [label.rsplit("-", 1)[0] for label in specs] == ["ssl_ball_predictor", "team_catcher", "passing_game",
                                                            "ssl_sim_bridge", "ssl_sim_bridge"]
    predictor = next(params_of(s)["/**"] for s in specs.values() if "ssl_ball_predictor" in s.label)
    assert (predictor["time_source"], predictor["field"], predictor["use_sim_time"]) == ("capture", "from_geometry",
                                                                                        True)
    assert (predictor["team_color"], predictor["defend_side"]) == ("yellow", "positive_x")
    bridges = {node_name(s): params_of(s)["/**"] for s in specs.values() if "ssl_sim_bridge" in s.label}
    ours = applied(bridges["ssl_sim_bridge"], "erforce_sim", "ssl_sim_bridge")
    theirs = bridges["opponent_sim_bridge"]
    assert (ours["team"], ours["team_color"], ours["robot_ids"], ours["command_port"], ours["control_port"]) == (
        "ours", "yellow", list(range(11)), 20301, 20300)
    assert (theirs["team"], theirs["team_color"], theirs["robot_ids"], theirs["command_port"],
            theirs["control_port"]) == ("opponents", "blue", [0, 1, 2], 20302, 0)
    assert ours["protocol"] == theirs["protocol"] == "ssl" and ours["defend_side"] == theirs["defend_side"]
    game = next(params_of(s)["/**"] for s in specs.values() if "passing_game" in s.label)
    assert game["use_sim_time"] and game["place_ball"] and game["field"] == "from_geometry"
    interceptor = next(params_of(s)["/**"] for s in specs.values() if "team_catcher" in s.label)
    assert interceptor["field"] == "from_geometry"
    field = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml", world="ssl", ai="passing",
                    sim_protocol="none")
    assert [label.rsplit("-", 1)[0] for label in field] == ["ssl_ball_predictor", "team_catcher", "passing_game"]
    assert next(params_of(s)["/**"] for s in field.values() if "passing_game" in s.label)["place_ball"] is False


@pytest.mark.parametrize(("launch_file", "args"), [
    ("erforce_sim/launch/demo.launch.yaml", {"receivers": "3"}),
    ("erforce_sim/launch/sim_one_robot.launch.yaml", {}),
    ("erforce_motion/launch/robot.launch.yaml", {}),
    ("erforce_motion/launch/team.launch.yaml", {}),
    ("erforce_sim/launch/team_sim.launch.yaml", {}),
])
def test_launch_files_restart_every_node_after_a_delay_unless_told_not_to(launch_file, args):
    """respawn is a launch argument (launch substitutes it); respawn_delay is a number in the file, as launch
    reads it: an argument of that name changes nothing."""
    path = REPO / "src" / launch_file
    specs = resolve(path, **args).values()
    assert specs and all(s.respawn and s.respawn_delay_s == 0.1 and s.respawn_max_retries == -1 for s in specs)
    assert not any(s.respawn for s in resolve(path, respawn="false", **args).values())
    assert {s.respawn_delay_s for s in resolve(path, respawn_delay="2.0", **args).values()} == {0.1}


def test_a_plant_that_stops_itself_is_not_restarted():
    specs = resolve(REPO / "src/erforce_sim/launch/sim_one_robot.launch.yaml", stop_after_s="5.0")
    assert {label.split("-")[0]: s.respawn for label, s in specs.items()} == {
        "plant": False, "velocity_controller": True, "motor_boards": True}


def test_show_args_lists_names_descriptions_and_defaults(capsys):
    assert main([str(HERE / "outer.launch.yaml"), "--show-args"]) == 0
    out = capsys.readouterr().out
    assert "    'robot':\n        robot name passed to the include\n        (default: 'bot1')" in out
    # args of the include are found too (its path is resolvable statically)
    assert "    'robot_name':\n        the robot (required)\n        (required)" in out
    assert [a[0] for a in declared_args(HERE / "outer.launch.yaml")] == ["robot", "robot_name", "share"]


def test_team_sim_plays_the_passing_game_with_ai_passing():
    """ai:=passing adds the passing_game node for the same robots, opponents and field as the plant and the
    predictor, and the opponents' interceptor presses our passing lanes; by default our robots have no AI."""
    path = REPO / "src/erforce_sim/launch/team_sim.launch.yaml"
    assert "passing_game" not in {node_name(s) for s in resolve(path).values()}
    specs = resolve(path, ai="passing", robot_ids="[0, 1, 2]", num_robots="3", field="division_b",
                    robot_poses="[-4.0, 0.0, 0.0, -3.0, 2.0, 0.0, -3.0, -2.0, 0.0]")
    params = {node_name(spec): params_of(spec)["/**"] for spec in specs.values()}
    game, predictor, plant = params["passing_game"], params["ball_predictor"], params["plant"]
    assert (game["num_robots"], game["num_opponents"]) == (3, 3)
    assert (predictor["num_robots"], predictor["num_opponents"]) == (3, 3)
    assert game["field"] == plant["field"] == "division_b" and game["use_sim_time"] is True
    # the opponents press our passing lanes, reading our 3 robots' odom, on the same field
    interceptor = params["opponent_interceptor"]
    assert interceptor["press_lanes"] is True and interceptor["num_other_robots"] == 3
    assert interceptor["field"] == "division_b"


# ================================================= strict as ros2 launch on Jazzy (issue 24)
LAUNCH_FILES = sorted((REPO / "src").glob("*/launch/*.launch.yaml"))
# what ros2 launch needs on the command line for a file; every node each file starts
REQUIRED_ARGS = {"receiver.launch.yaml": ["robot:=robot_0", "team_robot_ids:=[0]"]}
NODES = {
    "talker_listener.launch.yaml": ["talker-1", "listener-2"],
    "robot.launch.yaml": ["velocity_controller-1", "motor_boards-2"],
    "team.launch.yaml": ["team_firmware-1"],
    "demo.launch.yaml": ["plant-1", "ball_predictor-2", "velocity_controller-3", "motor_boards-4", "catcher-5"],
    "receiver.launch.yaml": ["velocity_controller-1", "motor_boards-2", "catcher-3"],
    "sim_one_robot.launch.yaml": ["plant-1", "velocity_controller-2", "motor_boards-3"],
    "team_sim.launch.yaml": ["plant-1", "ball_predictor-2", "team_catcher-3", "team_firmware-4"],
    "ssl_world.launch.yaml": ["plant-1", "team_firmware-2", "ssl_sim_server-3"],
}


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=lambda p: p.name)
def test_every_launch_file_in_src_loads_strictly_and_starts_every_node(path, capsys):
    assert main([str(path), *REQUIRED_ARGS.get(path.name, []), "--print"]) == 0, capsys.readouterr().err
    assert re.findall(r"^\[(\S+)\] ", capsys.readouterr().out, re.M) == NODES[path.name]


# one fixture per construct that ros2 launch on Jazzy rejects or gets wrong: (file, line, the one line)
STRICT = [
    ("strict_optenv.launch.yaml", 8,
     "Unknown substitution: optenv (a ROS 1 substitution; ROS 2 writes $(env NAME default)) "
     "(in '$(optenv ERFORCE_X fallback)')"),
    ("strict_include_missing_arg.launch.yaml", 7,
     "Included launch description missing required argument 'robot_name' (description: 'the robot (required)'), "
     "given: [share]; pass it in the include's 'arg' list"),
    ("strict_dirname_after_include.launch.yaml", 10,
     f"'$(dirname)' after an include is refused: ros2 launch on Jazzy resolves it to the folder of the last "
     f"included file ({HERE}), not to strict_dirname_after_include.launch.yaml's (ros2/launch#618); write "
     "$(find-pkg-share PKG)/... or use it before the first include (in '$(dirname)/talker_params.yaml')"),
]


@pytest.mark.parametrize(("name", "line", "message"), STRICT, ids=[s[0] for s in STRICT])
def test_what_ros2_launch_rejects_fails_with_one_line(name, line, message, capsys, monkeypatch):
    monkeypatch.chdir(HERE)
    assert main([name, "--print"]) == 2
    out, err = capsys.readouterr()
    assert (out, err) == ("", f"erforce-launch: error: {name}:{line}: {message}\n")


def test_a_failing_include_leaves_no_half_graph(ros_graph):
    """ros2 launch would have started the listener before it reached the include; erforce-launch starts nothing."""
    launch = ros_graph.start([LAUNCHER, str(HERE / "strict_include_missing_arg.launch.yaml")], name="launch")
    assert launch.wait_exit(30.0) == 2
    assert "process started" not in launch.output()
    assert launch.output().count("\n") == 1 and "missing required argument 'robot_name'" in launch.output()


def test_the_launch_files_need_their_required_args_on_the_command_line(capsys):
    path = REPO / "src/erforce_sim/launch/receiver.launch.yaml"
    assert main([str(path), "robot:=robot_0", "--print"]) == 2
    err = capsys.readouterr().err
    assert "receiver.launch.yaml:6: required argument 'team_robot_ids' not given" in err
    assert "pass team_robot_ids:=VALUE" in err


def test_receivers_get_the_team_from_their_include(capsys):
    specs = resolve(REPO / "src/erforce_sim/launch/demo.launch.yaml", receivers="3")
    catchers = {label: params_of(s) for label, s in specs.items() if label.startswith("catcher")}
    assert [next(iter(p.values()))["team_robot_ids"] for p in catchers.values()] == [[0, 2, 3]] * 3
    assert [next(iter(p)) for p in catchers.values()] == ["/robot_0/catcher", "/robot_2/catcher", "/robot_3/catcher"]


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


def test_required_args_below_an_include_are_checked_ahead_as_launch_does(tmp_path):
    """launch looks ahead into every include whose path needs no context ($(find-pkg-share), a plain
    path; not $(var) or $(dirname)), whatever its condition, and checks the required args there against
    the include's arg names; a skipped include it cannot look into is never checked."""
    child = _write(tmp_path / "child.launch.yaml", """\
        launch:
          - arg: {name: who}
          - executable: {cmd: "true", name: "$(var who)"}
        """)
    ahead = _write(tmp_path / "ahead.launch.yaml", f"""\
        launch:
          - let: {{name: who, value: "from the scope"}}
          - include: {{file: "{child}", if: "false"}}
        """)
    with pytest.raises(LaunchError, match=r"ahead.launch.yaml:3: Included launch description missing required "
                                          r"argument 'who' \(description: ''\), given: \[\]"):
        resolve(ahead)
    behind_var = _write(tmp_path / "behind_var.launch.yaml", f"""\
        launch:
          - let: {{name: folder, value: "{tmp_path}"}}
          - include: {{file: "$(var folder)/child.launch.yaml", if: "false"}}
          - executable: {{cmd: "true", name: ran}}
        """)
    assert list(resolve(behind_var)) == ["ran-1"]
    passed = _write(tmp_path / "passed.launch.yaml", f"""\
        launch:
          - include: {{file: "{child}", arg: [{{name: who, value: given}}]}}
        """)
    assert list(resolve(passed)) == ["given-1"]


def test_an_unconditional_required_arg_of_the_command_line_file_needs_the_command_line(tmp_path):
    """ros2 launch includes the given file with the command-line args: a let before the arg does not count,
    an arg under a condition is only checked when it runs."""
    path = _write(tmp_path / "top.launch.yaml", """\
        launch:
          - let: {name: who, value: "let"}
          - arg: {name: who}
          - group:
              if: "true"
              children:
                - arg: {name: later}
        """)
    with pytest.raises(LaunchError, match=r"top.launch.yaml:3: required argument 'who' not given"):
        resolve(path)
    with pytest.raises(LaunchError, match=r"top.launch.yaml:7: required argument 'later' not given"):
        resolve(path, who="cli")
    assert resolve(path, who="cli", later="x") == {}


def test_dirname_in_an_include_arg_value_is_the_included_files_folder(tmp_path):
    """launch makes the included file the current one before it sets the include's args."""
    child = _write(tmp_path / "b" / "child.launch.yaml", """\
        launch:
          - arg: {name: where}
          - executable: {cmd: "echo $(var where) $(dirname)", name: child}
        """)
    parent = _write(tmp_path / "a" / "parent.launch.yaml", f"""\
        launch:
          - include: {{file: "{child}", arg: [{{name: where, value: "$(dirname)"}}]}}
        """)
    (spec,) = resolve(parent).values()
    assert spec.cmd[1:] == [str(tmp_path / "b"), str(tmp_path / "b")]


def test_filename_after_an_include_is_refused_too(tmp_path):
    _write(tmp_path / "empty.launch.yaml", "launch: []\n")
    path = _write(tmp_path / "uses.launch.yaml", """\
        launch:
          - executable: {cmd: "echo $(filename)", name: before}
          - include: {file: "$(dirname)/empty.launch.yaml"}
          - executable: {cmd: "echo $(filename)", name: after}
        """)
    with pytest.raises(LaunchError, match=r"uses.launch.yaml:4: '\$\(filename\)' after an include is refused: "
                                          r"ros2 launch on Jazzy resolves it to the last included file \(.*"
                                          r"empty.launch.yaml\)"):
        resolve(path)


@pytest.mark.parametrize(("text", "what"), [
    ("$(optenv A)", "Unknown substitution: optenv (a ROS 1 substitution"),
    ("$(arg a)", "Unknown substitution: arg (a ROS 1 substitution; ROS 2 writes $(var NAME))"),
    ("$(nosuch x)", "Unknown substitution: nosuch (known: var, env, "),
    ("$(env $(optenv A))", "Unknown substitution: optenv"),
    ("$(eval 1)", "unsupported substitution '$(eval)'"),
])
def test_substitutions_are_checked_when_the_file_loads_in_every_branch(tmp_path, text, what):
    path = _write(tmp_path / "x.launch.yaml", f"""\
        launch:
          - group:
              if: "false"
              children:
                - executable: {{cmd: "true", name: "{text}"}}
        """)
    with pytest.raises(LaunchError, match=r"x.launch.yaml:5: ") as err:
        resolve(path)
    assert what in str(err.value)


def test_typed_launch_arguments_reach_parameters_with_the_declared_type(tmp_path):
    """launch_ros types an inline value by YAML ('0' is the integer 0); the node's schema says what it is."""
    plant = resolve(REPO / "src/erforce_sim/launch/demo.launch.yaml", real_time_factor="0")["plant-1"]
    rtf = params_of(plant)["/**"]["real_time_factor"]
    assert rtf == 0.0 and isinstance(rtf, float)
    specs = resolve(REPO / "src/erforce_sim/launch/team_sim.launch.yaml", robot_poses="[0, 1, 0]", num_robots="1",
                    robot_ids="[0]")
    poses = params_of(specs["plant-1"])["/**"]["robot_poses"]
    assert poses == [0.0, 1.0, 0.0] and all(isinstance(v, float) for v in poses)
    assert params_of(specs["ball_predictor-2"])["/**"]["num_robots"] == 1  # an int stays an int
    talker = resolve(TALKER_LISTENER, rate_hz="20")["talker-1"]
    assert params_of(talker)["/demo/talker"]["rate_hz"] == 20.0
    other = _write(tmp_path / "other.launch.yaml", """\
        launch:
          - node: {pkg: erforce_interfaces, exec: listener, param: [{name: x, value: "1"}]}
        """)
    (listener,) = resolve(other).values()
    assert params_of(listener)["/**"]["x"] == 1  # no schema: as launch_ros types it


# ======================================================================= one-line errors
ERRORS = [
    ("malformed", "launch:\n  - node: {pkg: x\n  - arg: {name: a}\n", 3, "invalid YAML"),
    ("unknown key", "launch:\n  - node:\n      pkg: erforce_interfaces\n      exec: talker\n      nmae: t\n",
     5, "unknown key 'nmae' in 'node'"),
    ("unknown action", "launch:\n  - arg: {name: a, default: '1'}\n  - nod: {}\n", 3, "unknown action 'nod'"),
    ("unknown package", "launch:\n  - node:\n      pkg: no_such_pkg\n      exec: talker\n", 3,
     "package 'no_such_pkg' not found"),
    ("unknown executable", "launch:\n  - node:\n      exec: talkr\n      pkg: erforce_interfaces\n", 4,
     "package 'erforce_interfaces' has no executable 'talkr' (executables: "),
    ("missing arg", "launch:\n  - arg: {name: a, default: '1'}\n  - arg: {name: robot, description: r}\n", 3,
     "required argument 'robot' not given; arguments of bad.launch.yaml: a='1', robot (required)"),
    ("unquoted default", "launch:\n  - arg: {name: a, default: 10}\n", 2, "'default' must be a string"),
    ("undefined var", "launch:\n  - let: {name: a, value: 'x'}\n  - let: {name: b, value: '$(var c)'}\n", 3,
     "launch configuration 'c' is not set"),
    ("unset env", "launch:\n  - let: {name: b, value: '$(env ERFORCE_SURELY_UNSET_VAR)'}\n", 2,
     "environment variable 'ERFORCE_SURELY_UNSET_VAR' is not set"),
    ("find-pkg-share", "launch:\n  - include: {file: '$(find-pkg-share nope_pkg)/x.yaml'}\n", 2,
     "package 'nope_pkg' not found"),
    ("duplicate key", "launch:\n  - node: {pkg: a, exec: b,\n      pkg: c}\n", 3, "duplicate key 'pkg'"),
    ("bad bool", "launch:\n  - node: {pkg: erforce_interfaces, exec: talker, respawn: maybe}\n", 2,
     "'respawn' must be true or false"),
    ("bad output", "launch:\n  - node: {pkg: erforce_interfaces, exec: talker, output: tty}\n", 2,
     "'output' must be screen, log or both"),
    ("negative delay", "launch:\n  - node: {pkg: erforce_interfaces, exec: talker, respawn_delay: -1.0}\n", 2,
     "'respawn_delay' must be a finite number >= 0"),
    ("bad name", "launch:\n  - node: {pkg: erforce_interfaces, exec: talker, name: a-b}\n", 2,
     "invalid node name 'a-b'"),
    ("bad namespace", "launch:\n  - node: {pkg: erforce_interfaces, exec: talker, namespace: '1x'}\n", 2,
     "invalid namespace '/1x'"),
    ("param file", "launch:\n  - node:\n      pkg: erforce_interfaces\n      exec: talker\n"
     "      param: [{from: /nonexistent/p.yaml}]\n", 5, "parameter file not found"),
    ("mixed list", "launch:\n  - node: {pkg: erforce_interfaces, exec: talker, param: [{name: x, value: [1, a]}]}\n",
     2, "a list parameter needs elements of one type"),
    ("no launch key", "nodes: []\n", 1, "expected a top-level 'launch:' list"),
    ("include missing", "launch:\n  - include: {file: 'nope/x.launch.yaml'}\n", 2, "included file not found"),
    ("eval", "launch:\n  - let: {name: a, value: '$(eval 1)'}\n", 2, "unsupported substitution '$(eval)'"),
    ("eval lists the boolean ones", "launch:\n  - let: {name: a, value: '$(eval 1)'}\n", 2,
     "anon, equals, not-equals, not, and, or)"),
    ("not arity", "launch:\n  - let: {name: a, value: x}\n  - let: {name: b, value: '$(not true false)'}\n", 3,
     "'$(not)' takes 1..1 argument(s), got 2"),
    ("and arity", "launch:\n  - node:\n      pkg: erforce_interfaces\n      exec: talker\n      if: $(and 1)\n", 5,
     "'$(and)' takes 2..2 argument(s), got 1"),
    ("or arity", "launch:\n  - let: {name: b, value: '$(or 1 1 1)'}\n", 2, "'$(or)' takes 2..2 argument(s), got 3"),
    ("equals arity", "launch:\n  - let: {name: b, value: '$(equals a)'}\n", 2,
     "'$(equals)' takes 2..2 argument(s), got 1"),
    ("not-equals arity", "launch:\n  - let: {name: b, value: '$(not-equals)'}\n", 2,
     "'$(not-equals)' takes 2..2 argument(s), got 0"),
    ("not a bool", "launch:\n  - arg: {name: n, default: '2'}\n  - node:\n      pkg: erforce_interfaces\n"
     "      exec: talker\n      unless: $(not $(var n))\n", 6,
     "'$(not)' needs a boolean (true/false, 1/0, yes/no, on/off), got '2' (in '$(not $(var n))')"),
    ("and not a bool", "launch:\n  - let: {name: b, value: '$(and true maybe)'}\n", 2,
     "'$(and)' needs a boolean (true/false, 1/0, yes/no, on/off), got 'maybe'"),
    ("or empty", "launch:\n  - let: {name: b, value: \"$(or '' true)\"}\n", 2, "'$(or)' needs a boolean"),
    ("any", "launch:\n  - let: {name: b, value: '$(any true false)'}\n", 2,
     "'$(any)' fails in ros2 launch on Jazzy (TypeError from its parser); nest '$(or)' instead"),
    ("all", "launch:\n  - let: {name: b, value: '$(all)'}\n", 2, "'$(all)' fails in ros2 launch on Jazzy"),
    ("choice", "launch:\n  - arg: {name: m, default: 'c', choice: [{value: a}, {value: b}]}\n", 2,
     "argument 'm' is 'c', not one of: a, b"),
]


@pytest.mark.parametrize(("content", "line", "what"), [e[1:] for e in ERRORS], ids=[e[0] for e in ERRORS])
def test_bad_launch_files_fail_with_one_line_naming_file_and_line(tmp_path, monkeypatch, capsys, content, line, what):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.launch.yaml").write_text(content)
    assert main(["bad.launch.yaml"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"erforce-launch: error: bad.launch.yaml:{line}: "), err
    assert what in err


def test_unknown_executable_error_lists_the_package_executables(tmp_path, capsys):
    (tmp_path / "x.yaml").write_text("launch:\n  - node: {pkg: erforce_interfaces, exec: talkr}\n")
    main([str(tmp_path / "x.yaml")])
    listed = capsys.readouterr().err.split("(executables: ")[1].rstrip(")\n").split(", ")
    assert {"talker", "listener", "erforce-launch"} <= set(listed)


@pytest.mark.parametrize("argv", [["nothere.launch.yaml"], ["erforce_interfaces", "nothere.yaml"],
                                  ["no_such_pkg", "x.yaml"], ["a", "b", "c"], ["x.yaml", ":=v"]])
def test_bad_command_lines_fail_with_one_line(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("erforce-launch: error: ")


def test_console_script_prints_exactly_one_line_for_a_bad_file(ros_graph, tmp_path):
    bad = tmp_path / "bad.launch.yaml"
    bad.write_text("launch:\n  - node:\n      pkg: erforce_interfaces\n      exec: talker\n      nmae: t\n")
    proc = ros_graph.start([LAUNCHER, str(bad)], name="bad")
    assert proc.wait_exit(30.0) == 2
    assert proc.output().startswith(f"erforce-launch: error: {bad}:5: unknown key 'nmae' in 'node' (known: ")
    assert proc.output().count("\n") == 1


# ============================================================================ real processes
@pytest.mark.integration
def test_talker_listener_launch_runs_and_ctrl_c_reaps_both(ros_graph):
    launch = ros_graph.start([LAUNCHER, str(TALKER_LISTENER), "rate_hz:=20.0"], name="launch")
    launch.wait_for_output(r"\[listener-2\] .*I heard: hello from the talker \d+", timeout_s=30.0)
    pids = started_pids(launch.output())
    assert len(pids) == 2 and all(alive(p) for p in pids)
    launch.signal(signal.SIGINT)
    assert launch.wait_exit(15.0) == 0
    out = launch.output()
    assert "[WARNING] [launch]: user interrupted with ctrl-c (SIGINT)" in out
    assert f"[INFO] [talker-1]: process has finished cleanly [pid {pids[0]}]" in out
    assert f"[INFO] [listener-2]: process has finished cleanly [pid {pids[1]}]" in out
    assert not any(alive(p) for p in pids)


@pytest.mark.integration
def test_params_from_file_and_remap_reach_the_real_nodes(ros_graph):
    launch = ros_graph.start([LAUNCHER, str(HERE / "params_remap.launch.yaml")], name="launch")
    # the text comes from talker_params.yaml; /b/listener only hears /a/chatter through its remap
    launch.wait_for_output(r"\[listener-2\] .*\[b\.listener\]: I heard: text from the params file \d+", 30.0)
    launch.signal(signal.SIGINT)
    assert launch.wait_exit(15.0) == 0


@pytest.mark.integration
def test_a_dead_node_is_reported_and_makes_the_exit_code_nonzero(ros_graph):
    launch = ros_graph.start([LAUNCHER, str(HERE / "talker_only.launch.yaml"), "rate_hz:=-1.0"], name="launch")
    assert launch.wait_exit(30.0) == 1  # the only process died: the launch ends by itself
    out = launch.output()
    (pid,) = started_pids(out)
    assert re.search(rf"\[ERROR\] \[talker-1\]: process has died \[pid {pid}, exit code 1, cmd '.*/talker "
                     r"--ros-args -r __node:=talker --params-file \S+'\]\.", out)
    assert re.search(r"\[talker-1\] .*rate_hz", out)  # the node's own reason, relayed with the prefix


@pytest.mark.integration
def test_respawn_restarts_a_dying_node_until_ctrl_c(ros_graph):
    launch = ros_graph.start([LAUNCHER, str(HERE / "talker_only.launch.yaml"), "rate_hz:=-1.0", "respawn:=true"],
                             name="launch")
    launch.wait_for_output(r"(?s)(?:process started with pid.*?){3}", timeout_s=45.0)
    assert "[INFO] [talker-1]: respawning in 0.2 s" in launch.output()
    launch.signal(signal.SIGINT)
    assert launch.wait_exit(15.0) == 0  # respawning processes' deaths are not failures
    assert not any(alive(p) for p in started_pids(launch.output()))


@pytest.mark.integration
def test_a_respawned_node_gets_its_generated_parameter_file_for_as_long_as_the_launcher_runs(ros_graph):
    launch = ros_graph.start([LAUNCHER, str(HERE / "respawn_talker.launch.yaml")], name="launch")
    launch.wait_for_output(r"I heard: from the generated file \d+", 30.0)
    first = started_pids(launch.output())[0]
    os.kill(first, signal.SIGKILL)
    launch.wait_for_output(r"respawning in 0.2 s", 15.0)
    died = re.search(r"process has died \[pid \d+, exit code -9, cmd '.*--params-file (\S+)'\]", launch.output())
    params_file = Path(died.group(1))
    assert params_file.exists()  # kept: the respawn and a restart by hand need it
    n = launch.output().count("I heard: from the generated file")
    deadline = time.monotonic() + 30.0
    while launch.output().count("I heard: from the generated file") < n + 5:  # the respawned talker's
        assert time.monotonic() < deadline, launch.output()[-2000:]
        time.sleep(0.05)
    second = started_pids(launch.output())[-1]
    assert second != first and alive(second)
    launch.signal(signal.SIGINT)
    assert launch.wait_exit(15.0) == 0
    assert not params_file.exists()  # removed once the launcher ends


@pytest.mark.parametrize(("ignore", "launcher_signal", "last_rung"), [
    ("INT", signal.SIGINT, "SIGTERM"), ("INT,TERM", signal.SIGTERM, "SIGKILL")])
def test_shutdown_ladder_escalates_and_reaps_children_and_grandchildren(ros_graph, ignore, launcher_signal,
                                                                         last_rung):
    launch = ros_graph.start([LAUNCHER, str(HERE / "stubborn.launch.yaml"), f"ignore:={ignore}",
                              "--sigterm-timeout", "0.3", "--sigkill-timeout", "0.3"], name="launch",
                             env={"ERFORCE_TEST_PYTHON": sys.executable})
    launch.wait_for_output(r"(?s)(?:\] ready pid=\d+ grandchild=\d+\n.*?){2}", timeout_s=30.0)
    out = launch.output()
    pids = started_pids(out) + [int(p) for p in re.findall(r"grandchild=(\d+)", out)]
    assert len(pids) == 4 and all(alive(p) for p in pids)
    launch.signal(launcher_signal)
    assert launch.wait_exit(10.0) == 0
    out = launch.output()
    reason = "user interrupted with ctrl-c (SIGINT)" if launcher_signal == signal.SIGINT else "received SIGTERM"
    assert f"[WARNING] [launch]: {reason}" in out
    assert "failed to terminate '0.3' seconds after receiving 'SIGINT', escalating to 'SIGTERM'" in out
    if last_rung == "SIGTERM":  # SIGTERM was enough
        assert "escalating to 'SIGKILL'" not in out and "exit code -15" in out
    else:
        assert "escalating to 'SIGKILL'" in out and "exit code -9" in out
    assert "[INFO] [polite-2]: process has finished cleanly" in out  # SIGINT was enough for it
    assert "[polite-2]: process failed to terminate" not in out
    assert not any(alive(p) for p in pids)


def test_second_ctrl_c_skips_the_wait(ros_graph):
    launch = ros_graph.start([LAUNCHER, str(HERE / "stubborn.launch.yaml"), "ignore:=INT", "--sigterm-timeout", "60"],
                             name="launch", env={"ERFORCE_TEST_PYTHON": sys.executable})
    launch.wait_for_output(r"(?s)(?:\] ready pid=\d+ grandchild=\d+\n.*?){2}", timeout_s=30.0)
    launch.signal(signal.SIGINT)
    launch.wait_for_output(r"polite-2\]: process has finished cleanly", timeout_s=10.0)
    launch.signal(signal.SIGINT)
    assert launch.wait_exit(10.0) == 0  # long before the 60 s SIGINT timeout
    out = launch.output()
    assert "user interrupted with ctrl-c (SIGINT) again, escalating" in out
    assert re.search(r"\[stubborn-1\]: process has died \[pid \d+, exit code -15,", out)


def test_children_die_with_a_sigkilled_launcher(ros_graph):
    launch = ros_graph.start([LAUNCHER, str(HERE / "stubborn.launch.yaml"), "ignore:=NONE"], name="launch",
                             env={"ERFORCE_TEST_PYTHON": sys.executable})
    launch.wait_for_output(r"(?s)(?:\] ready pid=\d+ grandchild=\d+\n.*?){2}", timeout_s=30.0)
    children = started_pids(launch.output())
    launch.signal(signal.SIGKILL)
    launch.wait_exit(10.0)
    deadline = time.monotonic() + 10.0
    while any(alive(p) for p in children) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(alive(p) for p in children)  # PR_SET_PDEATHSIG sent them SIGTERM


def test_shutdown_on_exit_stops_the_rest_when_one_process_ends(ros_graph, tmp_path):
    path = tmp_path / "short.launch.yaml"
    path.write_text("launch:\n  - executable: {cmd: 'sleep 600', output: screen}\n"
                    "  - executable: {cmd: 'sleep 0.2', output: screen}\n")
    launch = ros_graph.start([LAUNCHER, str(path), "--shutdown-on-exit"], name="launch")
    assert launch.wait_exit(10.0) == 0
    out = launch.output()
    assert "[INFO] [sleep-2]: process has finished cleanly" in out
    assert "--shutdown-on-exit is set" in out
    assert re.search(r"\[sleep-1\]: process has died \[pid \d+, exit code -2,", out)  # our SIGINT: no failure


def test_log_output_goes_to_files_and_a_partial_last_line_is_kept(ros_graph, tmp_path):
    path = tmp_path / "echo.launch.yaml"
    path.write_text(textwrap.dedent("""\
        launch:
          - executable: {cmd: "printf 'one\\\\ntwo'", name: quiet, output: log}
          - executable: {cmd: "printf 'a\\\\nno newline'", name: loud, output: screen}
          - executable: {cmd: "sh -c 'echo oops >&2; exit 3'", name: failing, output: both}
        """))
    launch = ros_graph.start([LAUNCHER, str(path)], name="launch", env={"ROS_LOG_DIR": str(tmp_path / "logs")})
    assert launch.wait_exit(20.0) == 1  # 'failing' exited 3
    out = launch.output()
    assert "[loud-2] a\n" in out and "[loud-2] no newline\n" in out
    assert "[quiet-1] one" not in out
    assert "[failing-3] oops\n" in out and "exit code 3" in out
    (log_dir,) = (tmp_path / "logs").iterdir()
    assert (log_dir / "quiet-1-stdout.log").read_text() == "one\ntwo\n"
    assert (log_dir / "failing-3-stderr.log").read_text() == "oops\n"
    assert not (log_dir / "loud-2-stdout.log").exists()


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=lambda p: p.name)
@pytest.mark.parametrize("user_range", [None, "SUBNET"])
def test_discovery_stays_on_this_computer_unless_the_user_chose_a_range(path, user_range, monkeypatch):
    """Safe by default (docs/graph.md, "DDS discovery"): every node of every launch file, under erforce-launch
    and (through the files' own set_env) under ros2 launch, discovers only this computer's participants
    unless ROS_AUTOMATIC_DISCOVERY_RANGE is set, as the two-host test sets it."""
    if user_range is None:
        monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE", raising=False)
    else:
        monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", user_range)
    assert "$(env ROS_AUTOMATIC_DISCOVERY_RANGE LOCALHOST)" in path.read_text()
    specs = resolve(path, **({"robot": "robot_0", "team_robot_ids": "[0]"} if path.name == "receiver.launch.yaml"
                             else {}))
    assert specs
    assert {s.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] for s in specs.values()} == {user_range or "LOCALHOST"}


def test_erforce_launch_defaults_to_localhost_also_for_a_file_that_says_nothing(tmp_path, monkeypatch):
    monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE", raising=False)
    path = tmp_path / "bare.launch.yaml"
    path.write_text("launch:\n  - node: {pkg: erforce_interfaces, exec: talker}\n")
    (spec,) = resolve(path).values()
    assert spec.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_a_groups_keep_entries_are_set_one_after_the_other_unless_the_group_forwards_nothing(tmp_path):
    path = _write(tmp_path / "keep.launch.yaml", """\
        launch:
          - let: {name: a, value: outer}
          - group:
              keep: [{name: a, value: inner}, {name: b, value: "$(var a)"}]
              children:
                - executable: {cmd: "true", name: "$(var a)-$(var b)"}
          - group:
              forwarding: false
              keep: [{name: a, value: inner}, {name: b, value: "$(var a)"}]
              children:
                - executable: {cmd: "true", name: "$(var a)-$(var b)"}
          - executable: {cmd: "true", name: "$(var a)"}
        """)
    assert list(resolve(path)) == ["inner-inner-1", "inner-outer-2", "outer-3"]


def test_show_args_names_each_argument_once_with_its_first_declaration():
    args = declared_args(REPO / "src/erforce_sim/launch/demo.launch.yaml")
    names = [name for name, _, _ in args]
    assert len(names) == len(set(names))
    assert {"receivers", "robot", "team_robot_ids", "lockstep_sync"} <= set(names)  # the includes' too
    assert dict((n, d) for n, d, _ in args)["launch_prefix"] == ""  # receiver.launch.yaml's, the first


# ====================================== docs/launch_attributes.md: one fixture per attribute row
ATTRIBUTES_DOC = REPO / "docs" / "launch_attributes.md"
ATTRIBUTE_FIXTURES = HERE / "attributes"


def attribute_rows() -> list[tuple[str, str, str]]:
    """(row, what ros2 launch did, what erforce-launch must do) of each table row of the document."""
    rows = []
    for line in ATTRIBUTES_DOC.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")] if line.startswith("| ") else []
        if len(cells) == 6 and re.fullmatch(r"[a-z_]+", cells[0]) and cells[0] != "row":
            rows.append((cells[0], cells[4], cells[5]))
    return rows


def test_every_attribute_fixture_has_a_row():
    fixtures = {p.name.removesuffix(".launch.yaml") for p in ATTRIBUTE_FIXTURES.glob("*.launch.yaml")}
    assert fixtures - {"included"} == {row for row, _, _ in attribute_rows()}


@pytest.mark.parametrize(("row", "real", "ours"), attribute_rows(), ids=[r[0] for r in attribute_rows()])
def test_attribute_table_row(row, real, ours, capsys):
    """erforce-launch accepts the row's fixture exactly where ros2 launch did, and refuses it where ros2 launch
    refused it or misreads it, with the error the table quotes, naming the fixture's line."""
    verdict, real_verdict = (re.match(r"\w+", cell).group() for cell in (ours, real))
    assert verdict in ("accepts", "refuses") and real_verdict in ("accepts", "refuses", "misreads")
    assert verdict == {"misreads": "refuses"}.get(real_verdict, real_verdict)
    code = main([str(ATTRIBUTE_FIXTURES / f"{row}.launch.yaml"), "--print"])
    err = capsys.readouterr().err
    if verdict == "accepts":
        assert (code, err) == (0, "")
    else:
        quoted = re.search(r"`([^`]+)`", ours).group(1)
        assert code == 2 and err.count("\n") == 1 and quoted in err, err
        assert re.search(rf"{row}\.launch\.yaml:\d+: ", err), err
