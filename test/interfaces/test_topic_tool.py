"""erforce-topic: message<->YAML conversion, rate statistics, QoS choice (in process), and every verb
as a real process over real DDS against the demo talker (50 Hz on /chatter)."""

from __future__ import annotations

import math
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Twist
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.qos import QoSDurabilityPolicy, QoSReliabilityPolicy
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header, String, UInt8MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from erforce_interfaces.tools import message_text as mt
from erforce_interfaces.tools import topic_tool as tt
from erforce_interfaces.tools.processes import stop_process
from erforce_interfaces.tools.testing import RosGraph
from erforce_interfaces.wire.contract import QOS_COMMAND

TOOL = str(Path(sys.executable).with_name("erforce-topic"))

# The JointState both the in-process and the over-DDS test use, and its YAML written by hand.
JOINT_STATE_YAML_IN = (
    "{header: {stamp: {sec: 12, nanosec: 500}, frame_id: base_link}, name: [wheel_0, wheel_1], "
    "position: [1.5, -2], velocity: [], effort: [0.25, 1.0e-5]}"
)
JOINT_STATE_YAML_OUT = """\
header:
  stamp:
    sec: 12
    nanosec: 500
  frame_id: base_link
name:
- wheel_0
- wheel_1
position:
- 1.5
- -2.0
velocity: []
effort:
- 0.25
- 1.0e-05
"""


def _joint_state() -> JointState:
    return JointState(
        header=Header(stamp=Time(sec=12, nanosec=500), frame_id="base_link"),
        name=["wheel_0", "wheel_1"], position=[1.5, -2.0], velocity=[], effort=[0.25, 1e-5],
    )


# ------------------------------------------------------------------------------ message types


@pytest.mark.parametrize("name", ["std_msgs/msg/String", "std_msgs/String", "/std_msgs/msg/String"])
def test_type_names_resolve_to_the_generated_class(name):
    assert mt.get_message_class(name) is String


@pytest.mark.parametrize(
    "name", ["String", "nopkg/msg/Foo", "std_msgs/msg/Nope", "std_msgs/srv/String", "a/b/c/d", "std_msgs/", ""]
)
def test_bad_type_names_are_tool_errors(name):
    with pytest.raises(mt.ToolError):
        mt.get_message_class(name)


# ------------------------------------------------------------------------------ message -> text


def test_yaml_of_a_message_with_header_and_arrays_is_exact():
    assert mt.message_to_yaml(_joint_state()) == JOINT_STATE_YAML_OUT


def test_yaml_of_fixed_size_numpy_arrays_is_a_plain_list():
    imu = Imu()
    imu.orientation_covariance = np.arange(9, dtype=np.float64) / 4.0
    text = mt.message_to_yaml(imu)
    expected_cov = "orientation_covariance:\n" + "".join(f"- {v}\n" for v in (0.0, 0.25, 0.5, 0.75, 1.0,
                                                                               1.25, 1.5, 1.75, 2.0))
    assert expected_cov in text
    assert "!!" not in text  # no python/numpy tags
    assert "orientation:\n  x: 0.0\n  y: 0.0\n  z: 0.0\n  w: 1.0\n" in text


@pytest.mark.parametrize(
    ("value", "text"),
    [(1e-5, "1.0e-05"), (1e20, "1.0e+20"), (0.1, "0.1"), (-0.0, "-0.0"), (math.inf, ".inf"),
     (-math.inf, "-.inf"), (math.nan, ".nan"), (3.0, "3.0")],
)
def test_floats_print_like_python_repr_in_yaml_spelling(value, text):
    assert mt.message_to_yaml(JointState(position=[value])).split("position:\n- ")[1].split("\n")[0] == text


@pytest.mark.parametrize(("data", "line"), [("yes", "data: 'yes'"), ("5", "data: '5'"), ("", "data: ''"),
                                             ("hello 3", "data: hello 3"), ("a: b", "data: 'a: b'")])
def test_strings_that_yaml_would_misread_are_quoted(data, line):
    assert mt.message_to_yaml(String(data=data)) == line + "\n"


