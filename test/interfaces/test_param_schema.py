"""Node parameter schemas (erforce_interfaces.runtime.param_schema): the rules, the shipped files, and one
default per quantity across the schemas, the cores and the docs."""

import dataclasses
import importlib
import inspect
import math
from pathlib import Path

import pytest
from setuptools.config.setupcfg import read_configuration

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.catch_time import CatchSearch
from erforce_ball_model.receiver import CatcherConfig
from erforce_ball_model.tracking import TrackerConfig
from erforce_interfaces.runtime import lockstep
from erforce_interfaces.runtime.param_schema import (
    HostSchema,
    ParamSchema,
    ParamSpec,
    check_finite_fields,
    fields_for,
    load_schema,
    robot_param_specs,
)
from erforce_interfaces.tools.docs import NODE_SCHEMAS
from erforce_motion.motor_board import MotorBoardConfig
from erforce_motion.pid import ANTI_WINDUP_MODES
from erforce_motion.velocity_control import VelocityControlConfig

ROOT = Path(__file__).resolve().parents[2]
ALL = (*NODE_SCHEMAS, ("erforce_interfaces", "talker"))


@pytest.mark.parametrize(("package", "node"), ALL, ids=[n for _, n in ALL])
def test_every_schema_loads_and_ships_in_share(package, node):
    schema = load_schema(package, node)
    assert schema.node == node and schema.specs
    for spec in schema.specs:
        assert spec.check(spec.default) is None and spec.description
    # installed with the package: package data of the Python package, and in share/<package>/params
    setup = _setup_kwargs(package)
    assert "params/*.yaml" in setup["package_data"][package]
    shared = {f for dest, files in setup["data_files"] if dest == f"share/{package}/params" for f in files}
    assert f"{package}/params/{node}.yaml" in shared


def _setup_kwargs(package: str) -> dict:
    """What the package's setup.cfg declares for setuptools (read by setuptools' own parser)."""
    return read_configuration(ROOT / "src" / package / "setup.cfg")["options"]


def _schema(body: str) -> ParamSchema:
    return ParamSchema.from_yaml_text("n:\n" + body)


@pytest.mark.parametrize(("body", "match"), [
    ("  a: {type: double, default_value: 1.0}\n", "needs type, default_value or default_from, description"),
    ("  a: {type: float, default_value: 1.0, description: x}\n", "unknown type"),
    ("  a: {type: double, default_value: 1.0, description: x, validation: {positive<>: []}}\n",
     "unknown validation"),
    ("  a: {type: double, default_value: 1.0, description: x, validation: {bounds<>: [1e-6, 2.0]}}\n",
     "not a number"),  # YAML 1.1 reads 1e-6 as a string
    ("  a: {type: double, default_value: 3.0, description: x, validation: {bounds<>: [0.0, 2.0]}}\n",
     "default of a: 3.0 is above the maximum"),
    ("  a: {type: string, default_value: c, description: x, validation: {one_of<>: [[a, b]]}}\n", "one of a, b"),
    ("  robot: {shared: something_else}\n", "the only shared group is robot"),
    ("  a: {type: int, default_value: 1, default_from: math:pi, description: x}\n", "default_value or default_from"),
    ("  a: {type: int, default_from: math:no_such_constant, description: x}\n", "is no module:CONSTANT"),
    ("  a: {type: int, default_from: no_such_module:X, description: x}\n", "is no module:CONSTANT"),
    ("  a: {type: int, default_from: math:pi, description: x}\n", "default of a: expected int"),  # a double for an int
])
def test_schema_files_with_mistakes_are_refused_naming_them(body, match):
    with pytest.raises(ValueError, match=match):
        _schema(body)


def test_a_default_from_code_is_the_constant_itself():
    schema = _schema("  p: {type: int, default_from: 'erforce_interfaces.ssl.ssl_sim:SIM_CONTROL_PORT',"
                     " description: x}\n"
                     "  e: {type: double, default_from: 'math:e', description: x}\n")
    assert schema.defaults() == {"p": 10300, "e": math.e}


def test_validation_rules_match_generate_parameter_library_meanings():
    s = _schema(
        "  gt: {type: double, default_value: 1.0, description: x, validation: {gt<>: [0.0]}}\n"
        "  lt_eq: {type: int, default_value: 1, description: x, validation: {lt_eq<>: [3]}}\n"
        "  ids: {type: int_array, default_value: [], description: x, validation: {bounds<>: [0, 9]}}\n"
        "  xy: {type: double_array, default_value: [0.0, 0.0], description: x, validation: {fixed_size<>: [2]}}\n"
        "  modes: {type: string_array, default_value: [a], description: x, validation: {subset_of<>: [[a, b]]}}\n")
    spec = s.by_name
    assert spec["gt"].check(0.0) and spec["gt"].check(1e-9) is None  # strictly greater
    assert spec["lt_eq"].check(3) is None and spec["lt_eq"].check(4)
    assert spec["lt_eq"].check(True) and spec["gt"].check(math.nan) and spec["gt"].check("1.0")
    assert spec["ids"].check([0, 9]) is None and spec["ids"].check([0, 10]) and spec["ids"].check([1.5])
    assert spec["xy"].check([1.0]) and spec["xy"].check([1.0, 2.0]) is None and spec["xy"].check([1.0, math.inf])
    assert spec["modes"].check(["b", "a"]) is None and spec["modes"].check(["a", "c"])
    config = s.parse(s.defaults())
    assert (config.gt, config.ids, config.xy, config.modes) == (1.0, (), (0.0, 0.0), ("a",))
    assert not hasattr(config, "robot")
    with pytest.raises(ValueError, match="invalid parameter gt"):
        s.parse({**s.defaults(), "gt": -1.0})


