"""One default per physical quantity: the robot's catching limits and the predictor's settings agree everywhere.

The planner (catch_time.RobotLimits), the catcher (CatcherConfig), both nodes' parameters, the launch
files and the parameter reference (docs/reference.md) all carry catch_time.ROBOT_A_MAX_MPS2 /
ROBOT_V_MAX_MPS; the predictor's core configuration has the node's parameter defaults. Any copy that
drifts fails here.
"""

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from erforce_ball_model import ball_predictor_node, catcher_node
from erforce_ball_model.catch_time import ROBOT_A_MAX_MPS2, ROBOT_V_MAX_MPS, RobotLimits
from erforce_ball_model.predictor import PredictorConfig
from erforce_ball_model.receiver import CatcherConfig

ROOT = Path(__file__).resolve().parents[2]
LAUNCH_FILES = ("src/erforce_sim/launch/demo.launch.yaml", "src/erforce_sim/launch/receiver.launch.yaml")


def _defaults(node_module) -> dict:
    return {s.name: s.default for s in node_module.SCHEMA.specs}


def test_the_robot_limits_have_one_default():
    limits = RobotLimits()
    assert (float(limits.a_max_mps2), float(limits.v_max_mps)) == (ROBOT_A_MAX_MPS2, ROBOT_V_MAX_MPS)
    assert (CatcherConfig().a_max_mps2, CatcherConfig().v_max_mps) == (ROBOT_A_MAX_MPS2, ROBOT_V_MAX_MPS)
    predictor = _defaults(ball_predictor_node)
    assert (predictor["robot_a_max_mps2"], predictor["robot_v_max_mps"]) == (ROBOT_A_MAX_MPS2, ROBOT_V_MAX_MPS)
    catcher = _defaults(catcher_node)
    assert (catcher["a_max_mps2"], catcher["v_max_mps"]) == (ROBOT_A_MAX_MPS2, ROBOT_V_MAX_MPS)
    config = PredictorConfig()
    assert (float(config.limits.a_max_mps2), float(config.limits.v_max_mps)) == (ROBOT_A_MAX_MPS2, ROBOT_V_MAX_MPS)


@pytest.mark.parametrize("path", LAUNCH_FILES)
def test_launch_files_default_to_the_same_robot_limits(path):
    args = {a["arg"]["name"]: a["arg"].get("default") for a in yaml.safe_load((ROOT / path).read_text())["launch"]
            if "arg" in a}
    assert float(args["robot_a_max_mps2"]) == ROBOT_A_MAX_MPS2
    assert float(args["robot_v_max_mps"]) == ROBOT_V_MAX_MPS


def test_the_parameter_reference_shows_the_same_robot_limits():
    text = (ROOT / "docs" / "reference.md").read_text()
    for name, value in (("robot_a_max_mps2", ROBOT_A_MAX_MPS2), ("a_max_mps2", ROBOT_A_MAX_MPS2),
                        ("robot_v_max_mps", ROBOT_V_MAX_MPS), ("v_max_mps", ROBOT_V_MAX_MPS)):
        rows = re.findall(rf"^\| `{name}` \| [a-z_]+ \| `([^`]*)` \|", text, flags=re.MULTILINE)
        assert rows and all(float(r) == value for r in rows), (name, rows)


def test_the_predictor_core_defaults_are_the_nodes_parameter_defaults():
    """The in-process scenes and the bench build PredictorConfig() themselves: it must be the node's configuration."""
    values = _defaults(ball_predictor_node)
    from_params = ball_predictor_node.build_config(ball_predictor_node.SCHEMA.parse(values))
    core = PredictorConfig(num_robots=values["num_robots"])
    for f in dataclasses.fields(PredictorConfig):
        got, want = getattr(core, f.name), getattr(from_params, f.name)
        if isinstance(want, RobotLimits):
            assert (float(got.a_max_mps2), float(got.v_max_mps)) == (float(want.a_max_mps2), float(want.v_max_mps))
        elif isinstance(want, np.ndarray):
            np.testing.assert_array_equal(got, want, err_msg=f.name)
        else:
            assert got == want, f.name


def test_the_predictor_core_speaks_the_contract():
    from erforce_ball_model import chip_model, predictor
    from erforce_interfaces.wire import contract

    assert predictor.CATCH_TIME_NEVER == contract.CATCH_TIME_NEVER
    assert predictor.MODEL_ROWS == contract.BALL_MODEL_PARAM_ROWS
    assert (set(predictor.PHASE_NAMES.values()) | {"unknown", chip_model.PHASE_CHIP, chip_model.PHASE_HOPPING}
            == set(contract.BALL_PHASES))


def test_the_chip_dampings_from_ssl_geometry_are_named_once():
    """/vision/chip_model's columns, the SSL decoder's chip_fixed_loss and what the predictor takes from SSL
    geometry are the same ChipParams fields: each of them alone is taken, any other ChipParams field refused."""
    from erforce_ball_model.ball_model import ChipParams
    from erforce_ball_model.predictor import BallPredictor
    from erforce_interfaces.ssl.ssl_vision import ChipModelFromVision
    from erforce_interfaces.wire import contract

    labels = contract.VISION_CHIP_MODEL_LABELS
    assert tuple(f.name for f in dataclasses.fields(ChipModelFromVision)) == labels
    chip_fields = {f.name for f in dataclasses.fields(ChipParams)}
    assert set(labels) < chip_fields
    predictor = BallPredictor(PredictorConfig(num_robots=1))
    for name in labels:
        predictor.set_vision_geometry(chip_dampings={name: 0.5})
        assert getattr(predictor.chip_model, name) == 0.5
    for name in sorted(chip_fields - set(labels)):
        with pytest.raises(ValueError, match="only"):
            predictor.set_vision_geometry(chip_dampings={name: 0.5})


def test_the_ball_and_wall_have_one_default_for_prediction_and_plant():
    """The predicted bounce (walls.Walls, the predictor's wall_restitution) and the plant's wall contact
    (erforce_sim.contacts, erforce_sim.ball) take the same restitution, friction, inertia and radius."""
    from erforce_ball_model.walls import Walls
    from erforce_interfaces.wire import robot_config as rc
    from erforce_sim.ball import BallParams
    from erforce_sim.contacts import ContactParams

    walls, contact, ball = Walls(1.0, 1.0), ContactParams(), BallParams()
    assert _defaults(ball_predictor_node)["wall_restitution"] == PredictorConfig().wall_restitution
    assert PredictorConfig().wall_restitution == walls.restitution == contact.ball_wall_restitution
    assert walls.restitution == rc.BALL_WALL_RESTITUTION
    assert walls.friction == contact.ball_wall_friction == rc.BALL_WALL_FRICTION
    assert walls.inertia_factor == ball.inertia_factor == rc.BALL_INERTIA_FACTOR
    assert ball.radius_m == rc.BALL_RADIUS_M