def test_byte_arrays_print_as_integer_lists():
    msg = UInt8MultiArray(data=[1, 2, 255])
    assert mt.message_to_yaml(msg).endswith("data:\n- 1\n- 2\n- 255\n")


def test_no_arr_no_str_and_truncation_match_ros2_echo():
    js = _joint_state()
    no_arr = mt.message_to_ordereddict(js, no_arr=True)
    assert no_arr["name"] == "<sequence type: string, length: 2>"
    assert no_arr["velocity"] == "<sequence type: double, length: 0>"
    assert mt.message_to_ordereddict(Imu(), no_arr=True)["orientation_covariance"] == "<array type: double[9]>"
    assert mt.message_to_ordereddict(js, no_str=True)["header"]["frame_id"] == "<string length: <9>>"
    short = mt.message_to_ordereddict(js, truncate_length=1)
    assert short["position"] == [1.5, "..."]
    assert short["name"] == ["w...", "..."]
    assert short["header"]["frame_id"] == "b..."


def test_csv_lists_the_leaves_depth_first():
    twist = Twist()
    twist.linear.x, twist.angular.z = 1.0, -0.5
    assert mt.message_to_csv(twist) == "1.0,0.0,0.0,0.0,0.0,-0.5"
    assert mt.message_to_csv(_joint_state()) == "12,500,base_link,wheel_0,wheel_1,1.5,-2.0,,0.25,1e-05"


@pytest.mark.parametrize(
    ("path", "tokens"),
    [("data", ["data"]), ("a.b[2].c", ["a", "b", 2, "c"]), ("a.b.2", ["a", "b", 2]), ("name[0]", ["name", 0])],
)
def test_field_paths_parse(path, tokens):
    assert mt.parse_field_path(path) == tokens


@pytest.mark.parametrize("path", ["", ".", "a..b", "a[x]", "a[", "a]b", "[0"])
def test_bad_field_paths_are_tool_errors(path):
    with pytest.raises(mt.ToolError):
        mt.parse_field_path(path)


def test_get_field_walks_messages_and_lists():
    js = _joint_state()
    assert mt.get_field(js, ["header", "stamp", "sec"]) == 12
    assert mt.get_field(js, ["name", 1]) == "wheel_1"
    assert mt.get_field(js, ["position", -1]) == -2.0
    for bad in (["nope"], ["name", 2], ["header", 0], ["header", "stamp", "sec", "x"]):
        with pytest.raises(mt.ToolError):
            mt.get_field(js, bad)


# ------------------------------------------------------------------------------ dict -> message


def test_numbers_become_floats_where_the_field_is_float():
    msg = Twist()
    mt.set_message_fields(msg, {"linear": {"x": 1}, "angular": {"z": -2}})
    assert type(msg.linear.x) is float and msg.linear.x == 1.0
    assert msg.angular.z == -2.0 and msg.linear.y == 0.0


def test_fields_from_yaml_text_rebuild_the_message():
    msg = mt.new_message(JointState)
    mt.set_message_fields(msg, yaml.safe_load(JOINT_STATE_YAML_IN))
    assert msg == _joint_state()


def test_sequences_of_messages_are_built_element_by_element():
    msg = JointTrajectory()
    mt.set_message_fields(msg, {"joint_names": ["a"], "points": [
        {"positions": [1, 2], "time_from_start": {"sec": 3}}, {"effort": [0.5]}]})
    assert [type(p) for p in msg.points] == [JointTrajectoryPoint, JointTrajectoryPoint]
    assert list(msg.points[0].positions) == [1.0, 2.0] and msg.points[0].time_from_start.sec == 3
    assert list(msg.points[1].effort) == [0.5]