def test_fields_for_refuses_a_core_option_the_node_does_not_declare():
    @dataclasses.dataclass
    class Core:
        gain: float = 1.0
        added_later: float = 2.0

    s = _schema("  gain: {type: double, default_value: 3.0, description: x}\n")
    with pytest.raises(TypeError, match="Core.added_later"):
        fields_for(Core, s.parse(s.defaults()))
    assert fields_for(Core, s.parse(s.defaults()), added_later=5.0) == {"gain": 3.0, "added_later": 5.0}


def test_check_finite_fields_names_the_first_field_out_of_its_bound():
    @dataclasses.dataclass
    class Core:
        gain: object = 1.0
        offset: object = 0

    check_finite_fields(Core(), ("gain", "offset"), 0.0)
    check_finite_fields(Core(offset=-2.0), ("gain",), 0.0, lower_open=True)
    for core, lower_open, match in (
            (Core(), True, r"Core\.offset: must be finite and > 0, got 0$"),
            (Core(offset=-1e-12), False, r"Core\.offset: must be finite and >= 0"),
            (Core(gain=math.nan, offset=-1.0), False, r"Core\.gain: .* got nan$"),
            (Core(gain=math.inf), False, r"Core\.gain: .* got inf$"),
            (Core(gain="1.0"), False, r"Core\.gain: .* got '1\.0'$")):  # a number's text is no number
        with pytest.raises(ValueError, match=match):
            check_finite_fields(core, ("gain", "offset"), 0.0, lower_open=lower_open)
    check_finite_fields(Core(gain=90.0), ("gain",), 0.0, 90.0)
    with pytest.raises(ValueError, match=r"Core\.gain: must be finite and in \[0, 90\), got 90\.0$"):
        check_finite_fields(Core(gain=90.0), ("gain",), 0.0, 90.0, upper_open=True)
    with pytest.raises(ValueError, match=r"Core\.offset: must be finite and in \(0, 1\], got 0$"):
        check_finite_fields(Core(), ("offset",), 0.0, 1.0, lower_open=True)


@pytest.mark.parametrize(("core", "field", "good", "bad"), [
    ("erforce_ball_model.passing.player:PlayerConfig", "hold_min_s", 0.0, -0.01),
    ("erforce_ball_model.passing.player:PlayerConfig", "turn_rate_radps", 1e-9, 0.0),
    ("erforce_ball_model.passing.decisions:PassConfig", "arrive_speed_mps", 1e-9, 0.0),
    ("erforce_ball_model.passing.decisions:PassConfig", "chip_step_back_m", 0.0, math.nan),
    ("erforce_sim.world_types:PhysicsParams", "max_step_s", 1e-9, 0.0),
    ("erforce_sim.world_types:PhysicsParams", "dribbler_pull_mps2", 0.0, -1.0),
    ("erforce_sim.world_types:PhysicsParams", "kick_spin_ratio", -1.0, 1.01),
    ("erforce_sim.world_types:PhysicsParams", "substep_hz", 1e6, 9999.0),
    ("erforce_ball_model.passing.player:PlayerConfig", "max_receive_angle_rad", 0.0, 0.5 * math.pi),
    ("erforce_ball_model.passing.decisions:PassConfig", "chip_angle_deg", 0.0, 90.0),
    ("erforce_ball_model.passing.decisions:PassConfig", "chip_settle_fraction", 1.0, 0.0),
    ("erforce_ball_model.passing.decisions:PassConfig", "press_fraction", 1.0, math.nan),
])
def test_core_configs_refuse_a_field_out_of_bound_naming_it(core, field, good, bad):
    module, _, name = core.partition(":")
    cls = getattr(importlib.import_module(module), name)
    cls(**{field: good})  # at the bound (just above it, for an open one): taken
    with pytest.raises(ValueError, match=rf"^{name}\.{field}: must be finite"):
        cls(**{field: bad})


# ------------------------------------------------------------------ one default per quantity
def _core_defaults(cls) -> dict:
    return {f.name: f.default for f in dataclasses.fields(cls)}