@pytest.mark.parametrize(
    ("cls", "values", "fragment"),
    [
        (Twist, {"linear": {"q": 1}}, "unknown field 'linear.q'"),
        (Twist, {"speed": 1}, "unknown field 'speed'"),
        (Twist, {"linear": 5}, "'linear': expected a mapping"),
        (Twist, {"linear": {"x": "fast"}}, "'linear.x': expected a number"),
        (Twist, {"linear": {"x": True}}, "'linear.x': expected a number"),
        (Imu, {"orientation_covariance": [1, 2, 3]}, "exactly 9 elements"),
        (JointState, {"position": 1.0}, "'position': expected a list"),
        (JointState, {"header": {"stamp": {"sec": 1.5}}}, "'header.stamp.sec': expected an integer"),
        (JointState, {"header": {"stamp": {"nanosec": -1}}}, "out of the uint32 range"),
        (UInt8MultiArray, {"data": [0, 256]}, "'data[1]'"),
        (JointState, {"name": [{"a": 1}]}, "'name[0]': expected a string"),
    ],
)
def test_bad_values_name_the_field(cls, values, fragment):
    with pytest.raises(mt.ToolError, match=re.escape(fragment)):
        mt.set_message_fields(mt.new_message(cls), values)


def test_integer_bounds_are_inclusive():
    from std_msgs.msg import Int8, UInt64

    for cls, ok, bad in ((Int8, (-128, 127), (-129, 128)), (UInt64, (0, 2**64 - 1), (-1, 2**64))):
        for v in ok:
            msg = mt.new_message(cls)
            mt.set_message_fields(msg, {"data": v})
            assert msg.data == v
        for v in bad:
            with pytest.raises(mt.ToolError, match="range"):
                mt.set_message_fields(mt.new_message(cls), {"data": v})


def test_header_auto_and_stamp_now_return_setters_that_stamp_the_message():
    msg = mt.new_message(JointState)
    setters = mt.set_message_fields(msg, {"header": "auto"})
    assert len(setters) == 1
    for set_stamp in setters:
        set_stamp(Time(sec=7, nanosec=9))
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (7, 9)
    msg = mt.new_message(JointState)
    (set_stamp,) = mt.set_message_fields(msg, {"header": {"stamp": "now", "frame_id": "f"}})
    set_stamp(Time(sec=3, nanosec=4))
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (3, 4, "f")


_names = st.lists(st.text(alphabet=st.characters(categories=("L", "N", "P", "Zs")), max_size=12), max_size=4)
_floats = st.lists(st.floats(allow_nan=False, width=64), max_size=5)


@settings(max_examples=60, deadline=None)
@given(names=_names, position=_floats, effort=_floats, sec=st.integers(-(2**31), 2**31 - 1),
       nanosec=st.integers(0, 2**32 - 1), frame=st.text(alphabet=st.characters(categories=("L", "N")), max_size=8))
def test_yaml_round_trip_restores_any_joint_state(names, position, effort, sec, nanosec, frame):
    original = JointState(header=Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame),
                          name=names, position=position, effort=effort)
    rebuilt = mt.new_message(JointState)
    mt.set_message_fields(rebuilt, yaml.safe_load(mt.message_to_yaml(original)))
    assert rebuilt == original


# ------------------------------------------------------------------------------ rate statistics


def test_rate_statistics_of_a_hand_computed_case():
    w = tt.RateWindow(10)
    for t_ms in (0, 20, 40, 70):
        w.add(t_ms * 1_000_000)
    s = w.stats()
    # intervals 20, 20, 30 ms: mean 70/3 ms; deviations -10/3, -10/3, 20/3 ms
    assert s.rate_hz == pytest.approx(3 / 0.070)
    assert (s.min_interval_s, s.max_interval_s, s.window) == (pytest.approx(0.020), pytest.approx(0.030), 3)
    assert s.std_dev_s == pytest.approx(math.sqrt((2 * (10 / 3) ** 2 + (20 / 3) ** 2) / 3) * 1e-3)
    assert s.text() == "average rate: 42.857\n\tmin: 0.020s max: 0.030s std dev: 0.00471s window: 3"


def test_rate_window_keeps_only_the_newest_intervals():
    w = tt.RateWindow(2)
    for t_ms in (0, 100, 110, 120):  # intervals 100, 10, 10: the 100 falls out
        w.add(t_ms * 1_000_000)
    assert w.stats().rate_hz == pytest.approx(100.0) and w.stats().window == 2