@pytest.mark.parametrize(("package", "node", "core", "skip"), [
    ("erforce_motion", "velocity_controller", VelocityControlConfig, ()),
    ("erforce_motion", "motor_boards", MotorBoardConfig,
     ("linear_duty_per_a", "loop_period_s", "average_current_limit_a", "i2t_time_constant_s")),
    ("erforce_ball_model", "catcher", CatcherConfig, ()),
    ("erforce_ball_model", "ball_predictor", TrackerConfig, None),
    ("erforce_ball_model", "ball_predictor", BallModelParams, None),
])
def test_node_defaults_are_the_cores_defaults(package, node, core, skip):
    """The schema declares a core option's default for the node; the core's own default must agree."""
    schema = load_schema(package, node)
    shared = [n for n in _core_defaults(core) if n in schema.by_name and n not in (skip or ())]
    if skip is not None:  # the node maps every option of the core except these
        assert set(shared) == set(_core_defaults(core)) - set(skip)
    assert shared
    for name in shared:
        assert schema.default(name) == _core_defaults(core)[name], name


def test_the_predictor_plans_with_the_limits_and_grid_the_catcher_and_search_use():
    predictor = load_schema("erforce_ball_model", "ball_predictor")
    catcher = load_schema("erforce_ball_model", "catcher")
    assert predictor.default("robot_a_max_mps2") == catcher.default("a_max_mps2") == CatcherConfig().a_max_mps2
    assert predictor.default("robot_v_max_mps") == catcher.default("v_max_mps") == CatcherConfig().v_max_mps
    grid = inspect.signature(CatchSearch).parameters["grid_step_s"].default
    assert predictor.default("grid_step_s") == grid


def test_one_lockstep_tick_for_plant_robot_nodes_and_docs():
    tick_s = lockstep.TICK_PERIOD_S
    assert load_schema("erforce_sim", "plant").default("control_period_s") == tick_s
    for node in ("velocity_controller", "motor_boards"):
        assert load_schema("erforce_motion", node).default("loop_rate_hz") == pytest.approx(1.0 / tick_s)
    assert f"default ``TICK_PERIOD_S``, {tick_s * 1e3:g} ms" in lockstep.__doc__
    assert f"Each tick ({tick_s * 1e3:g} ms by" in (ROOT / "docs/graph.md").read_text()


def test_anti_windup_choices_are_the_pids():
    for node in ("velocity_controller", "motor_boards"):
        assert load_schema("erforce_motion", node).by_name["anti_windup"].one_of == ANTI_WINDUP_MODES


def test_what_a_node_cannot_apply_while_running_is_read_only():
    plant = load_schema("erforce_sim", "plant")
    robot = [s for s in plant.specs if s.name.startswith("robot.")]
    assert robot and all(s.read_only for s in robot)  # the world is built once
    assert all(s.read_only for s in plant.specs
               if s.name in ("field", "robot_poses", "seed", "control_period_s", "startup_timeout_s"))
    assert load_schema("erforce_ball_model", "catcher").by_name["rate_hz"].read_only  # its timer is made once
    for node in ("velocity_controller", "motor_boards"):  # they rebuild their loop on any change
        assert not any(s.read_only for s in load_schema("erforce_motion", node).specs)


def test_a_host_schema_declares_the_hosted_parameters_under_a_prefix_and_parses_each_as_its_own():
    own = ParamSchema.from_yaml_text(
        "host:\n  ids: {type: int_array, default_value: [0], description: ids}\n  robot: {shared: robot_description}\n")
    hosted = ParamSchema.from_yaml_text(
        "part:\n  rate_hz: {type: double, default_value: 50.0, description: r, validation: {bounds<>: [1.0, 900.0]}}\n"
        "  wait: {type: bool, default_value: true, description: wait}\n  robot: {shared: robot_description}\n")
    host = HostSchema(own, {"a.": (hosted, ("wait",))})
    names = [s.name for s in host.specs]
    assert names[:2] == ["ids", "a.rate_hz"] and "a.wait" not in names and "wait" not in names
    assert sum(n.startswith("robot.") for n in names) == len(robot_param_specs())  # once, for the host
    values = host.defaults() | {"a.rate_hz": 200.0, "robot.mass_kg": 3.0}
    own_config, parts = host.parse(values)
    assert own_config.ids == (0,) and own_config.robot.mass_kg == 3.0
    assert (parts["a."].rate_hz, parts["a."].wait, parts["a."].robot.mass_kg) == (200.0, True, 3.0)
    with pytest.raises(ValueError, match="a.rate_hz"):
        host.parse(values | {"a.rate_hz": 1000.0})
    with pytest.raises(ValueError, match="listed twice"):
        HostSchema(own, {"": (own, ())})


@pytest.mark.parametrize(("kind", "given", "taken"), [
    ("double", 0, 0.0), ("double", -3, -3.0), ("double", 2.5, 2.5), ("double", True, True), ("double", "1", "1"),
    ("double_array", [1, 2.5], [1.0, 2.5]), ("double_array", (0,), [0.0]), ("int", 3, 3), ("int_array", [1], [1]),
    ("string", "0", "0"), ("bool", False, False),
])
def test_coerce_takes_an_integer_for_a_double_and_leaves_the_rest_to_check(kind, given, taken):
    default = {"double": 1.0, "double_array": [1.0], "int": 1, "int_array": [1], "string": "a", "bool": True}[kind]
    spec = ParamSpec("p", kind, default, "a parameter")
    value = spec.coerce(given)
    assert value == taken and type(value) is type(taken)
    if isinstance(taken, list):
        assert [type(v) for v in value] == [type(v) for v in taken]