def test_rate_window_restarts_when_time_goes_backwards():
    w = tt.RateWindow()
    assert w.stats() is None
    w.add(5_000_000_000)
    assert w.stats() is None  # one arrival has no interval
    w.add(5_100_000_000)
    w.add(1_000_000_000)  # sim time reset
    assert w.stats() is None
    w.add(1_250_000_000)
    assert w.stats().rate_hz == pytest.approx(4.0) and w.stats().window == 1


@pytest.mark.parametrize("window", [0, -1, 1.5, None])
def test_rate_window_rejects_bad_sizes(window):
    with pytest.raises(ValueError):
        tt.RateWindow(window)


@given(period_ns=st.integers(1_000, 10**10), n=st.integers(2, 50))
def test_a_steady_stream_has_rate_one_over_period_and_no_spread(period_ns, n):
    w = tt.RateWindow(100)
    for k in range(n):
        w.add(k * period_ns)
    s = w.stats()
    # No spread up to rounding: a few ulps of the period in seconds (8 s periods gave 1.8e-15 s).
    spread_tol_s = 1e-14 * max(1.0, period_ns * 1e-9)
    assert s.rate_hz == pytest.approx(1e9 / period_ns) and s.std_dev_s == pytest.approx(0.0, abs=spread_tol_s)
    assert s.window == n - 1


# ------------------------------------------------------------------------------ QoS choice


def _qos_args(**over):
    base = {"qos_profile": "sensor_data", "qos_reliability": None, "qos_durability": None,
            "qos_history": None, "qos_depth": None}
    return SimpleNamespace(**{**base, **over})


def _peer(rel, dur):
    return SimpleNamespace(qos_profile=SimpleNamespace(reliability=rel, durability=dur))


R, BE = QoSReliabilityPolicy.RELIABLE, QoSReliabilityPolicy.BEST_EFFORT
TL, VOL = QoSDurabilityPolicy.TRANSIENT_LOCAL, QoSDurabilityPolicy.VOLATILE


def test_echo_qos_adapts_to_publishers():
    assert tt.choose_qos(_qos_args(), [_peer(R, VOL), _peer(R, VOL)]).reliability == R
    mixed = tt.choose_qos(_qos_args(), [_peer(R, TL), _peer(BE, VOL)])
    assert (mixed.reliability, mixed.durability) == (BE, VOL)
    assert tt.choose_qos(_qos_args(), [_peer(R, TL)]).durability == TL
    alone = tt.choose_qos(_qos_args(), [])
    assert (alone.reliability, alone.depth) == (BE, 5)  # the sensor_data preset, untouched


def test_explicit_qos_options_win_and_presets_stay_unchanged():
    q = tt.choose_qos(_qos_args(qos_reliability="reliable", qos_depth=3), [_peer(BE, VOL)])
    assert (q.reliability, q.depth) == (R, 3)
    assert tt.choose_qos(_qos_args(), []).depth == 5  # the shared preset object was not modified


# ------------------------------------------------------------------------------ over DDS

pytestmark_dds = pytest.mark.integration


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    g = RosGraph(workdir=tmp_path_factory.mktemp("topic-tool"))
    try:
        # No probe subscription on /chatter here: info's counts must see the talker alone.
        g.start_node("erforce_interfaces", "talker", params={"rate_hz": 50.0})
        yield g
    finally:
        g.close()


@pytest.fixture
def spawned(graph):
    """Tool processes with piped output; reaped (SIGINT, SIGTERM, SIGKILL) after the test."""
    procs: list[subprocess.Popen] = []

    def spawn(*args: str) -> subprocess.Popen:
        p = subprocess.Popen([TOOL, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             stdin=subprocess.DEVNULL, env=graph.env, start_new_session=True)
        procs.append(p)
        return p

    yield spawn
    for p in procs:
        stop_process(p)


def run_tool(spawn, *args: str, timeout_s: float = 30.0) -> subprocess.CompletedProcess:
    p = spawn(*args)
    try:
        out, err = p.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        stop_process(p)
        out, err = p.communicate()
        pytest.fail(f"erforce-topic {' '.join(args)} still running after {timeout_s} s:\n{out}\n{err}")
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def run_until(spawn, args, wanted, timeout_s: float = 15.0) -> subprocess.CompletedProcess:
    """Run the tool again until its stdout satisfies ``wanted``: without a ros2 daemon, a fresh
    process sometimes needs one Fast DDS announcement period (about 3 s) to discover the talker."""
    deadline = time.monotonic() + timeout_s
    while True:
        r = run_tool(spawn, *args)
        assert r.returncode == 0, r.stderr
        if wanted(r.stdout) or time.monotonic() > deadline:
            return r


@pytestmark_dds
def test_list_shows_the_talker_topic_with_its_type(spawned):
    typed = run_until(spawned, ["list", "-t"], lambda out: "/chatter [" in out).stdout.splitlines()
    assert "/chatter [std_msgs/msg/String]" in typed
    assert "/rosout [rcl_interfaces/msg/Log]" in typed
    assert typed == sorted(typed)
    plain = run_until(spawned, ["list"], lambda out: "/chatter\n" in out).stdout.splitlines()
    assert "/chatter" in plain and all(" " not in line for line in plain)
    verbose = run_until(spawned, ["list", "-v"], lambda out: "/chatter" in out).stdout
    published, subscribed = verbose.split("\nSubscribed topics:\n")
    assert published.startswith("\nPublished topics:\n")
    assert " * /chatter [std_msgs/msg/String] 1 publisher\n" in published
    assert "/chatter" not in subscribed


@pytestmark_dds
def test_echo_once_prints_one_yaml_message(spawned):
    r = run_tool(spawned, "echo", "--once", "/chatter")
    assert r.returncode == 0, r.stderr
    assert re.fullmatch(r"data: hello \d+\n---\n", r.stdout), r.stdout


@pytestmark_dds
def test_echo_field_prints_the_bare_value(spawned):
    r = run_tool(spawned, "echo", "--once", "/chatter", "std_msgs/msg/String", "--field", "data")
    assert r.returncode == 0, r.stderr
    assert re.fullmatch(r"hello \d+\n---\n", r.stdout), r.stdout


@pytestmark_dds
def test_hz_reports_the_talker_rate(spawned):
    r = run_tool(spawned, "hz", "/chatter", "--count", "3", timeout_s=40.0)
    assert r.returncode == 0, r.stderr
    rates = [float(x) for x in re.findall(r"^average rate: (\d+\.\d{3})$", r.stdout, re.M)]
    details = re.findall(r"^\tmin: \d+\.\d{3}s max: \d+\.\d{3}s std dev: \d+\.\d{5}s window: (\d+)$",
                         r.stdout, re.M)
    assert len(rates) == 3 and len(details) == 3, r.stdout
    assert 45.0 <= rates[-1] <= 55.0, r.stdout
    assert int(details[-1]) > int(details[0])  # the window grows (default 10000)


@pytestmark_dds
def test_info_counts_and_verbose_endpoint_qos(spawned):
    r = run_tool(spawned, "info", "/chatter")
    assert r.returncode == 0, r.stderr
    assert r.stdout == "Type: std_msgs/msg/String\nPublisher count: 1\nSubscription count: 0\n"
    v = run_tool(spawned, "info", "-v", "chatter").stdout
    assert v.startswith("Type: std_msgs/msg/String\n\nPublisher count: 1\n\nNode name: talker\n"), v
    for line in ("Node namespace: /", "Topic type: std_msgs/msg/String", "Endpoint type: PUBLISHER",
                 "QoS profile:", "  Reliability: RELIABLE", "  Durability: VOLATILE",
                 "  Liveliness: AUTOMATIC"):
        assert line + "\n" in v, line
    for prefix in ("  History (Depth): ", "  Lifespan: ", "  Deadline: ", "  Liveliness lease duration: "):
        assert "\n" + prefix in v, prefix
    assert re.search(r"^GID: ([0-9a-f]{2}\.){15}[0-9a-f]{2}$", v, re.M)
    assert v.endswith("Subscription count: 0\n\n")


@pytestmark_dds
def test_pub_at_a_rate_reaches_a_subscriber_with_the_values(graph, spawned):
    got = graph.subscribe("/tool_test/cmd_vel", Twist, QOS_COMMAND)
    pub = spawned("pub", "/tool_test/cmd_vel", "geometry_msgs/msg/Twist", "{linear: {x: 1}, angular: {z: -0.5}}",
                  "-r", "20")
    graph.probe.spin_until(lambda: len(got) >= 3, 15.0, "3 Twists")
    assert {(m.linear.x, m.linear.y, m.angular.z) for m in got} == {(1.0, 0.0, -0.5)}
    stop_process(pub)
    out = pub.stdout.read()
    assert pub.returncode == 0
    assert "publisher: beginning loop\n" in out
    assert ("publishing #1: geometry_msgs.msg.Twist(linear=geometry_msgs.msg.Vector3(x=1.0, y=0.0, z=0.0), "
            "angular=geometry_msgs.msg.Vector3(x=0.0, y=0.0, z=-0.5))\n\n") in out


@pytestmark_dds
def test_pub_once_waits_for_the_subscriber_then_exits(graph, spawned):
    got = graph.subscribe("/tool_test/once", Twist, QOS_COMMAND)
    r = run_tool(spawned, "pub", "--once", "/tool_test/once", "geometry_msgs/Twist", "{linear: {y: 2.5}}")
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stdout.splitlines() if not ln.startswith("Waiting for at least 1 matching")]
    assert lines[:2] == ["publisher: beginning loop", "publishing #1: geometry_msgs.msg.Twist(linear="
                         "geometry_msgs.msg.Vector3(x=0.0, y=2.5, z=0.0), angular=geometry_msgs.msg.Vector3("
                         "x=0.0, y=0.0, z=0.0))"]
    graph.probe.spin_until(lambda: len(got) >= 1, 10.0, "the one Twist")  # it was acknowledged before exit
    assert len(got) == 1 and got[0].linear.y == 2.5


@pytestmark_dds
def test_echo_of_a_published_joint_state_is_the_exact_yaml(graph, spawned):
    echo = spawned("echo", "--once", "/tool_test/joints")  # waits for the topic to appear
    graph.start([TOOL, "pub", "/tool_test/joints", "sensor_msgs/msg/JointState", JOINT_STATE_YAML_IN, "-r", "10"])
    out, err = echo.communicate(timeout=30.0)
    assert echo.returncode == 0, err
    assert out == JOINT_STATE_YAML_OUT + "---\n"


@pytestmark_dds
@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (("pub", "/x", "geometry_msgs/msg/Twistt", "{}"), "unknown message type 'geometry_msgs/msg/Twistt'"),
        (("pub", "/x", "geometry_msgs/msg/Twist", "{linear: {x: [1}"), "invalid YAML"),
        (("pub", "/x", "geometry_msgs/msg/Twist", "{linear: {q: 1}}"), "unknown field 'linear.q'"),
        (("pub", "/x", "geometry_msgs/msg/Twist", "[1, 2]"), "dictionary"),
        (("echo", "/x", "nopkg/msg/Foo"), "unknown message type"),
        (("echo", "/chatter", "--once", "--field", "nope"), "invalid field 'nope'"),
    ],
)
def test_user_errors_are_one_line_and_exit_1(spawned, args, fragment):
    r = run_tool(spawned, *args)
    assert r.returncode == 1
    assert r.stdout == ""
    # a slow discovery may add the progress notice "waiting for topic ... to appear" (as ros2 topic
    # does); the error itself is one line
    errors = [line for line in r.stderr.splitlines() if not line.startswith("waiting for topic")]
    assert len(errors) == 1 and fragment in errors[0], r.stderr


@pytestmark_dds
def test_info_of_an_unknown_topic_is_an_error(spawned):
    r = run_tool(spawned, "info", "/tool_test/nobody", "--spin-time", "0.2")
    assert (r.returncode, r.stderr) == (1, "erforce-topic info: error: Unknown topic '/tool_test/nobody'\n")


@pytestmark_dds
def test_ctrl_c_ends_a_streaming_echo_cleanly(graph):
    echo = graph.start([TOOL, "echo", "/chatter"])
    echo.wait_for_output(r"(data: hello \d+\n---\n){3}", timeout_s=20.0)
    echo.signal(signal.SIGINT)
    assert echo.wait_exit(10.0) == 0
    assert "Traceback" not in echo.output()
